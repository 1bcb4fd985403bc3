"""The expert of the low-level environment: the project's own stack, planning from the environment's state and
acting through its steps, so that a recorded demonstration *is* an episode of ``pickplace/PickPlaceLowLevel-v0``.

At reset the expert does what the skill's IDLE does (:mod:`pickplace.task.skill`): it takes the object's pose from
the observation, ranks the grasps of the object (:func:`~pickplace.grasping.configurations.candidate_grasps`) and
solves the first whose whole chain is reachable collision free and whose pads hold the object
(:func:`~pickplace.grasping.configurations.solve_grasp_configurations`). Then, phase by phase:

========================  =================================================================================
phase                     what the expert commands (one joint target and gripper command per step)
========================  =================================================================================
``EXEC_APPROACH``         home to the pregrasp: RRT* (:func:`~pickplace.motion.planning.plan`) and TOPP-RA
                          (:func:`~pickplace.motion.timing.retime`), sampled at the end of every step
``DESCEND``               the straight approach to the grasp: the tcp along the line (minimum jerk), each
                          waypoint solved by IK from the one before (the arm stays on its branch)
``CLOSE``                 close and hold until the gripper settled with both pads pressing
``LIFT``                  straight up to the lift height, its acceleration within what the grip holds, taking
                          the object's weight on (the load below)
``EXEC_TRANSPORT``        the place re-targeted from the object's pose in the hand, planned and retimed with
                          the object carried (slowed down until the grip holds, as the skill does)
``DESCEND_PLACE``         down to 1 cm above the place; there the hand moved until the held object, as it sits
                          in the hand, is upright above its goal; down; its weight handed over to the table
``RELEASE``               open and hold until the environment reports the object placed and at rest
========================  =================================================================================

After each phase the expert applies the phase's check (the tcp within 5 mm of the grasp after DESCEND, the pads
settled on the object after CLOSE, the object risen with the hand after LIFT, the object placed within the
tolerances after RELEASE); a check that fails, a grasp, plan or IK that cannot be found, or a failure the
environment reports (an unexpected contact, the object off the table) ends the demonstration with the phase, the
error's kind and its reason. The expert is privileged: besides the observation (the object's pose, the arm's
joints and the controller's target) it reads the simulation state (:attr:`PickPlaceLowLevelEnv.sim_data
<pickplace.envs.lowlevel.PickPlaceLowLevelEnv.sim_data>`) for the world it plans in and for the pads' forces and the
fingers' speed, as the ideal profile's observer does; it never draws from the environment's random streams nor
writes to it, so that its actions alone make the episode.

Every action is a joint-mode action of the environment, ``(dq1..dq6, grip)`` in ``[-1, 1]`` as float32: the
increment from the environment's current target (``target_q`` in the observation) to the expert's next
reference, in units of ``max_joint_step_rad``. Replaying the recorded actions from the same seed and options
reproduces the episode step for step (the environment is deterministic); :func:`replay` does it.

The environment tracks its targets with the joint impedance and gravity compensation of
:class:`~pickplace.motion.control.ControlConfig`, but without an acceleration feedforward (its reference ramps
linearly over each step) and without payload compensation. So the trajectories are the stack's own, slowed down
(:class:`ExpertConfig`: the arm lags the reference by about ``M(q) qdd / kp`` while it accelerates), and while it
holds the object the expert leads its target by the object's weight (``K^-1 g_object(q)``, :meth:`Expert.lead`: a
1 kg box would otherwise sag the hand 12 mm at ``kp`` = 200 N m/rad), as a policy that learns from it must.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import pinocchio as pin

from pickplace.envs.lowlevel import PickPlaceLowLevelEnv
from pickplace.errors import ConfigError, GraspFailed, PickPlaceError, UnreachableTarget
from pickplace.grasping.configurations import GraspConfigurations, solve_grasp_configurations
from pickplace.grasping.grip import GripCapacity, com_accelerations, grip_capacity, slowdown_for_grip
from pickplace.grasping.targets import LIFT_STEP_M, MAX_RAISE_M, PLACE_DROP_M, place_targets
from pickplace.motion import control
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.control import Payload, min_jerk
from pickplace.motion.planning import plan
from pickplace.motion.timing import Trajectory, retime
from pickplace.robot import gripper
from pickplace.robot.ik import IKConfig, dls_iterate, solve_ik
from pickplace.robot.kinematics import frame_pose
from pickplace.task.arm import TURN_OVER_SLOWDOWN, hand_turn_rad
from pickplace.task.phases import Phase, PhaseFailed
from pickplace.world.checks import check_int, check_range
from pickplace.world.mass import mass_properties

log = logging.getLogger(__name__)

#: The phase label of the reset observation (nothing has been commanded yet).
RESET_PHASE = "RESET"
#: The kind of failure of an episode the environment truncated (its ``max_steps``).
TIME_LIMIT = "TimeLimit"
#: The tcp must end the straight approach within this distance of its grasp on the object (m), as the skill's.
DESCEND_TOLERANCE_M = 0.005
#: The held object is brought this far above where it is set down (m), and its place corrected there.
HOVER_M = 0.01
#: ... and turned upright there while it is tilted more than this (rad).
TILT_TOLERANCE_RAD = 0.005
#: Once the object is down, its weight is handed over to the table in this time (s).
HAND_OVER_S = 0.2
#: Minimum-jerk peak speed and acceleration per unit of length and duration: 15/8 and 10/sqrt(3).
_MJ_SPEED, _MJ_ACCEL = 1.875, 5.7735


@dataclass(frozen=True)
class ExpertConfig:
    """How the expert moves and waits (SI units).

    Attributes:
        velocity_scale: The planned trajectories' joint speed limits relative to the episode's ``timing``.
        acceleration_scale: Their acceleration limits relative to the episode's ``timing``; the arm lags the
            reference by about ``M(q) qdd / kp`` (the environment has no acceleration feedforward).
        line_speed_m_s: Peak tcp speed of the straight moves (minimum jerk) (m/s).
        line_accel_m_s2: Peak tcp acceleration of the straight moves (m/s^2); with the object held, at most what
            the grip holds (:class:`~pickplace.grasping.grip.GripCapacity`).
        line_min_duration_s: Shortest straight move (s).
        settle_speed_rad_s: After a motion, the expert waits until every joint is slower than this (rad/s) ...
        settle_timeout_s: ... or this long (s), then goes on.
        place_tolerance_m: Above the goal, the hand is moved again while the held object is farther than this
            from where it should hover (m) ...
        place_corrections: ... at most this many times.
        rest_timeout_s: After the pads cleared the released object, time allowed for it to come to rest (s).
    """

    velocity_scale: float = 0.5
    acceleration_scale: float = 0.25
    line_speed_m_s: float = 0.2
    line_accel_m_s2: float = 1.0
    line_min_duration_s: float = 0.3
    settle_speed_rad_s: float = 0.01
    settle_timeout_s: float = 0.5
    place_tolerance_m: float = 3e-4
    place_corrections: int = 3
    rest_timeout_s: float = 1.0

    def __post_init__(self) -> None:
        for name, lo, hi, unit in (("velocity_scale", 0.0, 1.0, ""), ("acceleration_scale", 0.0, 1.0, ""),
                                   ("line_speed_m_s", 0.0, 1.0, "m/s"), ("line_accel_m_s2", 0.0, 10.0, "m/s^2"),
                                   ("line_min_duration_s", 0.0, 10.0, "s"),
                                   ("settle_speed_rad_s", 0.0, 1.0, "rad/s"), ("settle_timeout_s", 0.0, 10.0, "s"),
                                   ("place_tolerance_m", 0.0, 0.01, "m"), ("rest_timeout_s", 0.0, 10.0, "s")):
            lo_open = name not in ("line_min_duration_s", "settle_timeout_s", "place_tolerance_m", "rest_timeout_s")
            object.__setattr__(self, name, check_range(f"expert.{name}", getattr(self, name), lo, hi,
                                                       lo_open=lo_open, unit=unit))
        object.__setattr__(self, "place_corrections", check_int("expert.place_corrections", self.place_corrections,
                                                                0, 10))


@dataclass(frozen=True)
class Command:
    """What the expert wants for the next step.

    Attributes:
        q: The joints' reference at the end of the step (6,) (rad).
        grip: Close the gripper.
        phase: The phase the step belongs to.
        load: The share (0 to 1) of the held object's weight the target leads the reference by: the environment's
            joint loop does not compensate a payload, so the expert commands ``q + load * K^-1 g_object(q)``
            (:meth:`Expert.action`), and the arm holds the reference while it carries the object.
    """

    q: np.ndarray
    grip: bool
    phase: Phase
    load: float = 0.0


@dataclass(frozen=True, eq=False)
class Demonstration:
    """One episode of the low-level environment, as acted by the expert (or replayed).

    Arrays are per step: ``N`` actions, ``N + 1`` observations and infos (the reset's first).

    Attributes:
        seed: The reset seed.
        options: The reset options (``{"config": JSON}``), or None.
        observations: Each observation key (N + 1, ...), as the environment returned them.
        actions: (N, 7) float32, ``(dq1..dq6, grip)`` in ``[-1, 1]``.
        rewards: (N,) float64.
        terminations: (N,) bool: the environment ended the episode (success or a failure it detected).
        truncations: (N,) bool: the last step when the expert stopped (its check failed) or ``max_steps`` ran out.
        infos: Per step (N + 1,): ``phase`` (str, :data:`RESET_PHASE` first), ``sim_time_s``, ``success``,
            ``released``, ``place_error_xy_m``, ``place_error_z_m``, ``place_error_yaw_rad`` (the environment's
            measures on the simulator's truth; nan at the reset), ``failure_phase``, ``failure_kind``,
            ``failure_reason`` (str, empty until the step that failed).
        success: The object placed and at rest (the environment's reward 1).
        failure_phase: The phase that failed, or None.
        failure_kind: The error behind it (``GraspFailed``, ``UnexpectedContact``, ``TimeLimit``...), or None.
        failure_reason: What failed, with the numbers, or None.
        grasp_approach: The grasp's approach (``top``, ``tilted``, ``side``), or None before a grasp was chosen.
        plan_time_s: Wall time of the expert's grasp search, planning and retiming (s).
        wall_time_s: Wall time of the whole episode (s).
    """

    seed: int
    options: dict[str, Any] | None
    observations: dict[str, np.ndarray]
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict[str, np.ndarray]
    success: bool
    failure_phase: str | None
    failure_kind: str | None
    failure_reason: str | None
    grasp_approach: str | None = None
    plan_time_s: float = 0.0
    wall_time_s: float = 0.0

    @property
    def steps(self) -> int:
        """Number of steps N."""
        return int(self.actions.shape[0])

    @property
    def sim_time_s(self) -> float:
        """Simulated time at the end (s)."""
        return float(self.infos["sim_time_s"][-1])


class Expert:
    """The stack as a policy of the low-level environment in joint mode (module docstring).

    Args:
        env: The environment, reset (its episode's models, configuration and simulation state are read).
        config: How the expert moves.
        seed: Seed of the planner's random stream.

    Raises:
        ConfigError: the environment is not in joint mode.
    """

    def __init__(self, env: PickPlaceLowLevelEnv, config: ExpertConfig | None = None, seed: int = 0) -> None:
        if env.action_mode != "joint":
            raise ConfigError("action_mode", env.action_mode, "must be 'joint' for the expert (it follows joint "
                                                              "trajectories; tilted and side grasps need all six)")
        self.env, self.cfg = env, config if config is not None else ExpertConfig()
        self.robot = env.robot
        self.episode = env.episode_config
        self.machine = self.episode.machine
        self.planner = dataclasses.replace(self.episode.planner, seed=int(seed))
        t = self.episode.timing
        self.timing = dataclasses.replace(
            t, velocity_limits_rad_s=tuple(v * self.cfg.velocity_scale for v in t.velocity_limits_rad_s),
            acceleration_limits_rad_s2=tuple(a * self.cfg.acceleration_scale for a in t.acceleration_limits_rad_s2))
        self.ik: IKConfig = self.episode.ik
        self.dt = 1.0 / env.control_rate_hz
        self.obs: dict[str, np.ndarray] = {}
        self.info: dict[str, Any] = {}
        self.phase = Phase.IDLE
        self.configs: GraspConfigurations | None = None
        self.capacity: GripCapacity | None = None
        self.plan_time_s = 0.0
        self._pdata = self.robot.pin.createData()
        self.q_ref = np.zeros(6)  # the last reference commanded (the environment's target less the load's lead)
        self.load = 0.0  # the load of the last command
        self._payload: tuple[control.ArmModel, control.ArmModel] | None = None  # (empty, holding) once grasped

    # ------------------------------------------------------------------ what the expert reads
    def _q(self) -> np.ndarray:
        return np.asarray(self.obs["joint_pos"], dtype=np.float64)

    def _target(self) -> np.ndarray:
        return np.asarray(self.obs["target_q"], dtype=np.float64)

    def _object_pose(self) -> pin.SE3:
        """The object's pose as the observation has it."""
        w, x, y, z = (float(v) for v in self.obs["object_quat"][0])
        R = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        return pin.SE3(R, np.asarray(self.obs["object_pos"][0], dtype=np.float64))

    def _finger_m(self) -> float:
        return gripper.finger_travel(self.robot, self.env.sim_data)

    def _fk(self, q: np.ndarray) -> pin.SE3:
        """The tcp's pose at ``q`` (the fingers as they are)."""
        return frame_pose(self.robot.pin, self._pdata, self.robot.pin_q(q, self._finger_m()),
                          self.robot.pin_tcp_frame)

    def lead(self, q: np.ndarray) -> np.ndarray:
        """How far (6,) (rad) the target must lead the reference ``q`` for the joint loop to hold the held object's
        weight there: its gravity torque over the loop's stiffness (``kp``, or ``w^2 M(q)`` with a joint
        bandwidth); zeros before the grasp."""
        if self._payload is None:
            return np.zeros(6)
        empty, holding = self._payload
        finger = self._finger_m()
        qp = self.robot.pin_q(q, finger)
        tau = (pin.computeGeneralizedGravity(holding.model, holding.data, qp)
               - pin.computeGeneralizedGravity(empty.model, empty.data, qp))[:6]
        c = self.episode.control
        if c.joint_bandwidth_rad_s > 0.0:
            return np.linalg.solve(control.arm_inertia(empty, q, finger), tau) / c.joint_bandwidth_rad_s**2
        return tau / c.joint_kp

    def action(self, command: Command) -> np.ndarray:
        """The environment's action (7,) float32 that moves its target to ``command.q`` (led by the load's share of
        :meth:`lead`), and remembers the command's reference."""
        q = np.asarray(command.q, dtype=np.float64)
        self.q_ref, self.load = q.copy(), float(command.load)
        target = q + command.load * self.lead(q) if command.load > 0.0 else q
        a = np.clip((target - self._target()) / self.env.max_joint_step_rad, -1.0, 1.0)
        return np.array([*a, 1.0 if command.grip else -1.0], dtype=np.float32)

    # ------------------------------------------------------------------ the script
    def script(self) -> Generator[Command, None, None]:
        """The commands, one per step; reads :attr:`obs` (set by the caller after each step).

        Raises:
            PickPlaceError: a check failed or no grasp, IK, plan or timing was found (the phase is
                :attr:`phase`).
        """
        self.phase = Phase.IDLE
        self.q_ref = self._target()
        configs = self._timed(self._solve_grasps)
        self.configs = configs
        # PLAN_APPROACH / EXEC_APPROACH
        self.phase = Phase.PLAN_APPROACH
        traj = self._timed(lambda: self._plan(self._free, configs.pregrasp.q))
        self.phase = Phase.EXEC_APPROACH
        yield from self._follow(traj, grip=False)
        # DESCEND
        self.phase = Phase.DESCEND
        yield from self._line(configs.targets.grasp, grip=False)
        grasp_now = self._object_pose() * configs.targets.T_object_tcp
        off = float(np.linalg.norm(self._fk(self._q()).translation - grasp_now.translation))
        if off > DESCEND_TOLERANCE_M:
            raise PhaseFailed(Phase.DESCEND, f"the tcp is {off * 1e3:.1f} mm from its grasp on the "
                                             f"{self.robot.scene.object.name} (limit {DESCEND_TOLERANCE_M * 1e3:g} mm)")
        # CLOSE
        self.phase = Phase.CLOSE
        yield from self._close()
        # LIFT
        self.phase = Phase.LIFT
        yield from self._lift()
        # PLAN_TRANSPORT / EXEC_TRANSPORT
        self.phase = Phase.PLAN_TRANSPORT
        traj, place = self._timed(self._plan_transport)
        self.phase = Phase.EXEC_TRANSPORT
        yield from self._follow(traj, grip=True)
        # DESCEND_PLACE
        self.phase = Phase.DESCEND_PLACE
        yield from self._descend_place(place)
        # RELEASE
        self.phase = Phase.RELEASE
        yield from self._release()

    def _timed(self, fn: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn()
        finally:
            self.plan_time_s += time.perf_counter() - t0

    # ------------------------------------------------------------------ planning
    def _solve_grasps(self) -> GraspConfigurations:
        m = self.machine
        obj = self._object_pose()
        configs = solve_grasp_configurations(self.robot, self.ik, obj, self.env.sim_data,
                                             m.planning_margin_m, retreat_m=m.retract_height_m,
                                             safety_factor=m.grip_safety_factor)
        targets = configs.targets
        self.capacity = grip_capacity(self.robot, self.robot.scene.object, targets.T_tcp_object, targets.width_m,
                                      m.grip_safety_factor, up_tcp=targets.grasp.rotation[2])
        self.capacity.require_holdable(self.robot.scene.object.name)
        log.debug("expert: grasp %s, %d tried", configs.chosen.approach.value, configs.grasps_tried)
        return configs

    def _free(self, margin_m: float) -> CollisionChecker:
        return CollisionChecker(self.robot, CollisionPolicy(margin_m=margin_m), world=self.env.sim_data)

    def _carrying(self, margin_m: float, T_tcp_object: pin.SE3) -> CollisionChecker:
        policy = CollisionPolicy(margin_m=margin_m, object_held=True, finger_m=self._finger_m())
        return CollisionChecker(self.robot, policy, world=self.env.sim_data, T_tcp_object=T_tcp_object)

    def _plan(self, checker_at: Any, q_goal: np.ndarray) -> Trajectory:
        """Plan from the current target to ``q_goal`` with the planner's margin; retime, accepted with half of it
        (as the skill's :meth:`~pickplace.task.arm.Arm.plan_segment`)."""
        margin = self.machine.planning_margin_m
        res = plan(checker_at(margin), self.q_ref, q_goal, self.robot.arm_lower, self.robot.arm_upper,
                   self.planner)
        return retime(np.asarray(res.path), self.timing, checker_at(margin / 2).all_valid)

    def _plan_transport(self) -> tuple[Trajectory, pin.SE3]:
        """The place re-targeted from the object's pose in the hand now; the path there with the object carried,
        slowed down until the grip holds (and three times more if the hand turns the object over)."""
        assert self.configs is not None and self.capacity is not None
        targets, m = self.configs.targets, self.machine
        tcp, obj = self._fk(self._q()), self._object_pose()
        T_tcp_object = tcp.actInv(obj)
        preplace, place = place_targets(self.robot.scene, tcp, obj, targets.R_world_object_goal,
                                        targets.preplace_height_m)
        finger = self._finger_m()
        carry = self._carrying(m.planning_margin_m, T_tcp_object)
        pre = solve_ik(self.robot, preplace, self.configs.preplace.q, "preplace", self.ik, carry.is_valid, finger)
        traj = self._plan(lambda margin: self._carrying(margin, T_tcp_object), pre.q)
        com = T_tcp_object.act(mass_properties(self.robot.scene.object).com_m)
        slowdown = slowdown_for_grip(com_accelerations(self.robot, traj, com, finger), self.capacity)
        if slowdown < TURN_OVER_SLOWDOWN and hand_turn_rad(self.robot, traj) > math.radians(45.0):
            slowdown = TURN_OVER_SLOWDOWN
        if slowdown > 1.0:
            traj = traj.slowed(slowdown)
        return traj, place

    # ------------------------------------------------------------------ motions
    def _follow(self, traj: Trajectory, grip: bool) -> Generator[Command, None, None]:
        """The trajectory sampled at the end of each step, then the last point held until the arm settles."""
        n = max(1, math.ceil(traj.duration_s / self.dt - 1e-9))
        qs, _, _ = traj.sample_many(np.arange(1, n + 1) * self.dt)
        for q in qs:
            yield Command(q, grip, self.phase, self.load)
        yield from self._settle(grip)

    def _settle(self, grip: bool) -> Generator[Command, None, None]:
        """Hold the reference until every joint is slower than ``settle_speed_rad_s`` (at least one step)."""
        q, waited = self.q_ref.copy(), 0.0
        while True:
            yield Command(q, grip, self.phase, self.load)
            waited += self.dt
            if float(np.max(np.abs(self.obs["joint_vel"]))) < self.cfg.settle_speed_rad_s or \
                    waited >= self.cfg.settle_timeout_s - 1e-9:
                return

    def _line(self, T_to: pin.SE3, grip: bool, accel_m_s2: float | None = None,
              load_to: float | None = None) -> Generator[Command, None, None]:
        """A straight tcp move from where the reference puts it to ``T_to`` (minimum jerk, orientation on SO(3)),
        each step's joints solved by IK from the previous step's (the arm stays on its branch), the load going
        to ``load_to`` along it; then :meth:`_settle`."""
        q = self.q_ref.copy()
        T0 = self._fk(q)
        length = float(np.linalg.norm(T_to.translation - T0.translation))
        turn = pin.log3(T0.rotation.T @ T_to.rotation)
        accel = self.cfg.line_accel_m_s2 if accel_m_s2 is None else min(self.cfg.line_accel_m_s2, accel_m_s2)
        duration = max(self.cfg.line_min_duration_s, _MJ_SPEED * length / self.cfg.line_speed_m_s,
                       math.sqrt(_MJ_ACCEL * length / accel), 2.0 * float(np.linalg.norm(turn)))
        n = max(1, math.ceil(duration / self.dt - 1e-9))
        s, _, _ = min_jerk(np.arange(1, n + 1) * self.dt, duration)
        load0 = self.load
        load1 = load0 if load_to is None else load_to
        finger = self._finger_m()
        for sk in s:
            T = pin.SE3(T0.rotation @ pin.exp3(float(sk) * turn), (1 - sk) * T0.translation + sk * T_to.translation)
            q_new, e, _ = dls_iterate(self.robot, self._pdata, T, q, self.ik, finger)
            if float(np.linalg.norm(e)) > self.ik.tolerance:
                raise UnreachableTarget(self.phase.value.lower(), f"the straight move does not converge "
                                        f"{float(sk) * length * 1e3:.0f} mm along it", float(np.linalg.norm(e[:3])),
                                        float(np.linalg.norm(e[3:])), q)
            if np.any(q_new < self.robot.arm_lower) or np.any(q_new > self.robot.arm_upper):
                raise UnreachableTarget(self.phase.value.lower(), "the straight move leaves the joint limits",
                                        0.0, 0.0, q_new)
            q = q_new
            yield Command(q, grip, self.phase, load0 + float(sk) * (load1 - load0))
        yield from self._settle(grip)

    def _close(self) -> Generator[Command, None, None]:
        """Close on the object and hold until the fingers settled with both pads pressing; then the object's
        weight as the hand holds it (the believed mass at its measured pose in the hand) is the one to lead for."""
        m = self.machine
        robot, d = self.robot, self.env.sim_data
        q, waited = self.q_ref.copy(), 0.0
        while True:
            yield Command(q, True, self.phase)
            waited += self.dt
            if gripper.is_settled(robot, d, m.finger_settle_speed_m_s) and \
                    bool(np.all(gripper.pad_forces(robot, d) >= m.min_pad_force_n)):
                break
            if waited >= m.close_timeout_s - 1e-9:
                forces = gripper.pad_forces(robot, d)
                raise GraspFailed(f"the pads did not settle on the {robot.scene.object.name} within "
                                  f"{m.close_timeout_s:g} s: pad forces {forces[0]:.1f} / {forces[1]:.1f} N (need "
                                  f"{m.min_pad_force_n:g} N each)")
        T_tcp_object = self._fk(self._q()).actInv(self._object_pose())
        self._payload = (control.arm_model(robot), control.arm_model(robot, Payload.held(robot.scene.object,
                                                                                          T_tcp_object)))

    def _lift(self) -> Generator[Command, None, None]:
        """Straight up to the lift height, its acceleration within the grip's, taking the object's weight on
        along the way; then the object must have risen with the hand, and the arm clear everything by the
        planner's margin (rising further in steps if not)."""
        assert self.configs is not None and self.capacity is not None
        z_object0 = float(self.obs["object_pos"][0][2])
        z_tcp0 = float(self.obs["tcp_pos"][2])
        accel = max(0.1, self.capacity.max_vertical_accel_m_s2)
        yield from self._line(self.configs.targets.lift, True, accel, load_to=1.0)
        rise = float(self.obs["object_pos"][0][2]) - z_object0
        lifted = float(self.obs["tcp_pos"][2]) - z_tcp0
        if abs(rise - lifted) > self.machine.slip_tolerance_m:
            raise GraspFailed(f"the {self.robot.scene.object.name} rose {rise * 1e3:.1f} mm while the tcp rose "
                              f"{lifted * 1e3:.1f} mm")
        T_tcp_object = self._fk(self._q()).actInv(self._object_pose())
        checker = self._carrying(self.machine.planning_margin_m, T_tcp_object)
        risen = 0.0
        while not checker.is_valid(self.q_ref):
            if risen >= MAX_RAISE_M - 1e-9:
                pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(self.q_ref))
                raise PhaseFailed(Phase.LIFT, f"still within {self.machine.planning_margin_m * 1e3:.0f} mm of "
                                              f"something after rising {risen:.2f} m: {pairs}")
            T = self._fk(self.q_ref)
            yield from self._line(pin.SE3(T.rotation, T.translation + np.array([0.0, 0.0, LIFT_STEP_M])), True, accel)
            risen += LIFT_STEP_M

    def _descend_place(self, place: pin.SE3) -> Generator[Command, None, None]:
        """Down to :data:`HOVER_M` above the place; there, move the hand until the held object, as it sits in the
        hand now, is upright above its goal (its planned orientation, within ``place_tolerance_m`` and
        :data:`TILT_TOLERANCE_RAD`: the arm lags on the way down, and a tall object turns a little in the grip on
        the way); then the last :data:`HOVER_M` straight down, and the weight handed to the table (the load taken
        off over :data:`HAND_OVER_S` while the reference goes :data:`PLACE_DROP_M` lower)."""
        assert self.configs is not None and self.capacity is not None
        accel = max(0.1, self.capacity.max_vertical_accel_m_s2)
        scene = self.robot.scene
        R_goal = self.configs.targets.R_world_object_goal
        T = self._fk(self.q_ref)
        hover = pin.SE3(T.rotation, np.array([T.translation[0], T.translation[1], place.translation[2] + HOVER_M]))
        yield from self._line(hover, True, accel)
        want = pin.SE3(R_goal, scene.goal_resting_m(R_goal) + np.array([0.0, 0.0, HOVER_M + PLACE_DROP_M]))
        for _ in range(self.cfg.place_corrections):
            obj = self._object_pose()
            err = want.translation - obj.translation
            tilt = float(np.linalg.norm(pin.log3(obj.rotation.T @ R_goal)))
            if float(np.linalg.norm(err)) <= self.cfg.place_tolerance_m and tilt <= TILT_TOLERANCE_RAD:
                break
            tcp, ref = self._fk(self._q()), self._fk(self.q_ref)
            need = want * obj.actInv(tcp)  # where the tcp must be for the object, held as it is, to be there
            R = need.rotation @ tcp.rotation.T @ ref.rotation  # the reference moved as the hand must move
            yield from self._line(pin.SE3(R, ref.translation + need.translation - tcp.translation), True, accel)
        T = self._fk(self.q_ref)
        yield from self._line(pin.SE3(T.rotation, T.translation - np.array([0.0, 0.0, HOVER_M])), True, accel)
        T = self._fk(self.q_ref)
        down = pin.SE3(T.rotation, T.translation - np.array([0.0, 0.0, PLACE_DROP_M]))
        n = max(1, round(HAND_OVER_S / self.dt))
        q = self.q_ref.copy()
        q_down, _, _ = dls_iterate(self.robot, self._pdata, down, q, self.ik, self._finger_m())
        load0 = self.load
        for k in range(1, n + 1):
            yield Command(q + (k / n) * (q_down - q), True, self.phase, load0 * (1.0 - k / n))

    def _release(self) -> Generator[Command, None, None]:
        """Open and hold until the environment reports success (the script ends when it does), or fail with
        the place's errors once the pads cleared the object and it rests, or when it does not come to rest."""
        m, q = self.machine, self.q_ref.copy()
        waited = 0.0
        limit = m.release_timeout_s + self.cfg.rest_timeout_s
        while True:
            yield Command(q, False, self.phase)
            waited += self.dt
            info = self.info
            if info.get("released") and info.get("object_speed_m_s", math.inf) <= m.object_rest_speed_m_s:
                name = self.robot.scene.object.name
                raise PhaseFailed(Phase.RELEASE, f"the {name} rests {info['place_error_xy_m'] * 1e3:.2f} mm from "
                                                 f"the goal (tolerance {m.place_tolerance_xy_m * 1e3:.2f} mm), "
                                                 f"{info['place_error_z_m'] * 1e3:.2f} mm above its resting height, "
                                                 f"its yaw {info['place_error_yaw_rad']:.3f} rad off")
            if waited >= limit - 1e-9:
                raise PhaseFailed(Phase.RELEASE, f"the {self.robot.scene.object.name} did not come to rest released "
                                                 f"within {limit:g} s (its speed "
                                                 f"{info.get('object_speed_m_s', math.nan) * 1e3:.1f} mm/s)")


# ---------------------------------------------------------------------- running it
_INFO_FLOATS = ("sim_time_s", "place_error_xy_m", "place_error_z_m", "place_error_yaw_rad")
_INFO_STRINGS = ("phase", "failure_phase", "failure_kind", "failure_reason")


class _Recorder:
    """The per-step arrays of one episode."""

    def __init__(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        self.obs = {k: [np.array(v, copy=True)] for k, v in obs.items()}
        self.actions: list[np.ndarray] = []
        self.rewards: list[float] = []
        self.terms: list[bool] = []
        self.truncs: list[bool] = []
        self.infos: dict[str, list[Any]] = {k: [] for k in (*_INFO_STRINGS, *_INFO_FLOATS, "success", "released")}
        self.add_info(RESET_PHASE, info)

    def add_info(self, phase: str, info: dict[str, Any], failure: tuple[str, str, str] = ("", "", "")) -> None:
        out = self.infos
        out["phase"].append(phase)
        for name in _INFO_FLOATS:
            out[name].append(float(info[name]) if info.get(name) is not None else math.nan)
        out["success"].append(bool(info.get("success", False)))
        out["released"].append(bool(info.get("released", False)))
        for name, value in zip(("failure_phase", "failure_kind", "failure_reason"), failure, strict=True):
            out[name].append(value)

    def step(self, action: np.ndarray, obs: dict[str, np.ndarray], reward: float, terminated: bool,
             truncated: bool, phase: str, info: dict[str, Any]) -> None:
        self.actions.append(np.array(action, dtype=np.float32, copy=True))
        for k, v in obs.items():
            self.obs[k].append(np.array(v, copy=True))
        self.rewards.append(float(reward))
        self.terms.append(bool(terminated))
        self.truncs.append(bool(truncated))
        self.add_info(phase, info)

    def fail_last(self, phase: str, kind: str, reason: str) -> None:
        """Mark the last step as the failure (and the end of the episode)."""
        for name, value in zip(("failure_phase", "failure_kind", "failure_reason"), (phase, kind, reason),
                               strict=True):
            self.infos[name][-1] = value
        if not self.terms[-1]:
            self.truncs[-1] = True

    def arrays(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                              dict[str, np.ndarray]]:
        infos = {k: np.array(v, dtype=str if k in _INFO_STRINGS else None) for k, v in self.infos.items()}
        return ({k: np.stack(v) for k, v in self.obs.items()}, np.stack(self.actions).astype(np.float32),
                np.array(self.rewards), np.array(self.terms, dtype=bool), np.array(self.truncs, dtype=bool), infos)


def _low_level(env: gym.Env) -> PickPlaceLowLevelEnv:
    low = env.unwrapped
    if not isinstance(low, PickPlaceLowLevelEnv):
        raise ConfigError("env", type(low).__name__, "must be pickplace/PickPlaceLowLevel-v0")
    return low


def demonstrate(env: gym.Env, seed: int, options: dict[str, Any] | None = None,
                config: ExpertConfig | None = None) -> Demonstration:
    """Reset ``env`` with ``seed`` (and ``options``) and run the expert through it to the end of the episode.

    Args:
        env: A ``pickplace/PickPlaceLowLevel-v0`` environment in joint mode (wrappers allowed; the steps go
            through them).
        seed: The reset seed (also the planner's seed).
        options: Reset options (``{"config": ...}``, see :class:`~pickplace.envs.lowlevel.PickPlaceLowLevelEnv`).
        config: How the expert moves.

    Returns:
        The :class:`Demonstration`; a failure is recorded in it, not raised. An episode that fails before its
        first step (no grasp reachable, nothing to plan) holds one step that commands nothing (the arm holds
        home, the gripper open), labelled with the phase that failed.

    Raises:
        ConfigError: the environment, the seed or the options are invalid.
    """
    low = _low_level(env)
    t0 = time.perf_counter()
    obs, info = env.reset(seed=seed, options=options)
    expert = Expert(low, config, seed)
    expert.obs, expert.info = obs, info
    rec = _Recorder(obs, info)
    script = expert.script()
    failure: tuple[str, str, str] | None = None
    success = False
    while True:
        try:
            command = next(script)
        except StopIteration:  # cannot happen: the release waits for the success that ends the episode
            failure = (expert.phase.value, "ExpertStopped", "the expert's script ended before the episode did")
            break
        except ConfigError:
            raise
        except PickPlaceError as exc:
            phase = exc.phase.value if isinstance(exc, PhaseFailed) else expert.phase.value
            reason = exc.reason if isinstance(exc, PhaseFailed) else str(exc)
            failure = (phase, type(exc).__name__, reason)
            break
        action = expert.action(command)
        obs, reward, terminated, truncated, info = env.step(action)
        expert.obs, expert.info = obs, info
        rec.step(action, obs, float(reward), terminated, truncated, command.phase.value, info)
        if terminated or truncated:
            success = bool(info.get("success"))
            if info.get("failure_kind"):
                failure = (command.phase.value, str(info["failure_kind"]), str(info["failure_reason"]))
            elif not success:
                failure = (command.phase.value, TIME_LIMIT, f"the episode reached the environment's max_steps "
                                                            f"({low.max_steps}) in {command.phase.value}")
            break
    script.close()
    if failure is not None and not rec.actions:  # failed before moving: one step that commands nothing
        hold = np.array([0.0] * 6 + [-1.0], dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(hold)
        rec.step(hold, obs, float(reward), terminated, truncated, failure[0], info)
    if failure is not None:
        rec.fail_last(*failure)
        log.info("demonstration (seed %d) failed in %s: %s: %s", seed, *failure)
    observations, actions, rewards, terms, truncs, infos = rec.arrays()
    configs = expert.configs
    return Demonstration(
        seed=int(seed), options=options, observations=observations, actions=actions, rewards=rewards,
        terminations=terms, truncations=truncs, infos=infos, success=success and failure is None,
        failure_phase=failure[0] if failure else None, failure_kind=failure[1] if failure else None,
        failure_reason=failure[2] if failure else None,
        grasp_approach=configs.chosen.approach.value if configs is not None else None,
        plan_time_s=expert.plan_time_s, wall_time_s=time.perf_counter() - t0)


def replay(env: gym.Env, seed: int, actions: np.ndarray, options: dict[str, Any] | None = None
           ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Reset ``env`` with ``seed`` and ``options`` and step it with ``actions`` (N, 7), stopping early if the
    environment ends the episode.

    Returns:
        The observations (each key (M + 1, ...)), rewards (M,), terminations (M,), truncations (M,) of the M
        steps run, and the last step's ``info``.
    """
    _low_level(env)
    obs, info = env.reset(seed=seed, options=options)
    observations = {k: [np.array(v, copy=True)] for k, v in obs.items()}
    rewards, terms, truncs = [], [], []
    for a in np.asarray(actions, dtype=np.float32):
        obs, reward, terminated, truncated, info = env.step(a)
        for k, v in obs.items():
            observations[k].append(np.array(v, copy=True))
        rewards.append(float(reward))
        terms.append(bool(terminated))
        truncs.append(bool(truncated))
        if terminated or truncated:
            break
    return ({k: np.stack(v) for k, v in observations.items()}, np.array(rewards), np.array(terms, dtype=bool),
            np.array(truncs, dtype=bool), info)


__all__ = ["RESET_PHASE", "TIME_LIMIT", "Command", "Demonstration", "Expert", "ExpertConfig", "demonstrate",
           "replay"]
