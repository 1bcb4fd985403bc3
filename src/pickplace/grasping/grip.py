"""What a grip can carry, and motion slowed down to it (grasp-aware motion).

The pads hold the object by friction: with both pads squeezing ``F`` (N) each and a friction coefficient
``mu``, they can transmit at most ``2 mu F`` along their faces. The grip's closing axis is horizontal, so the
whole force the object needs, ``m (a - g)`` (its weight and its inertia), lies along the faces and must stay
below that, with a safety factor ``s``:

    ``m |a - g| s <= 2 mu F``

Everything here uses what the robot *believes*: the configured mass and friction, the commanded squeeze
(:func:`~pickplace.robot.gripper.squeeze_per_pad_n`), the centre of mass from the geometry at uniform
density. An object whose weight alone needs more (``m g s > 2 mu F``) cannot be held at any acceleration: the
episode rejects it before the arm moves (:class:`~pickplace.errors.CannotHold`). Otherwise the lift and the
set-down are limited to the vertical acceleration that holds, and a carrying trajectory is slowed down
uniformly until the centre of mass's acceleration holds at every instant.

An object whose centre of mass is off the closing axis also turns in the grip: its weight has a torque
``m g l`` about the axis (``l`` the centre of mass's horizontal distance from it) that the pads resist by
their torsional friction, ``2 mu_t F`` (``mu_t`` a length: MuJoCo's torsional friction, the larger of the
pad's and the object's). With the safety factor, ``m g l s > 2 mu_t F`` is rejected like a weight the pads
cannot carry, and the acceleration budget is the smaller of the two. This counts only the torsional term: the
friction of a flat pad's contact patch adds to it, so the test errs on the side of rejecting.

A transport that tilts the object on its side (the arm going from one IK branch to another: the hand turns
over) loads the grip in a way this model does not bound, and the object creeps in it (:data:`TURN_OVER_RAD`):
grasps are chosen to keep it upright on the way (:func:`carried_tilt_rad`), and a transport that still tilts it
is slowed down.

Not modelled: dynamic effects of the squeeze itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickplace.errors import CannotHold
from pickplace.motion.timing import Trajectory
from pickplace.robot.gripper import GripperGeometry, squeeze_per_pad_n
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import Robot
from pickplace.world.mass import mass_properties
from pickplace.world.objects import ObjectConfig

#: Standard gravity (m/s^2).
G = 9.81
#: The slowest a carrying trajectory is made (times its time-optimal duration); beyond it the motion is deemed
#: impossible to hold rather than merely slow.
MAX_SLOWDOWN = 20.0
#: Spacing of the samples at which a trajectory's centre-of-mass acceleration is checked (s).
SAMPLE_DT_S = 0.005
#: A carried object that tilts more than this from how it was lifted (rad) is turned over on the way. Measured
#: on a 58 g ball held at 40 N, a transport that turned the hand over crept it 3.0 mm in the grip at full speed,
#: 2.5 mm at half speed and 1.3 mm at a third (the slip check's tolerance is 3 mm).
TURN_OVER_RAD = math.radians(45.0)


@dataclass(frozen=True)
class GripCapacity:
    """What a grip can carry, and what the object needs.

    Attributes:
        mass_kg: The object's (believed) mass (kg).
        friction: Its (believed) friction coefficient.
        pad_force_n: Normal force of each pad (N).
        safety_factor: Factor the needed force is multiplied by before it is compared (1 = no margin).
        com_tcp_m: The object's centre of mass in the tcp frame (3,) (m).
        lever_m: Horizontal distance of the centre of mass from the closing axis (m): the weight's lever.
        torsion_m: Torsional friction of the pads on the object (m: torque over normal force).
    """

    mass_kg: float
    friction: float
    pad_force_n: float
    safety_factor: float
    com_tcp_m: tuple[float, float, float]
    lever_m: float = 0.0
    torsion_m: float = 0.0

    @property
    def friction_force_n(self) -> float:
        """The most the pads transmit along their faces, ``2 mu F`` (N)."""
        return 2.0 * self.friction * self.pad_force_n

    @property
    def needed_at_rest_n(self) -> float:
        """What holding the object still needs, ``m g s`` (N)."""
        return self.mass_kg * G * self.safety_factor

    @property
    def torque_capacity_nm(self) -> float:
        """The most the pads resist about the closing axis, ``2 mu_t F`` (N m)."""
        return 2.0 * self.torsion_m * self.pad_force_n

    @property
    def needed_torque_at_rest_nm(self) -> float:
        """What holding the object still needs about the closing axis, ``m g l s`` (N m)."""
        return self.mass_kg * G * self.lever_m * self.safety_factor

    @property
    def holds_at_rest(self) -> bool:
        """Whether the pads hold the object still: its weight and the weight's torque about the axis."""
        return (self.needed_at_rest_n <= self.friction_force_n
                and self.needed_torque_at_rest_nm <= self.torque_capacity_nm)

    @property
    def acceleration_budget_m_s2(self) -> float:
        """The largest ``|a - g|`` of the centre of mass that holds (m/s^2): ``2 mu F / (m s)``, and with the
        centre of mass off the axis at most ``2 mu_t F / (m l s)`` (the torque of its inertia, taken as if
        it all acted on the lever)."""
        budget = self.friction_force_n / (self.mass_kg * self.safety_factor)
        if self.lever_m > 0.0:
            budget = min(budget, self.torque_capacity_nm / (self.mass_kg * self.lever_m * self.safety_factor))
        return budget

    @property
    def max_vertical_accel_m_s2(self) -> float:
        """The largest vertical acceleration (either way) that holds: the budget less gravity (m/s^2)."""
        return self.acceleration_budget_m_s2 - G

    def require_holdable(self, name: str) -> None:
        """Raise :class:`CannotHold` if the object's weight alone needs more friction than the pads have, or
        turns it about the closing axis harder than their torsional friction resists."""
        if self.needed_at_rest_n > self.friction_force_n:
            raise CannotHold(name, self.needed_at_rest_n, self.friction_force_n, self.mass_kg, self.friction,
                             self.pad_force_n, self.safety_factor)
        if self.needed_torque_at_rest_nm > self.torque_capacity_nm:
            raise CannotHold.turning(name, self.needed_torque_at_rest_nm, self.torque_capacity_nm, self.mass_kg,
                                     self.lever_m, self.torsion_m, self.pad_force_n, self.safety_factor)


def grip_capacity(robot: Robot, obj: ObjectConfig, T_tcp_object: pin.SE3, width_m: float,
                  safety_factor: float, mass_kg: float | None = None, up_tcp: np.ndarray | None = None,
                  geom: GripperGeometry | None = None) -> GripCapacity:
    """The capacity of a grip on ``obj`` held at ``T_tcp_object`` across ``width_m`` (m).

    Args:
        robot: The models (the gripper's actuator and pads).
        obj: The object as the robot believes it.
        T_tcp_object: The object's pose in the tcp frame.
        width_m: Its width between the pads (m).
        safety_factor: Margin on the needed force (>= 1).
        mass_kg: A mass to use instead of the configured one (e.g. after weighing it) (kg).
        up_tcp: The world's up direction in the tcp frame (3,); default: the object's z axis (it rests on its
            resting face).
        geom: The gripper's measured geometry, if the caller has it (measured here otherwise).
    """
    com = T_tcp_object.act(mass_properties(obj).com_m)
    up = T_tcp_object.rotation[:, 2] if up_tcp is None else np.asarray(up_tcp, dtype=float)
    lever = float(abs(com[2] * up[0] - com[0] * up[2]))  # |(com x up) . y|, y the closing axis
    pad_torsion = float(np.max(robot.mj.geom_friction[robot.handles.pad_geoms, 1]))
    return GripCapacity(obj.mass_kg if mass_kg is None else mass_kg, obj.friction,
                        squeeze_per_pad_n(robot, width_m, geom), safety_factor,
                        (float(com[0]), float(com[1]), float(com[2])), lever,
                        max(pad_torsion, obj.torsional_friction_m))


def com_accelerations(robot: Robot, traj: Trajectory, com_tcp_m: np.ndarray, finger_m: float,
                      dt_s: float = SAMPLE_DT_S) -> np.ndarray:
    """The held object's centre-of-mass acceleration (N, 3) in the world (m/s^2) along a trajectory, every
    ``dt_s`` (rigid with the tcp: ``a_tcp + alpha x r + omega x (omega x r)``)."""
    model, data, fid = robot.pin, robot.pin.createData(), robot.pin_tcp_frame
    ts = np.arange(0.0, traj.duration_s + dt_s, dt_s)
    qs, qds, qdds = traj.sample_many(ts)
    n = len(ts)
    lin, ang, w, r = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    v, a = np.zeros(model.nv), np.zeros(model.nv)
    r_tcp = np.asarray(com_tcp_m, dtype=float)
    for k in range(n):
        v[:6], a[:6] = qds[k], qdds[k]
        pin.forwardKinematics(model, data, robot.pin_q(qs[k], finger_m), v, a)
        acc = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        lin[k], ang[k] = acc.linear, acc.angular
        w[k] = pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED).angular
        r[k] = pin.updateFramePlacement(model, data, fid).rotation.dot(r_tcp)
    return lin + np.cross(ang, r) + np.cross(w, np.cross(w, r))  # the cross products for every sample at once


def slowdown_for_grip(accels: np.ndarray, capacity: GripCapacity) -> float:
    """The smallest factor (>= 1) by which a trajectory with these centre-of-mass accelerations (N, 3) (m/s^2)
    must be slowed down for the grip to hold at every sample (accelerations scale with its inverse square).

    Raises:
        CannotHold: the object cannot be held even at rest, or only slower than ``MAX_SLOWDOWN`` times.
    """
    budget = capacity.acceleration_budget_m_s2
    g = np.array([0.0, 0.0, -G])

    def holds(k: float) -> bool:
        return bool(np.all(np.linalg.norm(accels / k**2 - g, axis=1) <= budget))

    if holds(1.0):
        return 1.0
    if not holds(MAX_SLOWDOWN):
        worst = float(np.max(np.linalg.norm(accels / MAX_SLOWDOWN**2 - g, axis=1)))
        raise CannotHold("object", capacity.mass_kg * worst * capacity.safety_factor, capacity.friction_force_n,
                         capacity.mass_kg, capacity.friction, capacity.pad_force_n, capacity.safety_factor, worst)
    lo, hi = 1.0, MAX_SLOWDOWN
    for _ in range(40):  # bisection to ~1e-10 relative
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if holds(mid) else (mid, hi)
    return hi


def carried_tilt_rad(robot: Robot, qs: np.ndarray) -> float:
    """Largest tilt (rad) of a carried object over the arm configurations ``qs`` (N, 6) (rad): the angle from the
    world's vertical of the axis that is vertical at ``qs[0]`` (rigid with the tcp)."""
    model, data, fid = robot.pin, robot.pin.createData(), robot.pin_tcp_frame
    Rs = [frame_pose(model, data, robot.pin_q(q), fid).rotation for q in qs]
    up_tcp = Rs[0][2]  # the world's vertical in the tcp frame at the start
    return float(np.max(np.arccos(np.clip([R[2] @ up_tcp for R in Rs], -1.0, 1.0))))


def joint_line(q_a: np.ndarray, q_b: np.ndarray, step_rad: float = 0.05) -> np.ndarray:
    """Configurations (N, 6) along the straight joint-space line from ``q_a`` to ``q_b``, no joint moving more
    than ``step_rad`` between two, ends included."""
    n = max(2, math.ceil(float(np.max(np.abs(q_b - q_a))) / step_rad) + 1)
    return np.linspace(q_a, q_b, n)


__all__ = ["MAX_SLOWDOWN", "TURN_OVER_RAD", "G", "GripCapacity", "carried_tilt_rad", "com_accelerations",
           "grip_capacity", "joint_line", "slowdown_for_grip"]
