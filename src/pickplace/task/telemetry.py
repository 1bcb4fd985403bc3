"""What happened during an episode, sampled from the simulation: the input of plots and videos.

A :class:`TelemetryRecorder` is called once per simulation step by the state machine; it keeps a few
numbers per step (time, phase, arm joints, tcp and object positions, pad forces) and the full ``qpos`` at
the video frame rate. :meth:`TelemetryRecorder.freeze` returns the immutable :class:`Telemetry`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from pickplace.robot.gripper import pad_forces
from pickplace.robot.model import Robot


@dataclass(frozen=True, eq=False)
class JointSegment:
    """Reference and measured arm joints over one trajectory-tracking phase.

    Attributes:
        phase: Name of the phase (e.g. ``"EXEC_APPROACH"``).
        t_s: Simulated time of each sample (N,) (s), on the episode clock.
        q: Measured arm joints (N, 6) (rad).
        q_ref: Reference arm joints (N, 6) (rad).
    """

    phase: str
    t_s: np.ndarray
    q: np.ndarray
    q_ref: np.ndarray


@dataclass(frozen=True, eq=False)
class Telemetry:
    """Per-step samples of one episode (read-only arrays; N steps, F video frames).

    Attributes:
        t_s: Simulated time (N,) (s), 0 at the start of the episode.
        phase: Index into ``phase_names`` of the phase running at each step (N,).
        phase_names: Names of the phases, in the order they were first entered.
        q: Arm joints (N, 6) (rad).
        tcp_pos_m: Tcp position in the world (N, 3) (m).
        object_pos_m: Object origin in the world (N, 3) (m).
        pad_force_n: Normal force on the left and right pad (N, 2) (N).
        joint_segments: Reference vs measured joints of each tracked trajectory.
        frame_t_s: Time of each video frame (F,) (s).
        frame_qpos: Full MuJoCo ``qpos`` at each video frame (F, nq).
        goal_pos_m: The object's goal position (3,) (m).
    """

    t_s: np.ndarray
    phase: np.ndarray
    phase_names: tuple[str, ...]
    q: np.ndarray
    tcp_pos_m: np.ndarray
    object_pos_m: np.ndarray
    pad_force_n: np.ndarray
    joint_segments: tuple[JointSegment, ...]
    frame_t_s: np.ndarray
    frame_qpos: np.ndarray
    goal_pos_m: np.ndarray

    def phase_spans(self) -> list[tuple[str, float, float]]:
        """``[(phase, t_start_s, t_end_s)]`` in order, one entry per contiguous run of a phase."""
        if self.t_s.size == 0:
            return []
        change = np.flatnonzero(np.diff(self.phase)) + 1
        starts = np.concatenate([[0], change])
        ends = np.concatenate([change, [self.t_s.size]])
        dt = float(self.t_s[1] - self.t_s[0]) if self.t_s.size > 1 else 0.0
        return [(self.phase_names[int(self.phase[a])], float(self.t_s[a]), float(self.t_s[b - 1]) + dt)
                for a, b in zip(starts, ends, strict=True)]


@dataclass
class TelemetryRecorder:
    """Collects :class:`Telemetry` step by step (the only mutable piece; owned by one episode).

    Args:
        robot: The models (for the handles).
        frame_rate_hz: Video frames per simulated second (0 disables frame capture).
        goal_pos_m: The object's goal position (3,) (m).
    """

    robot: Robot
    frame_rate_hz: float = 30.0
    goal_pos_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    _t: list[float] = field(default_factory=list, repr=False)
    _phase: list[int] = field(default_factory=list, repr=False)
    _names: dict[str, int] = field(default_factory=dict, repr=False)
    _q: list[np.ndarray] = field(default_factory=list, repr=False)
    _tcp: list[np.ndarray] = field(default_factory=list, repr=False)
    _object: list[np.ndarray] = field(default_factory=list, repr=False)
    _force: list[np.ndarray] = field(default_factory=list, repr=False)
    _segments: list[JointSegment] = field(default_factory=list, repr=False)
    _frame_t: list[float] = field(default_factory=list, repr=False)
    _frames: list[np.ndarray] = field(default_factory=list, repr=False)
    _next_frame_s: float = 0.0

    def record(self, d: mujoco.MjData, t_s: float, phase: str) -> None:
        """Sample the state after a simulation step taken at episode time ``t_s`` (s) during ``phase``."""
        h = self.robot.handles
        self._t.append(t_s)
        self._phase.append(self._names.setdefault(phase, len(self._names)))
        self._q.append(d.qpos[h.arm_qpos].copy())
        self._tcp.append(d.site_xpos[h.tcp_site].copy())
        self._object.append(d.xpos[h.object_body].copy())
        self._force.append(pad_forces(self.robot, d))
        if self.frame_rate_hz > 0 and t_s >= self._next_frame_s - 1e-9:
            self._frame_t.append(t_s)
            self._frames.append(d.qpos.copy())
            self._next_frame_s += 1.0 / self.frame_rate_hz

    def add_joint_segment(self, phase: str, t_s: np.ndarray, q: np.ndarray, q_ref: np.ndarray) -> None:
        """Keep the reference and measured joints of one tracked trajectory (times on the episode clock)."""
        self._segments.append(JointSegment(phase, np.asarray(t_s), np.asarray(q), np.asarray(q_ref)))

    def freeze(self) -> Telemetry:
        """The samples so far as an immutable :class:`Telemetry`."""
        nq = self.robot.mj.nq

        def arr(rows: list[np.ndarray], width: int) -> np.ndarray:
            out = np.array(rows, dtype=float).reshape(len(rows), width)
            out.setflags(write=False)
            return out

        t = np.array(self._t, dtype=float)
        phase = np.array(self._phase, dtype=np.int64)
        frame_t = np.array(self._frame_t, dtype=float)
        for a in (t, phase, frame_t):
            a.setflags(write=False)
        names = tuple(sorted(self._names, key=self._names.__getitem__))
        return Telemetry(t, phase, names, arr(self._q, 6), arr(self._tcp, 3), arr(self._object, 3),
                         arr(self._force, 2), tuple(self._segments), frame_t, arr(self._frames, nq),
                         np.asarray(self.goal_pos_m, dtype=float).copy())


__all__ = ["JointSegment", "Telemetry", "TelemetryRecorder"]
