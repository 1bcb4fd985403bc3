"""Faults injected on purpose: each is a real change to the simulation, not a flag that skips code.

A :class:`FaultConfig` (the ``[faults]`` TOML table, or ``--fault KEY=VALUE`` on the command line) says what
goes wrong; :func:`apply_model_faults` changes the models before the episode starts (friction, contact
softness, mass, the tcp the controller believes in) and a :class:`FaultInjector`, called after every
simulation step by the state machine's monitor, applies the timed ones (pushes, the obstacle that appears).

What the machine *believes* stays the nominal scene: the object's mass for the payload compensation, the tcp
offset of the kinematic model, the world it planned in. That gap is the fault.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from pickplace.errors import ConfigError
from pickplace.robot.model import INTRUDER, INTRUDER_HALF_SIZE_M, Robot
from pickplace.world.config import check_range, check_vector

log = logging.getLogger(__name__)


#: ``[faults]`` keys of earlier versions, still accepted: old name -> field.
LEGACY_FAULT_KEYS = {"cube_mass_scale": "true_mass_scale"}


@dataclass(frozen=True)
class FaultConfig:
    """What goes wrong in an episode (all off by default). Forces in N, times in s, lengths in m.

    Attributes:
        pad_friction_scale: Friction of the pad-object contacts relative to the object's nominal friction.
        pad_softness_scale: Time constant of the pad contacts' solref relative to nominal (> 1 is softer, the
            reference design's "contact oscillation from a soft solref").
        true_mass_scale: The object's true mass relative to what the machine believes (payload compensation;
            ``cube_mass_scale`` in older configs).
        tcp_offset_error_m: Error of the tcp offset in the robot's kinematic model, along the tool axis: the
            machine believes the tcp is this much further out than it is (-0.2 m flips the 0.1 m offset).
        tcp_yaw_error_rad: Error of the tcp orientation in the robot's kinematic model, about the tool axis (a
            gripper mounted turned on the flange): the machine believes the tcp frame is turned this much
            further than it is, so it grasps and places turned by this angle.
        pre_pick_push_n: Horizontal force (x, y) on the resting object once it has been observed, while the arm
            approaches (the object is not where it was seen).
        pre_pick_push_s: How long that push lasts.
        placed_push_n: Horizontal force (x, y) on the placed object as the arm starts to retract (it is bumped
            after the release check).
        placed_push_s: How long that push lasts.
        transport_push_n: Force (x, y, z) on the object while it is carried.
        transport_push_start_s: When the transport push starts, after the transport trajectory starts.
        transport_push_s: How long the transport push lasts (0: no push).
        intruder: An obstacle appears across the transport path right after it was planned.
        joint_noise_rad: Standard deviation of the noise on the joint positions the controllers read (rad).
    """

    pad_friction_scale: float = 1.0
    pad_softness_scale: float = 1.0
    true_mass_scale: float = 1.0
    tcp_offset_error_m: float = 0.0
    tcp_yaw_error_rad: float = 0.0
    pre_pick_push_n: tuple[float, float] = (0.0, 0.0)
    pre_pick_push_s: float = 0.1
    placed_push_n: tuple[float, float] = (0.0, 0.0)
    placed_push_s: float = 0.1
    transport_push_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    transport_push_start_s: float = 0.2
    transport_push_s: float = 0.0
    intruder: bool = False
    joint_noise_rad: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "pad_friction_scale", check_range("faults.pad_friction_scale", self.pad_friction_scale,
                                                     0.0, 5.0))
        set_(self, "pad_softness_scale", check_range("faults.pad_softness_scale", self.pad_softness_scale,
                                                     0.1, 100.0))
        set_(self, "true_mass_scale", check_range("faults.true_mass_scale", self.true_mass_scale, 0.0, 50.0,
                                                  lo_open=True))
        set_(self, "tcp_offset_error_m", check_range("faults.tcp_offset_error_m", self.tcp_offset_error_m,
                                                     -0.3, 0.3, unit="m"))
        set_(self, "tcp_yaw_error_rad", check_range("faults.tcp_yaw_error_rad", self.tcp_yaw_error_rad,
                                                    -math.pi / 4, math.pi / 4, unit="rad"))
        set_(self, "pre_pick_push_n", check_vector("faults.pre_pick_push_n", self.pre_pick_push_n, 2, -200.0,
                                                   200.0, unit="N"))
        set_(self, "pre_pick_push_s", check_range("faults.pre_pick_push_s", self.pre_pick_push_s, 0.0, 2.0,
                                                  unit="s"))
        set_(self, "placed_push_n", check_vector("faults.placed_push_n", self.placed_push_n, 2, -200.0, 200.0,
                                                 unit="N"))
        set_(self, "placed_push_s", check_range("faults.placed_push_s", self.placed_push_s, 0.0, 2.0, unit="s"))
        set_(self, "transport_push_n", check_vector("faults.transport_push_n", self.transport_push_n, 3, -200.0,
                                                    200.0, unit="N"))
        set_(self, "transport_push_start_s", check_range("faults.transport_push_start_s",
                                                         self.transport_push_start_s, 0.0, 10.0, unit="s"))
        set_(self, "transport_push_s", check_range("faults.transport_push_s", self.transport_push_s, 0.0, 2.0,
                                                   unit="s"))
        if not isinstance(self.intruder, bool):
            raise ConfigError("faults.intruder", self.intruder, "must be true or false")
        set_(self, "joint_noise_rad", check_range("faults.joint_noise_rad", self.joint_noise_rad, 0.0, 0.05,
                                                  unit="rad"))

    @property
    def active(self) -> bool:
        """Whether any fault is on."""
        return self != FaultConfig()


def apply_model_faults(robot: Robot, faults: FaultConfig) -> None:
    """Change ``robot``'s MuJoCo model (the world) and Pinocchio model (the belief) in place.

    Call on a freshly built robot owned by one episode.
    """
    m, h = robot.mj, robot.handles
    if faults.pad_friction_scale != 1.0 or faults.pad_softness_scale != 1.0:
        # Nominally the pads share the object's priority and their solmix makes their own solref and solimp the
        # contact's, with the object's friction (the pads' own is 0). Raise the pads' priority above the object's
        # so that every pad-object contact takes the pads' parameters outright, and scale those: the object's
        # friction times the fault's scale, the pads' own time constant times its, their impedance and the
        # contact's condim as nominal. Only the pad-object contacts change (the object slides on the table as
        # before; a pad touching anything else fails the episode anyway).
        g = int(h.object_geoms[0])
        for pad in h.pad_geoms:
            m.geom_condim[pad] = max(int(m.geom_condim[pad]), int(m.geom_condim[g]))
            m.geom_priority[pad] = int(m.geom_priority[g]) + 1
            m.geom_friction[pad] = m.geom_friction[g] * [faults.pad_friction_scale, 1.0, 1.0]
            m.geom_solref[pad] = m.geom_solref[pad] * [faults.pad_softness_scale, 1.0]
    if faults.true_mass_scale != 1.0:
        b = h.object_body
        m.body_mass[b] *= faults.true_mass_scale
        m.body_inertia[b] *= faults.true_mass_scale
        mujoco.mj_setConst(m, mujoco.MjData(m))  # derived quantities (e.g. body_invweight0) follow the mass
    if faults.tcp_offset_error_m != 0.0 or faults.tcp_yaw_error_rad != 0.0:
        frame = robot.pin.frames[robot.pin_tcp_frame]
        frame.placement.translation = frame.placement.translation + np.array([0.0, 0.0, faults.tcp_offset_error_m])
        c, s = math.cos(faults.tcp_yaw_error_rad), math.sin(faults.tcp_yaw_error_rad)
        frame.placement.rotation = frame.placement.rotation @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        robot.pin.frames[robot.pin_tcp_frame] = frame
    if faults.active:
        log.info("faults applied to the model: %s", faults)


class FaultInjector:
    """The timed faults, applied after each simulation step (pushes, the obstacle that appears).

    Args:
        robot: The models.
        faults: What to inject.
    """

    def __init__(self, robot: Robot, faults: FaultConfig) -> None:
        self.robot = robot
        self.faults = faults
        self.intruder_mocap = int(robot.mj.body_mocapid[mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY,
                                                                            INTRUDER)])
        self._pre_pick_t0: float | None = None
        self._transport_t0: float | None = None
        self._placed_t0: float | None = None
        self.intruder_placed = False

    @property
    def pushes(self) -> bool:
        """Whether a push is configured at all; without one, :meth:`step` only ever writes a zero force."""
        f = self.faults
        return bool((f.pre_pick_push_s > 0 and any(f.pre_pick_push_n)) or (f.placed_push_s > 0 and any(f.placed_push_n))
                    or f.transport_push_s > 0)

    def pushing(self, phase: str, t_s: float) -> np.ndarray:
        """The force (3,) (N) on the object at episode time ``t_s`` during ``phase``."""
        f = self.faults
        if phase == "EXEC_APPROACH" and f.pre_pick_push_s > 0 and any(f.pre_pick_push_n):
            if self._pre_pick_t0 is None:
                self._pre_pick_t0 = t_s
            if t_s - self._pre_pick_t0 < f.pre_pick_push_s:
                return np.array([*f.pre_pick_push_n, 0.0])
        if phase == "RETRACT" and f.placed_push_s > 0 and any(f.placed_push_n):
            if self._placed_t0 is None:
                self._placed_t0 = t_s
            if t_s - self._placed_t0 < f.placed_push_s:
                return np.array([*f.placed_push_n, 0.0])
        if phase == "EXEC_TRANSPORT" and f.transport_push_s > 0:
            if self._transport_t0 is None:
                self._transport_t0 = t_s
            since = t_s - self._transport_t0
            if f.transport_push_start_s <= since < f.transport_push_start_s + f.transport_push_s:
                return np.asarray(f.transport_push_n, dtype=float)
        return np.zeros(3)

    def step(self, d: mujoco.MjData, phase: str, t_s: float) -> None:
        """Apply the pushes for the next step."""
        d.xfrc_applied[self.robot.handles.object_body, :3] = self.pushing(phase, t_s)

    def place_intruder(self, d: mujoco.MjData, start_xyz: np.ndarray, goal_xyz: np.ndarray) -> None:
        """Put the intruding wall across the straight line between two tcp positions (m), at their midpoint."""
        if not self.faults.intruder or self.intruder_placed:
            return
        mid = (np.asarray(start_xyz) + np.asarray(goal_xyz)) / 2
        heading = math.atan2(goal_xyz[1] - start_xyz[1], goal_xyz[0] - start_xyz[0])
        d.mocap_pos[self.intruder_mocap] = [mid[0], mid[1], self.robot.scene.table_height_m + INTRUDER_HALF_SIZE_M[2]]
        d.mocap_quat[self.intruder_mocap] = [math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2)]
        mujoco.mj_kinematics(self.robot.mj, d)
        self.intruder_placed = True
        log.info("fault: an obstacle appeared at (%.3f, %.3f) m", mid[0], mid[1])


__all__ = ["LEGACY_FAULT_KEYS", "FaultConfig", "FaultInjector", "apply_model_faults"]
