"""The executed motion measured against the robot's limits, and the tcp against a straight line, every step.

Trajectories are timed within the joints' speed and acceleration limits (:mod:`pickplace.motion.timing`) and
the controllers clip their torques to the motors' (:mod:`pickplace.motion.control`); what the arm *does* is
another matter: it tracks its reference with an error, a straight move is timed by the tcp's profile, contacts
jolt it. :class:`LimitMeter` reads the simulation after every physics step (1 ms) and compares each joint's
speed (``qvel``), acceleration (the change of ``qvel`` over the step: what the integrator applied) and the
torque its motor applied (``ctrl``) with the limits. A torque at its limit is one the controller asked more
than, clipped: it counts as a violation.

Steps are counted apart by what the arm was told to do: move (a trajectory, a straight move, a stop) or stand
still (a hold: while the gripper closes or opens, while waiting). Standing still, the arm moves only as
something pushes it: the first pad that meets the object as the gripper closes jolts the wrist (3-4 ms at up
to twice the wrists' acceleration limit in the ideal profile, whose mirrored finger lags 1 mm behind the driven
one through its soft coupling). The limits bound the motions the robot makes; what the world does to an arm
holding still is reported, not hidden, but apart.

:class:`LineMeter` measures how far the tcp strays from a straight line (the final approach to a grasp, the
set-down).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from pickplace.robot.model import Robot

#: The UR5e's joints, in order (for reports).
JOINT_NAMES = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
_KINDS = ("speed", "acceleration", "torque")


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
    mutable piece: call it after every step, :meth:`report` at the end).

    Args:
        robot: The models (the arm's joints and motors, their torque limits, the timestep).
        velocity_limits_rad_s: Joint speed limits (6,) (rad/s).
        acceleration_limits_rad_s2: Joint acceleration limits (6,) (rad/s^2).
    """

    #: Steps buffered before they are reduced (and whenever the phase or ``moving`` changes, and for a report).
    BATCH = 256

    def __init__(self, robot: Robot, velocity_limits_rad_s: np.ndarray | tuple[float, ...],
                 acceleration_limits_rad_s2: np.ndarray | tuple[float, ...]) -> None:
        h = robot.handles
        self._dof, self._act = _index(h.arm_dof), _index(h.arm_actuators)
        n = len(h.arm_dof)
        self._inv = np.stack([1.0 / np.asarray(velocity_limits_rad_s, dtype=float),
                              1.0 / np.asarray(acceleration_limits_rad_s2, dtype=float),
                              1.0 / np.asarray(robot.torque_limits_nm, dtype=float)])
        self._dt = float(robot.mj.opt.timestep)
        # the steps not reduced yet: one row before them (the last step reduced), then up to BATCH rows
        self._v = np.zeros((self.BATCH + 1, n))
        self._u = np.zeros((self.BATCH + 1, n))
        self._t = np.full(self.BATCH + 1, np.nan)
        self._n = 0
        self._label: tuple[str, bool] = ("", True)
        self._max = np.zeros((2, 3))  # moving, holding: speed, acceleration, torque
        self._counts = np.zeros(3, dtype=np.int64)  # moving
        self._any = [0, 0]
        self._samples = [0, 0]
        self._by_phase: tuple[dict[str, int], dict[str, int]] = ({}, {})
        self._worst = [(0.0, ""), (0.0, "")]

    def __call__(self, d: mujoco.MjData, phase: str = "", moving: bool = True) -> None:
        """Measure the state ``d`` has after a physics step, in ``phase``, the arm told to move or (``moving``
        False) to hold still (buffered: reduced every :attr:`BATCH` steps, when the phase or ``moving`` changes,
        and by :meth:`report`)."""
        if self._n == self.BATCH or (phase, moving) != self._label:
            self._reduce()
            self._label = (phase, moving)
        i = self._n = self._n + 1
        self._v[i] = d.qvel[self._dof]
        self._u[i] = d.ctrl[self._act]
        self._t[i] = d.time

    def _reduce(self) -> None:
        """Fold the buffered steps into the figures; keep the last as the one before the next."""
        n = self._n
        if n == 0:
            return
        v, t = self._v[: n + 1], self._t[: n + 1]
        ratios = np.empty((3, n, v.shape[1]))
        np.multiply(np.abs(v[1:]), self._inv[0], out=ratios[0])
        np.multiply(np.abs(np.diff(v, axis=0)), self._inv[1] / self._dt, out=ratios[1])
        ratios[1][~(np.abs(np.diff(t) - self._dt) < 1e-9)] = 0.0  # no step before it (the first, or after a reset)
        np.multiply(np.abs(self._u[1 : n + 1]), self._inv[2], out=ratios[2])
        peak = ratios.max(axis=2)  # (3, n): each step's largest ratio of each kind
        phase, moving = self._label
        which = 0 if moving else 1
        self._samples[which] += n
        np.maximum(self._max[which], peak.max(axis=1), out=self._max[which])
        over = np.stack([peak[0] > 1.0, peak[1] > 1.0, peak[2] >= 1.0 - 1e-12])
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
            joint = int(np.argmax(ratios[kind, k]))
            self._worst[which] = (top, f"{_KINDS[kind]} of {JOINT_NAMES[joint]} in {phase or '-'} at "
                                       f"t = {t[k + 1]:.3f} s: {top:.3f} of its limit")
        self._v[0], self._u[0], self._t[0] = self._v[n], self._u[n], self._t[n]
        self._n = 0

    def report(self) -> LimitReport:
        """The figures so far."""
        self._reduce()
        return LimitReport(self._samples[0], *(float(x) for x in self._max[0]), *(int(c) for c in self._counts),
                           self._any[0], dict(self._by_phase[0]), self._worst[0][1], self._samples[1], self._any[1],
                           dict(self._by_phase[1]), self._worst[1][1])


def _index(ids: np.ndarray) -> slice | np.ndarray:
    """A slice for consecutive indices (a view: cheaper to read every step), else the index array."""
    ids = np.asarray(ids)
    if ids.size and np.array_equal(ids, np.arange(ids[0], ids[0] + ids.size)):
        return slice(int(ids[0]), int(ids[0]) + ids.size)
    return ids


class LineMeter:
    """The largest distance of the tcp from the straight line through two points (the one mutable piece).

    Args:
        robot: The models (the tcp site).
        start_m, end_m: Two points (3,) (m) of the line, e.g. the pregrasp and the grasp.
    """

    def __init__(self, robot: Robot, start_m: np.ndarray, end_m: np.ndarray) -> None:
        self._site = robot.handles.tcp_site
        self._a = np.asarray(start_m, dtype=float).copy()
        u = np.asarray(end_m, dtype=float) - self._a
        norm = float(np.linalg.norm(u))
        self._u = u / norm if norm > 0.0 else np.array([0.0, 0.0, 1.0])
        self.max_m = 0.0

    def __call__(self, d: mujoco.MjData) -> None:
        """Measure the tcp where ``d`` has it."""
        r = d.site_xpos[self._site] - self._a
        off = r - float(r @ self._u) * self._u
        self.max_m = max(self.max_m, float(np.sqrt(off @ off)))


__all__ = ["JOINT_NAMES", "LimitMeter", "LimitReport", "LineMeter"]
