"""One pick and place as a unit: the phases that pick an object and set it down at its goal, each with its own
success check, and the recoveries between them.

``IDLE → PLAN_APPROACH → EXEC_APPROACH → DESCEND → CLOSE → LIFT → PLAN_TRANSPORT → EXEC_TRANSPORT →
DESCEND_PLACE → RELEASE → RETRACT → DONE`` (or ``FAILED``, with the phase and a specific reason).

Manipulation fails quietly — a slipped grasp raises nothing by itself — so every phase checks its own
outcome, and a monitor runs after *every* simulation step of every phase
(:class:`~pickplace.task.monitor.StepMonitor`):

* unexpected contacts: the arm or the gripper touching the table, the floor, an obstacle or itself; the
  object carried into the table, a wall or the floor; the gripper touching the object while it approaches it.
  The failure names the geoms.
* slip: from the end of CLOSE until RELEASE, the grip is compared with the one measured when it settled
  (the object's position in the tcp frame in the ideal profile; the fingers' travel and the wrist's load in
  the realistic one, :mod:`pickplace.task.observe`); more than ``MachineConfig.slip_tolerance_m``, or a lost
  load, fails the phase.

Where the profile allows it (``ControlConfig.blend_*``, all on in the ideal profile), the arm does not stop
between phases: the approach runs into the descent (one trajectory through the pregrasp, planned in
PLAN_APPROACH), the lift into the transport and the transport into the set-down (one trajectory, planned at the
start of LIFT from the grip as it settled), and the back-off after the release into the way home. Each phase
still runs its own part of the motion and checks its outcome where its part ends (the arm moving on): LIFT
that the object came up with the hand and weighs what it should, DESCEND_PLACE re-aims the rest of the set-down
from the object's pose in the hand as it passes the preplace. Where such a motion cannot be planned or timed,
or after any recovery, the phases move one after another as before.

The skill decides; its :class:`~pickplace.task.arm.Arm` moves (and keeps the clock and the record), so that a
task with several objects can run one skill per object on the same arm. The object and its goal are the
scene's (``robot.scene.object``, ``goal_xy_m``, ``goal_yaw_rad``): grasps and collision checks are computed
for the scene's object. What the skill measures goes into the arm's
:class:`~pickplace.task.phases.MachineOutcome`.
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

from pickplace.errors import (
    CannotHold,
    ConfigError,
    GraspFailed,
    PickPlaceError,
    PlanningFailed,
    TimingFailed,
    UnreachableTarget,
)
from pickplace.grasping.closure import analyze_grasp
from pickplace.grasping.configurations import GraspConfigurations, candidate_grasps, solve_grasp_configurations
from pickplace.grasping.grip import grip_capacity
from pickplace.grasping.synthesis import GraspCandidate
from pickplace.grasping.targets import CLEARANCE_M, PLACE_DROP_M, backed_off, object_yaw, place_targets, yaw_error
from pickplace.motion import control
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.control import Payload
from pickplace.motion.timing import retime
from pickplace.perception.pose import ObjectNotSeen
from pickplace.robot import gripper
from pickplace.robot.ik import IKConfig, IKResult, solve_ik, solve_line
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import object_geom_names
from pickplace.task.arm import Arm, StraightMove
from pickplace.task.monitor import UnexpectedContact
from pickplace.task.observe import SimulatorObserver
from pickplace.task.phases import MachineOutcome, Phase, PhaseFailed
from pickplace.task.recovery import FirstMove, RetryBudget, recovery_for
from pickplace.world.mass import mass_properties

log = logging.getLogger(__name__)


#: How far the hand backs off from a released object it hides from the camera before it looks again (m): near
#: enough still for the camera to measure the object against the hand.
LOOK_BACK_OFF_M = 0.04

#: The farthest point of the open fingers from the tcp's approach axis (m): a re-aim that turns the hand by an
#: angle moves them by up to this times the angle.
FINGER_REACH_M = 0.06

#: A lift that runs on into the transport corrects the payload compensation (the object weighs more than 20 % off
#: what was believed) where the tcp passes the lift height this far off its reference (m): the 1 mm of the straight
#: moves. The joint loops hold a heavier object lower: 1.9 mm for the default cube 1.5 times heavier, 13 mm for 5
#: times; a weighing made wrong by an object rocking in soft pads (0.58 kg for 0.15) left it 0.34 mm off.
PAYLOAD_ERROR_M = 1e-3

#: The share of the joint limits a set-down that the transport runs into is not timed with: the room its re-aim,
#: made as the tcp passes the preplace, blends in with (a minimum-jerk offset over the set-down's 0.3-0.4 s). 5 % of
#: the elbow's 8 rad/s^2 moves the end by some 5 mrad there, about 2.5 mm at the tcp; the object settles in the
#: hand by about 1 mm in transit.
RE_AIM_RESERVE = 0.05

#: A back-off that runs into the way home as one motion is a spline through its waypoints, within
#: ``arm.LINE_TOLERANCE_M`` (0.5 mm) of the line and tracked within a few hundredths of a millimetre more; the open
#: hand must keep this cushion (m) along the whole line from everything but the object it let go of (the table's
#: top aside, which it rises from), or it backs off by a Cartesian move on the line itself first. A cube let go
#: between the wall of a bin and another object leaves a finger a fraction of a millimetre from the wall.
RETRACT_CUSHION_M = 2e-3


#: A set-down that the surface ends before its trajectory does (the object sits lower in the hand than when it was
#: aimed) brings the still moving arm to rest at this share of the trajectories' deceleration limits, not at once by
#: the hold that follows: holding the position it had reached jolted the arm to 3.6 times wrist 1's acceleration
#: limit, and decelerating at the limits took the elbow 14 % past its own (the surface pushing back on the object).
SET_DOWN_STOP_SHARE = 0.5


#: A recovery that lowers an object whose grip failed onto what is below it aims the tcp this much (m) lower than
#: where the object would touch the table as the robot believes it sits in the hand: it has slipped since, mostly
#: downwards, and the descent ends where the surface takes the object's weight.
RECOVERY_SET_DOWN_OVERSHOOT_M = 5e-3


class _SetDown(Exception):
    """The table carries the object being set down (a guarded set-down ends here)."""


class PickPlaceSkill:
    """Picks the scene's object where it rests and places it at its goal, phase by phase, on an arm.

    Args:
        arm: The arm to move (its simulation, controllers, monitor and record).
        ik: IK settings.
        turn_over: Whether a grasp that reaches the place only by turning the hand over on the way (another wrist
            branch) may be taken when no grasp keeps the wrist's branch (a task with other spots to try says no:
            the pick then fails in IDLE, before the arm moves).

    Attributes:
        out: The record (the arm's).
        configs: The targets of the grasp in use, solved to joint configurations (after IDLE).
    """

    def __init__(self, arm: Arm, ik: IKConfig, turn_over: bool = True) -> None:
        self.arm, self.turn_over = arm, turn_over
        self.robot, self.d, self.cfg, self.ik = arm.robot, arm.d, arm.cfg, ik
        self.monitor, self.out = arm.monitor, arm.out
        self.observer = arm.observer  # everything the skill knows about the object comes through it
        self._truth = SimulatorObserver(arm.robot, arm.d)  # only to measure the episode (results), never to act
        self.faults, self.injector, self.timing = arm.faults, arm.injector, arm.timing
        self.budget = RetryBudget(arm.cfg.max_retries)
        self.configs: GraspConfigurations | None = None
        self._reaimed = False  # the approach was planned again after the look from the hand
        self._backed_off_m = 0.0  # how far the hand backed off after the release to look at the object (m)
        self._release_t = math.nan
        self._dropped: list[GraspCandidate] = []  # grasps given up on (no path to them), not tried again
        self._carried_on = False  # a slip in transit was answered by carrying on with the grip as it had become
        self._object_names = frozenset(object_geom_names(arm.robot.scene.object))
        self.ctrl = arm.ctrl
        self._through: set[Phase] = set()  # the phases that run on along the running trajectory (not stopping)
        # a robot that looks at the object (from the hand at the pregrasp, in the hand above the goal) stops there
        # whatever its motion settings say; one that reads the simulation's truth (the ideal profile) need not
        self._looks = not isinstance(arm.observer, SimulatorObserver)

    def _object_pose(self) -> pin.SE3:
        """Where the robot believes the object is (its observer's estimate)."""
        return self.observer.object_pose()

    def _observe(self, near: pin.SE3 | None = None) -> pin.SE3:
        """Look at the resting object (the observer's estimate), and measure the estimate against the truth
        for the record (the robot never sees that comparison)."""
        obj = self.observer.observe(near)
        self._reaimed = False
        self._note_estimate("resting")
        return obj

    def _note_estimate(self, what: str) -> None:
        """Record how far the observer's belief is from the truth (position (m) and yaw (rad))."""
        believed, truth = self.observer.object_pose(), self._truth.object_pose()
        period = self.robot.scene.object.yaw_period_rad
        self.out.estimates.append((self.monitor.phase, what,
                                   float(np.linalg.norm(believed.translation - truth.translation)),
                                   yaw_error(believed.rotation, truth.rotation, period)))

    def _idle(self) -> Phase:
        """Observe the object, solve every target (before the arm moves: unreachable goals fail here)."""
        t0 = time.perf_counter()
        mujoco.mj_forward(self.robot.mj, self.d)
        obj = self._observe()
        configs = self._solve_grasps(obj)
        self.robot.scene.check_goal_on_table()
        self.monitor.watching = True
        self._adopt(configs)
        self.arm.note_ik(*configs.results())
        self.out.wall_plan_time_s += time.perf_counter() - t0
        return Phase.PLAN_APPROACH

    def _solve_grasps(self, T_world_object: pin.SE3) -> GraspConfigurations:
        """The first grasp of the object where it rests whose targets all solve and whose pads hold it (not one
        given up on before)."""
        grasps = [g for g in candidate_grasps(self.robot, T_world_object) if not any(g is d for d in self._dropped)]
        return solve_grasp_configurations(self.robot, self.ik, T_world_object, self.observer.world(),
                                          self.cfg.planning_margin_m,
                                          grasps=grasps, retreat_m=self.cfg.retract_height_m,
                                          safety_factor=self.cfg.grip_safety_factor, turn_over=self.turn_over)

    def _adopt(self, configs: GraspConfigurations) -> None:
        """Take these targets, after checking that their grip can hold the object (:class:`CannotHold` if not)."""
        targets, obj = configs.targets, self.robot.scene.object
        capacity = grip_capacity(self.robot, obj, targets.T_tcp_object, targets.width_m, self.cfg.grip_safety_factor,
                                 up_tcp=targets.grasp.rotation[2])
        capacity.require_holdable(obj.name)
        self.configs, self.arm.capacity = configs, capacity
        grasp = configs.chosen
        self.out.grasp_approach, self.out.grasp_tilt_rad = grasp.approach.value, grasp.tilt_rad
        self.out.grasp_width_m, self.out.grasps_tried = grasp.width_m, configs.grasps_tried
        log.info("grasp: %s (tilted %.0f deg), %.1f mm wide, margin %.3f; %d tried", grasp.approach.value,
                 math.degrees(grasp.tilt_rad), grasp.width_m * 1e3, grasp.margin, configs.grasps_tried)

    def _plan_approach(self) -> Phase:
        """Plan the approach to the pregrasp; with ``blend_approach``, timed with the straight descent after it
        (the grasp's IK waypoints, solved in IDLE) as one motion."""
        assert self.configs is not None
        self._through = set()
        descent = self.configs.grasp.path
        after = StraightMove(descent, self.ctrl.vertical_speed_m_s) if (
            self.ctrl.blend_approach and not self._looks and descent is not None and len(descent) >= 2) else None
        if self.arm.plan_through("approach", self.arm.free, self.configs.pregrasp.q, after=after):
            self._through = {Phase.DESCEND}
        return Phase.EXEC_APPROACH

    def _exec_approach(self) -> Phase:
        """Run the approach to the pregrasp (on into the descent, without stopping, if they were planned as one)."""
        self.arm.execute(Phase.EXEC_APPROACH, until=1 if Phase.DESCEND in self._through else None)
        return Phase.DESCEND

    def _descend(self) -> Phase:
        """The straight approach from the pregrasp to the grasp (a descent for a top-down grasp), re-aimed at
        the object as seen against the hand above it (:meth:`_reaim`); or the rest of the approach planned with
        it, from the pregrasp on. The gripper closes as soon as the tcp is at the grasp."""
        assert self.configs is not None
        targets = self.configs.targets
        if Phase.DESCEND in self._through:
            self._through.discard(Phase.DESCEND)
            with self.arm.following(targets.pregrasp.translation, targets.grasp.translation) as line:
                self.arm.execute(Phase.DESCEND, settle_s=0.0)  # the pads in place: close at once
        else:
            aim = targets.grasp
            if self.observer.look_from_hand():
                self._note_estimate("from the hand")
                aim = self._reaim()
                if aim is None:
                    return Phase.PLAN_APPROACH
            with self.arm.following(self.arm.tcp_pose().translation, aim.translation) as line:
                self.arm.linear(Phase.DESCEND, aim, checker=self.arm.free(0.0), ik=self.ik)
        self.out.approach_line_deviation_max_m = float(np.fmax(self.out.approach_line_deviation_max_m, line.max_m))
        want = self._grasp_on(self._object_pose()).translation  # where the grasp is, the object as it is
        off = float(np.linalg.norm(self.arm.tcp_pose().translation - want))
        if off > 0.005:
            raise PhaseFailed(Phase.DESCEND, f"the tcp is {off * 1e3:.1f} mm from its grasp on the "
                                             f"{self.robot.scene.object.name} (limit 5 mm)")
        return Phase.CLOSE

    def _grasp_on(self, T_world_object: pin.SE3) -> pin.SE3:
        """The planned grasp on the object at this pose, its yaw taken as the symmetric equivalent nearest the
        one the grasp was planned for (a fit may return any of them)."""
        assert self.configs is not None
        targets = self.configs.targets
        planned = targets.grasp * targets.T_object_tcp.inverse()  # the object the grasp was planned for
        turn = yaw_error(T_world_object.rotation, planned.rotation, self.robot.scene.object.yaw_period_rad)
        return pin.SE3(rot_z(turn) @ planned.rotation, T_world_object.translation.copy()) * targets.T_object_tcp

    def _reaim(self) -> pin.SE3 | None:
        """The grasp on the object as now believed (its yaw the symmetric equivalent nearest the one planned
        for), the hand turned and moved to its pregrasp by a direct joint move. A re-aim that would move the
        fingers farther than the planner's margin (the straight approach was checked with that clearance: the
        shift plus the turn times :data:`FINGER_REACH_M`) solves the grasps again instead, and returns None: plan
        a new approach. Once per observation: a second look that still disagrees that much leaves the planned
        grasp as it is (a direct move that far would be unchecked)."""
        assert self.configs is not None
        targets, robot = self.configs.targets, self.robot
        seen = self._object_pose()
        grasp = self._grasp_on(seen)
        turn = float(np.linalg.norm(pin.log3(targets.grasp.rotation.T @ grasp.rotation)))
        shift = float(np.linalg.norm(grasp.translation - targets.grasp.translation))
        reach = shift + turn * FINGER_REACH_M
        if reach > self.cfg.planning_margin_m and self._reaimed:
            log.warning("DESCEND: the look from the hand puts the %s's grasp %.1f mm and %.1f deg from the plan "
                        "after planning again: descending as planned", robot.scene.object.name, shift * 1e3,
                        math.degrees(turn))
            return targets.grasp
        t0 = time.perf_counter()
        try:
            if reach > self.cfg.planning_margin_m:
                self._reaimed = True
                log.info("DESCEND: the %s's grasp is %.1f mm and %.1f deg from the planned one: planning again",
                         robot.scene.object.name, shift * 1e3, math.degrees(turn))
                self._adopt(self._solve_grasps(seen))
                self.arm.note_ik(*self.configs.results())
                return None
            pre = solve_ik(robot, backed_off(grasp, CLEARANCE_M), self.arm.q, "pregrasp", self.ik,
                           finger_m=gripper.finger_travel(robot, self.d))
            self.arm.note_ik(pre)
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        log.debug("DESCEND: re-aimed by %.2f mm and %.2f deg", shift * 1e3, math.degrees(turn))
        if float(np.max(np.abs(pre.q - self.arm.q))) > 1e-5:
            self.arm.trajectory = retime(np.vstack([self.arm.q, pre.q]), self.timing)
            self.arm.segment_checker = None  # within the planner's margin of the checked approach
            self.arm.execute(Phase.DESCEND)
        return grasp

    def _close(self) -> Phase:
        robot, d, cfg = self.robot, self.d, self.cfg
        self.monitor.watching = False  # the pads move it now
        self.monitor.allow_hand_object = True
        self.observer.closing()
        assert self.configs is not None
        # fast, then slowly onto the object, then the full squeeze, step by step
        drive = gripper.GripDrive(robot, d, True, self.configs.targets.width_m, max(self.configs.chosen.touch_m))
        hook = self._driving(drive)

        def gripping() -> bool:
            return (drive.done and gripper.is_settled(robot, d, cfg.finger_settle_speed_m_s)
                    and bool(np.all(self.observer.pad_forces() >= cfg.min_pad_force_n)))

        comply = self.arm.tcp_pose().rotation[:, 1] if self.arm.ctrl.comply_while_closing else None  # pads' axis
        settled = self.arm.hold_until(self.arm.q, gripping, cfg.close_timeout_s, min_s=5 * cfg.poll_s,
                                      comply_along=comply, hook=hook)
        forces = self.observer.pad_forces()
        gripper.command(robot, d, True)  # (the drive's end: fully closed)
        if not settled:
            travel = gripper.finger_travel(robot, d)
            raise GraspFailed(f"the pads did not settle on the {robot.scene.object.name} within "
                              f"{cfg.close_timeout_s:g} s: "
                              f"pad forces {forces[0]:.1f} / {forces[1]:.1f} N (need {cfg.min_pad_force_n:g} "
                              f"N each), finger travel {travel * 1e3:.1f} mm")
        assert self.configs is not None
        self.observer.grasped(self.configs.targets.T_tcp_object)
        contacts = self.observer.pad_contacts()
        obj = self._object_pose()
        fc = analyze_grasp(contacts, obj.act(mass_properties(robot.scene.object).com_m),
                           float(np.max(robot.scene.object.geometry().extent_m)) / 2)
        self.out.grip_force_n = float(forces.sum())
        self.out.force_closure = fc.force_closure
        self.out.grasp_margin = fc.margin
        if not fc.force_closure:
            raise GraspFailed(f"the grip is not force closure ({len(contacts)} contacts, margin {fc.margin:.3g})")
        self.monitor.start_holding(d)
        tcp = self.arm.tcp_pose()
        self.arm.T_tcp_object = tcp.actInv(obj)
        self.arm.payload = Payload.held(robot.scene.object, self.arm.T_tcp_object)
        self.arm.held_com_m = mass_properties(robot.scene.object).com_m
        return Phase.LIFT

    def _lift(self) -> Phase:
        """Lift straight up, weighing the object on the way (the pads' force over its acceleration).

        With ``blend_lift``, the lift, the transport and (``blend_set_down``) the set-down are planned first as one
        motion (:meth:`_plan_carry`) and the lift is its first part: the checks below are made at the lift
        height, the arm moving on.

        Otherwise the lift is a straight move of its own: a joint trajectory through its IK waypoints
        (:meth:`Arm.plan_line`), or, where none can be built, a Cartesian move.

        If the object is heavier (or lighter) than believed by more than 20 %, the payload compensation is
        corrected with the measured mass (a recovery): a Cartesian lift that could not hold its height is
        repeated once; a lift timed as a joint trajectory that ended more than ``PAYLOAD_ERROR_M`` off its
        reference goes on from where it ended; a lift that runs on into the transport goes on with the corrected
        payload if the grip still holds the rest of the motion at its speed, and otherwise stops there and plans the
        transport anew.
        """
        assert self.configs is not None and self.arm.payload is not None
        through = blended = self.ctrl.blend_lift and self._plan_carry()
        jointed = False  # a lift of its own, as a joint trajectory
        z_object0 = float(self._object_pose().translation[2])
        z_tcp0 = float(self.arm.tcp_pose().translation[2])
        self.monitor.allow_object_table = True  # until it leaves the table
        forces: list[float] = []
        f_z: list[float] = []
        g_plus_a: list[float] = []
        monitor, observer = self.monitor, self.observer
        g = float(-self.robot.mj.opt.gravity[2])
        mass_kg = self.arm.payload.mass_kg

        def hook(d: mujoco.MjData) -> None:
            monitor(d)
            if monitor.allow_object_table and observer.airborne(z_object0, mass_kg):
                monitor.allow_object_table = False  # airborne: touching the table again is a failure
            if not monitor.allow_object_table:  # airborne: only the pads (and gravity) act on the object
                normal, load, g_plus_a_now = observer.load_sample()
                forces.append(normal)
                f_z.append(load)
                g_plus_a.append(g_plus_a_now)

        def measured_mass() -> float:
            return float(np.sum(f_z) / np.sum(g_plus_a)) if f_z else math.nan

        if through:
            try:
                self.arm.execute(Phase.LIFT, until=1, hook=hook)
            finally:  # a slip aborts the move: still report what the pads felt
                mass = measured_mass()
                self.out.lift_load_n = mass * g if math.isfinite(mass) else 0.0
            height_error = float(self.arm.tcp_pose().translation[2]) - float(self.arm.tcp_at(self.arm.reference())[2])
            reached = True
        else:
            target_z = float(self.configs.targets.lift.translation[2])
            tcp = self.arm.tcp_pose()
            top = pin.SE3(tcp.rotation, np.array([*tcp.translation[:2], target_z]))
            # a joint trajectory through the lift's IK waypoints, the table holding the object (and what the pads
            # press it down with) at its start; the Cartesian controller only where none can be built
            jointed = self.arm.plan_line(Phase.LIFT, top, self.arm.carrying(0.0, True),
                                         self.arm.support_reserve(-self.observer.load_sample()[1]), self.ik)

            def lift() -> control.CartesianRecord:
                rec = control.move_vertical(self.robot, self.d, target_z, self.arm.motion_config(),
                                            payload=self.arm.payload, hook=self.arm.step_hook(hook),
                                            noise=self.arm.noise, loop=self.arm.loop, raise_on_timeout=False,
                                            joint_limits=self.arm.line_limits)
                self.arm.count(rec)
                return rec

            try:
                if jointed:
                    self.arm.execute(Phase.LIFT, hook=hook)
                else:
                    rec = lift()
            finally:  # a slip aborts the move: still report what the pads felt
                mass = measured_mass()
                self.out.lift_load_n = mass * g if math.isfinite(mass) else 0.0
            if jointed:  # the joint loop holds its end with a static error if the payload is off
                assert self.arm.trajectory is not None
                height_error = float(self.arm.tcp_pose().translation[2]) - \
                    float(self.arm.tcp_at(self.arm.trajectory.end)[2])
                reached = True
            else:
                height_error, reached = rec.final_height_error_m, rec.reached
        # the payload compensation is corrected where the object weighs 20 % off and the arm could not follow its
        # reference for it: a Cartesian lift stopped short; a joint trajectory was more than PAYLOAD_ERROR_M off
        tracked = through or jointed
        off = math.isfinite(mass) and abs(mass / self.arm.payload.mass_kg - 1.0) > 0.2 and (
            not reached or (tracked and abs(height_error) > PAYLOAD_ERROR_M))
        if off and self.budget.used < self.budget.max_retries:
            self.budget.used += 1
            note = (f"LIFT: the {self.robot.scene.object.name} weighs {mass:.3f} kg, not "
                    f"{self.arm.payload.mass_kg:.3f} kg (the tcp " + (
                        f"stopped {abs(height_error) * 1e3:.2f} mm short of the lift height" if not tracked else
                        f"was {abs(height_error) * 1e3:.2f} mm off its reference at the lift height") +
                    ") -> payload compensation corrected")
            self.out.recoveries.append(note)
            log.info("recovery: %s", note)
            self.arm.payload = dataclasses.replace(self.arm.payload, mass_kg=mass)
            self.arm.capacity = dataclasses.replace(self.arm.capacity, mass_kg=mass) if self.arm.capacity else None
            if not tracked:
                rec = lift()
                mass = measured_mass()
                height_error, reached = rec.final_height_error_m, rec.reached
            off = False
            if through and not self.arm.holds_at_speed(self.arm.trajectory, self.arm.time_in_trajectory()):
                log.info("LIFT: the grip does not hold the %.3f kg %s at the planned speed: stopping to plan the "
                         "transport again", mass, self.robot.scene.object.name)
                self.arm.stop()
                through = False
                self._through = set()
        self.out.lift_grip_force_n = float(np.mean(forces)) if forces else 0.0
        self.out.lift_load_n = mass * g if math.isfinite(mass) else 0.0
        name = self.robot.scene.object.name
        if not reached:
            raise PhaseFailed(Phase.LIFT, f"the tcp stopped {abs(height_error) * 1e3:.2f} mm from the lift height "
                                          f"(the {name} weighed {mass:.3f} kg)")
        if tracked and off:  # the payload compensation is that far off for the rest of the motion
            side = "below" if height_error < 0.0 else "above"
            raise PhaseFailed(Phase.LIFT, f"the tcp was {abs(height_error) * 1e3:.2f} mm {side} its reference at the "
                                          f"lift height (the {name} weighed {mass:.3f} kg, not the "
                                          f"{self.arm.payload.mass_kg:.3f} kg its payload compensation holds)")
        came_up = not self.monitor.allow_object_table
        self.monitor.allow_object_table = False
        rise = float(self._object_pose().translation[2]) - z_object0
        lifted = float(self.arm.tcp_pose().translation[2]) - z_tcp0 if blended or jointed else \
            target_z - float(self.configs.targets.grasp.translation[2])
        if abs(rise - lifted) > self.cfg.slip_tolerance_m:
            raise GraspFailed(f"the {name} rose {rise * 1e3:.1f} mm while the tcp rose {lifted * 1e3:.1f} mm")
        if not came_up:  # (a sensor that sees the object itself has said so above)
            raise GraspFailed(f"the {name} did not come up with the hand: it weighed "
                              f"{mass:.3f} kg of its {self.arm.payload.mass_kg:.3f} kg")
        weighed = self.observer.payload_mass_kg(self.arm.payload.mass_kg, mass)  # a robot's payload: as weighed
        if weighed != self.arm.payload.mass_kg:
            log.debug("LIFT: payload %.3f kg as weighed (model %.3f kg)", weighed, self.arm.payload.mass_kg)
            self.arm.payload = dataclasses.replace(self.arm.payload, mass_kg=weighed)
        self.observer.expect_load(self.arm.payload.mass_kg)  # airborne: the hand carries its weight from now on
        self.arm.T_tcp_object = self.arm.tcp_pose().actInv(self._object_pose())  # as it sits in the hand
        if not through:
            self.arm.rise_until_clear(Phase.LIFT, lambda margin: self.arm.carrying(margin, False), self.ik)
        return Phase.PLAN_TRANSPORT

    def _plan_carry(self) -> bool:
        """Plan the lift, the transport and (``blend_set_down``) the set-down as one motion, before the lift, from
        the grip as it settled: the lift straight up from where the tcp is (its IK waypoints), a path from the lift
        height to the preplace, the set-down to the place that puts the object, as it sits in the hand, at the
        goal. Returns whether it did; if not (the lift height is not clear of everything by the planner's margin
        with the object as it sits, or no path, no timing, no grip at speed), nothing was planned or moved and the
        phases lift, plan the transport and set down one after another."""
        assert self.configs is not None and self.arm.T_tcp_object is not None
        arm, robot, targets = self.arm, self.robot, self.configs.targets
        t0 = time.perf_counter()
        try:
            tcp = arm.tcp_pose()
            finger = gripper.finger_travel(robot, self.d)
            top = pin.SE3(tcp.rotation, np.array([*tcp.translation[:2], float(targets.lift.translation[2])]))
            lift = solve_line(robot, top, arm.q, "lift", self.ik, finger_m=finger)
            if not arm.carrying(self.cfg.planning_margin_m, False).is_valid(lift.q):
                log.info("LIFT: the lift height is within the planner's margin of something with the %s as it sits: "
                         "lifting on its own", robot.scene.object.name)
                return False
            pre, down = self._place_configurations(top, top * arm.T_tcp_object, finger)
        except UnreachableTarget as exc:
            log.info("LIFT: no lift and place for one motion (%s): lifting on its own", exc)
            return False
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        speed = self.ctrl.vertical_speed_m_s
        assert lift.path is not None
        # the table holds the object's weight (and what the pads press it down with) at the lift's start, the
        # weight at the set-down's end
        support = arm.support_reserve(-self.observer.load_sample()[1])
        after = StraightMove(down.path, speed, min(0.5, RE_AIM_RESERVE + arm.support_reserve())) \
            if down.path is not None else None
        try:
            arm.plan_through("transport", lambda margin: arm.carrying(margin, False), pre.q,
                             before=StraightMove(lift.path, speed, support), after=after)
        except (PlanningFailed, TimingFailed, CannotHold) as exc:
            log.info("LIFT: the lift and the transport cannot be one motion (%s): one after the other", exc)
            return False
        self._through = {Phase.EXEC_TRANSPORT} | ({Phase.DESCEND_PLACE} if after is not None else set())
        return True

    def _place_configurations(self, T_world_tcp: pin.SE3, T_world_object: pin.SE3,
                              finger: float) -> tuple[IKResult, IKResult]:
        """The preplace and the place of the object held as it is at ``T_world_object`` by the tcp at
        ``T_world_tcp`` (re-targeted from that grip), solved: the preplace clear of everything by the planner's
        margin (it ends a planned path), the place touching nothing but the table with the object. With
        ``blend_set_down`` the place is the end of the straight set-down from the preplace, followed waypoint by
        waypoint (its ``path``: the set-down can be timed with the transport); where that cannot be followed, it
        is solved alone and ``path`` is None.

        Raises:
            UnreachableTarget: either cannot be solved.
        """
        assert self.configs is not None
        targets = self.configs.targets
        preplace, place = place_targets(self.robot.scene, T_world_tcp, T_world_object, targets.R_world_object_goal,
                                        targets.preplace_height_m, R_world_tcp_planned=targets.place.rotation)
        carry_ik = self.arm.carrying(self.cfg.planning_margin_m, False)  # the planner accepts it as a goal
        place_ik = self.arm.carrying(0.0, True)
        pre = solve_ik(self.robot, preplace, self.configs.preplace.q, "preplace", self.ik, carry_ik.is_valid, finger)
        low: IKResult | None = None
        if self.ctrl.blend_set_down and not self._looks:
            try:
                low = solve_line(self.robot, place, pre.q, "place", self.ik, place_ik.is_valid, finger)
            except UnreachableTarget as exc:
                log.info("the set-down cannot be followed waypoint by waypoint (%s): it will be a move of its own", exc)
        if low is None:
            low = dataclasses.replace(solve_ik(self.robot, place, pre.q, "place", self.ik, place_ik.is_valid, finger),
                                      path=None)
        self.arm.note_ik(pre, low)
        return pre, low

    def _plan_transport(self) -> Phase:
        """Re-target the place from the object's measured pose in the hand, then plan to above the goal (with
        ``blend_set_down``, timed with the set-down as one motion). Nothing to do if the lift planned it."""
        assert self.configs is not None
        if Phase.EXEC_TRANSPORT in self._through:
            return Phase.EXEC_TRANSPORT  # planned with the lift, from the grip as it settled
        t0 = time.perf_counter()
        tcp, obj = self.arm.tcp_pose(), self._object_pose()
        self.arm.T_tcp_object = tcp.actInv(obj)
        try:
            pre, low = self._place_configurations(tcp, obj, gripper.finger_travel(self.robot, self.d))
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        reserve = min(0.5, RE_AIM_RESERVE + self.arm.support_reserve())  # the re-aim's room, the table's support
        after = StraightMove(low.path, self.ctrl.vertical_speed_m_s, reserve) if low.path is not None else None
        if self.arm.plan_through("transport", lambda margin: self.arm.carrying(margin, False), pre.q, after=after):
            self._through = {Phase.DESCEND_PLACE}
        return Phase.EXEC_TRANSPORT

    def _exec_transport(self) -> Phase:
        """Run the transport to the preplace (on into the set-down, without stopping, if they were planned as
        one)."""
        traj = self.arm.trajectory
        assert traj is not None
        self._through.discard(Phase.EXEC_TRANSPORT)
        until = self.arm.parts - 1 if Phase.DESCEND_PLACE in self._through else None
        if self.faults.intruder and not self.injector.intruder_placed:  # it appears once the path is planned
            q_end = traj.sample(traj.part_times_s[until])[0] if until is not None else traj.end
            self.injector.place_intruder(self.d, self.arm.tcp_pose().translation, self.arm.tcp_at(q_end))
        self.arm.execute(Phase.EXEC_TRANSPORT, until=until)
        return Phase.DESCEND_PLACE

    def _set_down_hook(self) -> control.Hook:
        """The monitor for the set-down at the goal: the object may touch the table once it is within 3 mm of resting
        on it (:meth:`_touch_down_hook`)."""
        assert self.configs is not None
        observer = self.observer
        z_table_touch = float(self.robot.scene.goal_resting_m(self.configs.targets.R_world_object_goal)[2]) + 0.003
        return self._touch_down_hook(lambda: observer.object_position()[2] < z_table_touch)

    def _touch_down_hook(self, near: Callable[[], bool]) -> control.Hook:
        """The monitor for lowering the held object onto a surface: once ``near()``, the object may touch the table,
        which then takes its weight; the move ends (:class:`_SetDown`) when what is below carries it."""
        monitor, observer = self.monitor, self.observer
        mass_kg = self.arm.payload.mass_kg if self.arm.payload is not None else 0.0

        def hook(d: mujoco.MjData) -> None:
            if near():
                monitor.allow_object_table = True  # setting it down
                observer.expect_load(None)  # the table takes its weight
            monitor(d)
            if monitor.allow_object_table and observer.touched_down(mass_kg):
                raise _SetDown  # the surface carries it: no need to go further

        return hook

    def _rest_after_touch_down(self) -> None:
        """Bring an arm that a surface stopped short of its set-down's end to rest gently (the surface pushes back),
        not at once by the hold that follows (:data:`SET_DOWN_STOP_SHARE`)."""
        if self.arm.moving:
            self.arm.stop(settle_s=0.0, share=SET_DOWN_STOP_SHARE)

    def _descend_place(self) -> Phase:
        """Re-aim from the object's pose in the hand *now* (it shifts a little in transit), then set it down.

        If the transport runs on into the set-down, the re-aim is made as the tcp passes the preplace: the rest of
        the set-down is bent to end at the re-aimed place (blended in by a minimum-jerk offset, within the joint
        limits' room: :meth:`Arm.offset_end`). Otherwise the arm, at rest above the goal, moves to the re-aimed
        preplace and goes straight down (a guarded Cartesian move). Either way the set-down ends as soon as the
        table carries the object.
        """
        assert self.configs is not None
        t0 = time.perf_counter()
        self.observer.look_in_hand()
        self._note_estimate("in hand")
        tcp, obj = self.arm.tcp_pose(), self._object_pose()
        preplace, place = place_targets(self.robot.scene, tcp, obj, self.configs.targets.R_world_object_goal,
                                        self.configs.targets.preplace_height_m,
                                        R_world_tcp_planned=self.configs.targets.place.rotation)
        finger = gripper.finger_travel(self.robot, self.d)
        if Phase.DESCEND_PLACE in self._through:
            self._through.discard(Phase.DESCEND_PLACE)
            traj = self.arm.trajectory
            assert traj is not None
            planned = traj.end
            aim = solve_ik(self.robot, place, planned, "place", self.ik, finger_m=finger)
            self.arm.note_ik(aim)
            fraction = self.arm.offset_end(aim.q - planned)
            if fraction < 1.0:
                log.info("DESCEND_PLACE: the set-down is re-aimed %.0f %% of the way (the joint limits' room)",
                         fraction * 100)
            self.out.wall_plan_time_s += time.perf_counter() - t0
            start, end = tcp.translation, self.arm.tcp_at(self.arm.trajectory.end)

            def move(hook: control.Hook) -> None:
                self.arm.execute(Phase.DESCEND_PLACE, hook=hook)
        else:
            aim = solve_ik(self.robot, preplace, self.arm.q, "preplace", self.ik, finger_m=finger)
            self.arm.note_ik(aim)
            self.out.wall_plan_time_s += time.perf_counter() - t0
            if float(np.max(np.abs(aim.q - self.arm.q))) > 1e-5:
                self.arm.trajectory = retime(np.vstack([self.arm.q, aim.q]), self.timing)
                self.arm.segment_checker = None  # a sub-millimetre correction: nothing to predict
                self.arm.execute(Phase.DESCEND_PLACE)
            start, end = self.arm.tcp_pose().translation, place.translation

            onto = self.arm.carrying(0.0, True)  # the object may touch the surface it is set on
            reserve = self.arm.support_reserve()  # the table takes the object's weight at the end

            def move(hook: control.Hook) -> None:
                self.arm.linear(Phase.DESCEND_PLACE, place, hook, onto, reserve, self.ik)
        with self.arm.following(start, end) as line:
            try:
                move(self._set_down_hook())
            except _SetDown:
                log.debug("set down at t = %.3f s, the tcp %.2f mm above its target", self.monitor.t,
                          (float(self.arm.tcp_pose().translation[2]) - float(end[2])) * 1e3)
                self._rest_after_touch_down()  # down early: the object sits lower in the hand
        self.out.place_line_deviation_max_m = float(np.fmax(self.out.place_line_deviation_max_m, line.max_m))
        return Phase.RELEASE

    def _release(self) -> Phase:
        """Open, wait for the pads to clear the object and the object to rest, and check where it rests (as the
        robot observes it; the result records the truth, :meth:`_measure_place`)."""
        robot, d, cfg, observer = self.robot, self.d, self.cfg, self.observer
        self.monitor.holding = False
        self.monitor.allow_object_table = True
        observer.expect_load(None)
        # the squeeze eased off, then open; the payload compensation held until the pads let go (the object's weight
        # goes over to the table as the squeeze eases)
        drive = gripper.GripDrive(robot, d, False)
        observer.released()
        self._release_t = self.monitor.t
        geom = gripper.GripperGeometry.measure(robot)
        clear_travel = geom.contact_travel_m(self.configs.targets.width_m) - cfg.release_clearance_m
        hook = self._driving(drive)

        def speed() -> float:
            return float(np.linalg.norm(observer.object_velocity()[:3]))

        def cleared() -> bool:
            return gripper.finger_travel(robot, d) <= clear_travel and not np.any(observer.pad_forces() > 0.0)

        def released() -> bool:
            if drive.done:
                self.arm.payload = None
            return cleared() and speed() < cfg.object_rest_speed_m_s

        rested = self.arm.hold_until(self.arm.q, released, cfg.release_timeout_s, min_s=cfg.poll_s, hook=hook)
        self.arm.payload = None
        gripper.command(robot, d, False)  # (the drive's end: fully open)
        if not rested and cleared() and not math.isfinite(speed()):  # the open pads hide it from the camera
            self._back_off_to_look(f"the camera does not see the {robot.scene.object.name} next to the open pads")
            rested = self.arm.hold_until(self.arm.q, released, cfg.release_timeout_s, min_s=cfg.poll_s)
        if not rested:
            forces = observer.pad_forces()
            raise PhaseFailed(Phase.RELEASE, f"the pads did not clear the {robot.scene.object.name} within "
                                             f"{cfg.release_timeout_s:g} "
                                             f"s (finger travel {gripper.finger_travel(robot, d) * 1e3:.1f} mm, pad "
                                             f"forces {forces[0]:.2f} / {forces[1]:.2f} N, its speed "
                                             f"{speed() * 1e3:.1f} mm/s)")
        self.monitor.allow_hand_object = False
        self._measure_place()
        try:
            seen = self._observe(near=observer.object_pose())
        except ObjectNotSeen as exc:  # the open pads hide it: back off a little and look again
            if self._backed_off_m > 0.0:
                raise
            self._back_off_to_look(str(exc))
            seen = self._observe(near=observer.object_pose())
        xy, z, yaw = self._place_errors(seen)
        name = robot.scene.object.name
        wrong = []  # every check that fails, so that one does not hide another
        if xy > cfg.place_tolerance_xy_m:
            wrong.append(f"the {name} rests {xy * 1e3:.2f} mm from the goal "
                         f"(tolerance {cfg.place_tolerance_xy_m * 1e3:.2f} mm)")
        if abs(z) > cfg.place_tolerance_z_m:
            wrong.append(f"the {name} rests {z * 1e3:.2f} mm above the table (it should sit on it; tolerance "
                         f"{cfg.place_tolerance_z_m * 1e3:.2f} mm)")
        if abs(yaw) > cfg.place_tolerance_yaw_rad:
            wrong.append(f"the {name}'s yaw is {yaw:.3f} rad off the goal's (tolerance "
                         f"{cfg.place_tolerance_yaw_rad:.3f} rad)")
        if wrong:
            raise PhaseFailed(Phase.RELEASE, "; ".join(wrong))
        return Phase.RETRACT

    def _back_off_to_look(self, why: str) -> None:
        """Back the open hand off the released object by :data:`LOOK_BACK_OFF_M` along the approach, so that the
        camera sees the object again (RETRACT backs off that much less)."""
        log.info("RELEASE: %s; backing off %.0f mm to look again", why, LOOK_BACK_OFF_M * 1e3)
        self.arm.linear(Phase.RELEASE, backed_off(self.arm.tcp_pose(), LOOK_BACK_OFF_M), checker=self._leaving(),
                        ik=self.ik)
        self._backed_off_m = LOOK_BACK_OFF_M

    def _place_errors(self, T_world_object: pin.SE3) -> tuple[float, float, float]:
        """Horizontal (m), height (m) and yaw (rad, modulo the object's symmetry) error of an object at rest at
        ``T_world_object`` against the goal."""
        assert self.configs is not None
        R_goal = self.configs.targets.R_world_object_goal
        err = T_world_object.translation - self.robot.scene.goal_resting_m(R_goal)
        return (float(np.hypot(err[0], err[1])), float(err[2]),
                yaw_error(T_world_object.rotation, R_goal, self.robot.scene.object.yaw_period_rad))

    def _measure_place(self) -> None:
        """Record where the object really rests (the simulator's truth: a measurement of the episode, which the
        robot does not use)."""
        xy, z, yaw = self._place_errors(self._truth.object_pose())
        self.out.place_error_xy_m, self.out.place_error_z_m, self.out.place_error_yaw_rad = xy, z, yaw

    def _retract(self) -> Phase:
        """Back off from the object along the approach, rise if the plan said so (or if the hand is still
        within the planner's margin of something), and go home; with ``blend_retract``, the back-off and the way
        home are one motion where the back-off ends clear of everything."""
        assert self.configs is not None
        back = self.cfg.retract_height_m - self._backed_off_m  # less what the place check backed off already
        if self.ctrl.blend_retract and self._plan_retract(back):
            self.arm.execute(Phase.RETRACT)
            return Phase.DONE
        leaving = self._leaving() if back > 0.0 or self.configs.targets.retreat_rise_m > 0.0 else None
        if back > 0.0:
            self.arm.linear(Phase.RETRACT, backed_off(self.arm.tcp_pose(), back), checker=leaving, ik=self.ik)
        if self.configs.targets.retreat_rise_m > 0.0:
            rise = self.configs.targets.retreat_rise_m
            self.arm.vertical(Phase.RETRACT, float(self.arm.tcp_pose().translation[2]) + rise, checker=leaving,
                              ik=self.ik)
        self.arm.rise_until_clear(Phase.RETRACT, self.arm.free, self.ik)
        self.arm.plan_segment("return", self.arm.free, self.robot.home_q)
        self.arm.execute(Phase.RETRACT)
        return Phase.DONE

    def _plan_retract(self, back_m: float) -> bool:
        """Plan the back-off by ``back_m`` (m) along the approach (its IK waypoints) and the way home as one
        motion; False (nothing planned) where the back-off is not all there is to it (none, a rise after it, or it
        ends within the planner's margin of something) or cannot be planned so."""
        if back_m <= 0.0 or self.configs is None or self.configs.targets.retreat_rise_m > 0.0:
            return False
        arm = self.arm
        t0 = time.perf_counter()
        try:
            away = solve_line(self.robot, backed_off(arm.tcp_pose(), back_m), arm.q, "retreat", self.ik,
                              finger_m=gripper.finger_travel(self.robot, self.d))
            clear = arm.free(self.cfg.planning_margin_m).is_valid(away.q)
        except UnreachableTarget as exc:
            log.info("RETRACT: the back-off cannot be followed waypoint by waypoint (%s)", exc)
            return False
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        if not clear or away.path is None:
            return False
        policy = CollisionPolicy(margin_m=RETRACT_CUSHION_M, allow_gripper_object=True, table_margin_m=0.0,
                                 finger_m=gripper.finger_travel(self.robot, self.d))
        near = CollisionChecker(self.robot, policy, world=arm.observer.world())
        k = near.first_invalid(away.path)
        if k >= 0:
            log.info("RETRACT: the hand backs off within %.1f mm of %s: on the line itself first",
                     1e3 * RETRACT_CUSHION_M,
                     ", ".join(f"{a} <-> {b}" for a, b in near.colliding_pairs(away.path[k])))
            return False
        try:
            arm.plan_through("return", arm.free, self.robot.home_q,
                             before=StraightMove(away.path, self.ctrl.vertical_speed_m_s))
        except (PlanningFailed, TimingFailed) as exc:
            log.info("RETRACT: the back-off and the way home cannot be one motion (%s): one after the other", exc)
            return False
        return True

    def _leaving(self) -> CollisionChecker:
        """What the open hand may not touch as it leaves the object it let go of: anything but that object (the
        straight moves away from it, checked at contact)."""
        policy = CollisionPolicy(margin_m=0.0, allow_gripper_object=True,
                                 finger_m=gripper.finger_travel(self.robot, self.d))
        return CollisionChecker(self.robot, policy, world=self.arm.observer.world())

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
        self.arm.finish_tracking()
        return out

    def _spent(self, phase: Phase, t0: float, outcome: str) -> None:
        durations = self.out.phase_durations_s
        durations[phase.value] = durations.get(phase.value, 0.0) + self.monitor.t - t0
        self.out.timeline.append((phase.value, t0, self.monitor.t - t0, outcome))

    def _recovery(self, phase: Phase, exc: PickPlaceError) -> Phase | None:
        """The phase to continue with after ``exc`` in ``phase`` (:mod:`pickplace.task.recovery`), or None. The
        motion that was running is given up: the phases after a recovery plan their own."""
        self._through = set()
        contact = isinstance(exc, UnexpectedContact)
        if contact:
            self.out.unexpected_contacts.extend(p for p in exc.pairs if p not in self.out.unexpected_contacts)
        held = isinstance(exc, GraspFailed) and not self._carried_on and self._still_held()
        recovery = recovery_for(phase, exc, contact and self._touches_object(exc), still_held=held,
                                at_lift=self._at_lift())
        if recovery is None:
            return None
        if not self.budget.admits(phase, exc, may_repeat=recovery.next_grasp, action=recovery.action):
            return None
        if recovery.next_grasp and self.configs is not None:
            self._dropped.append(self.configs.chosen)
        if recovery.regrip:
            self._carried_on = True
            self.monitor.start_holding(self.d)  # the grip as it has become: the stop must not trip on it again
        try:
            if recovery.first is FirstMove.STOP:
                self.arm.stop()  # before planning from where the arm stands
            elif recovery.first is FirstMove.BACK_OFF:
                self.arm.back_off()
            elif recovery.first is FirstMove.PUT_BACK:
                self._put_back()
        except ConfigError:
            raise
        except PickPlaceError as again:  # e.g. the slip goes on while the arm stops: answer that failure instead
            log.info("recovery: %s failed on the way: %s", recovery.first.value, again)
            return self._recovery(phase, again)
        self.budget.spend(phase, exc, recovery.action)
        note = f"{phase.value}: {type(exc).__name__}: {exc} -> {recovery.action}"
        self.out.recoveries.append(note)
        log.info("recovery %d/%d: %s", self.budget.used, self.budget.max_retries, note)
        return recovery.next_phase

    def _at_lift(self) -> bool:
        """Whether the arm holds the object where the lift left it: straight above its grasp (within 1 mm), the
        hand as it grasped (within 0.01 rad), and it has not carried on after a slip."""
        if self.configs is None or self.arm.payload is None or self._carried_on:
            return False
        tcp, grasp = self.arm.tcp_pose(), self.configs.targets.grasp
        off = tcp.translation - grasp.translation
        turn = float(np.linalg.norm(pin.log3(grasp.rotation.T @ tcp.rotation)))
        return bool(np.hypot(off[0], off[1]) < 0.001 and off[2] > 0.0 and turn < 0.01)

    def _put_back(self) -> None:
        """Set the held object back down where it was picked (the lift reversed, guarded like a set-down), let go,
        wait for the pads to clear it, and back the hand off along the approach."""
        assert self.configs is not None
        robot, d, cfg, monitor, observer = self.robot, self.d, self.cfg, self.monitor, self.observer
        targets = self.configs.targets
        z_grasp = float(targets.grasp.translation[2])
        log.info("recovery: setting the %s back down where it was picked", robot.scene.object.name)
        self._lower_onto_support(Phase.PLAN_TRANSPORT, z_grasp + PLACE_DROP_M, z_grasp + 0.003)
        monitor.holding = False
        monitor.allow_object_table = True
        self.arm.payload = None
        observer.expect_load(None)
        gripper.command(robot, d, False)
        observer.released()
        clear_travel = gripper.GripperGeometry.measure(robot).contact_travel_m(targets.width_m) - \
            cfg.release_clearance_m

        def cleared() -> bool:
            return gripper.finger_travel(robot, d) <= clear_travel and not np.any(observer.pad_forces() > 0.0)

        if not self.arm.hold_until(self.arm.q, cleared, cfg.release_timeout_s, min_s=cfg.poll_s):
            raise PhaseFailed(Phase.PLAN_TRANSPORT, f"the pads did not clear the {robot.scene.object.name} set back "
                                                    f"down within {cfg.release_timeout_s:g} s")
        self.arm.linear(Phase.PLAN_TRANSPORT, backed_off(self.arm.tcp_pose(), CLEARANCE_M), checker=self._leaving(),
                        ik=self.ik)
        monitor.allow_hand_object = False

    def _lower_onto_support(self, phase: Phase, target_z: float, allow_below_z: float) -> None:
        """Lower the held object straight down, the tcp towards ``target_z`` (m), until whatever is below carries
        it (a guarded set-down: :meth:`~pickplace.task.observe.SimulatorObserver.touched_down`), then bring the arm
        to rest; the object may touch the table once the tcp is below ``allow_below_z`` (m).

        Raises:
            PhaseFailed: the straight move down runs into something the held object or the hand may not touch (the
                geoms named), checked before the arm moves.
        """
        hook = self._touch_down_hook(lambda: float(self.arm.tcp_pose().translation[2]) < allow_below_z)
        try:
            self.arm.vertical(phase, target_z, hook, self.arm.carrying(0.0, True), self.arm.support_reserve(),
                              self.ik)
        except _SetDown:  # the surface carries it: no need to go further
            self._rest_after_touch_down()

    def _set_down_before_letting_go(self) -> bool:
        """Lower an object whose grip failed onto whatever is below it while the pads still touch it, so that
        letting go does not drop it from where the grip failed (the transport's height: onto a wall, off the table
        or into a roll). Returns whether it was lowered; False where nothing is in the hand any more, or the
        straight move down is blocked (the hand over a wall or a bin's rim) or fails on the way (then the object
        is let go where it is, as before)."""
        if self.arm.payload is None or self.arm.T_tcp_object is None or \
                not np.any(self.observer.pad_forces() > 0.0):
            return False
        scene = self.robot.scene
        tcp = self.arm.tcp_pose()
        obj = tcp * self.arm.T_tcp_object
        lowest = float(np.min(scene.object.geometry().vertices @ obj.rotation[2]) + obj.translation[2])
        target_z = float(tcp.translation[2]) - (lowest - scene.table_height_m) - RECOVERY_SET_DOWN_OVERSHOOT_M
        if target_z > float(tcp.translation[2]) - 0.002:
            return False  # it is down already
        try:
            self._lower_onto_support(Phase.RECOVER, target_z, math.inf)
        except ConfigError:
            raise
        except PickPlaceError as exc:
            log.info("recovery: the %s is let go where it is: %s", scene.object.name, exc)
            if self.arm.moving:
                self.arm.stop()
            return False
        log.info("recovery: the %s was set down before letting go, the tcp at %.4f m", scene.object.name,
                 float(self.arm.tcp_pose().translation[2]))
        return True

    def _driving(self, drive: gripper.GripDrive) -> control.Hook:
        """The monitor of a hold while the gripper's drive runs: the drive's command updated after every step."""
        monitor = self.monitor

        def hook(d: mujoco.MjData) -> None:
            drive(d)
            monitor(d)

        return hook

    def _still_held(self) -> bool:
        """Whether the robot senses the object in the hand: both pads squeezing it with at least the force a
        settled grip needs, and (a wrist sensor) its weight still carried."""
        forces = self.observer.pad_forces()
        return bool(np.all(forces >= self.cfg.min_pad_force_n)) and self.observer.grip_lost() is None

    def _touches_object(self, exc: UnexpectedContact) -> bool:
        """Whether every pair of the contact involves the object."""
        return all(any(name in self._object_names for name in pair) for pair in exc.pairs)

    def _recover(self) -> Phase:
        """Stop, set a held object down where the way down is free (:meth:`_set_down_before_letting_go`), let go,
        back off upwards, wait for the object to rest wherever it is, and observe it again for a new approach (with
        whatever grasp now works)."""
        robot, d, cfg = self.robot, self.d, self.cfg
        scene = robot.scene
        self.monitor.holding = False
        self.monitor.watching = False
        self.monitor.allow_hand_object = True
        self.monitor.allow_object_table = True
        self.arm.stop()  # with the grip as it is: opening at speed would throw whatever is still held
        self._set_down_before_letting_go()
        self.arm.payload = None
        self.observer.expect_load(None)
        gripper.command(robot, d, False)
        self.observer.released()
        self.arm.hold(self.arm.q, 0.15)
        z_safe = scene.table_height_m + float(np.max(scene.object.geometry().extent_m)) + CLEARANCE_M
        if float(self.arm.tcp_pose().translation[2]) < z_safe:  # the object may be anywhere, falling: unchecked
            self.arm.vertical(Phase.RECOVER, z_safe, ik=self.ik)
        name = scene.object.name
        self.monitor.object_falling = True  # the arm waits; whatever the object lands on, it came to it
        try:
            rested = self.arm.hold_until(None, lambda: float(np.linalg.norm(self.observer.object_velocity())) <= 0.01,
                                      cfg.object_settle_timeout_s)
        finally:
            self.monitor.object_falling = False
        if not rested:
            raise PhaseFailed(Phase.RECOVER, f"the {name} did not come to rest within "
                                             f"{cfg.object_settle_timeout_s:.1f} s")
        self.monitor.allow_hand_object = False
        obj = self._observe()
        lowest = float(np.min(scene.object.geometry().vertices @ obj.rotation[2]) + obj.translation[2])
        where = f"({obj.translation[0]:.3f}, {obj.translation[1]:.3f}) m"
        if lowest < scene.table_height_m - 0.01:
            raise PhaseFailed(Phase.RECOVER, f"the {name} fell off the table: it rests at {where}, "
                                             f"{scene.table_height_m - lowest:.3f} m below the table top")
        surface, what = scene.table_height_m, "the table"
        if scene.bin is not None:
            lo, hi = scene.bin.inner_box_xy_m
            if np.all(obj.translation[:2] >= lo) and np.all(obj.translation[:2] <= hi):  # it fell into the bin
                surface, what = scene.bin.floor_z_m(scene.table_height_m), "the bin's floor"
        if lowest > surface + 0.005:
            raise PhaseFailed(Phase.RECOVER, f"the {name} is not resting on {what}: its lowest point is "
                                             f"{(lowest - surface) * 1e3:.0f} mm above it at {where} "
                                             "(it is stuck on something)")
        t0 = time.perf_counter()
        try:
            self._adopt(self._solve_grasps(obj))
        except UnreachableTarget as exc:
            raise PhaseFailed(Phase.RECOVER, f"the {name} now rests at {where}, out of reach: {exc}") from exc
        finally:
            self.out.wall_plan_time_s += time.perf_counter() - t0
        self.monitor.watching = True
        log.info("recovery: the %s was observed again at (%.4f, %.4f) m, yaw %.3f rad", name, *obj.translation[:2],
                 object_yaw(obj.rotation))
        return Phase.PLAN_APPROACH

    def _fail(self, phase: Phase, exc: PickPlaceError) -> None:
        out = self.out
        out.phase = Phase.FAILED
        out.failure_phase = exc.phase if isinstance(exc, PhaseFailed) else phase
        out.failure_reason = exc.reason if isinstance(exc, PhaseFailed) else str(exc)
        out.failure_kind = type(exc).__name__
        if self.budget.repeated:
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
            if remaining > 0.5 * float(self.robot.mj.opt.timestep):  # (less is no step at all)
                self.arm.hold(self.robot.home_q, remaining)
        except PickPlaceError as exc:
            self._fail(Phase.DONE, exc)
            return
        obj = self._truth.object_pose()  # a measurement of the episode
        err = obj.translation[:2] - self.robot.scene.goal_pos_m[:2]
        self.out.final_place_error_xy_m = float(np.hypot(err[0], err[1]))
        tol = self.cfg.place_tolerance_xy_m
        if self.out.final_place_error_xy_m > tol:  # placed, then it moved: the place did not hold
            self._fail(Phase.RELEASE, PhaseFailed(
                Phase.RELEASE, f"the {self.robot.scene.object.name} moved after the release: it rests "
                f"{self.out.final_place_error_xy_m * 1e3:.2f}"
                f" mm from the goal {self.cfg.stable_after_release_s:g} s after it (tolerance {tol * 1e3:.2f} mm)"))


__all__ = ["PickPlaceSkill"]
