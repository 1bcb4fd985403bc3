"""The low-level environment ``pickplace/PickPlaceLowLevel-v0``: an action is a tcp (or joint) target and a gripper
command, at a control rate of 20 to 50 Hz, over the project's impedance controllers and the 1 kHz physics.

Each step moves the target by the action (a bounded increment, clipped to a box over the table and to a few
increments from where the arm is), then runs ``1 / rate`` s of physics: the reference ramps linearly from the old
target to the new one and the controller tracks it every control period of the profile's loop
(:class:`~pickplace.motion.loop.ControlLoop`: every 1 ms physics step in the ideal profile; 500 Hz with latency and
encoders in the realistic one), with gravity compensation:

* ``action_mode="cartesian"``: Cartesian impedance of the tcp
  (:func:`~pickplace.motion.control.cartesian_impedance`), its orientation the one at home turned about the
  vertical by the target's yaw;
* ``action_mode="joint"``: joint impedance with inverse-dynamics feedforward
  (:func:`~pickplace.motion.control.joint_impedance`).

Both use the config's gains (:class:`~pickplace.motion.control.ControlConfig`; the realistic profile's are
:meth:`ControlConfig.realistic`), without the integral action of the project's own motions and without payload
compensation (the policy decides when it holds something). The gripper command (close if the last action entry is
> 0) drives the gripper's own servo (:func:`pickplace.robot.gripper.command`).

The per-step monitor of the project (:class:`~pickplace.task.monitor.StepMonitor`) runs after every physics step:
the arm or the hand touching the table, the floor, the obstacle or itself, or the arm (not the hand) touching the
object, ends the episode (``terminate_on_contact``); so does the object falling off the table (its lowest point
1 cm below the top, the test of the skill's recovery) and a singular Cartesian controller.

Reward: 1.0 when the object rests at its goal within the machine's place tolerances (``place_tolerance_xy_m``,
``_z_m``, ``_yaw_rad``), released (no pad touches it) and at rest (``object_rest_speed_m_s``); else 0. With
``shaped_reward=True`` every step also gives ``-0.1 (|tcp - object| + |object - goal|)`` (m) and a failure -1.
``terminated``: success or a failure; ``truncated``: ``max_steps`` steps. Success and the reward are measured on the
simulator's truth (as the project's results are); the observation's object pose is what the robot knows (its
observer: the truth in the ideal profile, the depth camera's fit in the realistic one, re-taken every
``observe_every`` steps: a fit of three 848 x 480 frames costs about 0.5 s of wall time).

``reset(seed=..., options={"config": ...})`` runs that episode with another configuration than the constructor's:
an :class:`~pickplace.task.episode.EpisodeConfig`, or its ``to_dict()`` (a mapping, or that mapping as a JSON
string: what a dataset stores with the episode, :mod:`pickplace.eval.dataset`), in the environment's profile. The
model faults of a configuration (``[faults]`` ``pad_friction_scale``, ``pad_softness_scale``, ``true_mass_scale``,
``tcp_offset_error_m``, ``tcp_yaw_error_rad``: :func:`~pickplace.task.faults.apply_model_faults`) are applied to the
episode's model; the timed ones (pushes, the intruder, joint noise) are not injected here.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
import pinocchio as pin
from gymnasium import spaces

from pickplace.envs.common import (
    RenderedEnv,
    Views,
    check_bool,
    check_objects,
    check_size,
    draw_scene,
    image_spaces,
    object_observation,
    object_spaces,
    open_face_y_m,
    robot_observation,
    robot_spaces,
    start_pose,
)
from pickplace.envs.skill import _base_config
from pickplace.errors import ConfigError, PickPlaceError
from pickplace.grasping.targets import yaw_error
from pickplace.motion import control
from pickplace.motion.loop import IDEAL, Law
from pickplace.perception.pose import ObjectNotSeen
from pickplace.robot import gripper
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import Robot, build
from pickplace.task.episode import EpisodeConfig
from pickplace.task.faults import apply_model_faults
from pickplace.task.monitor import StepMonitor
from pickplace.task.observe import Observer, SimulatorObserver
from pickplace.world.checks import check_int, check_range

log = logging.getLogger(__name__)

#: The control rates allowed (Hz).
RATE_RANGE_HZ = (20.0, 50.0)
#: The object counts as fallen off the table when its lowest point is this far below the table top (m), as in the
#: skill's recovery.
OFF_TABLE_M = 0.01
#: Highest tcp target above the table top (m): 0.4 m keeps the hand top-down well inside the UR5e's reach over the
#: table (its home tcp is 0.335 m above it; at 0.45 m above x = 0.35 m the arm is nearly stretched).
MAX_TCP_HEIGHT_M = 0.4
#: The target may lead the arm by at most this many increments (a blocked arm does not wind the target up).
MAX_LEAD_STEPS = 2.0
#: The failure phase named in ``info`` for the low-level environment.
STEP_PHASE = "STEP"


class _Stop(Exception):
    """The controller cannot go on (a singular Cartesian Jacobian)."""


class PickPlaceLowLevelEnv(RenderedEnv, gym.Env):
    """Pick and place one object by low-level commands: tcp (or joint) increments and a gripper command.

    Action (``Box(-1, 1)``): ``action_mode="cartesian"``: ``(dx, dy, dz, dyaw, grip)``, the tcp target moved by
    ``max_tcp_step_m`` and turned about the vertical by ``max_yaw_step_rad`` per unit; ``"joint"``:
    ``(dq1, ..., dq6, grip)``, each joint target moved by ``max_joint_step_rad`` per unit. ``grip > 0`` closes the
    gripper, otherwise it opens.

    Observation (``Dict``): ``joint_pos`` (6,) rad, ``joint_vel`` (6,) rad/s, ``gripper_opening_m`` (1,),
    ``tcp_pos`` (3,) m, ``tcp_quat`` (4,); ``object_pos`` (1, 3) m, ``object_quat`` (1, 4), ``object_mask`` (1,),
    ``goal_pos`` (1, 3) m (where the object's origin rests at the goal), ``goal_yaw`` (1,) rad; ``target_pos`` (3,)
    m and ``target_yaw`` (1,) rad (cartesian) or ``target_q`` (6,) rad (joint): the controller's current target;
    with ``images``: ``rgb`` (H, W, 3) and ``depth`` (H, W) m.

    Args:
        render_mode: None or ``"rgb_array"``.
        config: The base configuration (scene, tolerances, gains, profile); default: the default scene.
        profile: ``ideal`` or ``realistic``.
        action_mode: ``cartesian`` or ``joint``.
        control_rate_hz: Steps per simulated second, 20 to 50 Hz, a whole number of the loop's control periods.
        max_steps: Steps before the episode is truncated (2 to 100000).
        randomize: Draw the object's start and goal around the config's from the reset seed.
        objects: Library objects to draw from at each reset (None: the config's).
        max_tcp_step_m: Largest tcp increment per step and axis (m).
        max_yaw_step_rad: Largest yaw increment per step (rad).
        max_joint_step_rad: Largest joint increment per step (rad).
        min_tcp_height_m: Lowest tcp target above the table top (m): the pads (10 mm below the tcp) stay clear of it.
        terminate_on_contact: End the episode on a contact the project's monitor forbids (else they are allowed).
        observe_every: Realistic profile: steps between the camera's fits of the object (1 to 1000).
        shaped_reward: Add the shaped terms (module docstring).
        images: Add ``rgb`` and ``depth``; image_size_px, render_size_px: their sizes (px).

    Raises:
        ConfigError: an argument is invalid (the message names it, its value and what is allowed).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, render_mode: str | None = None, *, config: EpisodeConfig | None = None,
                 profile: str = "ideal", action_mode: str = "cartesian", control_rate_hz: float = 20.0,
                 max_steps: int = 400, randomize: bool = True, objects: tuple[str, ...] | None = None,
                 max_tcp_step_m: float = 0.02, max_yaw_step_rad: float = 0.1, max_joint_step_rad: float = 0.05,
                 min_tcp_height_m: float = 0.012, terminate_on_contact: bool = True, observe_every: int = 10,
                 shaped_reward: bool = False, images: bool = False, image_size_px: tuple[int, int] = (128, 96),
                 render_size_px: tuple[int, int] = (640, 480)) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError("render_mode", render_mode, "must be None or 'rgb_array'")
        self.render_mode = render_mode
        self.config = _base_config(config, profile)
        if self.config.task is not None:
            raise ConfigError("config.task", self.config.task.kind, "the low-level environment has one object")
        if action_mode not in ("cartesian", "joint"):
            raise ConfigError("action_mode", action_mode, "must be 'cartesian' or 'joint'")
        self.action_mode = action_mode
        self.control_rate_hz = check_range("control_rate_hz", control_rate_hz, *RATE_RANGE_HZ, unit="Hz")
        self.steps_per_action = self._physics_steps(self.control_rate_hz)
        self.max_steps = check_int("max_steps", max_steps, 2, 100_000)
        self.randomize = check_bool("randomize", randomize)
        self.objects = check_objects("objects", objects)
        self.max_tcp_step_m = check_range("max_tcp_step_m", max_tcp_step_m, 0.0, 0.1, lo_open=True, unit="m")
        self.max_yaw_step_rad = check_range("max_yaw_step_rad", max_yaw_step_rad, 0.0, 0.5, lo_open=True, unit="rad")
        self.max_joint_step_rad = check_range("max_joint_step_rad", max_joint_step_rad, 0.0, 0.3, lo_open=True,
                                              unit="rad")
        self.min_tcp_height_m = check_range("min_tcp_height_m", min_tcp_height_m, 0.0, 0.3, unit="m")
        self.terminate_on_contact = check_bool("terminate_on_contact", terminate_on_contact)
        self.observe_every = check_int("observe_every", observe_every, 1, 1000)
        self.shaped_reward = check_bool("shaped_reward", shaped_reward)
        self.images = check_bool("images", images)
        self.image_size_px = check_size("image_size_px", image_size_px)
        self.render_size_px = check_size("render_size_px", render_size_px)
        self.metadata = {**self.metadata, "render_fps": self.control_rate_hz}  # a frame per step
        n = 5 if action_mode == "cartesian" else 7
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        parts: dict[str, spaces.Space[Any]] = {**robot_spaces(), **object_spaces(1)}
        if action_mode == "cartesian":
            parts["target_pos"] = spaces.Box(-5.0, 5.0, shape=(3,), dtype=np.float32)
            parts["target_yaw"] = spaces.Box(-math.pi, math.pi, shape=(1,), dtype=np.float32)
        else:
            parts["target_q"] = spaces.Box(-2 * math.pi - 0.5, 2 * math.pi + 0.5, shape=(6,), dtype=np.float32)
        if self.images:
            parts.update(image_spaces(*self.image_size_px))
        self.observation_space = spaces.Dict(parts)
        self._robot: Robot | None = None
        self._observer: Observer | None = None
        self._views: Views | None = None
        self._ended = False

    def _physics_steps(self, rate_hz: float, config: EpisodeConfig | None = None) -> int:
        """Physics steps per action; :class:`ConfigError` unless 1 / rate is a whole number of control periods."""
        config = config if config is not None else self.config
        dt = config.scene.timestep_s
        period = config.profile.loop.steps(dt)[0]
        n = round(1.0 / (rate_hz * dt))
        allowed = [r for r in range(int(RATE_RANGE_HZ[0]), int(RATE_RANGE_HZ[1]) + 1)
                   if abs(round(1.0 / (r * dt)) * r * dt - 1.0) < 1e-9 and round(1.0 / (r * dt)) % period == 0]
        if abs(n * rate_hz * dt - 1.0) > 1e-9 or n % period:
            raise ConfigError("control_rate_hz", rate_hz, f"must make 1/rate a whole number of control periods "
                                                         f"({period} x {dt:g} s physics steps); allowed: "
                                                         f"{', '.join(str(r) for r in allowed)} Hz")
        return n

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """A new scene from ``seed``: the arm at home, the gripper open, the object at its (drawn) start.

        Args:
            seed: Seed of the episode (the scene's draw, the model error and the sensors' noise).
            options: None, or ``{"config": ...}``: this episode's configuration (module docstring).

        Raises:
            ConfigError: ``options`` is invalid (the message names the key).
        """
        config = self._options_config(options)  # before anything changes: a bad option leaves the episode as it is
        super().reset(seed=seed)
        self._release()
        rng = self.np_random
        self._seed = int(rng.integers(0, 2**31 - 1))
        base = config.scene
        scene = draw_scene(base, rng, self.objects) if self.randomize else base
        cfg = dataclasses.replace(config, scene=scene)
        self._cfg = cfg
        robot = cfg.profile.plant(build(scene), np.random.default_rng([self._seed, 3]))
        apply_model_faults(robot, cfg.faults)
        d = robot.make_data()
        self._robot, self._d = robot, d
        if cfg.profile.realistic:
            self._observer = cfg.profile.observer(robot, d, np.random.default_rng([self._seed, 2]))
        else:
            self._observer = SimulatorObserver(robot, d)
        self._truth = SimulatorObserver(robot, d)  # the referee's (success, reward): never in the observation
        self._loop = cfg.profile.control_loop(np.random.default_rng([self._seed, 4]))
        self._arm = control.arm_model(robot)
        self._open_face_m = open_face_y_m(robot)
        monitor = StepMonitor(robot, None, cfg.machine.slip_tolerance_m, None, self._observer)
        monitor.allow_hand_object = True  # the policy grasps, pushes and sets down as it likes
        monitor.allow_object_table = True
        monitor.tolerate_contacts = not self.terminate_on_contact
        monitor.phase = STEP_PHASE
        self._monitor = monitor
        h = robot.handles
        self._R0 = d.site_xmat[h.tcp_site].reshape(3, 3).copy()
        self._p_target = d.site_xpos[h.tcp_site].copy()
        self._yaw_target = 0.0
        self._q_target = d.qpos[h.arm_qpos].copy()
        c, half = np.asarray(scene.table_center_xy_m), np.asarray(scene.table_size_xy_m) / 2
        self._lo = np.array([*(c - half), scene.table_height_m + self.min_tcp_height_m])
        self._hi = np.array([*(c + half), scene.table_height_m + MAX_TCP_HEIGHT_M])
        self._steps, self._ended, self._saturated = 0, False, 0
        self._belief = start_pose(scene)  # where the task says the object is, until the robot has seen it
        self._belief = self._look()
        if self.images or self.render_mode == "rgb_array":
            self._views = Views(robot, self.render_size_px, self.image_size_px)
        return self._observation(), self._info({})

    def _options_config(self, options: dict[str, Any] | None) -> EpisodeConfig:
        """The configuration of the next episode: ``options["config"]`` if given, else the constructor's."""
        if options is None:
            return self.config
        if not isinstance(options, Mapping) or set(options) - {"config"}:
            raise ConfigError("options", options, "must be None or {'config': EpisodeConfig, mapping or JSON}")
        value = options.get("config")
        if value is None:
            return self.config
        if isinstance(value, str):
            try:
                value = json.loads(value)
            except ValueError as exc:
                raise ConfigError("options.config", value[:80], f"is not valid JSON: {exc}") from None
        config = value if isinstance(value, EpisodeConfig) else EpisodeConfig.from_dict(value)
        if config.task is not None:
            raise ConfigError("options.config.task", config.task.kind, "the low-level environment has one object")
        if config.profile.name != self.config.profile.name:
            raise ConfigError("options.config.profile", config.profile.name,
                              f"must be the environment's profile ({self.config.profile.name!r})")
        try:
            steps = self._physics_steps(self.control_rate_hz, config)
        except ConfigError:
            steps = -1
        if steps != self.steps_per_action:
            raise ConfigError("options.config.scene.timestep_s", config.scene.timestep_s,
                              f"must be the environment's ({self.config.scene.timestep_s:g} s)")
        return config

    @property
    def robot(self) -> Robot:
        """The models of the current episode (its scene, as built and planted by the profile)."""
        if self._robot is None:
            raise ConfigError("robot", None, "call reset() first")
        return self._robot

    @property
    def episode_config(self) -> EpisodeConfig:
        """The configuration of the current episode (the drawn scene in it)."""
        if self._robot is None:
            raise ConfigError("episode_config", None, "call reset() first")
        return self._cfg

    @property
    def sim_data(self) -> mujoco.MjData:
        """The simulation state of the current episode, to read (the expert, :mod:`pickplace.envs.expert`, plans
        in it and reads the pads' forces from it); writing to it changes the episode."""
        if self._robot is None:
            raise ConfigError("sim_data", None, "call reset() first")
        return self._d

    def _look(self) -> pin.SE3:
        """The object's pose as the robot knows it now: its observer's fit (the camera may not see it: the last)."""
        assert self._observer is not None
        try:
            return self._observer.observe()
        except ObjectNotSeen as exc:
            log.debug("the camera does not see the object (%s): the last estimate stays", exc)
            return self._belief

    # ------------------------------------------------------------------ step
    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Move the target by the action and run ``1 / control_rate_hz`` s of control and physics."""
        if self._robot is None:
            raise ConfigError("step", action, "call reset() before step()")
        if self._ended:
            raise ConfigError("step", action, "the episode has ended (terminated or truncated): call reset()")
        n = self.action_space.shape[0]
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            a = np.full(n + 1, np.nan)
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            names = "(dx, dy, dz, dyaw, grip)" if self.action_mode == "cartesian" else "(dq1, ..., dq6, grip)"
            raise ConfigError("action", action, f"must be {n} finite numbers {names}, each in [-1, 1]")
        a = np.clip(a, -1.0, 1.0)
        robot, d = self._robot, self._d
        self._steps += 1
        gripper.command(robot, d, bool(a[-1] > 0.0))
        failure: dict[str, Any] = {}
        try:
            if self.action_mode == "cartesian":
                self._cartesian(a)
            else:
                self._joint(a)
        except PickPlaceError as exc:
            failure = {"failure_phase": STEP_PHASE, "failure_kind": type(exc).__name__, "failure_reason": str(exc)}
        except _Stop as exc:
            failure = {"failure_phase": STEP_PHASE, "failure_kind": "ControlError", "failure_reason": str(exc)}
        mujoco.mj_kinematics(robot.mj, d)  # positions of the state the last physics step reached
        measured = self._measure()
        if not failure and measured["off_table"]:
            failure = {"failure_phase": STEP_PHASE, "failure_kind": "ObjectOffTable",
                       "failure_reason": f"the {robot.scene.object.name} fell off the table: its lowest point is "
                                         f"{-measured['lowest_above_table_m'] * 1e3:.0f} mm below the table top"}
        if self._observer is not None and self._cfg.profile.realistic:
            if self._steps % self.observe_every == 0:
                self._belief = self._look()
        else:
            self._belief = self._truth.object_pose()
        success = not failure and measured["success"]
        terminated = success or bool(failure)
        truncated = not terminated and self._steps >= self.max_steps
        self._ended = terminated or truncated
        reward = 1.0 if success else 0.0
        if self.shaped_reward:
            reward -= 0.1 * (measured["tcp_object_m"] + measured["object_goal_m"])
            reward -= 1.0 if failure else 0.0
        outcome = {"success": success, "failure_phase": None, "failure_kind": None, "failure_reason": None}
        outcome.update(failure)
        outcome.update({k: v for k, v in measured.items() if k != "success"})
        return self._observation(), float(reward), terminated, truncated, self._info(outcome)

    def _cartesian(self, a: np.ndarray) -> None:
        robot, d, cfg = self._robot, self._d, self._cfg.control
        h = robot.handles
        p_now = d.site_xpos[h.tcp_site].copy()
        lead = MAX_LEAD_STEPS * self.max_tcp_step_m
        p_from = self._p_target
        p_to = np.clip(p_from + a[:3] * self.max_tcp_step_m, self._lo, self._hi)
        p_to = p_now + np.clip(p_to - p_now, -lead, lead)
        yaw_from = self._yaw_target
        yaw_to = float(np.clip(yaw_from + a[3] * self.max_yaw_step_rad, -math.pi, math.pi))
        self._p_target, self._yaw_target = p_to, yaw_to
        n = self.steps_per_action
        T = n * float(robot.mj.opt.timestep)
        v_ref = (p_to - p_from) / T
        zero3 = np.zeros(3)
        arm, R0, q_post = self._arm, self._R0, robot.home_q
        stiffness, zeta = cfg.cartesian_stiffness, cfg.cartesian_damping_ratio
        post_kp, post_kd = cfg.posture_kp_nm_rad, cfg.posture_kd
        finger = int(h.finger_qpos[0])
        limits = arm.torque_limits_nm

        def law(k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray | None:
            if k >= n:
                return None
            s = min(1.0, (k + 1) / n)
            try:
                cmd = control.cartesian_impedance(arm, q, qd, p_from + s * (p_to - p_from), v_ref, zero3,
                                                  rot_z(yaw_from + s * (yaw_to - yaw_from)) @ R0, stiffness, zeta,
                                                  q_post, post_kp, post_kd, finger_m=float(d.qpos[finger]),
                                                  modal_damping=cfg.cartesian_modal_damping,
                                                  bandwidth_rad_s=cfg.cartesian_bandwidth_rad_s)
            except np.linalg.LinAlgError as exc:
                raise _Stop(f"singular tcp Jacobian at q = {np.round(q, 4).tolist()} rad") from exc
            tau = cmd.tau
            if control.saturate(tau, limits):
                self._saturated += 1
            return tau

        self._run_loop(law)

    def _joint(self, a: np.ndarray) -> None:
        robot, d, cfg = self._robot, self._d, self._cfg.control
        h = robot.handles
        q_now = d.qpos[h.arm_qpos].copy()
        lead = MAX_LEAD_STEPS * self.max_joint_step_rad
        q_from = self._q_target
        q_to = np.clip(q_from + a[:6] * self.max_joint_step_rad, robot.arm_lower, robot.arm_upper)
        q_to = q_now + np.clip(q_to - q_now, -lead, lead)
        self._q_target = q_to
        n = self.steps_per_action
        qd_ref = (q_to - q_from) / (n * float(robot.mj.opt.timestep))
        zero6 = np.zeros(6)
        arm, kp, kd = self._arm, cfg.joint_kp, cfg.joint_kd
        finger = int(h.finger_qpos[0])
        limits = arm.torque_limits_nm

        def law(k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray | None:
            if k >= n:
                return None
            s = min(1.0, (k + 1) / n)
            tau = control.joint_impedance(arm, q, qd, q_from + s * (q_to - q_from), qd_ref, zero6, kp, kd,
                                          feedforward=cfg.feedforward, finger_m=float(d.qpos[finger]),
                                          bandwidth_rad_s=cfg.joint_bandwidth_rad_s,
                                          damping_ratio=cfg.joint_damping_ratio)
            if control.saturate(tau, limits):
                self._saturated += 1
            return tau

        self._run_loop(law)

    def _run_loop(self, law: Law) -> None:
        loop = self._loop if self._loop is not None else IDEAL
        loop.run(self._robot, self._d, law, self._monitor)

    # ------------------------------------------------------------------ measurements (the simulator's truth)
    def _measure(self) -> dict[str, Any]:
        robot, d, m = self._robot, self._d, self._cfg.machine
        scene = robot.scene
        T = self._truth.object_pose()
        geo = scene.object.geometry()
        lowest = float(np.min(geo.vertices @ T.rotation[2]) + T.translation[2])
        R_goal = rot_z(scene.goal_yaw_rad)
        err = T.translation - scene.goal_pos_m
        xy, z = float(np.hypot(err[0], err[1])), float(err[2])
        yaw = yaw_error(T.rotation, R_goal, scene.object.yaw_period_rad)
        speed = float(np.linalg.norm(self._truth.object_velocity()[:3]))
        released = not bool(np.any(gripper.pad_forces(robot, d) > 0.0))
        success = (xy <= m.place_tolerance_xy_m and abs(z) <= m.place_tolerance_z_m
                   and abs(yaw) <= m.place_tolerance_yaw_rad and released and speed <= m.object_rest_speed_m_s)
        tcp = d.site_xpos[robot.handles.tcp_site]
        return {"success": success, "place_error_xy_m": xy, "place_error_z_m": z, "place_error_yaw_rad": yaw,
                "object_speed_m_s": speed, "released": released,
                "lowest_above_table_m": lowest - scene.table_height_m,
                "off_table": lowest < scene.table_height_m - OFF_TABLE_M,
                "tcp_object_m": float(np.linalg.norm(tcp - T.translation)),
                "object_goal_m": float(np.linalg.norm(err))}

    # ------------------------------------------------------------------ observations
    def _observation(self) -> dict[str, np.ndarray]:
        robot, d = self._robot, self._d
        scene = robot.scene
        obs = {**robot_observation(robot, d, self._open_face_m, self._cfg.profile.loop.encoder_resolution_rad),
               **object_observation([self._belief], [(scene.goal_pos_m, scene.goal_yaw_rad)], 1)}
        if self.action_mode == "cartesian":
            obs["target_pos"] = np.clip(self._p_target, -5.0, 5.0).astype(np.float32)
            obs["target_yaw"] = np.array([self._yaw_target], dtype=np.float32)
        else:
            obs["target_q"] = self._q_target.astype(np.float32)
        if self.images:
            assert self._views is not None
            obs.update(self._views.rgbd(d))
        return obs

    def _info(self, outcome: dict[str, Any]) -> dict[str, Any]:
        info = {"sim_time_s": self._monitor.t, "steps": self._steps, "seed": self._seed,
                "object": self._robot.scene.object.name, "torque_saturation_steps": self._saturated}
        info.update(outcome)
        return info


__all__ = ["RATE_RANGE_HZ", "PickPlaceLowLevelEnv"]
