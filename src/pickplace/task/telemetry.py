"""What happened during an episode, sampled from the simulation: the input of plots, videos and the web viewer.

A :class:`TelemetryRecorder` is called once per simulation step by the state machine; it keeps a few
numbers per step (time, phase, arm joints, tcp and object positions, pad forces) and, at the video frame rate,
the full ``qpos``, the mocap bodies' poses and the force each pad exerts on the object. The arm also hands it
every path it plans (:meth:`TelemetryRecorder.add_plan`) and, for each approach, the grasps it chose from
(:meth:`TelemetryRecorder.add_grasp_choice`). :meth:`TelemetryRecorder.freeze` returns the immutable
:class:`Telemetry`. Recording only reads the simulation: an episode gives the same result with or without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.grasping.configurations import candidate_grasps
from pickplace.grasping.targets import CLEARANCE_M
from pickplace.motion.timing import Trajectory
from pickplace.robot.gripper import pad_contact_forces, pad_forces
from pickplace.robot.kinematics import frame_pose, rotation_distance
from pickplace.robot.model import Robot

#: Time between the samples of a planned path's tcp polyline (s).
PATH_SAMPLE_S = 0.02
#: Most grasp candidates kept per approach (the best ranked; the chosen one is always kept).
MAX_RECORDED_GRASPS = 32


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
class PlannedPath:
    """One planned and timed segment, as the tcp follows it.

    Attributes:
        name: The segment (``"approach"``, ``"transport"``, ``"return"``).
        t_s: When it was planned, on the episode clock (s).
        duration_s: Its timed duration (s).
        tcp_m: The tcp's position along it every :data:`PATH_SAMPLE_S` (K, 3) (m).
    """

    name: str
    t_s: float
    duration_s: float
    tcp_m: np.ndarray


@dataclass(frozen=True, eq=False)
class GraspChoice:
    """The grasp candidates of one approach and the one the arm went for.

    Attributes:
        t_s: When the approach was planned, on the episode clock (s).
        object_name: The object grasped.
        T_world_object: The object's pose as the robot believed it then (4, 4).
        T_world_tcp: The tcp at each candidate grasp, best ranked first (M, 4, 4).
        width_m: The object's width between the pads at each candidate (M,) (m).
        approach: Each candidate's approach (``top``, ``tilted``, ``side``).
        chosen: Index of the chosen grasp among the candidates, -1 if it is not among those kept.
        T_world_chosen: The tcp at the chosen grasp (4, 4): the planned pregrasp moved ``CLEARANCE_M`` along its
            approach.
    """

    t_s: float
    object_name: str
    T_world_object: np.ndarray
    T_world_tcp: np.ndarray
    width_m: np.ndarray
    approach: tuple[str, ...]
    chosen: int
    T_world_chosen: np.ndarray


def _empty(*shape: int) -> np.ndarray:
    out = np.zeros(shape)
    out.setflags(write=False)
    return out


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
        frame_mocap: Position and quaternion (w, x, y, z) of every mocap body at each video frame (F, nmocap, 7)
            (m; the fault's intruder, the camera's obstacle columns).
        frame_pad_force_n: The force of the left and right pad on the object at each video frame (F, 2, 3) (N).
        frame_pad_point_m: Where each of those forces acts (F, 2, 3) (m); zeros for a pad that does not touch.
        plans: Every path planned, in order.
        grasps: The grasp candidates and the chosen grasp of every approach planned, in order.
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
    frame_mocap: np.ndarray = field(default_factory=lambda: _empty(0, 0, 7))
    frame_pad_force_n: np.ndarray = field(default_factory=lambda: _empty(0, 2, 3))
    frame_pad_point_m: np.ndarray = field(default_factory=lambda: _empty(0, 2, 3))
    plans: tuple[PlannedPath, ...] = ()
    grasps: tuple[GraspChoice, ...] = ()

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
    _tcp_pos: list[np.ndarray] = field(default_factory=list, repr=False)
    _object: list[np.ndarray] = field(default_factory=list, repr=False)
    _force: list[np.ndarray] = field(default_factory=list, repr=False)
    _segments: list[JointSegment] = field(default_factory=list, repr=False)
    _frame_t: list[float] = field(default_factory=list, repr=False)
    _frames: list[np.ndarray] = field(default_factory=list, repr=False)
    _mocap: list[np.ndarray] = field(default_factory=list, repr=False)
    _pad_force: list[np.ndarray] = field(default_factory=list, repr=False)
    _pad_point: list[np.ndarray] = field(default_factory=list, repr=False)
    _plans: list[PlannedPath] = field(default_factory=list, repr=False)
    _grasps: list[GraspChoice] = field(default_factory=list, repr=False)
    _next_frame_s: float = 0.0

    def record(self, d: mujoco.MjData, t_s: float, phase: str) -> None:
        """Sample the state after a simulation step taken at episode time ``t_s`` (s) during ``phase``."""
        h = self.robot.handles
        self._t.append(t_s)
        self._phase.append(self._names.setdefault(phase, len(self._names)))
        self._q.append(d.qpos[h.arm_qpos])  # an index array: already a copy
        self._tcp_pos.append(d.site_xpos[h.tcp_site].copy())
        self._object.append(d.xpos[h.object_body].copy())
        self._force.append(pad_forces(self.robot, d))
        if self.frame_rate_hz > 0 and t_s >= self._next_frame_s - 1e-9:
            self._frame_t.append(t_s)
            self._frames.append(d.qpos.copy())
            self._mocap.append(np.hstack([d.mocap_pos, d.mocap_quat]))
            force, point = pad_contact_forces(self.robot, d)
            self._pad_force.append(force)
            self._pad_point.append(point)
            self._next_frame_s += 1.0 / self.frame_rate_hz

    def add_joint_segment(self, phase: str, t_s: np.ndarray, q: np.ndarray, q_ref: np.ndarray) -> None:
        """Keep the reference and measured joints of one tracked trajectory (times on the episode clock)."""
        self._segments.append(JointSegment(phase, np.asarray(t_s), np.asarray(q), np.asarray(q_ref)))

    def _tcp(self, q: np.ndarray, data: pin.Data | None = None) -> pin.SE3:
        robot = self.robot
        data = data if data is not None else robot.pin.createData()
        return frame_pose(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame)

    def add_plan(self, name: str, t_s: float, traj: Trajectory) -> None:
        """Keep the tcp's path along a trajectory planned at episode time ``t_s`` (s)."""
        n = max(2, math.ceil(traj.duration_s / PATH_SAMPLE_S) + 1)
        qs, _, _ = traj.sample_many(np.linspace(0.0, traj.duration_s, n))
        data = self.robot.pin.createData()
        tcp = np.array([self._tcp(q, data).translation for q in qs])
        tcp.setflags(write=False)
        self._plans.append(PlannedPath(name, float(t_s), float(traj.duration_s), tcp))

    def add_grasp_choice(self, t_s: float, T_world_object: pin.SE3, q_pregrasp: np.ndarray) -> None:
        """Keep the grasp candidates of the object where the robot believes it is, and the one whose pregrasp
        ``q_pregrasp`` (6,) (rad) the arm plans to at episode time ``t_s`` (s)."""
        T_pre = self._tcp(q_pregrasp)
        R = T_pre.rotation
        chosen = pin.SE3(R, T_pre.translation + CLEARANCE_M * R[:, 2])
        grasps = candidate_grasps(self.robot, T_world_object)
        poses = [g.T_world_tcp(T_world_object) for g in grasps]
        index = -1
        if poses:
            gap = [float(np.linalg.norm(p.translation - chosen.translation)) + 0.05 * rotation_distance(p.rotation, R)
                   for p in poses]
            best = int(np.argmin(gap))
            index = best if gap[best] < 0.005 else -1  # the IK's residual is far below this
        keep = list(range(min(len(poses), MAX_RECORDED_GRASPS)))
        if index >= MAX_RECORDED_GRASPS:
            keep[-1], index = index, len(keep) - 1
        T = np.array([poses[k].homogeneous for k in keep]).reshape(len(keep), 4, 4)
        width = np.array([grasps[k].width_m for k in keep], dtype=float)
        for a in (T, width):
            a.setflags(write=False)
        self._grasps.append(GraspChoice(float(t_s), self.robot.scene.object.name, T_world_object.homogeneous.copy(),
                                        T, width, tuple(grasps[k].approach.value for k in keep), index,
                                        chosen.homogeneous.copy()))

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
        nmocap = self.robot.mj.nmocap
        mocap = np.array(self._mocap, dtype=float).reshape(len(self._mocap), nmocap, 7)
        force = np.array(self._pad_force, dtype=float).reshape(len(self._pad_force), 2, 3)
        point = np.array(self._pad_point, dtype=float).reshape(len(self._pad_point), 2, 3)
        for a in (mocap, force, point):
            a.setflags(write=False)
        return Telemetry(t, phase, names, arr(self._q, 6), arr(self._tcp_pos, 3), arr(self._object, 3),
                         arr(self._force, 2), tuple(self._segments), frame_t, arr(self._frames, nq),
                         np.asarray(self.goal_pos_m, dtype=float).copy(), mocap, force, point, tuple(self._plans),
                         tuple(self._grasps))


__all__ = ["MAX_RECORDED_GRASPS", "PATH_SAMPLE_S", "GraspChoice", "JointSegment", "PlannedPath", "Telemetry",
           "TelemetryRecorder"]
