"""The executed motion measured against the robot's limits, and the tcp against a straight line, every step.

Trajectories are timed within the joints' speed and acceleration limits (:mod:`pickplace.motion.timing`) and
the controllers clip their torques to the motors' (:mod:`pickplace.motion.control`); what the arm *does* is
another matter: it tracks its reference with an error, a straight move is timed by the tcp's profile, contacts
jolt it. :class:`LimitMeter` reads every physics step (1 ms) from the control loops' tapes of the arm's state
(MuJoCo's arm sensors, copied once per step: :class:`~pickplace.motion.loop.Measured`) and compares each joint's
speed, acceleration (the change of its speed over the step: what the integrator applied) and the torque its
actuator applied (the torque commanded, or the joint servo's) with the limits. A torque at its limit is one the
controller asked more than, clipped: it counts as a violation.

Steps are counted apart by what the arm was told to do: move (a trajectory, a straight move, a stop) or stand
still (a hold: while the gripper closes or opens, while waiting). Standing still, the arm moves only as
something pushes it: the pads meeting the object as the gripper closes, or letting it go (the gripper's drive
closes both fingers together and slows before contact, :class:`~pickplace.robot.gripper.GripDrive`, so that the
held wrist stays within its limits; a pad that met the object alone used to jolt it to twice its acceleration
limit). The limits bound the motions the robot makes; what the world does to an arm holding still is reported, not
hidden, but apart.

:class:`LineMeter` measures how far the tcp strays from a straight line (the final approach to a grasp, the
set-down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pickplace.robot.model import Robot

#: The UR5e's joints, in order (for reports).
JOINT_NAMES = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
_KINDS = ("speed", "acceleration", "torque")
#: Columns of a row of the arm's state tape (robot.model.ARM_STATE_FIELDS): velocities, torques, tcp.
_QD, _TAU, _TCP = slice(6, 12), slice(12, 18), slice(18, 21)


@dataclass(frozen=True)
class LimitReport:
    """The executed motion against the limits, over every physics step measured while the arm moved (and,
    apart, while it held still).

    Attributes:
        samples: Physics steps measured while the arm moved.
        speed_ratio_max: Largest ``|qd_j| / vlim_j`` over joints and those steps.
        acceleration_ratio_max: Largest ``|qdd_j| / alim_j`` (the change of ``qd_j`` over the step).
        torque_ratio_max: Largest ``|tau_j| / tau_max_j`` of the torques applied (1 where one was clipped).
        speed_violations: Steps at which some joint was faster than its limit.
        acceleration_violations: Steps at which some joint accelerated harder than its limit.
        torque_violations: Steps at which some motor's torque was at its limit (the controller asked for more).
        violations: Steps at which any of the three happened.
        violations_by_phase: Those steps by phase (phases with none left out).
        worst: The step closest to (or furthest past) a limit: what, which joint, in which phase, when; "" if none.
        hold_samples: Physics steps measured while the arm held still.
        hold_violations: Steps at which any limit was passed while it held still (contacts jolting it).
        hold_violations_by_phase: Those by phase.
        hold_worst: The held step closest to (or furthest past) a limit.
    """

    samples: int = 0
    speed_ratio_max: float = 0.0
    acceleration_ratio_max: float = 0.0
    torque_ratio_max: float = 0.0
    speed_violations: int = 0
    acceleration_violations: int = 0
    torque_violations: int = 0
    violations: int = 0
    violations_by_phase: dict[str, int] = field(default_factory=dict)
    worst: str = ""
    hold_samples: int = 0
    hold_violations: int = 0
    hold_violations_by_phase: dict[str, int] = field(default_factory=dict)
    hold_worst: str = ""


class LimitMeter:
    """Measures each physics step's joint speeds, accelerations and torques against the limits (the one
    mutable piece: hand it the control loops' tapes of the arm's state, :meth:`report` at the end).

    Args:
        robot: The models (the torque limits, the timestep).
        velocity_limits_rad_s: Joint speed limits (6,) (rad/s).
        acceleration_limits_rad_s2: Joint acceleration limits (6,) (rad/s^2).
    """

    def __init__(self, robot: Robot, velocity_limits_rad_s: np.ndarray | tuple[float, ...],
                 acceleration_limits_rad_s2: np.ndarray | tuple[float, ...]) -> None:
        self._inv = np.stack([1.0 / np.asarray(velocity_limits_rad_s, dtype=float),
                              1.0 / np.asarray(acceleration_limits_rad_s2, dtype=float),
                              1.0 / np.asarray(robot.torque_limits_nm, dtype=float)])
        self._dt = float(robot.mj.opt.timestep)
        self._last_v: np.ndarray | None = None  # the velocities of the last step measured, and its time
        self._last_t = math.nan
        self._max = np.zeros((2, 3))  # moving, holding: speed, acceleration, torque
        self._counts = np.zeros(3, dtype=np.int64)  # moving
        self._any = [0, 0]
        self._samples = [0, 0]
        self._by_phase: tuple[dict[str, int], dict[str, int]] = ({}, {})
        self._worst = [(0.0, ""), (0.0, "")]

    def add(self, rows: np.ndarray, t0_s: float, phase: str = "", moving: bool = True) -> None:
        """Measure a block of consecutive physics steps (a control loop's tape, :class:`~pickplace.motion.loop.
        Measured`): rows (k, ARM_STATE_WIDTH) of the arm's state, the first at simulated time ``t0_s`` (s), taken in
        ``phase`` with the arm told to move or (``moving`` False) to hold still.

        A step's speed is its row's velocities, its torque the torques applied in it, and its acceleration the
        change of the velocities from the step before (the previous block's last row when the blocks are
        consecutive in time; none for the first step after a gap).
        """
        n = len(rows)
        if n == 0:
            return
        v = rows[:, _QD]
        dv = np.empty_like(v)
        np.subtract(v[1:], v[:-1], out=dv[1:])
        if self._last_v is not None and abs(t0_s - self._last_t - self._dt) < 1e-9:
            np.subtract(v[0], self._last_v, out=dv[0])
        else:  # no step before it (the first, or after a reset)
            dv[0] = 0.0
        self._last_v = v[-1].copy()
        self._last_t = t0_s + (n - 1) * self._dt
        # each step's largest ratio of each kind (3, n): speed, acceleration, torque
        ratios = (np.abs(v) * self._inv[0], np.abs(dv) * (self._inv[1] / self._dt),
                  np.abs(rows[:, _TAU]) * self._inv[2])
        peak = np.array([r.max(axis=1) for r in ratios])
        which = 0 if moving else 1
        self._samples[which] += n
        np.maximum(self._max[which], peak.max(axis=1), out=self._max[which])
        over = peak > 1.0
        over[2] = peak[2] >= 1.0 - 1e-12  # a torque at its limit was clipped
        any_over = int(over.any(axis=0).sum())
        if any_over:
            if moving:
                self._counts += over.sum(axis=1)
            self._any[which] += any_over
            self._by_phase[which][phase] = self._by_phase[which].get(phase, 0) + any_over
        tops = peak.max(axis=0)
        k = int(np.argmax(tops))
        top = float(tops[k])
        if top > self._worst[which][0]:
            kind = int(np.argmax(peak[:, k]))
            joint = int(np.argmax(ratios[kind][k]))
            self._worst[which] = (top, f"{_KINDS[kind]} of {JOINT_NAMES[joint]} in {phase or '-'} at "
                                       f"t = {t0_s + k * self._dt:.3f} s: {top:.3f} of its limit")

    def report(self) -> LimitReport:
        """The figures so far."""
        return LimitReport(self._samples[0], *(float(x) for x in self._max[0]), *(int(c) for c in self._counts),
                           self._any[0], dict(self._by_phase[0]), self._worst[0][1], self._samples[1], self._any[1],
                           dict(self._by_phase[1]), self._worst[1][1])


class LineMeter:
    """The largest distance of the tcp from the straight line through two points (the one mutable piece).

    Args:
        start_m, end_m: Two points (3,) (m) of the line, e.g. the pregrasp and the grasp.
    """

    def __init__(self, start_m: np.ndarray, end_m: np.ndarray) -> None:
        self._a = np.asarray(start_m, dtype=float).copy()
        u = np.asarray(end_m, dtype=float) - self._a
        norm = float(np.linalg.norm(u))
        self._u = u / norm if norm > 0.0 else np.array([0.0, 0.0, 1.0])
        self.max_m = 0.0

    def add(self, rows: np.ndarray) -> None:
        """Measure the tcp in a block of a control loop's tape of the arm's state (rows (k, ARM_STATE_WIDTH))."""
        if len(rows) == 0:
            return
        r = rows[:, _TCP] - self._a
        off = r - np.outer(r @ self._u, self._u)
        self.max_m = max(self.max_m, float(np.sqrt(np.max(np.einsum("ij,ij->i", off, off)))))


__all__ = ["JOINT_NAMES", "LimitMeter", "LimitReport", "LineMeter"]
