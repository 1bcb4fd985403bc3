"""The pick-and-place state machine: phases, each with its controller, termination, success check and timeout.

``IDLE → PLAN_APPROACH → EXEC_APPROACH → DESCEND → CLOSE → LIFT → PLAN_TRANSPORT → EXEC_TRANSPORT →
DESCEND_PLACE → RELEASE → RETRACT → DONE`` (or ``FAILED``, with the phase and a specific reason).

Manipulation fails quietly — a slipped grasp raises nothing by itself — so every phase checks its own
outcome, and a monitor runs after *every* simulation step of every phase:

* unexpected contacts: the arm or the gripper touching the table, the floor, an obstacle or itself; the
  object touching an obstacle or the floor, or the table while it is carried; the gripper touching the object
  while it approaches it. The failure names the geoms.
* slip: from the end of CLOSE until RELEASE, the object's position in the tcp frame is compared with the
  one measured when the grip settled; moving more than ``MachineConfig.slip_tolerance_m`` fails the phase.

Everything the machine measures is collected in a :class:`MachineOutcome`; :mod:`pickplace.task.episode` turns
it into the user-facing :class:`~pickplace.task.episode.EpisodeResult`.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import ConfigError, GraspFailed, PickPlaceError, UnreachableTarget
from pickplace.grasping.closure import analyze_grasp
from pickplace.grasping.configurations import GraspConfigurations, solve_grasp_configurations
from pickplace.grasping.grip import GripCapacity, com_accelerations, grip_capacity, slowdown_for_grip
from pickplace.grasping.targets import (
    CLEARANCE_M,
    LIFT_STEP_M,
    MAX_RAISE_M,
    backed_off,
    object_yaw,
    place_targets,
    yaw_error,
)
from pickplace.motion import control
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.control import ControlConfig, Payload
from pickplace.motion.planning import PlannerConfig, plan
from pickplace.motion.timing import TimingConfig, Trajectory, retime
from pickplace.robot import gripper
from pickplace.robot.ik import IKConfig, solve_ik
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import Robot, object_geom_names
from pickplace.task.faults import FaultConfig, FaultInjector
from pickplace.task.monitor import ObjectMoved, StepMonitor, UnexpectedContact
from pickplace.task.telemetry import TelemetryRecorder
from pickplace.world.config import check_int, check_range
from pickplace.world.mass import mass_properties

log = logging.getLogger(__name__)


class Phase(enum.Enum):
    """The phases of a pick and place, in order (FAILED is terminal)."""

    IDLE = "IDLE"
    PLAN_APPROACH = "PLAN_APPROACH"
    EXEC_APPROACH = "EXEC_APPROACH"
    DESCEND = "DESCEND"
    CLOSE = "CLOSE"
    LIFT = "LIFT"
    PLAN_TRANSPORT = "PLAN_TRANSPORT"
    EXEC_TRANSPORT = "EXEC_TRANSPORT"
    DESCEND_PLACE = "DESCEND_PLACE"
    RELEASE = "RELEASE"
    RETRACT = "RETRACT"
    RECOVER = "RECOVER"  # only after a recoverable failure: stop, open, back off, re-observe the object
    DONE = "DONE"
    FAILED = "FAILED"


class PhaseFailed(PickPlaceError):
    """A phase's own success check failed.

    Attributes:
        phase: The phase that failed.
        reason: What was measured and what was required.
    """

    def __init__(self, phase: Phase, reason: str) -> None:
        self.phase = phase
        self.reason = reason
        super().__init__(f"{phase.value}: {reason}")


class CollisionPredicted(PickPlaceError):
    """The rest of the running trajectory would collide with the world as it is now (it changed).

    Attributes:
        pairs: The geom pairs that would collide first.
    """

    def __init__(self, pairs: list[tuple[str, str]], t_s: float, ahead_s: float) -> None:
        self.pairs = pairs
        names = ", ".join(f"{a} <-> {b}" for a, b in pairs) or "unknown geoms"
        super().__init__(f"collision predicted at t = {t_s:.3f} s, {ahead_s:.2f} s ahead: {names}")


@dataclass(frozen=True)
class MachineConfig:
    """Tolerances, timeouts and motion choices of the state machine (SI units).

    Attributes:
        planning_margin_m: Clearance the planner keeps from the table, floor and obstacles (m).
        close_timeout_s: Time allowed for the gripper to close and settle on the object (s).
        min_pad_force_n: Normal force each pad must press with for the grip to count (N).
        finger_settle_speed_m_s: Fingers slower than this count as settled (m/s).
        slip_tolerance_m: Largest allowed motion of the object in the tcp frame while it is held (m).
        release_timeout_s: Time allowed for the pads to open and clear the object (s).
        release_clearance_m: Gap between each pad and the object needed before retracting (m).
        object_rest_speed_m_s: The released object counts as resting below this speed (m/s).
        place_tolerance_xy_m: Largest horizontal distance of the placed object from the goal (m).
        place_tolerance_z_m: Largest height error of the placed object (m).
        place_tolerance_yaw_rad: Largest yaw error of the placed object (rad, modulo its symmetry).
        retract_height_m: Vertical retreat after the release, before returning home (m).
        settle_s: Hold at the end of each trajectory before the next phase (s).
        poll_s: Step of the loops that wait for the gripper (s).
        stable_after_release_s: After DONE, the simulation continues until this long after the release; the
            object must then still lie within ``place_tolerance_xy_m`` of the goal, or the episode fails (s).
        max_retries: Recoveries allowed per episode (regrasp, re-pick, replan); 0 turns recovery off. A
            failure identical (numbers aside) to the one the last recovery answered is not retried again.
        predict_period_s: While a trajectory runs, the rest of it is checked against the world as it is now
            this often (s); a predicted collision stops the arm and replans.
        object_settle_timeout_s: During a recovery, time allowed for the released object to come to rest (s).
        grip_safety_factor: Margin of the grip: the friction the object needs (its weight, and its inertia in a
            motion) times this must stay within what the pads give; an object whose weight alone needs more is
            rejected before the arm moves, and motions that carry it are slowed down until it holds.
    """

    planning_margin_m: float = 0.01
    close_timeout_s: float = 1.0
    min_pad_force_n: float = 2.0
    finger_settle_speed_m_s: float = 2e-3
    slip_tolerance_m: float = 0.003
    release_timeout_s: float = 1.0
    release_clearance_m: float = 0.002
    object_rest_speed_m_s: float = 0.002
    place_tolerance_xy_m: float = 0.003
    place_tolerance_z_m: float = 0.003
    place_tolerance_yaw_rad: float = 0.05
    retract_height_m: float = 0.06
    settle_s: float = 0.02
    poll_s: float = 0.01
    stable_after_release_s: float = 1.0
    max_retries: int = 3
    predict_period_s: float = 0.05
    object_settle_timeout_s: float = 2.0
    grip_safety_factor: float = 1.25

    def __post_init__(self) -> None:
        limits = {
            "planning_margin_m": (0.0, 0.1, "m"), "close_timeout_s": (0.01, 10.0, "s"),
            "min_pad_force_n": (0.0, 100.0, "N"), "finger_settle_speed_m_s": (1e-5, 1.0, "m/s"),
            "slip_tolerance_m": (1e-4, 0.05, "m"), "release_timeout_s": (0.01, 10.0, "s"),
            "release_clearance_m": (0.0, 0.03, "m"), "object_rest_speed_m_s": (1e-5, 1.0, "m/s"),
            "place_tolerance_xy_m": (1e-4, 0.1, "m"),
            "place_tolerance_z_m": (1e-4, 0.1, "m"), "place_tolerance_yaw_rad": (1e-4, math.pi / 4, "rad"),
            "retract_height_m": (0.0, 0.5, "m"), "settle_s": (0.0, 5.0, "s"), "poll_s": (0.001, 0.1, "s"),
            "stable_after_release_s": (0.0, 10.0, "s"), "predict_period_s": (0.001, 1.0, "s"),
            "object_settle_timeout_s": (0.01, 10.0, "s"), "grip_safety_factor": (1.0, 10.0, ""),
        }
        for name, (lo, hi, unit) in limits.items():
            object.__setattr__(self, name, check_range(f"machine.{name}", getattr(self, name), lo, hi, unit=unit))
        object.__setattr__(self, "max_retries", check_int("machine.max_retries", self.max_retries, 0, 20))


@dataclass(frozen=True)
class SegmentPlan:
    """How one joint-space segment was planned and timed.

    Attributes:
        name: ``"approach"``, ``"transport"`` or ``"return"``.
        plan_time_s: Wall time of planning (search + shortcut) (s).
        retime_time_s: Wall time of TOPP-RA (s).
        waypoints_raw: Waypoints of the tree path.
        waypoints_shortcut: Waypoints after shortcutting.
        cost_rad: Joint-space length after shortcutting (rad).
        duration_s: Duration of the timed trajectory (s).
        status: The planner's status (``direct``, ``solved``, ``refined``).
        slowdown: How many times slower than time-optimal it was run so that the grip holds (1: not slowed).
    """

    name: str
    plan_time_s: float
    retime_time_s: float
    waypoints_raw: int
    waypoints_shortcut: int
    cost_rad: float
    duration_s: float
    status: str
    slowdown: float = 1.0


@dataclass
class MachineOutcome:
    """Everything one run of the machine measured (filled in as the phases run).

    Attributes:
        phase: The final phase (DONE or FAILED).
        failure_phase: The phase that failed, or None.
        failure_reason: Why, with the numbers, or None.
        failure_kind: The exception class behind the failure (e.g. ``"UnreachableTarget"``), or None.
        phase_durations_s: Simulated time spent in each phase (s), in order.
        cycle_time_s: Simulated time from IDLE to DONE (s).
        segments: The planned segments.
        ik_position_error_m: Largest tcp position residual of the IK solutions (m).
        ik_orientation_error_rad: Largest tcp orientation residual of the IK solutions (rad).
        tracking: Tracking errors per phase, of every control loop that ran in it (trajectories, holds,
            Cartesian moves).
        tracking_total: The same over the whole episode.
        torque_saturation_events: Control steps with a clipped torque, all phases.
        grip_force_n: Sum of the pads' normal forces when the grip settled (N).
        lift_grip_force_n: Mean sum of the pads' normal forces while the object is lifted off the table (N).
        lift_load_n: Weight of the object as the pads measure it while lifting (N): ``g * sum(F_z) / sum(g + a_z)``
            over the airborne steps, with F_z the pads' vertical force on the object and a_z its measured
            acceleration. It equals m g when the pads alone hold the object.
        force_closure: Whether the settled grip was force closure (6D wrench test on the actual contacts).
        grasp_margin: Ferrari–Canny margin of that grip (normalized wrench units).
        grasp_approach: How the grasp that was executed last approaches the object (``top``, ``tilted``,
            ``side``; in the object's resting frame), or "" before one is chosen.
        grasp_tilt_rad: Its approach's angle from straight down (rad).
        grasp_width_m: The object's width between its pads (m).
        grasps_tried: Candidates tried (IK and collisions) before it was found, last time a grasp was chosen.
        slip_max_m: Largest motion of the object in the tcp frame while it was held (m).
        place_error_xy_m, place_error_z_m, place_error_yaw_rad: The object at rest after the release,
            relative to the goal (m, m, rad modulo 90 degrees).
        final_place_error_xy_m: Horizontal error ``stable_after_release_s`` after the release (m).
        unexpected_contacts: Geom pairs of unexpected contacts seen (empty on success).
        wall_plan_time_s: Wall time spent planning, IK and retiming (s).
        recoveries: One line per recovery: the failure that was caught and what was done about it.
        timeline: ``(phase, start_s, duration_s, outcome)`` of every phase run, in order; outcome is ``ok``,
            ``recovered`` (it failed and a recovery followed) or ``failed``. Phases repeat after a recovery.
    """

    phase: Phase = Phase.IDLE
    failure_phase: Phase | None = None
    failure_reason: str | None = None
    failure_kind: str | None = None
    phase_durations_s: dict[str, float] = field(default_factory=dict)
    cycle_time_s: float = 0.0
    segments: list[SegmentPlan] = field(default_factory=list)
    ik_position_error_m: float = 0.0
    ik_orientation_error_rad: float = 0.0
    tracking: dict[str, control.PhaseTracking] = field(default_factory=dict)
    tracking_total: control.PhaseTracking = field(default_factory=control.PhaseTracking)
    torque_saturation_events: int = 0
    grip_force_n: float = 0.0
    lift_grip_force_n: float = 0.0
    lift_load_n: float = 0.0
    force_closure: bool = False
    grasp_margin: float = 0.0
    grasp_approach: str = ""
    grasp_tilt_rad: float = math.nan
    grasp_width_m: float = math.nan
    grasps_tried: int = 0
    slip_max_m: float = 0.0
    place_error_xy_m: float = math.nan
    place_error_z_m: float = math.nan
    place_error_yaw_rad: float = math.nan
    final_place_error_xy_m: float = math.nan
    unexpected_contacts: list[tuple[str, str]] = field(default_factory=list)
    wall_plan_time_s: float = 0.0
    recoveries: list[str] = field(default_factory=list)
    timeline: list[tuple[str, float, float, str]] = field(default_factory=list)


#: Numbers in a failure message (ignored when comparing two failures).
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: Phases whose grasp failures are recovered by letting go and grasping again.
_GRASP_PHASES = (Phase.CLOSE, Phase.LIFT, Phase.PLAN_TRANSPORT, Phase.EXEC_TRANSPORT, Phase.DESCEND_PLACE)
#: Where to go back to when a collision is predicted or met while a trajectory runs.
_REPLAN = {Phase.EXEC_APPROACH: Phase.PLAN_APPROACH, Phase.EXEC_TRANSPORT: Phase.PLAN_TRANSPORT,
           Phase.RETRACT: Phase.RETRACT}

class PickPlaceMachine:
    """Runs one pick and place in a MuJoCo simulation, phase by phase.

    Args:
        robot: The models (the scene gives the object and the goal).
        data: The simulation state, advanced in place.
        machine: Tolerances and timeouts.
        control_config: Controller gains and vertical-move profile.
        planner: RRT* settings (its seed is the episode's).
        timing: TOPP-RA limits.
        ik: IK settings.
        recorder: Optional telemetry (plots, video).
        faults: Faults to inject (the model faults must already be applied, see
            :func:`pickplace.task.faults.apply_model_faults`).
        rng: Seeded generator for the sensor noise fault.
    """

    def __init__(
        self,
        robot: Robot,
        data: mujoco.MjData,
        machine: MachineConfig,
        control_config: ControlConfig,
        planner: PlannerConfig,
        timing: TimingConfig,
        ik: IKConfig,
        recorder: TelemetryRecorder | None = None,
        faults: FaultConfig | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.robot, self.d = robot, data
        self.cfg, self.ctrl, self.planner, self.timing, self.ik = machine, control_config, planner, timing, ik
        self.recorder = recorder
        self.faults = faults if faults is not None else FaultConfig()
        self.injector = FaultInjector(robot, self.faults)
        rng = rng if rng is not None else np.random.default_rng(0)
        self.noise = control.JointNoise(self.faults.joint_noise_rad, rng) if self.faults.joint_noise_rad > 0 else None
        self.monitor = StepMonitor(robot, recorder, machine.slip_tolerance_m, self.injector)
        self.monitor.predict_every = max(1, round(machine.predict_period_s / float(robot.mj.opt.timestep)))
        self.retries = 0
        self._last_recovered: tuple[Phase, str, str] | None = None  # the failure the last recovery answered
        self._repeated = False
        self._segment_checker: CollisionChecker | None = None
        self._traj_t0 = 0.0
        self.out = MachineOutcome()
        self.configs: GraspConfigurations | None = None
        self._trajectory: Trajectory | None = None
        self._payload: Payload | None = None
        self._capacity: GripCapacity | None = None
        self._T_tcp_object: pin.SE3 | None = None
        self._release_t = math.nan
        self._object_names = frozenset(object_geom_names(robot.scene.object))
        self._tallies: dict[str, control.TrackingTally] = {}
        self._tally_total = control.TrackingTally()

    # ------------------------------------------------------------------ helpers
    @property
    def q(self) -> np.ndarray:
        """Current arm joints (6,) (rad)."""
        return self.d.qpos[self.robot.handles.arm_qpos].copy()

    def _object_pose(self) -> pin.SE3:
        h = self.robot.handles
        return pin.SE3(self.d.xmat[h.object_body].reshape(3, 3).copy(), self.d.xpos[h.object_body].copy())

    def _tcp_pose(self) -> pin.SE3:
        h = self.robot.handles
        return pin.SE3(self.d.site_xmat[h.tcp_site].reshape(3, 3).copy(), self.d.site_xpos[h.tcp_site].copy())

    def _note_ik(self, *results: object) -> None:
        for r in results:
            self.out.ik_position_error_m = max(self.out.ik_position_error_m, r.position_error_m)  # type: ignore[attr-defined]
            self.out.ik_orientation_error_rad = max(self.out.ik_orientation_error_rad,
                                                    r.orientation_error_rad)  # type: ignore[attr-defined]

    def _count(self, rec: control.TrackingRecord | control.CartesianRecord) -> None:
        """Account for one control loop: its saturated steps and its tracking errors (in the current phase)."""
        self.out.torque_saturation_events += rec.saturation_events
        self._tallies.setdefault(self.monitor.phase, control.TrackingTally()).add(rec)
        self._tally_total.add(rec)

    def _hold(self, q: np.ndarray, duration_s: float) -> control.TrackingRecord:
        rec = control.hold(self.robot, self.d, q, duration_s, self.ctrl, payload=self._payload, hook=self.monitor,
                           noise=self.noise)
        self._count(rec)
        return rec

    def _stop(self) -> None:
        """Bring the arm to rest at the trajectories' deceleration limits, then hold it for 0.15 s."""
        rec = control.stop(self.robot, self.d, self.timing.acceleration_limits_rad_s2, self.ctrl,
                           payload=self._payload, hook=self.monitor, noise=self.noise, settle_s=0.15)
        self._count(rec)

    def _hold_until(self, q: np.ndarray | None, done: Callable[[], bool], timeout_s: float,
                    min_s: float = 0.0) -> bool:
        """Hold ``q`` in steps of ``poll_s`` until ``done()`` (checked from ``min_s`` on) or ``timeout_s`` (s).

        ``q`` None holds the arm where it is at each step (it is not driven anywhere).

        Returns:
            Whether ``done()`` became true in time.
        """
        waited = 0.0
        while True:
            if waited >= min_s and done():
                return True
            if waited >= timeout_s:
                return False
            self._hold(self.q if q is None else q, self.cfg.poll_s)
            waited += self.cfg.poll_s

    def _plan_segment(self, name: str, checker_at: Callable[[float], CollisionChecker], q_goal: np.ndarray) -> None:
        """Plan with the full clearance margin; accept the timed trajectory with half of it.

        The planner keeps ``planning_margin_m`` from the table and obstacles along its straight segments;
        the TOPP-RA spline deviates from them by up to ~1e-3 rad, so it is checked with half the margin (a
        path that grazes the full margin everywhere cannot be densified into passing it again).
        """
        t0 = time.perf_counter()
        margin = self.cfg.planning_margin_m
        res = plan(checker_at(margin), self.q, q_goal, self.robot.arm_lower, self.robot.arm_upper, self.planner)
        t1 = time.perf_counter()
        accept = checker_at(margin / 2)
        traj = retime(np.asarray(res.path), self.timing, accept.all_valid)
        slowdown = 1.0
        if self._capacity is not None and self._payload is not None:  # carrying: slow down to what the grip holds
            assert self._T_tcp_object is not None
            com = self._T_tcp_object.act(mass_properties(self.robot.scene.object).com_m)
            accels = com_accelerations(self.robot, traj, com, gripper.finger_travel(self.robot, self.d))
            slowdown = slowdown_for_grip(accels, self._capacity)
            if slowdown > 1.0:
                traj = traj.slowed(slowdown)
                log.info("%s: slowed down %.2f times so that the grip holds (%.3f s)", name, slowdown,
                         traj.duration_s)
        self._segment_checker = accept
        t2 = time.perf_counter()
        self.out.wall_plan_time_s += t2 - t0
        self.out.segments.append(SegmentPlan(name, t1 - t0, t2 - t1, len(res.path_raw), len(res.path), res.cost_rad,
                                             traj.duration_s, res.status.value, slowdown))
        self._trajectory = traj

    def _motion_config(self) -> ControlConfig:
        """The controller config of a straight move: with the object held, its peak acceleration limited to
        what the grip holds (``GripCapacity.max_vertical_accel_m_s2``, at least 0.1 m/s^2)."""
        if self._capacity is None or self._payload is None:
            return self.ctrl
        limit = max(0.1, self._capacity.max_vertical_accel_m_s2)
        if limit >= self.ctrl.vertical_accel_m_s2:
            return self.ctrl
        return dataclasses.replace(self.ctrl, vertical_accel_m_s2=limit)

    def _predict(self, t_start: float) -> Callable[[mujoco.MjData, float], None]:
        """A check of the rest of the running trajectory against the world as it is now."""
        traj, checker = self._trajectory, self._segment_checker
        assert traj is not None and checker is not None

        def predictor(d: mujoco.MjData, t: float) -> None:
            ts = np.arange(t - t_start, traj.duration_s, 0.01)
            if ts.size == 0:
                return
            checker.set_world(d)
            qs, _, _ = traj.sample_many(ts)
            if not checker.all_valid(qs):
                valid = checker.are_valid(qs)
                k = int(np.argmin(valid))
                raise CollisionPredicted(checker.colliding_pairs(qs[k]), t, float(ts[k] - ts[0]))

        return predictor

    def _free(self, margin_m: float) -> CollisionChecker:
        """A checker for the empty hand, with the world (the object, anything that moved) as it is now."""
        return CollisionChecker(self.robot, CollisionPolicy(margin_m=margin_m), world=self.d)

    def _execute(self, phase: Phase) -> None:
        assert self._trajectory is not None
        t_start = self._traj_t0 = self.monitor.t
        if self._segment_checker is not None and self.cfg.max_retries > 0:
            self.monitor.predictor = self._predict(t_start)
        try:
            rec = control.track(self.robot, self.d, self._trajectory, self.ctrl, payload=self._payload,
                                hook=self.monitor, settle_s=self.cfg.settle_s, noise=self.noise)
        finally:
            self.monitor.predictor = None
        self._count(rec)
        if self.recorder is not None:
            self.recorder.add_joint_segment(phase.value, t_start + rec.t, rec.q, rec.q_ref)
        if rec.final_error_rad > 0.01:  # knocked off its path (a push): give it time to settle at the end
            settle = self._hold(self._trajectory.waypoints[-1], 0.3)
            if settle.final_error_rad > 0.01:
                raise PhaseFailed(phase, f"the arm ended {settle.final_error_rad:.4f} rad from the trajectory's "
                                         "end, 0.3 s after it (limit 0.01 rad)")

    def _vertical(self, phase: Phase, target_z: float, hook: control.Hook | None = None) -> control.CartesianRecord:
        """Move the tcp straight up or down to ``target_z`` (m); ``hook`` replaces the monitor (and must call it)."""
        target = self._tcp_pose().translation.copy()
        target[2] = target_z
        return self._linear(phase, target, hook)

    def _linear(self, phase: Phase, target: np.ndarray, hook: control.Hook | None = None) -> control.CartesianRecord:
        """Move the tcp along a straight line to ``target`` (3,) (m); ``hook`` replaces the monitor."""
        rec = control.move_linear(self.robot, self.d, target, self._motion_config(), payload=self._payload,
                                  hook=hook or self.monitor, noise=self.noise)
        self._count(rec)
        if not rec.reached:
            raise PhaseFailed(phase, f"the tcp stopped {rec.final_error_m * 1e3:.2f} mm from its target")
        return rec

    # ------------------------------------------------------------------ phases
    def _idle(self) -> Phase:
        """Observe the object, solve every target (before the arm moves: unreachable goals fail here)."""
        t0 = time.perf_counter()
        mujoco.mj_forward(self.robot.mj, self.d)
        obj = self._object_pose()
        configs = self._solve_grasps(obj)
        self.robot.scene.check_goal_on_table()
        self.monitor.watch_object_at = obj.translation.copy()
        self._adopt(configs)
        self._note_ik(*configs.results())
        self.out.wall_plan_time_s += time.perf_counter() - t0
        return Phase.PLAN_APPROACH

    def _solve_grasps(self, T_world_object: pin.SE3) -> GraspConfigurations:
        """The first grasp of the object where it rests whose targets all solve and whose pads hold it."""
        return solve_grasp_configurations(self.robot, self.ik, T_world_object, self.d, self.cfg.planning_margin_m,
                                          retreat_m=self.cfg.retract_height_m,
                                          safety_factor=self.cfg.grip_safety_factor)

    def _rise_until_clear(self, phase: Phase, checker_at: Callable[[float], CollisionChecker]) -> None:
        """Rise straight up in ``LIFT_STEP_M`` steps (up to ``MAX_RAISE_M``) until the arm clears everything by
        the planner's margin, as the next planned path needs (the object settled in the grip a little
        differently from the plan, the place ended a little off).

        Raises:
            PhaseFailed: still not clear at the highest step; the geoms are named.
        """
        checker = checker_at(self.cfg.planning_margin_m)
        risen = 0.0
        while not checker.is_valid(self.q):
            if risen >= MAX_RAISE_M - 1e-9:
                pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(self.q))
                raise PhaseFailed(phase, f"still within {self.cfg.planning_margin_m * 1e3:.0f} mm of something "
                                         f"after rising {risen:.2f} m: {pairs}")
            log.info("%s: within the planner's margin of something; rising %.2f m more", phase.value, LIFT_STEP_M)
            self._vertical(phase, float(self._tcp_pose().translation[2]) + LIFT_STEP_M)
            risen += LIFT_STEP_M

    def _adopt(self, configs: GraspConfigurations) -> None:
        """Take these targets, after checking that their grip can hold the object (:class:`CannotHold` if not)."""
        targets, obj = configs.targets, self.robot.scene.object
        capacity = grip_capacity(self.robot, obj, targets.T_tcp_object, targets.width_m, self.cfg.grip_safety_factor,
                                 up_tcp=targets.grasp.rotation[2])
        capacity.require_holdable(obj.name)
        self.configs, self._capacity = configs, capacity
        grasp = configs.chosen
        self.out.grasp_approach, self.out.grasp_tilt_rad = grasp.approach.value, grasp.tilt_rad
        self.out.grasp_width_m, self.out.grasps_tried = grasp.width_m, configs.grasps_tried
        log.info("grasp: %s (tilted %.0f deg), %.1f mm wide, margin %.3f; %d tried", grasp.approach.value,
                 math.degrees(grasp.tilt_rad), grasp.width_m * 1e3, grasp.margin, configs.grasps_tried)

    def _plan_approach(self) -> Phase:
        assert self.configs is not None
        self._plan_segment("approach", self._free, self.configs.pregrasp.q)
        return Phase.EXEC_APPROACH

    def _exec_approach(self) -> Phase:
        self._execute(Phase.EXEC_APPROACH)
        return Phase.DESCEND

    def _descend(self) -> Phase:
        """The straight approach from the pregrasp to the grasp (a descent for a top-down grasp)."""
        assert self.configs is not None
        targets = self.configs.targets
        self._linear(Phase.DESCEND, targets.grasp.translation)
        want = (self._object_pose() * targets.T_object_tcp).translation  # where the grasp is, the object as it is
        off = float(np.linalg.norm(self._tcp_pose().translation - want))
        if off > 0.005:
            raise PhaseFailed(Phase.DESCEND, f"the tcp is {off * 1e3:.1f} mm from its grasp on the "
                                             f"{self.robot.scene.object.name} (limit 5 mm)")
        return Phase.CLOSE

    def _close(self) -> Phase:
        robot, d, cfg = self.robot, self.d, self.cfg
        self.monitor.watch_object_at = None  # the pads move it now
        self.monitor.allow_hand_object = True
        gripper.command(robot, d, True)

        def gripping() -> bool:
            return (gripper.is_settled(robot, d, cfg.finger_settle_speed_m_s)
                    and bool(np.all(gripper.pad_forces(robot, d) >= cfg.min_pad_force_n)))

        settled = self._hold_until(self.q, gripping, cfg.close_timeout_s, min_s=5 * cfg.poll_s)
        forces = gripper.pad_forces(robot, d)
        if not settled:
            travel = gripper.finger_travel(robot, d)
            raise GraspFailed(f"the pads did not settle on the {robot.scene.object.name} within "
                              f"{cfg.close_timeout_s:g} s: "
                              f"pad forces {forces[0]:.1f} / {forces[1]:.1f} N (need {cfg.min_pad_force_n:g} "
                              f"N each), finger travel {travel * 1e3:.1f} mm")
        contacts = gripper.pad_contacts(robot, d)
        obj = self._object_pose()
        fc = analyze_grasp(contacts, obj.act(mass_properties(robot.scene.object).com_m),
                           float(np.max(robot.scene.object.geometry().extent_m)) / 2)
        self.out.grip_force_n = float(forces.sum())
        self.out.force_closure = fc.force_closure
        self.out.grasp_margin = fc.margin
        if not fc.force_closure:
            raise GraspFailed(f"the grip is not force closure ({len(contacts)} contacts, margin {fc.margin:.3g})")
        self.monitor.start_holding(d)
        tcp = self._tcp_pose()
        self._T_tcp_object = tcp.actInv(obj)
        self._payload = Payload.held(robot.scene.object, self._T_tcp_object)
        return Phase.LIFT

    def _lift(self) -> Phase:
        """Lift straight up, weighing the object on the way (the pads' force over its acceleration).

        If the arm cannot hold the lift height because the object is heavier (or lighter) than believed, the
        payload compensation is corrected with the measured mass and the move is repeated once.
        """
        assert self.configs is not None and self._payload is not None
        target_z = float(self.configs.targets.lift.translation[2])
        z_object0 = float(self._object_pose().translation[2])
        self.monitor.allow_object_table = True  # until it leaves the table
        forces: list[float] = []
        f_z: list[float] = []
        g_plus_a: list[float] = []
        monitor, h = self.monitor, self.robot.handles
        g = float(-self.robot.mj.opt.gravity[2])
        object_az = h.object_dof + 2  # the free joint's world z acceleration

        def hook(d: mujoco.MjData) -> None:
            monitor(d)
            if monitor.allow_object_table and d.xpos[h.object_body][2] > z_object0 + 0.003:
                monitor.allow_object_table = False  # airborne: touching the table again is a failure
            if not monitor.allow_object_table:  # airborne: only the pads (and gravity) act on the object
                normal, f = gripper.pad_load(self.robot, d)
                forces.append(float(normal.sum()))
                f_z.append(float(f[2]))
                g_plus_a.append(g + float(d.qacc[object_az]))

        def measured_mass() -> float:
            return float(np.sum(f_z) / np.sum(g_plus_a)) if f_z else math.nan

        try:
            rec = control.move_vertical(self.robot, self.d, target_z, self._motion_config(), payload=self._payload,
                                        hook=hook,
                                        noise=self.noise, raise_on_timeout=False)
        finally:  # a slip aborts the move: still report what the pads felt
            mass = measured_mass()
            self.out.lift_load_n = mass * g if math.isfinite(mass) else 0.0
        self._count(rec)
        if (not rec.reached and math.isfinite(mass) and abs(mass / self._payload.mass_kg - 1.0) > 0.2
                and self.retries < self.cfg.max_retries):
            self.retries += 1
            note = (f"LIFT: the {self.robot.scene.object.name} weighs {mass:.3f} kg, not "
                    f"{self._payload.mass_kg:.3f} kg (the arm stopped "
                    f"{rec.final_height_error_m * 1e3:.2f} mm short) -> payload compensation corrected")
            self.out.recoveries.append(note)
            log.info("recovery: %s", note)
            self._payload = dataclasses.replace(self._payload, mass_kg=mass)
            self._capacity = dataclasses.replace(self._capacity, mass_kg=mass) if self._capacity else None
            rec = control.move_vertical(self.robot, self.d, target_z, self._motion_config(), payload=self._payload,
                                        hook=hook,
                                        noise=self.noise, raise_on_timeout=False)
            self._count(rec)
            mass = measured_mass()
        self.out.lift_grip_force_n = float(np.mean(forces)) if forces else 0.0
        self.out.lift_load_n = mass * g if math.isfinite(mass) else 0.0
        if not rec.reached:
            raise PhaseFailed(Phase.LIFT, f"the tcp stopped {rec.final_height_error_m * 1e3:.2f} mm from the lift "
                                          f"height (the {self.robot.scene.object.name} weighed {mass:.3f} kg)")
        self.monitor.allow_object_table = False
        rise = float(self._object_pose().translation[2]) - z_object0
        lifted = target_z - float(self.configs.targets.grasp.translation[2])
        if abs(rise - lifted) > self.cfg.slip_tolerance_m:
            raise GraspFailed(f"the {self.robot.scene.object.name} rose {rise * 1e3:.1f} mm while the tcp rose "
                              f"{lifted * 1e3:.1f} mm")
        self._T_tcp_object = self._tcp_pose().actInv(self._object_pose())  # as it sits in the hand
        self._rise_until_clear(Phase.LIFT, lambda margin: self._carrying(margin, False))
        return Phase.PLAN_TRANSPORT

    def _carrying(self, margin_m: float, allow_object_table: bool) -> CollisionChecker:
        assert self.configs is not None
        policy = CollisionPolicy(margin_m=margin_m, object_held=True, allow_object_table=allow_object_table,
                                 finger_m=gripper.finger_travel(self.robot, self.d))
        return CollisionChecker(self.robot, policy, world=self.d, T_tcp_object=self._T_tcp_object)

    def _plan_transport(self) -> Phase:
        """Re-target the place from the object's measured pose in the hand, then plan to above the goal."""
        assert self.configs is not None
        t0 = time.perf_counter()
        tcp, obj = self._tcp_pose(), self._object_pose()
        self._T_tcp_object = tcp.actInv(obj)
        preplace, place = place_targets(self.robot.scene, tcp, obj, self.configs.targets.R_world_object_goal,
                                        self.configs.targets.preplace_height_m)
        finger = gripper.finger_travel(self.robot, self.d)
        carry_ik = self._carrying(self.cfg.planning_margin_m, False)  # the planner accepts it as a goal
        place_ik = self._carrying(0.0, True)
        pre = solve_ik(self.robot, preplace, self.configs.preplace.q, "preplace", self.ik, carry_ik.is_valid, finger)
        low = solve_ik(self.robot, place, pre.q, "place", self.ik, place_ik.is_valid, finger)
        self._note_ik(pre, low)
        self.out.wall_plan_time_s += time.perf_counter() - t0
        self._plan_segment("transport", lambda margin: self._carrying(margin, False), pre.q)
        return Phase.EXEC_TRANSPORT

    def _exec_transport(self) -> Phase:
        assert self._trajectory is not None
        if self.faults.intruder and not self.injector.intruder_placed:  # it appears once the path is planned
            T_end = frame_pose(self.robot.pin, self.robot.pin.createData(),
                               self.robot.pin_q(self._trajectory.waypoints[-1]), self.robot.pin_tcp_frame)
            self.injector.place_intruder(self.d, self._tcp_pose().translation, T_end.translation)
        self._execute(Phase.EXEC_TRANSPORT)
        return Phase.DESCEND_PLACE

    def _descend_place(self) -> Phase:
        """Re-aim from the object's pose in the hand *now* (it shifts a little in transit), then set it down."""
        assert self.configs is not None
        t0 = time.perf_counter()
        tcp, obj = self._tcp_pose(), self._object_pose()
        preplace, place = place_targets(self.robot.scene, tcp, obj, self.configs.targets.R_world_object_goal,
                                        self.configs.targets.preplace_height_m)
        finger = gripper.finger_travel(self.robot, self.d)
        aim = solve_ik(self.robot, preplace, self.q, "preplace", self.ik, finger_m=finger)
        self._note_ik(aim)
        self.out.wall_plan_time_s += time.perf_counter() - t0
        if float(np.max(np.abs(aim.q - self.q))) > 1e-5:
            self._trajectory = retime(np.vstack([self.q, aim.q]), self.timing)
            self._segment_checker = None  # a sub-millimetre correction: nothing to predict
            self._execute(Phase.DESCEND_PLACE)
        monitor = self.monitor
        z_table_touch = self.robot.scene.resting_z_m(self.configs.targets.R_world_object_goal) + 0.003

        def hook(d: mujoco.MjData) -> None:
            if d.xpos[self.robot.handles.object_body][2] < z_table_touch:
                monitor.allow_object_table = True  # setting it down
            monitor(d)

        self._vertical(Phase.DESCEND_PLACE, float(place.translation[2]), hook)
        return Phase.RELEASE

    def _release(self) -> Phase:
        robot, d, cfg = self.robot, self.d, self.cfg
        self.monitor.holding = False
        self.monitor.allow_object_table = True
        self._payload = None
        gripper.command(robot, d, False)
        self._release_t = self.monitor.t
        geom = gripper.GripperGeometry.measure(robot)
        clear_travel = geom.contact_travel_m(self.configs.targets.width_m) - cfg.release_clearance_m
        object_v = slice(robot.handles.object_dof, robot.handles.object_dof + 3)

        def released() -> bool:
            return (gripper.finger_travel(robot, d) <= clear_travel and not np.any(gripper.pad_forces(robot, d) > 0.0)
                    and float(np.linalg.norm(d.qvel[object_v])) < cfg.object_rest_speed_m_s)

        if not self._hold_until(self.q, released, cfg.release_timeout_s, min_s=cfg.poll_s):
            forces = gripper.pad_forces(robot, d)
            raise PhaseFailed(Phase.RELEASE, f"the pads did not clear the {robot.scene.object.name} within "
                                             f"{cfg.release_timeout_s:g} "
                                             f"s (finger travel {gripper.finger_travel(robot, d) * 1e3:.1f} mm, pad "
                                             f"forces {forces[0]:.2f} / {forces[1]:.2f} N, its speed "
                                             f"{float(np.linalg.norm(d.qvel[object_v])) * 1e3:.1f} mm/s)")
        self.monitor.allow_hand_object = False
        self._measure_place()
        if self.out.place_error_xy_m > cfg.place_tolerance_xy_m:
            raise PhaseFailed(Phase.RELEASE, f"the {robot.scene.object.name} rests "
                                             f"{self.out.place_error_xy_m * 1e3:.2f} mm from the goal "
                                             f"(tolerance {cfg.place_tolerance_xy_m * 1e3:.2f} mm)")
        if abs(self.out.place_error_z_m) > cfg.place_tolerance_z_m:
            raise PhaseFailed(Phase.RELEASE, f"the {robot.scene.object.name} rests "
                                             f"{self.out.place_error_z_m * 1e3:.2f} mm above the "
                                             "table (it should sit on it; tolerance "
                                             f"{cfg.place_tolerance_z_m * 1e3:.2f} mm)")
        if abs(self.out.place_error_yaw_rad) > cfg.place_tolerance_yaw_rad:
            raise PhaseFailed(Phase.RELEASE, f"the {robot.scene.object.name}'s yaw is "
                                             f"{self.out.place_error_yaw_rad:.3f} rad off the "
                                             f"goal's (tolerance {cfg.place_tolerance_yaw_rad:.3f} rad)")
        return Phase.RETRACT

    def _measure_place(self) -> None:
        scene = self.robot.scene
        assert self.configs is not None
        obj = self._object_pose()
        err = obj.translation - scene.goal_resting_m(self.configs.targets.R_world_object_goal)
        self.out.place_error_xy_m = float(np.hypot(err[0], err[1]))
        self.out.place_error_z_m = float(err[2])
        self.out.place_error_yaw_rad = yaw_error(obj.rotation, self.configs.targets.R_world_object_goal,
                                                 scene.object.yaw_period_rad)

    def _retract(self) -> Phase:
        """Back off from the object along the approach, rise if the plan said so (or if the hand is still
        within the planner's margin of something), and go home."""
        assert self.configs is not None
        self._linear(Phase.RETRACT, backed_off(self._tcp_pose(), self.cfg.retract_height_m).translation)
        if self.configs.targets.retreat_rise_m > 0.0:
            self._vertical(Phase.RETRACT, float(self._tcp_pose().translation[2]) + self.configs.targets.retreat_rise_m)
        self._rise_until_clear(Phase.RETRACT, self._free)
        self._plan_segment("return", self._free, self.robot.home_q)
        self._execute(Phase.RETRACT)
        return Phase.DONE

    # ------------------------------------------------------------------ driver
    def run(self) -> MachineOutcome:
        """Run the phases to DONE or FAILED; never raises for a failure of the task itself."""
        steps = {
            Phase.IDLE: self._idle, Phase.PLAN_APPROACH: self._plan_approach,
            Phase.EXEC_APPROACH: self._exec_approach, Phase.DESCEND: self._descend, Phase.CLOSE: self._close,
            Phase.LIFT: self._lift, Phase.PLAN_TRANSPORT: self._plan_transport,
            Phase.EXEC_TRANSPORT: self._exec_transport, Phase.DESCEND_PLACE: self._descend_place,
            Phase.RELEASE: self._release, Phase.RETRACT: self._retract, Phase.RECOVER: self._recover,
        }
        phase = Phase.IDLE
        out = self.out
        while phase is not Phase.DONE:
            self.monitor.phase = phase.value
            t0 = self.monitor.t
            try:
                nxt = steps[phase]()
            except ConfigError:
                raise  # bad input is the caller's error, not a failed episode
            except PickPlaceError as exc:
                recovery = self._recovery(phase, exc)
                self._spent(phase, t0, "failed" if recovery is None else "recovered")
                if recovery is None:
                    self._fail(phase, exc)
                    break
                phase = recovery
                continue
            self._spent(phase, t0, "ok")
            log.debug("%s done in %.3f s (t = %.3f s)", phase.value, self.monitor.t - t0, self.monitor.t)
            phase = nxt
        else:
            out.phase = Phase.DONE
            out.cycle_time_s = self.monitor.t
            self._after_done()
        out.slip_max_m = self.monitor.slip_max_m
        out.tracking = {phase: tally.result() for phase, tally in self._tallies.items()}
        out.tracking_total = self._tally_total.result()
        return out

    def _spent(self, phase: Phase, t0: float, outcome: str) -> None:
        durations = self.out.phase_durations_s
        durations[phase.value] = durations.get(phase.value, 0.0) + self.monitor.t - t0
        self.out.timeline.append((phase.value, t0, self.monitor.t - t0, outcome))

    # ------------------------------------------------------------------ recovery
    def _recovery(self, phase: Phase, exc: PickPlaceError) -> Phase | None:
        """The phase to continue with after ``exc`` in ``phase``, or None if it cannot be recovered."""
        if isinstance(exc, UnexpectedContact):
            self.out.unexpected_contacts.extend(p for p in exc.pairs if p not in self.out.unexpected_contacts)
        if self.retries >= self.cfg.max_retries:
            return None
        signature = (phase, type(exc).__name__, _NUMBER.sub("#", str(exc)))
        if signature == self._last_recovered:  # recovering changed nothing: the cause is not transient
            self._repeated = True
            return None
        if isinstance(exc, CollisionPredicted) and phase in _REPLAN:
            action, nxt = "stop and replan", _REPLAN[phase]
            self._stop()  # before planning from where the arm stands
        elif isinstance(exc, UnexpectedContact) and phase in _REPLAN and not self._touches_object(exc):
            action, nxt = "back off along the executed path and replan", _REPLAN[phase]
            self._back_off()
        elif isinstance(exc, GraspFailed) and phase in _GRASP_PHASES:
            action, nxt = "stop, open, back off, re-observe the object and grasp again", Phase.RECOVER
        elif isinstance(exc, UnexpectedContact) and phase in _GRASP_PHASES and self._touches_object(exc):
            # the held object (slipping, knocked) hit the table or a wall: the robot itself touched nothing
            action, nxt = "stop, open, back off, re-observe the object and grasp again", Phase.RECOVER
        elif isinstance(exc, ObjectMoved) and phase in (Phase.EXEC_APPROACH, Phase.DESCEND):
            action, nxt = "stop, wait for the object to rest, observe it again and approach again", Phase.RECOVER
        elif phase is Phase.DESCEND and (isinstance(exc, PhaseFailed) or
                                         (isinstance(exc, UnexpectedContact) and self._touches_object(exc))):
            action, nxt = "back off, re-observe the object and approach again", Phase.RECOVER
        else:
            return None
        self.retries += 1
        self._last_recovered = signature
        note = f"{phase.value}: {type(exc).__name__}: {exc} -> {action}"
        self.out.recoveries.append(note)
        log.info("recovery %d/%d: %s", self.retries, self.cfg.max_retries, note)
        return nxt

    def _touches_object(self, exc: UnexpectedContact) -> bool:
        """Whether every pair of the contact involves the object."""
        return all(any(name in self._object_names for name in pair) for pair in exc.pairs)

    def _back_off(self) -> None:
        """Retrace the last 0.3 s of the running trajectory (collisions tolerated), then stand still."""
        traj = self._trajectory
        if traj is None:
            return
        t_in = self.monitor.t - self._traj_t0
        q_back = traj.sample(max(0.0, min(t_in, traj.duration_s) - 0.3))[0]
        self.monitor.tolerate_contacts = True
        try:
            path = np.vstack([self.q, q_back])
            if float(np.max(np.abs(path[1] - path[0]))) > 1e-6:
                rec = control.track(self.robot, self.d, retime(path, self.timing), self.ctrl, payload=self._payload,
                                    hook=self.monitor, settle_s=0.1, noise=self.noise)
                self._count(rec)
        finally:
            self.monitor.tolerate_contacts = False

    def _recover(self) -> Phase:
        """Stop, let go, back off upwards, wait for the object to rest wherever it fell, and observe it again for
        a new approach (with whatever grasp now works)."""
        robot, d, cfg = self.robot, self.d, self.cfg
        scene = robot.scene
        self.monitor.holding = False
        self.monitor.watch_object_at = None
        self.monitor.allow_hand_object = True
        self.monitor.allow_object_table = True
        self._stop()  # with the grip as it is: opening at speed would throw whatever is still held
        self._payload = None
        gripper.command(robot, d, False)
        self._hold(self.q, 0.15)
        z_safe = scene.table_height_m + float(np.max(scene.object.geometry().extent_m)) + CLEARANCE_M
        if float(self._tcp_pose().translation[2]) < z_safe:
            self._vertical(Phase.RECOVER, z_safe)
        object_v = slice(robot.handles.object_dof, robot.handles.object_dof + 6)
        name = scene.object.name
        self.monitor.object_falling = True  # the arm waits; whatever the object lands on, it came to it
        try:
            rested = self._hold_until(None, lambda: float(np.linalg.norm(d.qvel[object_v])) <= 0.01,
                                      cfg.object_settle_timeout_s)
        finally:
            self.monitor.object_falling = False
        if not rested:
            raise PhaseFailed(Phase.RECOVER, f"the {name} did not come to rest within "
                                             f"{cfg.object_settle_timeout_s:.1f} s")
        self.monitor.allow_hand_object = False
        obj = self._object_pose()
        lowest = float(np.min(scene.object.geometry().vertices @ obj.rotation[2]) + obj.translation[2])
        where = f"({obj.translation[0]:.3f}, {obj.translation[1]:.3f}) m"
        if lowest < scene.table_height_m - 0.01:
            raise PhaseFailed(Phase.RECOVER, f"the {name} fell off the table: it rests at {where}, "
                                             f"{scene.table_height_m - lowest:.3f} m below the table top")
        if lowest > scene.table_height_m + 0.005:
            raise PhaseFailed(Phase.RECOVER, f"the {name} is not resting on the table: its lowest point is "
                                             f"{(lowest - scene.table_height_m) * 1e3:.0f} mm above it at {where} "
                                             "(it is stuck on something)")
        t0 = time.perf_counter()
        try:
            self._adopt(self._solve_grasps(obj))
        except UnreachableTarget as exc:
            raise PhaseFailed(Phase.RECOVER, f"the {name} now rests at {where}, out of reach: {exc}") from exc
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        self.monitor.watch_object_at = obj.translation.copy()
        log.info("recovery: the %s was observed again at (%.4f, %.4f) m, yaw %.3f rad", name, *obj.translation[:2],
                 object_yaw(obj.rotation))
        return Phase.PLAN_APPROACH

    def _fail(self, phase: Phase, exc: PickPlaceError) -> None:
        out = self.out
        out.phase = Phase.FAILED
        out.failure_phase = exc.phase if isinstance(exc, PhaseFailed) else phase
        out.failure_reason = exc.reason if isinstance(exc, PhaseFailed) else str(exc)
        out.failure_kind = type(exc).__name__
        if self._repeated:
            out.failure_reason += " (the same failure as before the last recovery: not transient, no more retries)"
        out.cycle_time_s = self.monitor.t
        if isinstance(exc, UnexpectedContact):
            out.unexpected_contacts = list(exc.pairs)
        log.info("episode failed in %s: %s", out.failure_phase.value, out.failure_reason)

    def _after_done(self) -> None:
        """Keep simulating at home until ``stable_after_release_s`` after the release; measure the object."""
        remaining = self._release_t + self.cfg.stable_after_release_s - self.monitor.t
        self.monitor.phase = Phase.DONE.value
        try:
            if remaining > 0:
                self._hold(self.robot.home_q, remaining)
        except PickPlaceError as exc:
            self._fail(Phase.DONE, exc)
            return
        obj = self._object_pose()
        err = obj.translation[:2] - self.robot.scene.goal_pos_m[:2]
        self.out.final_place_error_xy_m = float(np.hypot(err[0], err[1]))
        tol = self.cfg.place_tolerance_xy_m
        if self.out.final_place_error_xy_m > tol:  # placed, then it moved: the place did not hold
            self._fail(Phase.RELEASE, PhaseFailed(
                Phase.RELEASE, f"the {self.robot.scene.object.name} moved after the release: it rests "
                f"{self.out.final_place_error_xy_m * 1e3:.2f}"
                f" mm from the goal {self.cfg.stable_after_release_s:g} s after it (tolerance {tol * 1e3:.2f} mm)"))


__all__ = [
    "CollisionPredicted",
    "MachineConfig",
    "MachineOutcome",
    "Phase",
    "PhaseFailed",
    "PickPlaceMachine",
    "SegmentPlan",
]
