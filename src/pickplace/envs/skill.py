"""Skill-level environments: an action chooses *what* to do, the project's stack plans and runs the whole motion.

:class:`PickPlaceEnv` (``pickplace/PickPlace-v0``): the default pick-and-place scene (one object, drawn around the
config's from the reset seed). An action chooses one of the object's grasp candidates, ranked as the skill ranks
them (:func:`~pickplace.grasping.configurations.candidate_grasps`), and optionally one of a small set of place
poses. One step runs a whole :class:`~pickplace.task.skill.PickPlaceSkill` with that grasp: IDLE to DONE or FAILED,
every phase's check, its recoveries (a recovery after a drop chooses its own grasp again) and the settling after the
release. A choice whose pick cannot start (no IK, no collision-free path to the grasp, the pads cannot hold it:
found before the arm moves) changes nothing but the mask, which drops that grasp: the next step can choose another.

:class:`TaskEnv` (``pickplace/Place-v0``, ``pickplace/Stack-v0``, ``pickplace/Clear-v0``): a task with several
objects (:mod:`pickplace.task.tasks`). One step is one pick and place, of the object the action names (its goal the
task planner's: its own goal or a buffer spot for ``place``, the tower's next level for ``stack``, a free spot in
the bin for ``clear``), or, with the last action, of the object the task planner takes next in its order. The step
runs as :func:`~pickplace.task.task_episode.run_task` runs each pick: the other objects are obstacles, another bin
or buffer spot is tried when one does not fit, knocked objects are checked for and repaired, a failed pick whose
object rests where it can be taken again leaves the task going.

Rewards: sparse by default, 1.0 on success (the object at its goal within the machine's place tolerances 1 s after
the release, the arm home; for a task every object where the task wants it), else 0. With ``shaped_reward=True``:
the success 1.0 less 0.01 per simulated second of the pick and place; -0.5 for a pick and place that moved the arm
and failed; -0.1 for a choice that could not start or is masked; for a task 1/N per object newly done instead of the
1.0 (N objects). ``terminated``: success, or a failure after the arm moved (a task goes on after a failed pick whose
object can be taken again). ``truncated``: ``max_steps`` choices.

Observations (:mod:`pickplace.envs.common`): the robot's own state, and the objects' poses as the robot knows them
(its :class:`~pickplace.task.observe.Observer`: the simulator's truth in the ideal profile, the depth camera's
estimate in the realistic one), their goals, and the action mask. Tasks run in the ideal profile only (as
:func:`~pickplace.task.task_episode.run_task`). ``info`` holds the outcome: ``success``, ``started``,
``failure_phase``, ``failure_kind``, ``failure_reason`` and the measured place errors (on the simulator's truth, a
measurement that the robot never uses).
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
import pinocchio as pin
from gymnasium import spaces

from pickplace.envs.common import (
    POSITION_LIMIT_M,
    RenderedEnv,
    Views,
    box,
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
)
from pickplace.errors import CannotHold, ConfigError
from pickplace.grasping.configurations import candidate_grasps, feasible_grasps, holdable
from pickplace.grasping.synthesis import ApproachKind, GraspCandidate
from pickplace.robot.model import Robot, build
from pickplace.task.arm import Arm
from pickplace.task.episode import EpisodeConfig
from pickplace.task.faults import apply_model_faults
from pickplace.task.observe import Observer, SimulatorObserver
from pickplace.task.phases import MachineOutcome, Phase
from pickplace.task.skill import PickPlaceSkill
from pickplace.task.task_episode import SPOT_LABELS, SPOTS_TRIED, _did_not_start, _Measure, _TaskRun, _view
from pickplace.task.tasks import TaskConfig, TaskKind, TaskPlanner, TaskStuck, random_task_scene
from pickplace.world.checks import check_int, check_vector

log = logging.getLogger(__name__)

#: Features of each grasp candidate in the ``grasps`` observation (G, 9): whether it exists, its approach (top,
#: tilted, side: one-hot), its tilt from straight down (rad), the object's width between the pads (m), its
#: force-closure margin, the centre of mass's distance from the grip axis (m), and the pads' support (0-1).
GRASP_FEATURES = ("exists", "top", "tilted", "side", "tilt_rad", "width_m", "margin", "com_offset_m", "support")
#: Phases in which the arm has not moved yet: a pick that failed in them changed nothing.
_NOT_MOVED = frozenset({Phase.IDLE.value, Phase.PLAN_APPROACH.value})


def _base_config(config: EpisodeConfig | None, profile: str) -> EpisodeConfig:
    config = config if config is not None else EpisodeConfig()
    if not isinstance(config, EpisodeConfig):
        raise ConfigError("config", config, "must be a pickplace.task.episode.EpisodeConfig or None")
    if not isinstance(profile, str) or profile not in ("ideal", "realistic"):
        raise ConfigError("profile", profile, "must be 'ideal' or 'realistic'")
    return config if config.profile.name == profile else config.with_profile(profile)


def _grasp_features(grasps: list[GraspCandidate], g: int) -> np.ndarray:
    out = np.zeros((g, len(GRASP_FEATURES)), dtype=np.float32)
    for i, c in enumerate(grasps[:g]):
        kind = [c.approach is ApproachKind.TOP, c.approach is ApproachKind.TILTED, c.approach is ApproachKind.SIDE]
        out[i] = [1.0, *kind, c.tilt_rad, c.width_m, c.margin, c.com_offset_m, c.support]
    return np.clip(out, -10.0, 10.0)


def _nothing_moved(out: MachineOutcome) -> bool:
    """Whether a pick and place ended before the arm moved (only IDLE and PLAN_APPROACH ran)."""
    return all(phase in _NOT_MOVED for phase, *_ in out.timeline)


class _ChosenGrasp(PickPlaceSkill):
    """The pick-and-place skill with its first grasp chosen from outside: its IDLE tries that grasp only (the
    candidates are identified by identity, as the skill's own list of dropped grasps does). Later grasp searches (a
    re-aim, a recovery after a drop) choose as the skill does."""

    def __init__(self, arm: Arm, env_config: EpisodeConfig, grasp: GraspCandidate) -> None:
        super().__init__(arm, env_config.ik)
        self._only: GraspCandidate | None = grasp

    def _solve_grasps(self, T_world_object: pin.SE3) -> Any:
        if self._only is None:
            return super()._solve_grasps(T_world_object)
        only, self._only = self._only, None
        saved = self._dropped
        self._dropped = [g for g in candidate_grasps(self.robot, T_world_object) if g is not only]
        try:
            return super()._solve_grasps(T_world_object)
        finally:
            self._dropped = saved


class PickPlaceEnv(RenderedEnv, gym.Env):
    """One object to pick and place; an action chooses the grasp (and optionally the place pose).

    Action: ``Discrete(max_grasps)``, the index of a grasp in the ranked candidate list of the object where the
    robot sees it (0: the best ranked; indices past the list, or masked, are refused without moving: see
    ``info["action_mask"]`` and :meth:`action_masks`); with ``place_poses``, ``MultiDiscrete([max_grasps, P])``:
    the grasp and the place pose.

    Observation (``Dict``): ``joint_pos`` (6,) rad, ``joint_vel`` (6,) rad/s, ``gripper_opening_m`` (1,),
    ``tcp_pos`` (3,) m, ``tcp_quat`` (4,); ``object_pos`` (1, 3) m, ``object_quat`` (1, 4), ``object_mask`` (1,),
    ``goal_pos`` (1, 3) m (where the object's origin rests at the goal), ``goal_yaw`` (1,) rad; ``grasps``
    (max_grasps, 9) (:data:`GRASP_FEATURES`), ``action_mask`` (max_grasps,); with ``place_poses``: ``place_poses``
    (P, 4) (x, y, z of the resting origin (m), yaw (rad)); with ``images``: ``rgb`` (H, W, 3) and ``depth`` (H, W) m.

    Args:
        render_mode: None or ``"rgb_array"`` (:meth:`render` returns a frame of the scene's overview camera).
        config: The base configuration (scene, tolerances, gains, planner, profile); default: the default scene.
        profile: ``ideal`` or ``realistic`` (the robot senses the object with its depth camera).
        randomize: Draw the object's start (±5 cm, ±45°) and goal (±5 cm) around the config's from the reset seed;
            False: the config's scene every reset.
        objects: Library objects to draw the object from at each reset (None: the config's object).
        max_grasps: Length of the ranked grasp list the action indexes (1 to 128).
        mask_unreachable: Mask the grasps whose pads cannot hold the object or whose pregrasp and approach do not
            solve collision free where the object is seen (checked at reset, 0.1 to 0.5 s); False: mask only the
            indices past the list. The place end of a grasp is checked when the step runs it.
        place_poses: None, or a few place poses ``(x, y, yaw)`` (m, m, rad) the action chooses among: the step's
            goal is the chosen one (and the observation's ``goal_pos`` once a pick and place with it has started;
            the drawn goal of the scene before).
        max_steps: Choices before the episode is truncated (2 to 100).
        shaped_reward: The shaped reward (module docstring) instead of the sparse one.
        images: Add ``rgb`` and ``depth`` to the observation.
        image_size_px: Their (width, height) (px).
        render_size_px: :meth:`render`'s (width, height) (px).

    Raises:
        ConfigError: an argument is invalid (the message names it, its value and what is allowed).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, render_mode: str | None = None, *, config: EpisodeConfig | None = None,
                 profile: str = "ideal", randomize: bool = True, objects: tuple[str, ...] | None = None,
                 max_grasps: int = 32, mask_unreachable: bool = True,
                 place_poses: tuple[tuple[float, float, float], ...] | None = None, max_steps: int = 5,
                 shaped_reward: bool = False, images: bool = False, image_size_px: tuple[int, int] = (128, 96),
                 render_size_px: tuple[int, int] = (640, 480)) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError("render_mode", render_mode, "must be None or 'rgb_array'")
        self.render_mode = render_mode
        self.config = _base_config(config, profile)
        if self.config.task is not None:
            raise ConfigError("config.task", self.config.task.kind, "PickPlace-v0 picks one object: use "
                                                                   "pickplace/Place-v0, Stack-v0 or Clear-v0 for tasks")
        self.randomize = check_bool("randomize", randomize)
        self.objects = check_objects("objects", objects)
        self.max_grasps = check_int("max_grasps", max_grasps, 1, 128)
        self.mask_unreachable = check_bool("mask_unreachable", mask_unreachable)
        self.place_poses = self._check_places(place_poses)
        self.max_steps = check_int("max_steps", max_steps, 2, 100)
        self.shaped_reward = check_bool("shaped_reward", shaped_reward)
        self.images = check_bool("images", images)
        self.image_size_px = check_size("image_size_px", image_size_px)
        self.render_size_px = check_size("render_size_px", render_size_px)
        g = self.max_grasps
        if self.place_poses is None:
            self.action_space: spaces.Space[Any] = spaces.Discrete(g)
        else:
            self.action_space = spaces.MultiDiscrete([g, len(self.place_poses)])
        parts: dict[str, spaces.Space[Any]] = {**robot_spaces(), **object_spaces(1),
                                               "grasps": spaces.Box(-10.0, 10.0, (g, len(GRASP_FEATURES)), np.float32),
                                               "action_mask": spaces.MultiBinary(g)}
        if self.place_poses is not None:
            parts["place_poses"] = box((len(self.place_poses), 4), POSITION_LIMIT_M)
        if self.images:
            parts.update(image_spaces(*self.image_size_px))
        self.observation_space = spaces.Dict(parts)
        self._robot: Robot | None = None
        self._d: mujoco.MjData | None = None
        self._observer: Observer | None = None
        self._views: Views | None = None
        self._grasps: list[GraspCandidate] = []
        self._mask = np.zeros(g, dtype=np.int8)
        self._ended = False

    @staticmethod
    def _check_places(value: Any) -> tuple[tuple[float, float, float], ...] | None:
        if value is None:
            return None
        if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list)) or not 1 <= len(value) <= 16:
            raise ConfigError("place_poses", value, "must be None or 1 to 16 poses (x, y, yaw) (m, m, rad)")
        return tuple(tuple(check_vector(f"place_poses[{i}]", p, 3)) for i, p in enumerate(value))

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """A new scene from ``seed`` (the same seed: the same scene, the same first observation)."""
        super().reset(seed=seed)
        self._release()
        rng = self.np_random
        self._seed = int(rng.integers(0, 2**31 - 1))
        base = self.config.scene
        scene = draw_scene(base, rng, self.objects) if self.randomize else base
        cfg = dataclasses.replace(self.config, scene=scene,
                                  planner=dataclasses.replace(self.config.planner, seed=self._seed))
        self._cfg = cfg
        robot = cfg.profile.plant(build(scene), np.random.default_rng([self._seed, 3]))
        apply_model_faults(robot, cfg.faults)
        d = robot.make_data()
        self._robot, self._d = robot, d
        if cfg.profile.realistic:  # the camera's calibration and noise: a stream of their own, as run_episode's
            self._observer = cfg.profile.observer(robot, d, np.random.default_rng([self._seed, 2]))
        else:
            self._observer = SimulatorObserver(robot, d)
        self._loop = cfg.profile.control_loop(np.random.default_rng([self._seed, 4]))
        self._noise_rng = np.random.default_rng([self._seed, 1])
        self._encoder = cfg.profile.loop.encoder_resolution_rad
        self._open_face_m = open_face_y_m(robot)
        T = self._observer.observe()  # the robot's first look at the object
        self._grasps = candidate_grasps(robot, T)[: self.max_grasps]
        self._mask = self._grasp_mask(T)
        self._steps, self._t, self._ended = 0, 0.0, False
        if self.images or self.render_mode == "rgb_array":
            self._views = Views(robot, self.render_size_px, self.image_size_px)
        return self._observation(), self._info({})

    def _grasp_mask(self, T_world_object: pin.SE3) -> np.ndarray:
        mask = np.zeros(self.max_grasps, dtype=np.int8)
        ok = list(self._grasps)
        if self.mask_unreachable and ok:
            assert self._robot is not None
            cfg = self._cfg
            try:
                ok = holdable(self._robot, ok, cfg.machine.grip_safety_factor, T_world_object)
            except CannotHold:
                ok = []
            ok = feasible_grasps(self._robot, ok, T_world_object, cfg.machine.planning_margin_m, cfg.ik,
                                 cfg.machine.retract_height_m)
        for i, g in enumerate(self._grasps):
            mask[i] = any(g is k for k in ok)
        return mask

    # ------------------------------------------------------------------ step
    def _decode(self, action: Any) -> tuple[int, int]:
        g, n = self.max_grasps, len(self.place_poses) if self.place_poses is not None else 0
        try:
            a = np.asarray(action)
        except (TypeError, ValueError):
            a = np.array(None)
        if n == 0:
            if a.shape != () or not np.issubdtype(a.dtype, np.integer) or not 0 <= int(a) < g:
                raise ConfigError("action", action, f"must be an integer grasp index in [0, {g - 1}] "
                                                    "(info['action_mask'] says which are valid now)")
            return int(a), -1
        if a.shape != (2,) or not np.issubdtype(a.dtype, np.integer) or not (0 <= a[0] < g and 0 <= a[1] < n):
            raise ConfigError("action", action, f"must be (grasp index in [0, {g - 1}], place index in "
                                                f"[0, {n - 1}])")
        return int(a[0]), int(a[1])

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Run the pick and place with the chosen grasp (and place pose), to DONE or FAILED."""
        if self._robot is None or self._d is None or self._observer is None:
            raise ConfigError("step", action, "call reset() before step()")
        if self._ended:
            raise ConfigError("step", action, "the episode has ended (terminated or truncated): call reset()")
        g, p = self._decode(action)
        self._steps += 1
        outcome: dict[str, Any] = {"grasp_index": g, "place_index": p}
        robot = self._robot
        invalid = ""
        if not self._mask[g]:
            invalid = (f"grasp {g} is masked: " + (f"there are only {len(self._grasps)} candidates"
                                                    if g >= len(self._grasps) else
                                                    "its pads cannot hold the object or its approach does not "
                                                    "solve collision free where the object is seen"))
        elif p >= 0:
            assert self.place_poses is not None
            x, y, yaw = self.place_poses[p]
            try:
                scene = dataclasses.replace(robot.scene, goal_xy_m=(x, y), goal_yaw_rad=yaw)
                scene.check_goal_on_table()
                robot = dataclasses.replace(robot, scene=scene)
            except ConfigError as exc:
                invalid = f"place {p} is invalid here: {exc}"
        if invalid:
            self._ended = self._steps >= self.max_steps
            outcome.update(started=False, success=False, invalid_action=invalid)
            reward = -0.1 if self.shaped_reward else 0.0
            return self._observation(), reward, False, self._ended, self._info(outcome)
        out, moved, success = self._run(robot, self._grasps[g])
        if moved:
            self._robot = robot  # the goal of the episode is now the chosen place (the observation's goal_pos)
        elif out.failure_kind != "ConfigError":  # this grasp cannot start here (a bad place is the place's fault)
            self._mask[g] = 0
        terminated = success or moved
        truncated = not terminated and self._steps >= self.max_steps
        self._ended = terminated or truncated
        outcome.update(started=moved, success=success, invalid_action="", failure_phase=(
            out.failure_phase.value if out.failure_phase is not None else None), failure_kind=out.failure_kind,
            failure_reason=out.failure_reason, place_error_xy_m=out.place_error_xy_m,
            place_error_z_m=out.place_error_z_m, place_error_yaw_rad=out.place_error_yaw_rad,
            final_place_error_xy_m=out.final_place_error_xy_m, cycle_time_s=out.cycle_time_s,
            grasp_approach=out.grasp_approach, grasps_tried=out.grasps_tried, retries=len(out.recoveries))
        if success:
            reward = 1.0 - (0.01 * out.cycle_time_s if self.shaped_reward else 0.0)
        elif self.shaped_reward:
            reward = -0.5 if moved else -0.1
        else:
            reward = 0.0
        return self._observation(), float(reward), terminated, truncated, self._info(outcome)

    def _run(self, robot: Robot, grasp: GraspCandidate) -> tuple[MachineOutcome, bool, bool]:
        """One pick and place on the env's simulation: its record, whether the arm moved, whether it succeeded."""
        cfg = self._cfg
        arm = Arm(robot, self._d, cfg.machine, cfg.control, cfg.planner, cfg.timing, None, cfg.faults,
                  self._noise_rng, observer=self._observer, loop=self._loop)
        t0 = self._t
        arm.monitor.t = t0
        try:
            out = _ChosenGrasp(arm, cfg, grasp).run()
        except ConfigError as exc:  # the chosen goal does not suit the object (nothing has moved)
            out = arm.out
            out.phase, out.failure_phase, out.failure_reason = Phase.FAILED, Phase.IDLE, str(exc)
            out.failure_kind = type(exc).__name__
        self._t = arm.monitor.t
        out.cycle_time_s = self._t - t0
        mujoco.mj_kinematics(robot.mj, self._d)  # positions of the state the last physics step reached
        return out, not _nothing_moved(out), out.phase is Phase.DONE

    # ------------------------------------------------------------------ observations
    def _observation(self) -> dict[str, np.ndarray]:
        robot, d, observer = self._robot, self._d, self._observer
        assert robot is not None and d is not None and observer is not None
        scene = robot.scene
        goal = (scene.goal_pos_m, scene.goal_yaw_rad)
        obs = {**robot_observation(robot, d, self._open_face_m, self._encoder),
               **object_observation([observer.object_pose()], [goal], 1),
               "grasps": _grasp_features(self._grasps, self.max_grasps), "action_mask": self._mask.copy()}
        if self.place_poses is not None:
            rest = scene.rest_z_m
            obs["place_poses"] = np.array([[x, y, rest, yaw] for x, y, yaw in self.place_poses], dtype=np.float32)
        if self.images:
            assert self._views is not None
            obs.update(self._views.rgbd(d))
        return obs

    def _info(self, outcome: dict[str, Any]) -> dict[str, Any]:
        info = {"action_mask": self._mask.copy(), "sim_time_s": self._t, "steps": self._steps,
                "seed": self._seed, "object": self._robot.scene.object.name if self._robot else ""}
        info.update(outcome)
        return info

    def action_masks(self) -> np.ndarray:
        """The valid grasp indices now (max_grasps,) bool (the convention of masked-action learners)."""
        return self._mask.astype(bool)


class TaskEnv(RenderedEnv, gym.Env):
    """A task with several objects (``kind``: place, stack or clear); an action chooses the next object.

    Action: ``Discrete(max_objects + 1)``: ``k < max_objects`` picks and places the scene's object ``k`` (its goal
    the task planner's for it), ``max_objects`` lets the task planner choose the object too (its ``order``). Objects
    that do not exist or are done are masked (``info["action_mask"]``, :meth:`action_masks`; refused without
    moving).

    Observation (``Dict``): the robot's state as :class:`PickPlaceEnv`'s; ``object_pos`` (K, 3) m, ``object_quat``
    (K, 4), ``object_mask`` (K,) (which rows are objects), ``goal_pos`` (K, 3) m and ``goal_yaw`` (K,) rad (place:
    each object's goal; stack: the tower's spot; clear: the bin's centre on its floor), ``object_done`` (K,),
    ``action_mask`` (K + 1,); with ``images``: ``rgb`` and ``depth``. K = ``max_objects``.

    Args:
        render_mode: None or ``"rgb_array"``.
        config: The base configuration (tolerances, gains, planner; with ``randomize=False`` its scene's objects and
            bin, and its ``[task]`` if any); the profile must be ideal.
        n_objects: Objects drawn at each reset (1 to 8) with :func:`~pickplace.task.tasks.random_task_scene`
            (``place``: the first two swap places).
        objects: Library objects to draw from (None: :func:`random_task_scene`'s default for the kind).
        max_objects: Rows of the object observation and object actions (at least ``n_objects``; default: it).
        order: The task planner's order (``planned`` or ``listed``) for the planner's action.
        randomize: Draw the scene from the reset seed; False: the config's scene (it must suit the task).
        max_steps: Pick and places before the episode is truncated (default 3 per object).
        shaped_reward: The shaped reward (module docstring).
        images: Add ``rgb`` and ``depth``; image_size_px, render_size_px: their sizes (px).

    Raises:
        ConfigError: an argument is invalid (the message names it, its value and what is allowed).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 4}
    #: The task (``place``, ``stack`` or ``clear``); set by the subclasses.
    KIND: ClassVar[str] = ""

    def __init__(self, render_mode: str | None = None, *, kind: str | None = None,
                 config: EpisodeConfig | None = None, n_objects: int = 3, objects: tuple[str, ...] | None = None,
                 max_objects: int | None = None, order: str = "planned", randomize: bool = True,
                 max_steps: int | None = None, shaped_reward: bool = False, images: bool = False,
                 image_size_px: tuple[int, int] = (128, 96), render_size_px: tuple[int, int] = (640, 480)) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError("render_mode", render_mode, "must be None or 'rgb_array'")
        self.render_mode = render_mode
        kind = kind if kind is not None else self.KIND
        kinds = [k.value for k in TaskKind]
        if kind not in kinds:
            raise ConfigError("kind", kind, f"must be one of {', '.join(kinds)}")
        self.kind = kind
        base = _base_config(config, "ideal" if config is None else config.profile.name)
        if base.profile.realistic:
            raise ConfigError("config.profile.name", base.profile.name, "tasks with several objects run in the ideal "
                                                                       "profile (as run_task)")
        task = base.task if base.task is not None else TaskConfig()
        task = dataclasses.replace(task, kind=kind, order=order)  # validates the order
        self.config = dataclasses.replace(base, task=None)
        self.task = task
        self.randomize = check_bool("randomize", randomize)
        self.objects = check_objects("objects", objects)
        if self.randomize:
            self.n_objects = check_int("n_objects", n_objects, 1, 8)
        else:
            task.check_scene(base.scene)
            self.n_objects = len(base.scene.objects)
        self.max_objects = check_int("max_objects", max_objects if max_objects is not None else self.n_objects,
                                     self.n_objects, 16)
        self.max_steps = check_int("max_steps", max_steps if max_steps is not None else 3 * self.n_objects, 2, 200)
        self.shaped_reward = check_bool("shaped_reward", shaped_reward)
        self.images = check_bool("images", images)
        self.image_size_px = check_size("image_size_px", image_size_px)
        self.render_size_px = check_size("render_size_px", render_size_px)
        k = self.max_objects
        self.action_space = spaces.Discrete(k + 1)
        parts: dict[str, spaces.Space[Any]] = {**robot_spaces(), **object_spaces(k),
                                               "object_done": spaces.MultiBinary(k),
                                               "action_mask": spaces.MultiBinary(k + 1)}
        if self.images:
            parts.update(image_spaces(*self.image_size_px))
        self.observation_space = spaces.Dict(parts)
        self._run: _TaskRun | None = None
        self._views: Views | None = None
        self._names: list[str] = []
        self._ended = False

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """A new task scene from ``seed`` (the same seed: the same scene, the same first observation)."""
        super().reset(seed=seed)
        self._release()
        rng = self.np_random
        self._seed = int(rng.integers(0, 2**31 - 1))
        if self.randomize:
            plain = dataclasses.replace(self.config.scene, others=(), bin=None)
            scene = random_task_scene(self.kind, self.n_objects, rng, base=plain, names=self.objects)
        else:
            scene = self.config.scene
        cfg = dataclasses.replace(self.config, scene=scene, task=self.task,
                                  planner=dataclasses.replace(self.config.planner, seed=self._seed))
        robot = build(scene)
        d = robot.make_data()
        planner = TaskPlanner(scene, self.task, cfg.machine.place_tolerance_xy_m, cfg.machine.place_tolerance_yaw_rad)
        self._run = _TaskRun(cfg, self._seed, robot, d, planner, None, _Measure(robot, d), None)
        self._robot, self._d, self._cfg = robot, d, cfg
        self._open_face_m = open_face_y_m(robot)
        self._names = [o.name for o in scene.objects]
        self._skip: set[str] = set()
        self._steps, self._ended = 0, False
        if self.images or self.render_mode == "rgb_array":
            self._views = Views(robot, self.render_size_px, self.image_size_px)
        poses = self._run.measure.poses()
        return self._observation(poses), self._info(poses, {})

    # ------------------------------------------------------------------ step
    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """One pick and place of the chosen object (or of the task planner's), to its goal."""
        run = self._run
        if run is None:
            raise ConfigError("step", action, "call reset() before step()")
        if self._ended:
            raise ConfigError("step", action, "the episode has ended (terminated or truncated): call reset()")
        k = self.max_objects
        a = np.asarray(action) if isinstance(action, (int, np.integer, np.ndarray)) else np.array(None)
        if a.shape != () or not np.issubdtype(a.dtype, np.integer) or not 0 <= int(a) <= k:
            raise ConfigError("action", action, f"must be an integer in [0, {k}]: an object index below {k}, or {k} "
                                                "for the task planner's choice (info['action_mask'] says which are "
                                                "valid now)")
        choice = int(a)
        self._steps += 1
        poses = run.measure.poses()
        mask = self._mask(poses)
        done_before = sum(self._done(poses))
        outcome: dict[str, Any] = {"choice": choice, "object": self._names[choice] if choice < len(self._names)
                                   else None}
        if not mask[choice]:
            what = ("there is no such object" if choice < k and choice >= len(self._names) else
                    "it is already where the task wants it" if choice < k else "every object is done")
            outcome.update(started=False, success=False, invalid_action=f"action {choice} is masked: {what}")
            self._ended = self._steps >= self.max_steps
            return (self._observation(poses), -0.1 if self.shaped_reward else 0.0, False, self._ended,
                    self._info(poses, outcome))
        name = self._names[choice] if choice < k else None
        outcome["invalid_action"] = ""
        outcome.update(self._pick_and_place(name))
        poses = run.measure.poses()
        done = self._done(poses)
        failed = outcome.get("terminal_failure", False)
        success = False
        if all(done) and not failed:
            objects = run.final_outcomes()
            success = all(o.ok for o in objects)
            if not success:
                bad = next(o for o in objects if not o.ok)
                outcome.update(failure_kind="TaskIncomplete", failure_reason=f"{bad.name}: {bad.note}")
            failed = not success
        terminated = success or failed
        truncated = not terminated and self._steps >= self.max_steps
        self._ended = terminated or truncated
        outcome["success"] = success
        if self.shaped_reward:
            reward = (sum(done) - done_before) / len(self._names)
            reward -= 0.5 if failed else (0.1 if not outcome.get("started", False) else 0.0)
        else:
            reward = 1.0 if success else 0.0
        return self._observation(poses), float(reward), terminated, truncated, self._info(poses, outcome)

    def _pick_and_place(self, name: str | None) -> dict[str, Any]:
        """One pick and place as :func:`run_task` runs it (another spot when one does not fit, knocks repaired):
        ``name``'s (None: the task planner's choice). What happened, for ``info``."""
        run = self._run
        assert run is not None
        planner, world = run.planner, run.world
        excluded: list[tuple[float, float]] = []
        while True:
            poses = run.measure.poses()
            skip = self._skip if name is None else {n for n in self._names if n != name}
            try:
                pick = planner.next_pick(poses, skip)
            except TaskStuck as exc:
                return {"started": False, "failure_kind": "TaskStuck", "failure_reason": str(exc),
                        "terminal_failure": name is None}
            if pick is None or (name is not None and pick.name != name):
                return {"started": False, "failure_kind": "TaskStuck", "failure_reason": "no pick of it can start"}
            chosen = run._other_spot(pick, poses, excluded)
            if chosen is None:
                if excluded and run._turning_allowed(pick.name):
                    excluded.clear()
                    continue
                self._skip.add(pick.name)
                return {"started": False, "object": pick.name, "failure_kind": "UnreachableTarget",
                        "failure_reason": f"no {pick.goal.label} spot of the {pick.name} can start"}
            pick = chosen
            if run.count[pick.name] >= self.task.max_picks_per_object:
                return {"started": False, "object": pick.name, "failure_kind": "TaskStuck", "terminal_failure": True,
                        "failure_reason": f"the {pick.name} was picked {run.count[pick.name]} times "
                                          "(task.max_picks_per_object) and is still not done"}
            try:
                view = _view(world, pick.name, poses[pick.name], pick)
            except ConfigError as exc:
                return {"started": False, "object": pick.name, "failure_kind": type(exc).__name__,
                        "terminal_failure": True,
                        "failure_reason": f"the {pick.name} cannot be picked and placed from where it is: {exc}"}
            result = run._run_pick(pick, view)
            mujoco.mj_kinematics(self._robot.mj, self._d)
            after = run.measure.poses()
            knocked = run._knocks(pick, poses, after)
            info = {"object": pick.name, "goal_label": pick.goal.label, "started": not _did_not_start(result),
                    "failure_phase": result.failure_phase, "failure_kind": result.failure_kind,
                    "failure_reason": result.failure_reason, "place_error_xy_m": result.place_error_xy_m,
                    "cycle_time_s": result.cycle_time_s, "knocked": [kn.name for kn in knocked]}
            if result.success:
                self._skip.clear()
                excluded.clear()
                run.turn_over.discard(pick.name)
                planner.placed(pick, after)
                if knocked and not run._repair(knocked, after):
                    info.update(terminal_failure=True, failure_kind="ObjectKnocked",
                                failure_reason=run.failure.reason if run.failure else "an object was knocked")
                return info
            if _did_not_start(result):
                run.skipped.append(f"{pick.name} -> {pick.goal.label}: {result.failure_reason}")
                planner.buffered.discard(pick.name)
                if pick.goal.label in SPOT_LABELS:
                    excluded.append(pick.goal.xy_m)
                    if len(excluded) < SPOTS_TRIED:
                        continue
                    if run._turning_allowed(pick.name):
                        excluded.clear()
                        continue
                self._skip.add(pick.name)
                return info
            if run._can_retry(pick.name, after):  # it rests where it can be picked again: the task goes on
                if knocked and not run._repair(knocked, after):
                    info.update(terminal_failure=True, failure_kind="ObjectKnocked")
                return info
            info["terminal_failure"] = True
            return info

    # ------------------------------------------------------------------ observations
    def _done(self, poses: dict[str, pin.SE3]) -> list[bool]:
        assert self._run is not None
        return [self._run.planner.done(n, poses) for n in self._names]

    def _mask(self, poses: dict[str, pin.SE3]) -> np.ndarray:
        k = self.max_objects
        mask = np.zeros(k + 1, dtype=np.int8)
        done = self._done(poses)
        for i, ok in enumerate(done):
            mask[i] = not ok
        mask[k] = not all(done)
        return mask

    def _goals(self) -> list[tuple[np.ndarray, float]]:
        scene, task = self._cfg.scene, self.task
        out = []
        for o in scene.objects:
            rest = -o.object.geometry().z_min_m
            if self.kind == TaskKind.PLACE:
                assert o.goal_xy_m is not None
                out.append((np.array([*o.goal_xy_m, scene.table_height_m + rest]), o.goal_yaw_rad))
            elif self.kind == TaskKind.STACK:
                out.append((np.array([*task.stack_xy_m, scene.table_height_m + rest]), task.stack_yaw_rad))
            else:
                assert scene.bin is not None
                out.append((np.array([*scene.bin.xy_m, scene.bin.floor_z_m(scene.table_height_m) + rest]), 0.0))
        return out

    def _observation(self, poses: dict[str, pin.SE3]) -> dict[str, np.ndarray]:
        k = self.max_objects
        done = np.zeros(k, dtype=np.int8)
        done[: len(self._names)] = self._done(poses)
        obs = {**robot_observation(self._robot, self._d, self._open_face_m),
               **object_observation([poses[n] for n in self._names], self._goals(), k),
               "object_done": done, "action_mask": self._mask(poses)}
        if self.images:
            assert self._views is not None
            obs.update(self._views.rgbd(self._d))
        return obs

    def _info(self, poses: dict[str, pin.SE3], outcome: dict[str, Any]) -> dict[str, Any]:
        assert self._run is not None
        info = {"action_mask": self._mask(poses), "objects": list(self._names), "steps": self._steps,
                "seed": self._seed, "sim_time_s": self._run.t, "order": [f"{n}->{g}" for n, g in self._run.order],
                "objects_done": int(sum(self._done(poses)))}
        info.update({key: v for key, v in outcome.items() if key != "terminal_failure"})
        return info

    def action_masks(self) -> np.ndarray:
        """The valid actions now (max_objects + 1,) bool."""
        if self._run is None:
            return np.zeros(self.max_objects + 1, dtype=bool)
        return self._mask(self._run.measure.poses()).astype(bool)


class PlaceEnv(TaskEnv):
    """``pickplace/Place-v0``: every object to its own goal (:class:`TaskEnv`)."""

    KIND: ClassVar[str] = "place"


class StackEnv(TaskEnv):
    """``pickplace/Stack-v0``: a tower of the objects (:class:`TaskEnv`; random objects from the stackable ones)."""

    KIND: ClassVar[str] = "stack"


class ClearEnv(TaskEnv):
    """``pickplace/Clear-v0``: every object into the bin (:class:`TaskEnv`)."""

    KIND: ClassVar[str] = "clear"


__all__ = ["GRASP_FEATURES", "ClearEnv", "PickPlaceEnv", "PlaceEnv", "StackEnv", "TaskEnv"]

