"""The parallel-jaw gripper: geometry, commands, contact state and grip force.

How well it holds is measured by the hold test, :mod:`pickplace.grasping.hold`.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from pickplace.errors import ConfigError
from pickplace.robot.model import Robot
from pickplace.world.config import check_range
from pickplace.world.contact import Contact

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- #
# drive: closing speed and grip force
# --------------------------------------------------------------------------- #

#: The finger drive as ``gripper.xml`` builds it: the position servo saturates at 40 N on the coupled finger pair,
#: 20 N per pad, against 60 N s/m of damping per finger slide, so the fingers close at 40 / (2 x 60) = 1/3 m/s.
IDEAL_GRIP_FORCE_N = 20.0
IDEAL_CLOSING_SPEED_M_S = 40.0 / 120.0
#: Robotiq 2F-85 datasheet (Robotiq, "2F-85 & 2F-140 Instruction Manual", specifications): closing speed
#: 20-150 mm/s, grip force 20-235 N. The realistic profile takes the top speed, and the lowest force, which is
#: also this gripper's squeeze: the grasp capacities (``grasping.grip``) are computed from the model's force
#: limit either way, so a stronger grip stays an explicit choice.
ROBOTIQ_2F85_MAX_CLOSING_SPEED_M_S = 0.150
ROBOTIQ_2F85_MIN_GRIP_FORCE_N = 20.0
ROBOTIQ_2F85_MAX_GRIP_FORCE_N = 235.0
#: Time constant (s) of the equality that keeps the two fingers symmetric, as built.
IDEAL_COUPLING_TIMECONST_S = 0.005
#: A linkage gripper's (the 2F-85's) fingers are coupled rigidly: the stiffest the soft constraint stays stable
#: at, two physics steps of 1 ms (s).
LINKAGE_COUPLING_TIMECONST_S = 0.002


@dataclass(frozen=True)
class GripperConfig:
    """How fast the fingers close and how hard they squeeze (defaults: the model as built, the ideal profile).

    The finger servo is a position actuator that, commanded fully closed, saturates at its force limit and
    drives the two coupled finger slides against their damping: free closing speed = force limit / (2 x
    damping per finger). :func:`with_gripper` sets the force limit to ``2 x grip_force_n`` (both pads) and the
    damping to ``grip_force_n / closing_speed_m_s`` per finger; a force above the built one scales the servo's
    stiffness with it, so that it still saturates as soon as the fingers stop 8 mm short of the closed target.

    The servo drives the fingers' mean travel (a tendon, half its force on each finger), so they close together
    and squeeze a centred object equally; a soft equality constraint keeps them symmetric about the tcp, and an
    object off centre meets one pad first and is pushed by it against that constraint's compliance until the
    other arrives. A linkage drive is stiffer.

    Attributes:
        closing_speed_m_s: Speed of each finger (pad) closing or opening freely (m/s).
        grip_force_n: Normal force of each pad on a held object, the servo saturated (N).
        coupling_timeconst_s: Time constant of the finger coupling (MuJoCo ``solref``) (s): at least two
            physics steps.
    """

    closing_speed_m_s: float = IDEAL_CLOSING_SPEED_M_S
    grip_force_n: float = IDEAL_GRIP_FORCE_N
    coupling_timeconst_s: float = IDEAL_COUPLING_TIMECONST_S

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "closing_speed_m_s", check_range("gripper.closing_speed_m_s", self.closing_speed_m_s,
                                                    0.005, 1.0, unit="m/s"))
        set_(self, "grip_force_n", check_range("gripper.grip_force_n", self.grip_force_n, 1.0,
                                               ROBOTIQ_2F85_MAX_GRIP_FORCE_N, unit="N"))
        set_(self, "coupling_timeconst_s", check_range("gripper.coupling_timeconst_s", self.coupling_timeconst_s,
                                                       0.001, 0.1, unit="s"))

    @classmethod
    def realistic(cls) -> GripperConfig:
        """A Robotiq 2F-85-like drive: 0.15 m/s, 20 N (:data:`ROBOTIQ_2F85_MAX_CLOSING_SPEED_M_S`), the fingers
        coupled by its linkage (:data:`LINKAGE_COUPLING_TIMECONST_S`)."""
        return cls(closing_speed_m_s=ROBOTIQ_2F85_MAX_CLOSING_SPEED_M_S, grip_force_n=ROBOTIQ_2F85_MIN_GRIP_FORCE_N,
                   coupling_timeconst_s=LINKAGE_COUPLING_TIMECONST_S)


def with_gripper(robot: Robot, config: GripperConfig) -> Robot:
    """A copy of ``robot`` whose finger drive has ``config``'s closing speed, grip force and coupling.

    Returns:
        ``robot`` itself when its model already has them (the ideal default, so ideal runs are unchanged bit
        for bit); otherwise a :class:`Robot` with its own MuJoCo model (the Pinocchio model is shared: the
        fingers' damping and force do not enter the arm's controllers).

    Raises:
        ConfigError: ``config`` is not a :class:`GripperConfig`, or its coupling is faster than two physics
            steps.
    """
    if not isinstance(config, GripperConfig):
        raise ConfigError("gripper", config, "must be a GripperConfig")
    m, h = robot.mj, robot.handles
    if config.coupling_timeconst_s < 2.0 * m.opt.timestep - 1e-12:
        raise ConfigError("gripper.coupling_timeconst_s", config.coupling_timeconst_s,
                          f"must be at least two physics steps ({2.0 * m.opt.timestep:g} s)")
    a = h.gripper_actuator
    eq = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, "finger_coupling")
    force = 2.0 * config.grip_force_n
    damping = config.grip_force_n / config.closing_speed_m_s
    now_force = float(m.actuator_forcerange[a, 1])
    now_damping = m.dof_damping[h.finger_dof]
    if (math.isclose(force, now_force, rel_tol=1e-9) and np.allclose(now_damping, damping, rtol=1e-9, atol=0.0)
            and math.isclose(config.coupling_timeconst_s, float(m.eq_solref[eq, 0]), rel_tol=1e-9)):
        return robot
    mj = copy.deepcopy(m)
    mj.eq_solref[eq, 0] = config.coupling_timeconst_s
    mj.actuator_forcerange[a] = (-force, force)
    mj.actuator_forcelimited[a] = 1
    mj.dof_damping[h.finger_dof] = damping
    # the servo saturates (squeezes with its force limit) once the fingers stop short of the closed target by
    # more than limit / kp: keep that distance (8 mm as built) for a stronger limit by scaling kp with it
    kp = float(m.actuator_gainprm[a, 0]) * max(1.0, force / now_force)
    mj.actuator_gainprm[a, 0] = kp
    mj.actuator_biasprm[a, 1] = -kp
    log.info("gripper drive: %.3f m/s, %.1f N per pad, coupling %.0f ms", config.closing_speed_m_s,
             config.grip_force_n, config.coupling_timeconst_s * 1e3)
    return dataclasses.replace(robot, mj=mj)


def closing_speed_m_s(robot: Robot) -> float:
    """The fingers' free closing speed (m/s) of ``robot``'s model: force limit / total finger damping."""
    m, h = robot.mj, robot.handles
    return float(m.actuator_forcerange[h.gripper_actuator, 1] / m.dof_damping[h.finger_dof].sum())


# --------------------------------------------------------------------------- #
# geometry and commands
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class GripperGeometry:
    """Gripper dimensions measured on the compiled model (m, in the tcp frame).

    Attributes:
        open_inner_face_y_m: Distance from the tcp to each pad's inner face, fully open.
        closed_inner_face_y_m: The same, fully closed (the actuator's closed target).
        open_width_m: Gap between the pads, fully open.
        pad_half_height_m: Half the pads' height along the tcp z axis.
        travel_m: Finger slide travel (0 = open).
        tcp_offset_m: Distance from ``tool0`` to the tcp along the flange axis.
        pad_box_m: The left (+y) pad's collision box, fully open: centre (x, y, z) then half extents (x, y, z)
            in the tcp frame; the right pad is its mirror image in y.
        finger_box_m: The left finger's collision box, fully open, as ``pad_box_m`` (the box bounding its
            collision geoms other than the pad).
        palm_boxes_m: Boxes bounding each collision geom fixed to the gripper's base (palm, coupling), as
            ``pad_box_m``; these do not move with the fingers.
    """

    open_inner_face_y_m: float
    closed_inner_face_y_m: float
    open_width_m: float
    pad_half_height_m: float
    travel_m: float
    tcp_offset_m: float
    pad_box_m: tuple[float, ...]
    finger_box_m: tuple[float, ...]
    palm_boxes_m: tuple[tuple[float, ...], ...]

    @classmethod
    def measure(cls, robot: Robot) -> GripperGeometry:
        """Measure the pads' faces by forward kinematics at both ends of the finger travel."""
        m, h = robot.mj, robot.handles
        d = mujoco.MjData(m)
        pad = int(h.pad_geoms[0])
        travel = float(m.jnt_range[m.dof_jntid[h.finger_dof[0]], 1])  # the servo drives both fingers' mean

        def inner_face(q: float) -> float:
            d.qpos[h.finger_qpos] = q
            mujoco.mj_kinematics(m, d)
            R = d.site_xmat[h.tcp_site].reshape(3, 3)
            local = R.T @ (d.geom_xpos[pad] - d.site_xpos[h.tcp_site])
            return float(abs(local[1]) - m.geom_size[pad, 1])

        def tcp_box(geoms: list[int]) -> tuple[float, ...]:
            # the box, aligned with the tcp frame, bounding these collision geoms at the current pose
            R = d.site_xmat[h.tcp_site].reshape(3, 3)
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            for g in geoms:
                size, kind = m.geom_size[g], int(m.geom_type[g])
                if kind == mujoco.mjtGeom.mjGEOM_BOX:
                    half = size.copy()
                elif kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
                    tip = size[1] + (size[0] if kind == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0)
                    half = np.array([size[0], size[0], tip])
                else:  # sphere, ellipsoid, mesh: the bounding radius
                    half = np.full(3, float(m.geom_rbound[g]))
                centre = R.T @ (d.geom_xpos[g] - d.site_xpos[h.tcp_site])
                ext = np.abs(R.T @ d.geom_xmat[g].reshape(3, 3)) @ half
                lo, hi = np.minimum(lo, centre - ext), np.maximum(hi, centre + ext)
            return tuple(float(v) for v in (*(lo + hi) / 2, *(hi - lo) / 2))

        def colliding(body: int) -> list[int]:
            return [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) == body and
                    (m.geom_contype[g] or m.geom_conaffinity[g])]

        mujoco.mj_kinematics(m, d)
        tcp_offset = float(np.linalg.norm(d.site_xpos[h.tcp_site] - d.xpos[h.tool0_body]))
        open_face = inner_face(0.0)
        finger_geoms = [g for g in colliding(int(m.geom_bodyid[pad])) if g != pad]
        pad_box, finger_box = tcp_box([pad]), tcp_box(finger_geoms)
        palm_boxes = tuple(tcp_box([g]) for g in colliding(int(m.site_bodyid[h.tcp_site])))
        return cls(
            open_inner_face_y_m=open_face,
            closed_inner_face_y_m=inner_face(travel),
            open_width_m=2 * open_face,
            pad_half_height_m=float(m.geom_size[pad, 2]),
            travel_m=travel,
            tcp_offset_m=tcp_offset,
            pad_box_m=pad_box,
            finger_box_m=finger_box,
            palm_boxes_m=palm_boxes,
        )

    def contact_travel_m(self, width_m: float) -> float:
        """Finger travel (m) at which the pads touch an object this wide across them (m)."""
        return self.open_inner_face_y_m - width_m / 2


def squeeze_per_pad_n(robot: Robot, width_m: float, geom: GripperGeometry | None = None) -> float:
    """Normal force (N) each pad presses with on an object ``width_m`` wide, the gripper commanded closed.

    The position actuator pulls the fingers towards the fully closed stroke with ``kp`` times the distance
    still to go, up to its force limit, and the coupled fingers share that force between the two pads (half
    each, by virtual work): 20 N per pad for anything wider than ~20 mm, less for thinner objects (the servo
    reaches its target before the limit).
    """
    m, a = robot.mj, robot.handles.gripper_actuator
    geom = GripperGeometry.measure(robot) if geom is None else geom
    kp = float(m.actuator_gainprm[a, 0])
    limit = float(m.actuator_forcerange[a, 1]) if m.actuator_forcelimited[a] else math.inf
    short = geom.travel_m - geom.contact_travel_m(width_m)  # finger travel left when the pads touch (m)
    return max(0.0, min(limit, kp * short)) / 2.0


def command(robot: Robot, d: mujoco.MjData, closed: bool) -> None:
    """Command the gripper fully open or fully closed (the closed target lies far past any object)."""
    lo, hi = robot.mj.actuator_ctrlrange[robot.handles.gripper_actuator]
    d.ctrl[robot.handles.gripper_actuator] = hi if closed else lo


#: A closing gripper slows down this far (m of finger travel) before its pads are expected to meet the object ...
SLOW_GAP_M = 0.001
#: ... to this speed (m/s), so that a pad that meets it first pushes it with only the force that drives the fingers
#: at that speed (about 5 N per pad as built), not the servo's full squeeze.
SLOW_SPEED_M_S = 0.08
#: Once both pads press on the object (the fingers stop), the squeeze is brought up to the servo's force limit over
#: this time (s), and before the pads open it is brought down to nothing over the same time: the arm, holding still,
#: takes a change of the pads' forces over 10 ms as a push, not a jolt.
SQUEEZE_RAMP_S = 0.01


class GripDrive:
    """The gripper's command step by step (call it after every physics step): a close onto an object whose width is
    known, or an open.

    Closing: the fingers close at the drive's full speed until the pads are :data:`SLOW_GAP_M` from the object, then
    at :data:`SLOW_SPEED_M_S` until they stop on it, then the squeeze rises to the servo's force limit over
    :data:`SQUEEZE_RAMP_S`; then the command is the fully closed stroke (as :func:`command`). Opening: the squeeze
    falls to nothing over :data:`SQUEEZE_RAMP_S`, then the command is fully open. The position servo is driven as a
    force source: its target is set, every step, so far ahead of the fingers' mean travel that the servo pushes with
    the force wanted (``F = kp (target - travel) - kv travel'``; the fingers' damping sets their speed,
    ``v = F / (sum of the fingers' damping)``, within a millisecond).

    Args:
        robot: The models (the gripper's servo, the fingers' damping).
        d: The simulation state (read, and its gripper control written).
        closed: Close (True) or open.
        width_m: The object's width between the pads (m), for a close; None closes at full speed throughout.
        early_m: How far before the width a pad may meet the object (m): the surface standing proud of the planned
            contacts (``GraspCandidate.touch_m``); the fingers slow down that much earlier.

    Attributes:
        done: The command has reached its end (fully closed or fully open).
    """

    def __init__(self, robot: Robot, d: mujoco.MjData, closed: bool, width_m: float | None = None,
                 early_m: float = 0.0) -> None:
        m, h = robot.mj, robot.handles
        self._a = a = h.gripper_actuator
        self._q, self._v = h.finger_qpos, h.finger_dof
        self._lo, self._hi = (float(x) for x in m.actuator_ctrlrange[a])
        self._kp = float(m.actuator_gainprm[a, 0])
        self._kv = float(-m.actuator_biasprm[a, 2])
        self._fmax = float(m.actuator_forcerange[a, 1]) if m.actuator_forcelimited[a] else math.inf
        self._damping = float(m.dof_damping[h.finger_dof].sum())
        self._dt = float(m.opt.timestep)
        self._closed = closed
        self._t = 0.0
        if closed:
            self._slow_from = -math.inf if width_m is None else \
                GripperGeometry.measure(robot).contact_travel_m(width_m) - max(0.0, early_m) - SLOW_GAP_M
            self._stage = "fast" if width_m is not None else "closed"
            self._f0 = 0.0
        else:
            self._stage = "release"
            self._f0 = max(0.0, min(self._fmax, float(d.actuator_force[a])))
        self.done = self._stage == "closed"
        self(d, advance=False)

    def _travel(self, d: mujoco.MjData) -> tuple[float, float]:
        """The fingers' mean travel (m) and its rate (m/s)."""
        return float(d.qpos[self._q].mean()), float(d.qvel[self._v].mean())

    def _pushing(self, d: mujoco.MjData, force_n: float, travel: float, rate: float) -> None:
        """Set the servo's target so that it pushes the fingers closed with ``force_n`` (N) now."""
        d.ctrl[self._a] = min(self._hi, max(self._lo, travel + (force_n + self._kv * rate) / self._kp))

    def __call__(self, d: mujoco.MjData, advance: bool = True) -> None:
        """Update the command after a physics step (``advance`` False: only set it, at the start)."""
        if advance:
            self._t += self._dt
        travel, rate = self._travel(d)
        if self._stage == "fast" and travel >= self._slow_from:
            self._stage = "slow"
        elif self._stage == "fast" and advance and self._t > SQUEEZE_RAMP_S and rate < 0.25 * SLOW_SPEED_M_S:
            self._stage = "closed"  # met the object before it was expected: squeezing at full force already
        slow_force = self._damping * SLOW_SPEED_M_S
        if self._stage == "slow" and advance and rate < 0.25 * SLOW_SPEED_M_S:  # the pads stopped on the object
            self._stage, self._t, self._f0 = "squeeze", 0.0, slow_force
        if self._stage in ("squeeze", "release"):
            ramp = min(1.0, self._t / SQUEEZE_RAMP_S)
            force = self._f0 + (self._fmax - self._f0) * ramp if self._closed else self._f0 * (1.0 - ramp)
            if ramp >= 1.0:
                self._stage = "closed" if self._closed else "open"
        if self._stage == "slow":
            self._pushing(d, slow_force, travel, rate)
        elif self._stage in ("squeeze", "release"):
            self._pushing(d, force, travel, 0.0)
        else:
            d.ctrl[self._a] = self._hi if self._stage in ("fast", "closed") else self._lo
        self.done = self._stage in ("closed", "open")


def finger_travel(robot: Robot, d: mujoco.MjData) -> float:
    """Current finger travel (m), 0 = open."""
    return float(d.qpos[robot.handles.finger_qpos[0]])


def is_settled(robot: Robot, d: mujoco.MjData, speed_tol_m_s: float = 1e-3) -> bool:
    """True when both fingers move slower than ``speed_tol_m_s``."""
    return bool(np.all(np.abs(d.qvel[robot.handles.finger_dof]) < speed_tol_m_s))


def _pad_object_contacts(robot: Robot, d: mujoco.MjData) -> Iterator[tuple[int, int, bool]]:
    """``(contact index, pad 0 left / 1 right, whether the object is geom2)`` of every pad-object contact."""
    n = d.ncon
    if not n:
        return
    h = robot.handles
    left, right = int(h.pad_geoms[0]), int(h.pad_geoms[1])
    obj = h.object_geom_set
    # the geom pairs in one read (a d.contact[i] struct per contact costs a few µs each, and this runs every step)
    for i, (g1, g2) in enumerate(d.contact.geom[:n].tolist()):
        if g2 in obj and g1 in (left, right):
            yield i, int(g1 == right), True
        elif g1 in obj and g2 in (left, right):
            yield i, int(g2 == right), False


def pad_load(robot: Robot, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """The pads' normal forces and their total force on the object, as the simulation has them now.

    Returns:
        ``(normal, force_on_object)``: the normal force of the object on the left and right pad (2,) (N), and
        the total force the pads exert on the object (3,) in the world (N).
    """
    normal, total, f = np.zeros(2), np.zeros(3), np.zeros(6)
    for i, pad, object_is_geom2 in _pad_object_contacts(robot, d):
        mujoco.mj_contactForce(robot.mj, d, i, f)
        normal[pad] += f[0]
        force_on_geom2 = d.contact.frame[i].reshape(3, 3).T @ f[:3]  # frame rows: normal, tangent 1, tangent 2
        total += force_on_geom2 if object_is_geom2 else -force_on_geom2
    return normal, total


def pad_contact_forces(robot: Robot, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """The force each pad exerts on the object and where, as the simulation has them now (for drawing).

    Returns:
        ``(force, point)``: the total force of the left and right pad on the object (2, 3) in the world (N), and
        the point it acts at (2, 3) (m), the contact points averaged by their normal force; zeros for a pad that
        does not touch the object.
    """
    force, point, weight, f = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2), np.zeros(6)
    for i, pad, object_is_geom2 in _pad_object_contacts(robot, d):
        mujoco.mj_contactForce(robot.mj, d, i, f)
        c = d.contact[i]
        on_geom2 = c.frame.reshape(3, 3).T @ f[:3]  # frame rows: normal, tangent 1, tangent 2
        force[pad] += on_geom2 if object_is_geom2 else -on_geom2
        point[pad] += abs(f[0]) * c.pos
        weight[pad] += abs(f[0])
    touching = weight > 0
    point[touching] /= weight[touching, None]
    return force, point


def pad_forces(robot: Robot, d: mujoco.MjData) -> np.ndarray:
    """Normal force (N) of the object on the left and right pad, (2,)."""
    f, out = np.zeros(6), np.zeros(2)
    for i, pad, _ in _pad_object_contacts(robot, d):
        mujoco.mj_contactForce(robot.mj, d, i, f)
        out[pad] += f[0]
    return out


def pad_contacts(robot: Robot, d: mujoco.MjData) -> list[Contact]:
    """The pad-object contacts as the simulation has them now, for the force-closure test: one
    :class:`~pickplace.world.contact.Contact` per MuJoCo contact point (world frame, normal pointing into the
    object, the contact's own friction coefficients)."""
    contacts: list[Contact] = []
    for i, _, object_is_geom2 in _pad_object_contacts(robot, d):
        c = d.contact[i]
        normal = c.frame[:3] if object_is_geom2 else -c.frame[:3]  # the frame's normal points from geom1 to geom2
        contacts.append(Contact(c.pos.copy(), normal.copy(), float(c.friction[0]), float(c.friction[2])))
    return contacts


def in_contact(robot: Robot, d: mujoco.MjData, min_force_n: float = 0.5) -> bool:
    """True when both pads press on the object with at least ``min_force_n``."""
    return bool(np.all(pad_forces(robot, d) >= min_force_n))
