"""The arm in the simulation: motions executed under the per-step monitor, and what they cost.

:class:`Arm` owns what moving the arm needs and what it measures: the controllers and their gains, the
planner and the retiming, the monitor that runs after every simulation step (and its clock), the payload
compensation and the grip's capacity while something is held, and the tally of tracking errors and torque
saturation per phase. A skill (:mod:`pickplace.task.skill`) says *what* to do; the arm does it and raises
when a motion fails (:class:`~pickplace.task.phases.PhaseFailed`, or whatever the monitor raises). Several
skills run one after another on the same arm share its clock and its record.

A motion that does not stop between phases (the approach that runs into the descent, the lift into the
transport, the transport into the set-down) is one trajectory timed at once (:meth:`Arm.plan_through`,
:func:`~pickplace.motion.timing.retime_parts`) and run part by part (:meth:`Arm.execute` with ``until``): each
phase runs its part and checks what it must where the part ends, the arm still moving.

A straight tcp move made on its own (the final approach, the lift, the set-down, the back-off and the rises, where
they do not run on from or into a planned path) is a joint trajectory too (:meth:`Arm.linear`): its IK waypoints
(:func:`~pickplace.robot.ik.solve_line`), timed within the joints' limits with the spline on the line and checked
against collisions, tracked by the joint controller. Only where no such trajectory can be built (a waypoint does not
solve on the arm's branch, the spline does not stay on the line even through waypoints 1 mm apart) is the move
made by the Cartesian controller (timed within the joints' limits as well).

Every physics step of every motion is measured against the UR5e's joint speed, acceleration and torque limits
(:class:`~pickplace.motion.limits.LimitMeter`, the record's ``limits``), and the straight line the tcp follows
where a phase asks for it (:meth:`Arm.following`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import TimingFailed, UnreachableTarget
from pickplace.grasping.grip import TURN_OVER_RAD, GripCapacity, carried_tilt_rad, com_accelerations, slowdown_for_grip
from pickplace.grasping.targets import LIFT_STEP_M, MAX_RAISE_M
from pickplace.motion import control
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.control import ControlConfig, Payload
from pickplace.motion.limits import LimitMeter, LineMeter
from pickplace.motion.loop import ControlLoop, Measured
from pickplace.motion.planning import PlannerConfig, plan, segment_valid
from pickplace.motion.timing import PathPart, TimingConfig, Trajectory, retime, retime_parts
from pickplace.robot import gripper
from pickplace.robot.ik import LINE_STEP_M, IKConfig, IKResult, solve_line
from pickplace.robot.kinematics import frame_jacobian, frame_pose
from pickplace.robot.model import Robot
from pickplace.task.faults import FaultConfig, FaultInjector
from pickplace.task.monitor import StepMonitor
from pickplace.task.observe import Observer, SimulatorObserver
from pickplace.task.phases import CollisionPredicted, MachineConfig, MachineOutcome, Phase, PhaseFailed, SegmentPlan
from pickplace.task.telemetry import TelemetryRecorder

log = logging.getLogger(__name__)


#: A carrying trajectory that tilts the object more than :data:`~pickplace.grasping.grip.TURN_OVER_RAD` is run
#: this many times slower than time-optimal: the grip model (:func:`slowdown_for_grip`) bounds the object's linear
#: acceleration only, and a third of the speed cut the creep of a turned-over ball from 3.0 to 1.3 mm.
TURN_OVER_SLOWDOWN = 3.0


def hand_turn_rad(robot: Robot, traj: Trajectory, dt_s: float = 0.02) -> float:
    """Largest tilt (rad) of a carried object along a trajectory (every ``dt_s``) from how it is held at its start
    (:func:`~pickplace.grasping.grip.carried_tilt_rad`)."""
    qs, _, _ = traj.sample_many(np.arange(0.0, traj.duration_s + dt_s, dt_s))
    return carried_tilt_rad(robot, qs)


#: How far the spline of a straight move timed with its neighbours (:meth:`Arm.plan_through`) may stray from the
#: move's line (m): half the final approach's 1 mm, the rest for tracking.
LINE_TOLERANCE_M = 0.5e-3


@dataclass(frozen=True, eq=False)
class StraightMove:
    """A straight tcp move to time together with a planned path (:meth:`Arm.plan_through`).

    Attributes:
        path: The configurations it passes through (N, 6) (rad), e.g. :attr:`IKResult.path` of
            :func:`~pickplace.robot.ik.solve_line`: its IK waypoints, 1 cm apart.
        speed_m_s: The tcp's speed limit along it (m/s).
        reserve: The share of the joint limits it is not timed with: room for correcting where it ends while it
            runs (:meth:`Arm.offset_end`).
    """

    path: np.ndarray
    speed_m_s: float
    reserve: float = 0.0


#: The share of the joints' acceleration limits kept, beyond the held weight's, by a straight move that starts or
#: ends with the object on the table (:meth:`Arm.support_reserve`): the contacts' transients at lift-off.
SUPPORT_MARGIN = 0.03

#: Waypoint spacing (m) of a straight move re-solved to be timed with its neighbours (:meth:`Arm.plan_through`)
#: where its 1 cm waypoints do not keep the spline on its line.
REFINED_LINE_STEP_M = 0.0025

#: Waypoint spacings (m) at which a straight move made on its own (:meth:`Arm.linear`) is solved, in turn, until
#: the spline through its IK waypoints stays within :data:`LINE_TOLERANCE_M` of its line: 1 cm, then
#: :data:`REFINED_LINE_STEP_M`, then 1 mm (the arm stretched out).
STRAIGHT_STEPS_M = (LINE_STEP_M, REFINED_LINE_STEP_M, 0.001)

#: Steps of the straight line to ``home`` tried for a start within the planner's margin (fraction of the line).
ESCAPE_STEP = 0.05
#: Joint-space step at which the way out is checked (rad, max-norm): it starts close to something.
ESCAPE_RESOLUTION_RAD = 0.001
#: The arm's links nearest its base (the UR5e's MJCF collision geoms): a straight rise of the hand does not take
#: them away from what they are near (reaching far, it lowers the upper arm towards the table's edge).
PROXIMAL_GEOMS = frozenset({"base_collision", "shoulder_collision", "upper_arm_joint_collision",
                            "upper_arm_collision", "elbow_collision", "forearm_collision"})


#: The trajectory predictor checks the rest of the running trajectory again only when something in the world it
#: checks against moved more than this since the last check found it clear (m, and quaternion components): resting
#: objects settle by far less, an obstacle that appears or an object that is knocked moves by far more.
WORLD_STILL = 1e-4


class Arm:
    """Runs the arm in a MuJoCo simulation: holds, stops, planned and timed trajectories, straight moves.

    Args:
        robot: The models.
        data: The simulation state, advanced in place.
        machine: Tolerances and timeouts.
        control_config: Controller gains and straight-move profile.
        planner: RRT* settings.
        timing: TOPP-RA limits.
        recorder: Optional telemetry (plots, video).
        faults: Faults to inject while it runs (the model faults must already be applied).
        rng: Seeded generator for the sensor-noise fault.
        out: The record the motions add to (segments, saturation, wall time); default: a new one.
        observer: What the robot knows about the object (:mod:`pickplace.task.observe`); default: the
            simulator's truth (the ideal profile).
        loop: The control loop every motion runs in (rate, latency, encoders,
            :class:`~pickplace.motion.loop.ControlLoop`); default: the ideal loop.

    Attributes:
        observer: The robot's source of knowledge about the object (the skills' and the monitor's).
        monitor: The per-step checks and the clock (``monitor.t``, s).
        payload: The held object's compensation, or None.
        capacity: What the grip holds, or None; motions that carry are slowed down to it.
        T_tcp_object: The held object's pose in the tcp frame, or None.
        held_com_m: The held object's centre of mass in its own frame (3,) (m).
        trajectory: The last planned trajectory.
    """

    def __init__(
        self,
        robot: Robot,
        data: mujoco.MjData,
        machine: MachineConfig,
        control_config: ControlConfig,
        planner: PlannerConfig,
        timing: TimingConfig,
        recorder: TelemetryRecorder | None = None,
        faults: FaultConfig | None = None,
        rng: np.random.Generator | None = None,
        out: MachineOutcome | None = None,
        observer: Observer | None = None,
        loop: ControlLoop | None = None,
    ) -> None:
        self.robot, self.d = robot, data
        self.cfg, self.ctrl, self.planner, self.timing = machine, control_config, planner, timing
        self.recorder = recorder
        self.faults = faults if faults is not None else FaultConfig()
        self.injector = FaultInjector(robot, self.faults)
        rng = rng if rng is not None else np.random.default_rng(0)
        self.noise = control.JointNoise(self.faults.joint_noise_rad, rng) if self.faults.joint_noise_rad > 0 else None
        self.loop = loop  # None: the ideal loop (exact state, every physics step, no delay)
        self.observer: Observer = observer if observer is not None else SimulatorObserver(robot, data)
        self.monitor = StepMonitor(robot, recorder, machine.slip_tolerance_m, self.injector, self.observer)
        self.monitor.predict_every = max(1, round(machine.predict_period_s / float(robot.mj.opt.timestep)))
        self.out = out if out is not None else MachineOutcome()
        self.payload: Payload | None = None
        self.capacity: GripCapacity | None = None
        self.T_tcp_object: pin.SE3 | None = None
        self.held_com_m = np.zeros(3)
        self._trajectory: Trajectory | None = None
        self._straight: tuple[bool, ...] = (False,)  # per part of the trajectory: a straight tcp move
        self._next_step = 0  # the step of the trajectory its next part starts at
        self._next_part = 0
        self.segment_checker: CollisionChecker | None = None
        # the last trajectory the planner accepted and the world its acceptance check saw (Arm.predict)
        self._accepted: tuple[Trajectory | None, tuple[np.ndarray, np.ndarray, np.ndarray]] = (
            None, (np.zeros(0), np.zeros(0), np.zeros(0)))
        self._traj_t0 = 0.0
        self._tallies: dict[str, control.TrackingTally] = {}
        self._tally_total = control.TrackingTally()
        self.limits = LimitMeter(robot, timing.velocity_limits_rad_s, timing.acceleration_limits_rad_s2)
        self.line_meter: LineMeter | None = None
        shrink = 1.0 - timing.limit_margin
        #: The joint limits a straight (Cartesian) move keeps: the trajectories' (TOPP-RA's, less its margin).
        self.line_limits = (np.array(timing.velocity_limits_rad_s) * shrink,
                            np.array(timing.acceleration_limits_rad_s2) * shrink)
        self._pdata = robot.pin.createData()

    @property
    def trajectory(self) -> Trajectory | None:
        """The trajectory to execute (the last planned or timed one); setting one starts it from its beginning."""
        return self._trajectory

    @trajectory.setter
    def trajectory(self, traj: Trajectory | None) -> None:
        self._trajectory = traj
        self._straight = (False,)
        self._next_step = self._next_part = 0

    @property
    def running(self) -> bool:
        """Whether the trajectory has been run part of the way (the arm moves on along it)."""
        return self._trajectory is not None and 0 < self._next_part < len(self._trajectory.part_times_s) - 1

    def step_hook(self, hook: control.Hook, moving: bool = True) -> Measured:
        """``hook`` (the monitor, or a phase's hook that calls it) after every step, and the loop's tape of the arm's
        state measured against the limits, the arm told to move or (``moving`` False) to hold still, and against the
        line being followed (:meth:`following`)."""
        limits, monitor = self.limits, self.monitor

        def tape(rows: np.ndarray, t0_s: float) -> None:
            limits.add(rows, t0_s, monitor.phase, moving)
            if self.line_meter is not None:
                self.line_meter.add(rows)

        return Measured(hook, tape)

    @contextlib.contextmanager
    def following(self, start_m: np.ndarray, end_m: np.ndarray) -> Iterator[LineMeter]:
        """Measure how far the tcp strays from the straight line through ``start_m`` and ``end_m`` (3,) (m) in
        every step run inside the block (the meter's ``max_m``)."""
        meter = LineMeter(start_m, end_m)
        self.line_meter = meter
        try:
            yield meter
        finally:
            self.line_meter = None

    def finish_tracking(self) -> None:
        """Write the tracking errors per phase, and over everything, and the limits measured, into the record."""
        self.out.tracking = {phase: tally.result() for phase, tally in self._tallies.items()}
        self.out.tracking_total = self._tally_total.result()
        self.out.limits = self.limits.report()

    @property
    def q(self) -> np.ndarray:
        """Current arm joints (6,) (rad)."""
        return self.d.qpos[self.robot.handles.arm_qpos].copy()

    def tcp_pose(self) -> pin.SE3:
        h = self.robot.handles
        return pin.SE3(self.d.site_xmat[h.tcp_site].reshape(3, 3).copy(), self.d.site_xpos[h.tcp_site].copy())

    def note_ik(self, *results: IKResult) -> None:
        for r in results:
            self.out.ik_position_error_m = max(self.out.ik_position_error_m, r.position_error_m)
            self.out.ik_orientation_error_rad = max(self.out.ik_orientation_error_rad,
                                                    r.orientation_error_rad)

    def count(self, rec: control.TrackingRecord | control.CartesianRecord) -> None:
        """Account for one control loop: its saturated steps and its tracking errors (in the current phase)."""
        self.out.torque_saturation_events += rec.saturation_events
        self._tallies.setdefault(self.monitor.phase, control.TrackingTally()).add(rec)
        self._tally_total.add(rec)

    def hold(self, q: np.ndarray, duration_s: float, comply_along: np.ndarray | None = None,
             hook: control.Hook | None = None) -> control.TrackingRecord:
        """Hold ``q`` (6,) (rad) for ``duration_s`` (s); ``hook`` replaces the monitor (and must call it)."""
        rec = control.hold(self.robot, self.d, q, duration_s, self.ctrl, payload=self.payload,
                           hook=self.step_hook(hook or self.monitor, moving=False), noise=self.noise, loop=self.loop,
                           comply_along=comply_along)
        self.count(rec)
        return rec

    def stop(self, settle_s: float = 0.15, share: float = 1.0) -> None:
        """Bring the arm to rest at ``share`` (0..1] of the trajectories' deceleration limits, then hold it for
        ``settle_s`` (s)."""
        rec = control.stop(self.robot, self.d, share * self.line_limits[1], self.ctrl, payload=self.payload,
                           hook=self.step_hook(self.monitor), noise=self.noise, loop=self.loop, settle_s=settle_s)
        self.count(rec)
        self.trajectory = None

    @property
    def moving(self) -> bool:
        """Whether the arm is told to move now: the running trajectory's reference turns a joint faster than 1 mrad/s
        where the clock has got to along it (a motion that a hook ended before its end)."""
        traj = self._trajectory
        if traj is None:
            return False
        return bool(np.max(np.abs(traj.sample(self.monitor.t - self._traj_t0)[1])) > 1e-3)

    def hold_until(self, q: np.ndarray | None, done: Callable[[], bool], timeout_s: float,
                    min_s: float = 0.0, comply_along: np.ndarray | None = None,
                    hook: control.Hook | None = None) -> bool:
        """Hold ``q`` in steps of ``poll_s`` until ``done()`` (checked from ``min_s`` on) or ``timeout_s`` (s).

        ``q`` None holds the arm where it is at each step (it is not driven anywhere). ``comply_along`` (3,)
        (a world direction): the arm yields along it, stiff in every other direction (:func:`control.hold`);
        each step holds the reference where the last one left it. ``hook`` replaces the monitor (and must call it),
        e.g. to drive the gripper step by step.

        Returns:
            Whether ``done()`` became true in time.
        """
        waited = 0.0
        while True:
            if waited >= min_s and done():
                return True
            if waited >= timeout_s:
                return False
            rec = self.hold(self.q if q is None else q, self.cfg.poll_s, comply_along, hook)
            if comply_along is not None:
                q = rec.q_ref[-1].copy()
            waited += self.cfg.poll_s

    def plan_segment(self, name: str, checker_at: Callable[[float], CollisionChecker], q_goal: np.ndarray) -> None:
        """Plan a path from here to ``q_goal`` and time it (:meth:`plan_through` with no straight moves)."""
        self.plan_through(name, checker_at, q_goal)

    def plan_through(self, name: str, checker_at: Callable[[float], CollisionChecker], q_goal: np.ndarray,
                     before: StraightMove | None = None, after: StraightMove | None = None) -> bool:
        """Plan a path to ``q_goal`` and time it, as one motion with the straight moves ``before`` it (the arm is
        at its start; the path starts where it ends) and ``after`` it (it starts at ``q_goal``), if given.

        Plan with the full clearance margin; accept the timed trajectory with half of it. The planner keeps
        ``planning_margin_m`` from the table and obstacles along its straight segments; the TOPP-RA spline
        deviates from them, so it is checked with half the margin (a path that grazes the full margin everywhere
        cannot be densified into passing it again).

        With straight moves the arm passes from one part to the next without stopping
        (:func:`~pickplace.motion.timing.retime_parts`): the spline of each straight move stays within
        :data:`LINE_TOLERANCE_M` of its line and the tcp within its speed limit along it. Carrying, the whole
        motion is slowed down until the grip holds (:func:`slowdown_for_grip`), the lift and the set-down
        included. Where the straight moves cannot be timed with the path, the path alone is (then the caller
        makes the moves): that needs the arm at the path's start, so with a move ``before`` it raises instead.

        Returns:
            Whether the trajectory includes the straight moves (run it part by part: :meth:`execute`).

        Raises:
            PlanningFailed: no path (the planner's error).
            TimingFailed: the motion cannot be timed (with ``before``: also with the straight moves).
        """
        t0 = time.perf_counter()
        try:
            margin = self.cfg.planning_margin_m
            checker = checker_at(margin)
            if before is None and not checker.is_valid(self.q):  # within the margin of something, not touching
                self._leave(checker_at)  # it: leave towards home
            start = self.q if before is None else np.asarray(before.path[-1])
            res = plan(checker, start, q_goal, self.robot.arm_lower, self.robot.arm_upper, self.planner)
            t1 = time.perf_counter()
            accept = checker_at(margin / 2)
            traj: Trajectory | None = None
            straight: tuple[bool, ...] = (False,)
            if before is not None or after is not None:
                parts = [self._straight_part(before)] if before is not None else []
                parts.append(PathPart(np.asarray(res.path), is_valid=accept.all_valid))
                if after is not None:
                    parts.append(self._straight_part(after))
                try:
                    traj = self._time_parts(name, parts, before is not None, after is not None)
                    straight = tuple(p.straight for p in parts)
                except TimingFailed as exc:
                    if before is not None:
                        raise
                    log.info("%s: the straight move after it cannot be timed with the path (%s): timed alone", name,
                             exc)
            if traj is None:
                traj = retime(np.asarray(res.path), self.timing, accept.all_valid)
            traj, slowdown = self._slowed_for_grip(name, traj)
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        self.segment_checker = accept
        t2 = time.perf_counter()
        self.out.segments.append(SegmentPlan(name, t1 - t0, t2 - t1, len(res.path_raw), len(res.path), res.cost_rad,
                                             traj.duration_s, res.status.value, slowdown))
        self.trajectory = traj
        self._straight = straight
        self._accepted = (traj, accept.world_state())  # the trajectory checked, and the world it was checked in
        if self.recorder is not None:  # the tcp's path; an approach goes to the pregrasp of the grasp it chose
            self.recorder.add_plan(name, self.monitor.t, traj)
            if name == "approach":
                self.recorder.add_grasp_choice(self.monitor.t, self.observer.object_pose(), q_goal)
        return len(straight) > 1

    def _time_parts(self, name: str, parts: list[PathPart], first: bool, last: bool) -> Trajectory:
        """Time ``parts`` as one motion (:func:`~pickplace.motion.timing.retime_parts`); where that fails, once more
        with the straight moves (the ``first`` part, the ``last`` one, if they are) re-solved with waypoints every
        :data:`REFINED_LINE_STEP_M` along their lines: near a singularity (the arm stretched out) the joints turn
        fast along the line and a spline through waypoints 1 cm apart strays off it between them."""
        try:
            return retime_parts(parts, self.timing, self._tcp_rate)
        except TimingFailed as exc:
            refined = list(parts)
            try:
                for i in ([0] if first else []) + ([len(parts) - 1] if last else []):
                    refined[i] = dataclasses.replace(parts[i], waypoints=self._refined_line(parts[i].waypoints))
            except UnreachableTarget as again:
                raise TimingFailed(f"{exc}; the straight moves cannot be refined: {again}") from exc
            log.info("%s: %s; timing it again with the straight moves' waypoints every %.1f mm", name, exc,
                     REFINED_LINE_STEP_M * 1e3)
            return retime_parts(refined, self.timing, self._tcp_rate)

    def _refined_line(self, path: np.ndarray) -> np.ndarray:
        """The straight tcp move through the configurations ``path`` (N, 6) (its start and its end as given)
        re-solved by IK every :data:`REFINED_LINE_STEP_M` (m).

        Raises:
            UnreachableTarget: a waypoint does not solve on the arm's branch.
        """
        end = frame_pose(self.robot.pin, self._pdata, self.robot.pin_q(path[-1]), self.robot.pin_tcp_frame)
        res = solve_line(self.robot, end, path[0], "refined line", finger_m=gripper.finger_travel(self.robot, self.d),
                         step_m=REFINED_LINE_STEP_M)
        assert res.path is not None
        waypoints = np.array(res.path)
        waypoints[-1] = path[-1]  # the same pose, solved once: where the next part starts (or the last ended)
        return waypoints

    def _slowed_for_grip(self, name: str, traj: Trajectory) -> tuple[Trajectory, float]:
        """The trajectory slowed down so that the grip holds the object it carries (unchanged if it carries
        nothing), and the factor."""
        if self.capacity is None or self.payload is None:
            return traj, 1.0
        assert self.T_tcp_object is not None
        com = self.T_tcp_object.act(self.held_com_m)
        accels = com_accelerations(self.robot, traj, com, gripper.finger_travel(self.robot, self.d))
        slowdown = slowdown_for_grip(accels, self.capacity)
        if slowdown < TURN_OVER_SLOWDOWN:  # already slower otherwise: no need to look at the hand's turn
            tilt = hand_turn_rad(self.robot, traj)
            if tilt > TURN_OVER_RAD:
                log.info("%s: the object tilts %.0f deg on the way (the arm changes branch): slowed down %.1f "
                         "times", name, math.degrees(tilt), TURN_OVER_SLOWDOWN)
                slowdown = TURN_OVER_SLOWDOWN
        if slowdown > 1.0:
            traj = traj.slowed(slowdown)
            log.info("%s: slowed down %.2f times so that the grip holds (%.3f s)", name, slowdown, traj.duration_s)
        return traj, slowdown

    def holds_at_speed(self, traj: Trajectory, t_from_s: float) -> bool:
        """Whether the grip holds the carried object along ``traj`` from ``t_from_s`` (s) on as it is timed (with
        the capacity as it is now, e.g. after weighing the object)."""
        if self.capacity is None or self.payload is None:
            return True
        assert self.T_tcp_object is not None
        com = self.T_tcp_object.act(self.held_com_m)
        accels = com_accelerations(self.robot, traj, com, gripper.finger_travel(self.robot, self.d))
        ts = np.arange(0.0, traj.duration_s + 0.005, 0.005)[: len(accels)]
        return slowdown_for_grip(accels[ts >= t_from_s - 1e-9], self.capacity) <= 1.0

    def support_reserve(self, pressed_n: float = 0.0) -> float:
        """The share of the joints' acceleration limits (0..0.5) that the payload compensation takes while the held
        object still rests on the table, here: the controller holds up, and accelerates, an object the table still
        carries (and the pads press onto it with ``pressed_n`` (N), if they do), so the arm accelerates up to
        ``M^-1 J_com^T F`` harder than its reference until the object is airborne (or once it touches down), with
        ``F = m (g + a) + pressed_n`` and ``a`` the straight moves' peak tcp acceleration
        (``ControlConfig.vertical_accel_m_s2``). A lift or a set-down timed at the limits less this share (and the
        trajectories' own margin) stays within them. The default cube (0.15 kg): its weight alone takes 6 % of the
        elbow's limit there, and the elbow went 6.4 % past its reference in the lift's first milliseconds (at
        friction 1.5; 3 % at 1.0). The contacts' transients at lift-off (the table letting go, the pads' patches
        settling) add to it beyond this model: :data:`SUPPORT_MARGIN` more is kept (a 0.24 kg cube at friction 1.4
        went 0.5 % past a reserve of the model's share alone, once in the 100 trials of the default campaign)."""
        if self.payload is None or self.payload.mass_kg <= 0.0:
            return 0.0
        robot = self.robot
        finger = gripper.finger_travel(robot, self.d)
        arm = control.arm_model(robot, self.payload)
        M = control.arm_inertia(arm, self.q, finger)
        J = frame_jacobian(robot.pin, self._pdata, robot.pin_q(self.q, finger), robot.pin_tcp_frame)
        r = self.tcp_pose().rotation @ np.asarray(self.payload.com_tcp_m)
        J_com = J[:3] - pin.skew(r) @ J[3:]  # the centre of mass's velocity: v + w x r
        g = float(-robot.mj.opt.gravity[2])
        weight = np.array([0.0, 0.0, self.payload.mass_kg * (g + self.ctrl.vertical_accel_m_s2) + max(0.0, pressed_n)])
        extra = np.linalg.solve(M, J_com.T @ weight)
        share = float(np.max(np.abs(extra) / np.asarray(self.timing.acceleration_limits_rad_s2)))
        return min(0.5, share + SUPPORT_MARGIN + self.timing.limit_margin)

    def _tcp_rate(self, qs: np.ndarray, dqs: np.ndarray) -> np.ndarray:
        """The tcp's speed per unit path speed ``|J_v(q) q'|`` (M,) (m/rad) at configurations (M, 6) with path
        derivatives (M, 6)."""
        robot, data = self.robot, self._pdata
        return np.array([float(np.linalg.norm(frame_jacobian(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame)[:3]
                                              @ dq)) for q, dq in zip(qs, dqs, strict=True)])

    def tcp_at(self, q: np.ndarray) -> np.ndarray:
        """The tcp's position (3,) (m) at the arm configuration ``q`` (6,)."""
        robot = self.robot
        return frame_pose(robot.pin, self._pdata, robot.pin_q(q), robot.pin_tcp_frame).translation.copy()

    def _straight_part(self, move: StraightMove, checker: CollisionChecker | None = None) -> PathPart:
        """A straight move as a part of a path to time: its spline checked against its line (and, with ``checker``,
        against collisions)."""
        a, b = self.tcp_at(move.path[0]), self.tcp_at(move.path[-1])
        u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)

        def on_line(qs: np.ndarray) -> bool:
            off = np.array([self.tcp_at(q) - a for q in qs])
            side = off - np.outer(off @ u, u)
            return bool(np.all(np.einsum("ij,ij->i", side, side) <= LINE_TOLERANCE_M**2)) and (
                checker is None or checker.all_valid(qs))

        return PathPart(move.path, straight=True, is_valid=on_line, tcp_speed_m_s=move.speed_m_s,
                        reserve=move.reserve)

    def _leave(self, checker_at: Callable[[float], CollisionChecker]) -> None:
        """Move an arm that is within the planner's margin of something, but touches nothing (a recovery stopped it
        there), straight towards ``home`` until it clears the margin with a step to spare, keeping half the
        clearance it has (of the margin's halves down to a sixteenth) on the way; nothing if there is no such
        move (planning from here then fails, naming the geoms)."""
        margin, q = self.cfg.planning_margin_m, self.q
        clearance = next((m for m in (margin / 2, margin / 4, margin / 8, margin / 16) if checker_at(m).is_valid(q)),
                         None)
        if clearance is None:
            return
        full, kept = checker_at(margin), checker_at(clearance / 2)  # room for what lies between the line's checks
        for s in np.arange(ESCAPE_STEP, 1.0 + 1e-9, ESCAPE_STEP):
            q_s = q + min(1.0, s + ESCAPE_STEP) * (self.robot.home_q - q)  # a step past the first clear one
            if not segment_valid(kept, q, q_s, ESCAPE_RESOLUTION_RAD):
                return
            if full.is_valid(q + s * (self.robot.home_q - q)) and full.is_valid(q_s):
                log.info("plan: the arm starts within %.0f mm of something; it moves %.0f %% of the way towards home "
                         "first", margin * 1e3, min(1.0, s + ESCAPE_STEP) * 100)
                self.trajectory = retime(np.vstack([q, q_s]), self.timing, kept.all_valid)
                self.segment_checker = None  # checked above, at the clearance it has
                self.execute(Phase(self.monitor.phase))
                return

    def motion_config(self) -> ControlConfig:
        """The controller config of a straight move: with the object held, its peak acceleration limited to
        what the grip holds (``GripCapacity.max_vertical_accel_m_s2``, at least 0.1 m/s^2)."""
        if self.capacity is None or self.payload is None:
            return self.ctrl
        limit = max(0.1, self.capacity.max_vertical_accel_m_s2)
        if limit >= self.ctrl.vertical_accel_m_s2:
            return self.ctrl
        return dataclasses.replace(self.ctrl, vertical_accel_m_s2=limit)

    def predict(self, t_start: float, until_s: float | None = None,
                from_s: float = 0.0) -> Callable[[mujoco.MjData, float], None]:
        """A check of the rest of the running trajectory (started at ``t_start`` on the clock, from ``from_s`` up to
        ``until_s`` along it, default its end) against the world as the robot sees it now."""
        traj, checker = self.trajectory, self.segment_checker
        assert traj is not None and checker is not None
        end = traj.duration_s if until_s is None else until_s
        # what the check reads of the world: every body's pose but the arm's, the fingers' and a held object's (the
        # checker carries it in the hand), and the mocap bodies
        h = self.robot.handles
        fixed = np.ones(self.robot.mj.nq, dtype=bool)
        fixed[h.arm_qpos] = fixed[h.finger_qpos] = False
        if checker.policy.object_held:
            fixed[h.object_qpos : h.object_qpos + 7] = False
        world_qpos = np.flatnonzero(fixed)

        def key(qpos: np.ndarray, mocap_pos: np.ndarray, mocap_quat: np.ndarray) -> np.ndarray:
            return np.concatenate((qpos[world_qpos], mocap_pos.ravel(), mocap_quat.ravel()))

        # the world when the rest of the trajectory was last found clear: when it was planned, if this is the
        # trajectory the planner's acceptance check passed (every check_step_rad, with this checker: finer than here)
        accepted_traj, accepted_world = self._accepted
        checked: list[np.ndarray] = [key(*accepted_world)] if accepted_traj is traj else []

        def predictor(_: mujoco.MjData, t: float) -> None:
            ts = np.arange(max(t - t_start, from_s), end, 0.01)
            if ts.size == 0:
                return
            world = self.observer.world()
            now = key(world.qpos, world.mocap_pos, world.mocap_quat)
            if checked and float(np.max(np.abs(now - checked[0]))) <= WORLD_STILL:
                return  # nothing moved since the rest of the trajectory (a superset of what is left) was found clear
            checker.set_world(world)
            qs, _, _ = traj.sample_many(ts)
            if not checker.all_valid(qs):
                valid = checker.are_valid(qs)
                k = int(np.argmin(valid))
                raise CollisionPredicted(checker.colliding_pairs(qs[k]), t, float(ts[k] - ts[0]))
            checked[:] = [now]

        return predictor

    def free(self, margin_m: float) -> CollisionChecker:
        """A checker for the empty hand, in the world as the robot believes it is now (the object where it was
        seen, what the camera sees besides the map: :meth:`Observer.world`)."""
        return CollisionChecker(self.robot, CollisionPolicy(margin_m=margin_m), world=self.observer.world())

    def carrying(self, margin_m: float, allow_object_table: bool) -> CollisionChecker:
        policy = CollisionPolicy(margin_m=margin_m, object_held=True, allow_object_table=allow_object_table,
                                 finger_m=gripper.finger_travel(self.robot, self.d))
        return CollisionChecker(self.robot, policy, world=self.observer.world(), T_tcp_object=self.T_tcp_object)

    def execute(self, phase: Phase, until: int | None = None, hook: control.Hook | None = None,
                settle_s: float | None = None) -> control.TrackingRecord:
        """Run the trajectory on from where the last call left it: to the start of its part ``until`` (the arm
        keeps moving; the next call goes on from there), or to its end (None), then hold its end for
        ``settle_s`` (default ``machine.settle_s``).

        While a planned part runs, the rest of it is checked against the world as it is now (:meth:`predict`);
        straight parts are not (their lines were checked when the grasp was chosen, as the straight moves are).
        ``hook`` replaces the monitor (and must call it).
        """
        traj = self.trajectory
        assert traj is not None
        dt = float(self.robot.mj.opt.timestep)
        period = 1 if self.loop is None else self.loop.config.steps(dt)[0]
        k0, part = self._next_step, self._next_part
        last = len(traj.part_times_s) - 1
        stop = last if until is None else until
        if not part < stop <= last:
            raise ValueError(f"part {stop} is not ahead of the trajectory's part {part} (of {last})")
        t_start = self.monitor.t
        if k0 == 0:
            self._traj_t0 = t_start
        if stop == last:
            stop_s, k1 = None, math.ceil(traj.duration_s / dt - 1e-9)
        else:
            n = math.ceil(traj.part_times_s[stop] / dt - 1e-9) - k0
            k1 = k0 + max(period, -(-n // period) * period)
            stop_s = k1 * dt
        planned = [i for i, straight in enumerate(self._straight[part:stop], start=part) if not straight]
        if planned and self.segment_checker is not None and self.cfg.max_retries > 0:
            # the planned parts only: a straight part (a back-off from an object just let go, in a bin by its wall)
            # runs closer to things than the planner's margin, on a line checked when it was solved
            self.monitor.predictor = self.predict(self._traj_t0, traj.part_times_s[stop],
                                                  from_s=traj.part_times_s[planned[0]])
        try:
            rec = control.track(self.robot, self.d, traj, self.ctrl, payload=self.payload,
                                hook=self.step_hook(hook or self.monitor),
                                settle_s=(self.cfg.settle_s if settle_s is None else settle_s) if stop_s is None
                                else 0.0, noise=self.noise, loop=self.loop, start_s=k0 * dt, stop_s=stop_s)
        finally:
            self.monitor.predictor = None
        self._next_step, self._next_part = k1, stop
        self.count(rec)
        if self.recorder is not None:
            self.recorder.add_joint_segment(phase.value, t_start + rec.t, rec.q, rec.q_ref)
        if stop_s is None and rec.final_error_rad > 0.01:  # knocked off its path (a push): let it settle at the end
            settle = self.hold(traj.end, 0.3)
            if settle.final_error_rad > 0.01:
                raise PhaseFailed(phase, f"the arm ended {settle.final_error_rad:.4f} rad from the trajectory's "
                                         "end, 0.3 s after it (limit 0.01 rad)")
        return rec

    @property
    def parts(self) -> int:
        """The number of parts of the trajectory (1 unless timed with straight moves)."""
        return 0 if self.trajectory is None else len(self.trajectory.part_times_s) - 1

    def reference(self) -> np.ndarray:
        """The trajectory's configuration (6,) (rad) where the arm is along it."""
        assert self.trajectory is not None
        return self.trajectory.sample(self.time_in_trajectory())[0]

    def time_in_trajectory(self) -> float:
        """Where the arm is along the running trajectory (s from its start)."""
        return self._next_step * float(self.robot.mj.opt.timestep)

    def offset_end(self, dq: np.ndarray) -> float:
        """Move the end of the running trajectory by ``dq`` (6,) (rad), blended in from where the arm is on it
        (:meth:`Trajectory.with_offset`), as much of it as its joint limits leave room for.

        Returns:
            The fraction of ``dq`` applied (0..1).
        """
        traj = self.trajectory
        assert traj is not None
        t0 = self.time_in_trajectory()
        dt = float(self.robot.mj.opt.timestep)
        fraction = min(1.0, traj.offset_headroom(t0, dq, *self.line_limits, dt))
        if fraction > 0.0:
            step, part, straight = self._next_step, self._next_part, self._straight
            self._trajectory = traj.with_offset(t0, fraction * np.asarray(dq))
            self._next_step, self._next_part, self._straight = step, part, straight
        return fraction

    def vertical(self, phase: Phase, target_z: float, hook: control.Hook | None = None,
                 checker: CollisionChecker | None = None, reserve: float = 0.0,
                 ik: IKConfig | None = None) -> control.TrackingRecord | control.CartesianRecord:
        """Move the tcp straight up or down to ``target_z`` (m), the hand turned as it is (:meth:`linear`)."""
        tcp = self.tcp_pose()
        return self.linear(phase, np.array([*tcp.translation[:2], target_z]), hook, checker, reserve, ik)

    def linear(self, phase: Phase, target: np.ndarray | pin.SE3, hook: control.Hook | None = None,
               checker: CollisionChecker | None = None, reserve: float = 0.0,
               ik: IKConfig | None = None) -> control.TrackingRecord | control.CartesianRecord:
        """Move the tcp along a straight line to ``target``: a position (3,) (m), the hand turned as it is, or a
        pose; as a joint trajectory through the line's IK waypoints (:meth:`line_trajectory`), tracked by the joint
        controller, or, where none can be built, by the Cartesian controller. ``hook`` replaces the monitor (and
        must call it); it may end the move early by raising.

        Args:
            phase: The phase it runs in (for the record and errors).
            target: Where the tcp goes.
            hook: Called after every physics step instead of the monitor.
            checker: What the arm may not touch on the way (the trajectory is checked against it at every
                ``timing.check_step_rad`` of the joints' path); None: nothing checked before it runs (the monitor
                still watches every step).
            reserve: The share of the joints' limits kept for what the controller must hold beyond the reference
                (an object the table still carries: :meth:`support_reserve`).
            ik: IK settings for the waypoints (default :class:`IKConfig`).

        Raises:
            PhaseFailed: the line runs into something ``checker`` forbids (the geoms are named), or the Cartesian
                move stopped short of the target.
        """
        goal = target if isinstance(target, pin.SE3) else pin.SE3(self.tcp_pose().rotation, np.asarray(target, float))
        if self.plan_line(phase, goal, checker, reserve, ik):
            return self.execute(phase, hook=hook)
        return self._cartesian(phase, goal.translation, hook)

    def plan_line(self, phase: Phase, target: pin.SE3, checker: CollisionChecker | None = None, reserve: float = 0.0,
                  ik: IKConfig | None = None) -> bool:
        """Make the straight move from here to ``target`` the trajectory to execute (:meth:`line_trajectory`, slowed
        down until the grip holds what it carries), or say that none can be built (then the caller makes the move
        by the Cartesian controller; logged).

        Returns:
            Whether the trajectory was made.

        Raises:
            PhaseFailed: a waypoint of the line touches something ``checker`` forbids (the geoms are named).
        """
        try:
            traj = self.line_trajectory(target, checker, reserve, ik)
        except UnreachableTarget as exc:
            if "collision" in exc.reason and exc.q is not None and checker is not None:
                pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(exc.q))
                raise PhaseFailed(phase, f"the straight move to ({', '.join(f'{v:.3f}' for v in target.translation)})"
                                         f" m runs into something: {exc.reason}; {pairs}") from exc
            log.info("%s: no joint trajectory along the straight move (%s): the Cartesian controller makes it",
                     phase.value, exc)
            return False
        except TimingFailed as exc:
            log.info("%s: no joint trajectory along the straight move (%s): the Cartesian controller makes it",
                     phase.value, exc)
            return False
        traj, _ = self._slowed_for_grip(phase.value, traj)
        self.trajectory = traj
        self._straight = (True,)
        self.segment_checker = None  # checked against its line and collisions as it was timed
        return True

    def line_trajectory(self, target: pin.SE3, checker: CollisionChecker | None = None, reserve: float = 0.0,
                        ik: IKConfig | None = None) -> Trajectory:
        """The straight tcp move from here to ``target`` as a joint trajectory, at rest at both ends: the line's IK
        waypoints (on the arm's branch, every :data:`STRAIGHT_STEPS_M` in turn until one spacing works) timed
        within the joints' speed and acceleration limits (less ``reserve``) and the tcp's straight-move speed
        (``ControlConfig.vertical_speed_m_s``), its spline within :data:`LINE_TOLERANCE_M` of the line and (with
        ``checker``) touching nothing the checker forbids.

        Returns:
            The trajectory (one that stands still if the tcp is already at ``target``, within 1 µm and 1 µrad).

        Raises:
            UnreachableTarget: the line cannot be followed on the arm's branch at any spacing; the reason says
                "collision" (and ``q`` is where) if a waypoint touches something.
            TimingFailed: the spline leaves the line, or touches something, at every spacing.
        """
        tcp = self.tcp_pose()
        turn = float(np.linalg.norm(pin.log3(tcp.rotation.T @ target.rotation)))
        if float(np.linalg.norm(target.translation - tcp.translation)) < 1e-6 and turn < 1e-6:
            return retime(np.vstack([self.q, self.q]), self.timing)
        finger = gripper.finger_travel(self.robot, self.d)
        valid = None if checker is None else checker.is_valid
        failure: UnreachableTarget | TimingFailed | None = None
        for step in STRAIGHT_STEPS_M:
            try:
                res = solve_line(self.robot, target, self.q, "straight move", ik, valid, finger, step_m=step)
            except UnreachableTarget as exc:
                if "collision" in exc.reason:
                    raise  # closer waypoints do not take it away from what it touches
                failure = exc
                continue
            assert res.path is not None
            part = self._straight_part(StraightMove(res.path, self.ctrl.vertical_speed_m_s, reserve), checker)
            try:
                return retime_parts([part], self.timing, self._tcp_rate)
            except TimingFailed as exc:
                failure = exc
        assert failure is not None
        raise failure

    def _cartesian(self, phase: Phase, target: np.ndarray, hook: control.Hook | None = None) -> control.CartesianRecord:
        """Move the tcp along a straight line to ``target`` (3,) (m) by the Cartesian controller (timed within the
        joints' limits); ``hook`` replaces the monitor."""
        rec = control.move_linear(self.robot, self.d, target, self.motion_config(), payload=self.payload,
                                  hook=self.step_hook(hook or self.monitor), noise=self.noise, loop=self.loop,
                                  joint_limits=self.line_limits)
        self.count(rec)
        if not rec.reached:
            raise PhaseFailed(phase, f"the tcp stopped {rec.final_error_m * 1e3:.2f} mm from its target")
        return rec

    def rise_until_clear(self, phase: Phase, checker_at: Callable[[float], CollisionChecker],
                         ik: IKConfig | None = None) -> None:
        """Rise straight up in ``LIFT_STEP_M`` steps (up to ``MAX_RAISE_M``) until the arm clears everything by
        the planner's margin, as the next planned path needs (the object settled in the grip a little
        differently from the plan, the place ended a little off). Each step is a straight move (:meth:`vertical`)
        that touches nothing ``checker_at(0)`` forbids.

        It does not rise when the arm's links near its base are what is too close (:data:`PROXIMAL_GEOMS`): the
        next plan leaves from there towards ``home`` (:meth:`plan_segment`).

        Raises:
            PhaseFailed: still not clear at the highest step; the geoms are named.
        """
        checker = checker_at(self.cfg.planning_margin_m)
        touching: CollisionChecker | None = None
        risen = 0.0
        while not checker.is_valid(self.q):
            pairs_now = checker.colliding_pairs(self.q)
            if any(a in PROXIMAL_GEOMS or b in PROXIMAL_GEOMS for a, b in pairs_now):
                # the upper arm near the table's edge: a rise of the hand brings it lower still; the planner leaves
                # straight towards home first (plan_segment)
                log.info("%s: the arm is within the planner's margin (%s); not rising", phase.value,
                         ", ".join(f"{a} <-> {b}" for a, b in pairs_now))
                return
            if risen >= MAX_RAISE_M - 1e-9:
                pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(self.q))
                raise PhaseFailed(phase, f"still within {self.cfg.planning_margin_m * 1e3:.0f} mm of something "
                                         f"after rising {risen:.2f} m: {pairs}")
            log.info("%s: within the planner's margin of something; rising %.2f m more", phase.value, LIFT_STEP_M)
            touching = touching or checker_at(0.0)
            self.vertical(phase, float(self.tcp_pose().translation[2]) + LIFT_STEP_M, checker=touching, ik=ik)
            risen += LIFT_STEP_M

    def back_off(self) -> None:
        """Retrace the last 0.3 s of the running trajectory (collisions tolerated), then stand still."""
        traj = self.trajectory
        if traj is None:
            return
        t_in = self.monitor.t - self._traj_t0
        q_back = traj.sample(max(0.0, min(t_in, traj.duration_s) - 0.3))[0]
        self.monitor.tolerate_contacts = True
        try:
            path = np.vstack([self.q, q_back])
            if float(np.max(np.abs(path[1] - path[0]))) > 1e-6:
                rec = control.track(self.robot, self.d, retime(path, self.timing), self.ctrl, payload=self.payload,
                                    hook=self.step_hook(self.monitor), settle_s=0.1, noise=self.noise, loop=self.loop)
                self.count(rec)
        finally:
            self.monitor.tolerate_contacts = False


__all__ = ["LINE_TOLERANCE_M", "REFINED_LINE_STEP_M", "STRAIGHT_STEPS_M", "SUPPORT_MARGIN", "Arm", "StraightMove"]
