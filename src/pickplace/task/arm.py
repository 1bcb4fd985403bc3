"""The arm in the simulation: motions executed under the per-step monitor, and what they cost.

:class:`Arm` owns what moving the arm needs and what it measures: the controllers and their gains, the
planner and the retiming, the monitor that runs after every simulation step (and its clock), the payload
compensation and the grip's capacity while something is held, and the tally of tracking errors and torque
saturation per phase. A skill (:mod:`pickplace.task.skill`) says *what* to do; the arm does it and raises
when a motion fails (:class:`~pickplace.task.phases.PhaseFailed`, or whatever the monitor raises). Several
skills run one after another on the same arm share its clock and its record.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.grasping.grip import TURN_OVER_RAD, GripCapacity, carried_tilt_rad, com_accelerations, slowdown_for_grip
from pickplace.grasping.targets import LIFT_STEP_M, MAX_RAISE_M
from pickplace.motion import control
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.control import ControlConfig, Payload
from pickplace.motion.loop import ControlLoop
from pickplace.motion.planning import PlannerConfig, plan, segment_valid
from pickplace.motion.timing import TimingConfig, Trajectory, retime
from pickplace.robot import gripper
from pickplace.robot.ik import IKResult
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


#: Steps of the straight line to ``home`` tried for a start within the planner's margin (fraction of the line).
ESCAPE_STEP = 0.05
#: Joint-space step at which the way out is checked (rad, max-norm): it starts close to something.
ESCAPE_RESOLUTION_RAD = 0.001
#: The arm's links nearest its base (the UR5e's MJCF collision geoms): a straight rise of the hand does not take
#: them away from what they are near (reaching far, it lowers the upper arm towards the table's edge).
PROXIMAL_GEOMS = frozenset({"base_collision", "shoulder_collision", "upper_arm_joint_collision",
                            "upper_arm_collision", "elbow_collision", "forearm_collision"})


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
        self.trajectory: Trajectory | None = None
        self.segment_checker: CollisionChecker | None = None
        self._traj_t0 = 0.0
        self._tallies: dict[str, control.TrackingTally] = {}
        self._tally_total = control.TrackingTally()

    def finish_tracking(self) -> None:
        """Write the tracking errors per phase, and over everything, into the record."""
        self.out.tracking = {phase: tally.result() for phase, tally in self._tallies.items()}
        self.out.tracking_total = self._tally_total.result()

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

    def hold(self, q: np.ndarray, duration_s: float, comply_along: np.ndarray | None = None) -> control.TrackingRecord:
        rec = control.hold(self.robot, self.d, q, duration_s, self.ctrl, payload=self.payload, hook=self.monitor,
                           noise=self.noise, loop=self.loop, comply_along=comply_along)
        self.count(rec)
        return rec

    def stop(self) -> None:
        """Bring the arm to rest at the trajectories' deceleration limits, then hold it for 0.15 s."""
        rec = control.stop(self.robot, self.d, self.timing.acceleration_limits_rad_s2, self.ctrl,
                           payload=self.payload, hook=self.monitor, noise=self.noise, loop=self.loop, settle_s=0.15)
        self.count(rec)

    def hold_until(self, q: np.ndarray | None, done: Callable[[], bool], timeout_s: float,
                    min_s: float = 0.0, comply_along: np.ndarray | None = None) -> bool:
        """Hold ``q`` in steps of ``poll_s`` until ``done()`` (checked from ``min_s`` on) or ``timeout_s`` (s).

        ``q`` None holds the arm where it is at each step (it is not driven anywhere). ``comply_along`` (3,)
        (a world direction): the arm yields along it, stiff in every other direction (:func:`control.hold`);
        each step holds the reference where the last one left it.

        Returns:
            Whether ``done()`` became true in time.
        """
        waited = 0.0
        while True:
            if waited >= min_s and done():
                return True
            if waited >= timeout_s:
                return False
            rec = self.hold(self.q if q is None else q, self.cfg.poll_s, comply_along)
            if comply_along is not None:
                q = rec.q_ref[-1].copy()
            waited += self.cfg.poll_s

    def plan_segment(self, name: str, checker_at: Callable[[float], CollisionChecker], q_goal: np.ndarray) -> None:
        """Plan with the full clearance margin; accept the timed trajectory with half of it.

        The planner keeps ``planning_margin_m`` from the table and obstacles along its straight segments;
        the TOPP-RA spline deviates from them by up to ~1e-3 rad, so it is checked with half the margin (a
        path that grazes the full margin everywhere cannot be densified into passing it again).
        """
        t0 = time.perf_counter()
        margin = self.cfg.planning_margin_m
        checker = checker_at(margin)
        if not checker.is_valid(self.q):  # within the margin of something, not touching it: leave towards home
            self._leave(checker_at)
        res = plan(checker, self.q, q_goal, self.robot.arm_lower, self.robot.arm_upper, self.planner)
        t1 = time.perf_counter()
        accept = checker_at(margin / 2)
        traj = retime(np.asarray(res.path), self.timing, accept.all_valid)
        slowdown = 1.0
        if self.capacity is not None and self.payload is not None:  # carrying: slow down to what the grip holds
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
                log.info("%s: slowed down %.2f times so that the grip holds (%.3f s)", name, slowdown,
                         traj.duration_s)
        self.segment_checker = accept
        t2 = time.perf_counter()
        self.out.wall_plan_time_s += t2 - t0
        self.out.segments.append(SegmentPlan(name, t1 - t0, t2 - t1, len(res.path_raw), len(res.path), res.cost_rad,
                                             traj.duration_s, res.status.value, slowdown))
        self.trajectory = traj
        if self.recorder is not None:  # the tcp's path; an approach goes to the pregrasp of the grasp it chose
            self.recorder.add_plan(name, self.monitor.t, traj)
            if name == "approach":
                self.recorder.add_grasp_choice(self.monitor.t, self.observer.object_pose(), q_goal)

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

    def predict(self, t_start: float) -> Callable[[mujoco.MjData, float], None]:
        """A check of the rest of the running trajectory against the world as the robot sees it now."""
        traj, checker = self.trajectory, self.segment_checker
        assert traj is not None and checker is not None

        def predictor(_: mujoco.MjData, t: float) -> None:
            ts = np.arange(t - t_start, traj.duration_s, 0.01)
            if ts.size == 0:
                return
            checker.set_world(self.observer.world())
            qs, _, _ = traj.sample_many(ts)
            if not checker.all_valid(qs):
                valid = checker.are_valid(qs)
                k = int(np.argmin(valid))
                raise CollisionPredicted(checker.colliding_pairs(qs[k]), t, float(ts[k] - ts[0]))

        return predictor

    def free(self, margin_m: float) -> CollisionChecker:
        """A checker for the empty hand, in the world as the robot believes it is now (the object where it was
        seen, what the camera sees besides the map: :meth:`Observer.world`)."""
        return CollisionChecker(self.robot, CollisionPolicy(margin_m=margin_m), world=self.observer.world())

    def carrying(self, margin_m: float, allow_object_table: bool) -> CollisionChecker:
        policy = CollisionPolicy(margin_m=margin_m, object_held=True, allow_object_table=allow_object_table,
                                 finger_m=gripper.finger_travel(self.robot, self.d))
        return CollisionChecker(self.robot, policy, world=self.observer.world(), T_tcp_object=self.T_tcp_object)

    def execute(self, phase: Phase) -> None:
        assert self.trajectory is not None
        t_start = self._traj_t0 = self.monitor.t
        if self.segment_checker is not None and self.cfg.max_retries > 0:
            self.monitor.predictor = self.predict(t_start)
        try:
            rec = control.track(self.robot, self.d, self.trajectory, self.ctrl, payload=self.payload,
                                hook=self.monitor, settle_s=self.cfg.settle_s, noise=self.noise, loop=self.loop)
        finally:
            self.monitor.predictor = None
        self.count(rec)
        if self.recorder is not None:
            self.recorder.add_joint_segment(phase.value, t_start + rec.t, rec.q, rec.q_ref)
        if rec.final_error_rad > 0.01:  # knocked off its path (a push): give it time to settle at the end
            settle = self.hold(self.trajectory.waypoints[-1], 0.3)
            if settle.final_error_rad > 0.01:
                raise PhaseFailed(phase, f"the arm ended {settle.final_error_rad:.4f} rad from the trajectory's "
                                         "end, 0.3 s after it (limit 0.01 rad)")

    def vertical(self, phase: Phase, target_z: float, hook: control.Hook | None = None) -> control.CartesianRecord:
        """Move the tcp straight up or down to ``target_z`` (m); ``hook`` replaces the monitor (and must call it)."""
        target = self.tcp_pose().translation.copy()
        target[2] = target_z
        return self.linear(phase, target, hook)

    def linear(self, phase: Phase, target: np.ndarray, hook: control.Hook | None = None) -> control.CartesianRecord:
        """Move the tcp along a straight line to ``target`` (3,) (m); ``hook`` replaces the monitor."""
        rec = control.move_linear(self.robot, self.d, target, self.motion_config(), payload=self.payload,
                                  hook=hook or self.monitor, noise=self.noise, loop=self.loop)
        self.count(rec)
        if not rec.reached:
            raise PhaseFailed(phase, f"the tcp stopped {rec.final_error_m * 1e3:.2f} mm from its target")
        return rec

    def rise_until_clear(self, phase: Phase, checker_at: Callable[[float], CollisionChecker]) -> None:
        """Rise straight up in ``LIFT_STEP_M`` steps (up to ``MAX_RAISE_M``) until the arm clears everything by
        the planner's margin, as the next planned path needs (the object settled in the grip a little
        differently from the plan, the place ended a little off).

        It does not rise when the arm's links near its base are what is too close (:data:`PROXIMAL_GEOMS`): the
        next plan leaves from there towards ``home`` (:meth:`plan_segment`).

        Raises:
            PhaseFailed: still not clear at the highest step; the geoms are named.
        """
        checker = checker_at(self.cfg.planning_margin_m)
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
            self.vertical(phase, float(self.tcp_pose().translation[2]) + LIFT_STEP_M)
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
                                    hook=self.monitor, settle_s=0.1, noise=self.noise, loop=self.loop)
                self.count(rec)
        finally:
            self.monitor.tolerate_contacts = False


__all__ = ["Arm"]
