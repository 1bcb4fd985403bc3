"""One pick-and-place episode: its configuration, the run, and the measured :class:`EpisodeResult`.

``run_episode(config, seed)`` builds the scene, runs :class:`~pickplace.task.machine.PickPlaceMachine` in MuJoCo
and returns every figure the machine measured, together with the config and the seed it ran with, so that
any episode can be re-run alone and gives the same result (wall times aside).

Configs can be written as TOML, one table per part::

    [object]
    library = "soda_can"
    mass_kg = 0.3

    [scene]
    start_xy_m = [0.35, 0.20]
    obstacle = true

    [planner]
    time_budget_s = 0.5

Tables: ``object``, ``scene``, ``machine``, ``control``, ``planner``, ``timing``, ``ik``, ``faults``,
``profile`` (with its ``camera`` and ``sensing`` sub-tables, :mod:`pickplace.task.profile`); keys are
the dataclass fields (``[object]`` also takes ``library = "NAME"``; ``[scene]`` also takes the ``cube_*`` keys
of earlier versions, see :data:`~pickplace.world.config.LEGACY_SCENE_KEYS`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from pickplace.errors import ConfigError
from pickplace.motion.control import ControlConfig, PhaseTracking
from pickplace.motion.planning import PlannerConfig
from pickplace.motion.timing import TimingConfig
from pickplace.robot.ik import IKConfig
from pickplace.robot.model import Robot, build
from pickplace.task.faults import LEGACY_FAULT_KEYS, FaultConfig, apply_model_faults
from pickplace.task.machine import MachineConfig, MachineOutcome, Phase, PickPlaceMachine, SegmentPlan
from pickplace.task.observe import Observer
from pickplace.task.profile import ProfileConfig
from pickplace.task.tasks import TaskConfig
from pickplace.task.telemetry import Telemetry, TelemetryRecorder
from pickplace.world.config import LEGACY_SCENE_KEYS, BinConfig, SceneConfig, SceneObject, from_mapping
from pickplace.world.objects import ObjectConfig

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class EpisodeConfig:
    """Everything an episode depends on besides its seed.

    Attributes:
        scene: The world: the object, its start and goal, the table, the obstacle.
        machine: The state machine's tolerances and timeouts.
        control: Controller gains and vertical-move profile.
        planner: RRT* settings (the seed is replaced by the episode's).
        timing: TOPP-RA limits.
        ik: IK settings.
        faults: Faults injected on purpose (none by default).
        profile: How the robot knows the world and is controlled: ``ideal`` (the simulator's truth) or
            ``realistic`` (a depth camera and the robot's own sensors, a 500 Hz loop with latency, model error),
            :mod:`pickplace.task.profile`. With a realistic loop, a default ``control`` becomes
            :meth:`ControlConfig.realistic` (the ideal gains do not hold such a loop).
        task: A task with several objects (``place``, ``stack``, ``clear``; :mod:`pickplace.task.tasks`), run by
            :func:`~pickplace.task.task_episode.run_task`; None (default): one pick and place of the scene's
            object, run by :func:`run_episode`.
    """

    scene: SceneConfig = field(default_factory=SceneConfig)
    machine: MachineConfig = field(default_factory=MachineConfig)
    control: ControlConfig = field(default_factory=ControlConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    timing: TimingConfig = field(default_factory=TimingConfig.ur5e)
    ik: IKConfig = field(default_factory=IKConfig)
    faults: FaultConfig = field(default_factory=FaultConfig)
    profile: ProfileConfig = field(default_factory=ProfileConfig)
    task: TaskConfig | None = None

    def __post_init__(self) -> None:
        for name, cls in _SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(name, getattr(self, name), f"must be a {cls.__name__}")
        if self.task is not None:
            if not isinstance(self.task, TaskConfig):
                raise ConfigError("task", self.task, "must be a TaskConfig (the [task] table)")
            self.task.check_scene(self.scene)
        if self.control == ControlConfig():  # the default gains: the profile's (ProfileConfig.control_defaults)
            object.__setattr__(self, "control", self.profile.control_defaults())

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EpisodeConfig:
        """Build from nested mappings ``{"scene": {...}, "planner": {...}, ...}`` (unknown keys are errors)."""
        if not isinstance(data, dict):
            raise ConfigError("config", data, "must be a table of tables")
        tables = ["object", "objects", "bin", "task", *_SECTIONS]
        unknown = sorted(set(data) - set(tables))
        if unknown:
            raise ConfigError(unknown[0], data[unknown[0]], f"unknown table; allowed: {', '.join(tables)}")
        for name in tables:
            if name != "objects" and not isinstance(data.get(name, {}), dict):
                raise ConfigError(name, data[name], "must be a table of keys")
        scene = SceneConfig.from_mapping(data.get("scene", {}), object_data=data.get("object"))
        if "objects" in data or "bin" in data:
            scene = _with_objects(scene, data)
        parts: dict[str, Any] = {"scene": scene, "profile": ProfileConfig.from_mapping(data.get("profile", {}))}
        if "task" in data:
            parts["task"] = TaskConfig.from_mapping(data["task"])
        for name, section_cls in _SECTIONS.items():
            if name not in ("scene", "profile"):
                base = _base(section_cls, parts["profile"])
                aliases = LEGACY_FAULT_KEYS if section_cls is FaultConfig else None
                parts[name] = from_mapping(section_cls, data.get(name, {}), name, base, aliases)
        return cls(**parts)

    @classmethod
    def from_toml(cls, path: str | Path) -> EpisodeConfig:
        """Load a TOML file (see the module docstring); errors name the file, the key and the problem."""
        return cls.from_dict(read_toml(path))

    def to_dict(self) -> dict[str, Any]:
        """Nested plain data (lists for tuples), the inverse of :meth:`from_dict`."""
        out = {"object": _plain(self.scene.object.to_dict()), "scene": _plain(self.scene.to_dict())}
        out.update({name: _plain(dataclasses.asdict(getattr(self, name))) for name in _SECTIONS if name != "scene"})
        if self.scene.others:
            out["objects"] = [_plain(_object_entry(o)) for o in self.scene.objects]
            del out["object"]
            for key in _PLACEMENT_KEYS:  # each object's own, in its entry
                out["scene"].pop(key, None)
        if self.scene.bin is not None:
            out["bin"] = _plain(dataclasses.asdict(self.scene.bin))
        if self.task is not None:
            out["task"] = _plain(dataclasses.asdict(self.task))
        return out

    def with_profile(self, name: str) -> EpisodeConfig:
        """A copy in the profile ``name`` with its defaults, the controller's gains included (the realistic
        profile's are :meth:`ControlConfig.realistic`) unless they were changed from either default."""
        profile = ProfileConfig.named(name)
        control = self.control
        if control in (ControlConfig(), ControlConfig.realistic()):
            control = profile.control_defaults()
        return dataclasses.replace(self, profile=profile, control=control)

    def with_scene(self, **changes: Any) -> EpisodeConfig:
        """A copy with some scene fields changed (validated); the ``cube_*`` keys of earlier versions work too
        (:data:`~pickplace.world.config.LEGACY_SCENE_KEYS`)."""
        return dataclasses.replace(self, scene=SceneConfig.from_mapping(changes, self.scene))

    def with_object(self, **changes: Any) -> EpisodeConfig:
        """A copy whose object has some fields changed (validated)."""
        return dataclasses.replace(self, scene=self.scene.with_object(**changes))


#: Keys of an ``[[objects]]`` entry that place the object (the others describe it, as ``[object]`` does).
_PLACEMENT_KEYS = ("start_xy_m", "start_yaw_rad", "goal_xy_m", "goal_yaw_rad")


def _with_objects(scene: SceneConfig, data: dict[str, Any]) -> SceneConfig:
    """The scene with the ``[[objects]]`` (the first is the scene's own object) and the ``[bin]`` of a config."""
    changes: dict[str, Any] = {}
    if "bin" in data:
        changes["bin"] = BinConfig.from_mapping(data["bin"])
    entries = data.get("objects")
    if entries is not None:
        if "object" in data:
            raise ConfigError("object", data["object"], "give either one [object] or a list of [[objects]], not both")
        clash = sorted(set(data.get("scene", {})) & {*_PLACEMENT_KEYS, *LEGACY_SCENE_KEYS})
        if clash:
            raise ConfigError(f"scene.{clash[0]}", data["scene"][clash[0]],
                              "with [[objects]], each object's start and goal go in its own entry")
        if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
            raise ConfigError("objects", entries, "must be a list of tables ([[objects]]), at least one")
        placed = [_scene_object(i, e) for i, e in enumerate(entries)]
        first = placed[0]
        changes.update(object=first.object, start_xy_m=first.start_xy_m, start_yaw_rad=first.start_yaw_rad,
                       goal_yaw_rad=first.goal_yaw_rad, others=tuple(placed[1:]))
        if first.goal_xy_m is not None:
            changes["goal_xy_m"] = first.goal_xy_m
    return dataclasses.replace(scene, **changes)


def _scene_object(i: int, entry: dict[str, Any]) -> SceneObject:
    """One ``[[objects]]`` entry: ``name``, an object (``library = "NAME"`` and/or ``[object]`` keys) and its
    placement (start, optional goal)."""
    if "name" not in entry:
        raise ConfigError(f"objects[{i}].name", None, "each object needs a name (letters, digits, underscores)")
    described = {k: v for k, v in entry.items() if k not in _PLACEMENT_KEYS}
    if "start_xy_m" not in entry:
        raise ConfigError(f"objects.{entry['name']}.start_xy_m", None, "each object needs a start (x, y) on the table")
    obj = ObjectConfig.from_mapping(described)
    placement = {k: tuple(v) if isinstance(v, list) else v for k, v in entry.items() if k in _PLACEMENT_KEYS}
    return SceneObject(obj, **placement)


def _object_entry(o: SceneObject) -> dict[str, Any]:
    """An ``[[objects]]`` entry (the inverse of :func:`_scene_object`)."""
    out = o.object.to_dict()
    out.update(start_xy_m=list(o.start_xy_m), start_yaw_rad=o.start_yaw_rad, goal_yaw_rad=o.goal_yaw_rad)
    if o.goal_xy_m is not None:
        out["goal_xy_m"] = list(o.goal_xy_m)
    return out


def read_toml(path: str | Path) -> dict[str, Any]:
    """The tables of a TOML file; :class:`ConfigError` naming the file if it cannot be read or parsed."""
    p = Path(path)
    try:
        return tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError("config", str(p), f"cannot be read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("config", str(p), f"is not valid TOML: {exc}") from None


_SECTIONS: dict[str, type] = {"scene": SceneConfig, "machine": MachineConfig, "control": ControlConfig,
                              "planner": PlannerConfig, "timing": TimingConfig, "ik": IKConfig,
                              "faults": FaultConfig, "profile": ProfileConfig}


def _base(section_cls: type, profile: ProfileConfig) -> Any:
    """The defaults a TOML table starts from: the UR5e's limits for ``[timing]``, the profile's gains for
    ``[control]`` (:meth:`ProfileConfig.control_defaults`); None (the class's own defaults) otherwise."""
    if section_cls is TimingConfig:
        return TimingConfig.ur5e()
    if section_cls is ControlConfig:
        return profile.control_defaults()
    return None


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _plain(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@dataclass(frozen=True, eq=False)
class EpisodeResult:
    """What one episode did, measured. Lengths in m, angles in rad, times in s, forces in N.

    Attributes:
        success: The object was placed at the goal and the arm returned home, every check passing, and the object
            still lay within ``machine.place_tolerance_xy_m`` of the goal ``machine.stable_after_release_s``
            after the release.
        failure_phase: Name of the phase that failed, or None.
        failure_reason: What failed, with the numbers, or None.
        failure_kind: The error behind the failure (e.g. ``"UnreachableTarget"``, ``"GraspFailed"``), or None.
        seed: The episode's seed (the planner's random stream).
        cycle_time_s: Simulated time from IDLE to DONE (or to the failure).
        wall_time_s: Wall-clock time of the whole episode, model building included.
        real_time_factor: Simulated seconds per wall-clock second (simulation incl. the hold after DONE).
        phase_durations_s: Simulated time per phase (summed over repeats), in the order first run.
        phase_timeline: ``(phase, start_s, duration_s, outcome)`` of every phase run, in order; outcome is
            ``ok``, ``recovered`` (it failed, then a recovery followed) or ``failed``.
        plan_time_s: Wall time of planning per segment (``approach``, ``transport``, ``return``).
        retime_time_s: Wall time of TOPP-RA per segment.
        waypoints_raw: Waypoints of the tree path per segment.
        waypoints_shortcut: Waypoints after shortcutting per segment.
        trajectory_duration_s: Duration of the timed trajectory per segment.
        slowdown_for_grip: How many times slower than time-optimal each segment ran so that the grip holds the
            object (1: not slowed; see :mod:`pickplace.grasping.grip`).
        place_error_xy_m: Horizontal distance of the released object (at rest) from the goal.
        place_error_z_m: Height error of the released object (positive: above its resting height).
        place_error_yaw_rad: Yaw error of the released object, modulo its symmetry
            (``object.yaw_period_rad``; 0 where yaw is not defined).
        final_place_error_xy_m: Horizontal error ``machine.stable_after_release_s`` after the release.
        ik_position_error_m: Largest tcp position residual of the IK solutions.
        ik_orientation_error_rad: Largest tcp orientation residual of the IK solutions.
        tracking_error_max_rad: Largest joint tracking error ``|q_ref - q|`` of every joint-space loop of every
            phase: the planned trajectories and the holds (while the gripper closes or opens, after a push...).
        tracking_error_rms_rad: RMS joint tracking error over the same loops.
        tcp_tracking_error_max_m: Largest distance of the tcp from its reference in the Cartesian moves
            (DESCEND, LIFT, DESCEND_PLACE, RETRACT and the back-offs of a recovery).
        tcp_orientation_error_max_rad: Largest rotation of the tcp from its reference in those moves.
        tracking_by_phase: The tracking errors of each phase that ran a control loop, by phase name.
        grip_force_n: Sum of the pads' normal forces when the grip settled.
        lift_grip_force_n: Mean sum of the pads' normal forces while the object is lifted off the table.
        lift_load_n: Weight carried by the pads while lifting (their vertical force minus m times the object's
            vertical acceleration, averaged); m g when the pads alone hold the object.
        force_closure: The settled grip passed the 6D force-closure test on the simulated contacts.
        grasp_margin: Ferrari–Canny margin of that grip.
        grasp_approach: The executed grasp's approach in the object's resting frame: ``top``, ``tilted`` or
            ``side`` (the last one chosen, after a regrasp).
        grasp_tilt_rad: Its approach's angle from straight down (rad).
        grasp_width_m: The object's width between the pads at that grasp (m).
        grasps_tried: Grasp candidates tried (IK, collisions) until that one worked (1: the best ranked).
        slip_max_m: Largest motion of the object in the tcp frame while held.
        torque_saturation_events: Control steps with a clipped torque.
        unexpected_contacts: Geom pairs of every unexpected contact met (recovered from or not).
        retries: Recoveries used.
        recoveries: One line per recovery: the failure caught and what was done.
        measured_mass_kg: The object's mass as the pads felt it while lifting (``lift_load_n / g``).
        pose_estimates: ``(phase, what, position_error_m, yaw_error_rad)`` of every estimate of the object's
            pose the robot took (``resting`` or ``in hand``), against the truth (which it never used): zero in
            the ideal profile, the camera's error in the realistic one.
        limit_violations: Physics steps (1 ms) of the arm's motions (trajectories, straight moves, stops) at which
            a joint was faster or accelerated harder than the UR5e's limits (``timing.velocity_limits_rad_s``,
            ``timing.acceleration_limits_rad_s2``), or a motor's torque was at its limit (clipped)
            (:mod:`pickplace.motion.limits`).
        joint_speed_ratio_max: Largest ``|qd_j| / vlim_j`` of any joint at any step of a motion.
        joint_acceleration_ratio_max: Largest ``|qdd_j| / alim_j`` (the change of the joint's velocity over one step).
        torque_ratio_max: Largest ``|tau_j| / tau_max_j`` of the torques applied.
        limit_violations_by_phase: ``limit_violations`` by phase (phases with none left out).
        limit_worst: The step of a motion closest to (or furthest past) a limit: what, which joint, which phase, when.
        hold_limit_violations: The same, over the steps at which the arm held still (the gripper closing or opening,
            waits, the hold after DONE): what contacts did to it.
        hold_limit_worst: The held step closest to (or furthest past) a limit.
        approach_line_deviation_max_m: Largest distance of the tcp from the straight line from the pregrasp to the
            grasp while it descends to the grasp (every step of DESCEND's final approach); NaN if none ran.
        place_line_deviation_max_m: The same for the set-down, from above the goal to the place as aimed.
        config: The full config the episode ran with.
        telemetry: Per-step samples for plots and video (only when asked for; not serialized).
    """

    success: bool
    failure_phase: str | None
    failure_reason: str | None
    failure_kind: str | None
    seed: int
    cycle_time_s: float
    wall_time_s: float
    real_time_factor: float
    phase_durations_s: dict[str, float]
    phase_timeline: tuple[tuple[str, float, float, str], ...]
    plan_time_s: dict[str, float]
    retime_time_s: dict[str, float]
    waypoints_raw: dict[str, int]
    waypoints_shortcut: dict[str, int]
    trajectory_duration_s: dict[str, float]
    slowdown_for_grip: dict[str, float]
    place_error_xy_m: float
    place_error_z_m: float
    place_error_yaw_rad: float
    final_place_error_xy_m: float
    ik_position_error_m: float
    ik_orientation_error_rad: float
    tracking_error_max_rad: float
    tracking_error_rms_rad: float
    tcp_tracking_error_max_m: float
    tcp_orientation_error_max_rad: float
    tracking_by_phase: dict[str, PhaseTracking]
    grip_force_n: float
    lift_grip_force_n: float
    lift_load_n: float
    force_closure: bool
    grasp_margin: float
    grasp_approach: str
    grasp_tilt_rad: float
    grasp_width_m: float
    grasps_tried: int
    slip_max_m: float
    torque_saturation_events: int
    unexpected_contacts: tuple[tuple[str, str], ...]
    retries: int
    recoveries: tuple[str, ...]
    measured_mass_kg: float
    pose_estimates: tuple[tuple[str, str, float, float], ...]
    limit_violations: int
    joint_speed_ratio_max: float
    joint_acceleration_ratio_max: float
    torque_ratio_max: float
    limit_violations_by_phase: dict[str, int]
    limit_worst: str
    hold_limit_violations: int
    hold_limit_worst: str
    approach_line_deviation_max_m: float
    place_line_deviation_max_m: float
    config: EpisodeConfig
    telemetry: Telemetry | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (NaN becomes None; the telemetry is left out)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name == "telemetry":
                continue
            value = getattr(self, f.name)
            out[f.name] = value.to_dict() if f.name == "config" else _plain(value)
        return out


def run_episode(config: EpisodeConfig | None = None, seed: int = 0, *, record: bool = False,
                frame_rate_hz: float = 30.0,
                observer: Callable[[Robot, mujoco.MjData], Observer] | None = None) -> EpisodeResult:
    """Run one pick and place in simulation and measure it.

    Args:
        config: The episode's configuration (default: the default scene).
        seed: Seed of the episode's random stream (the planner's).
        record: Keep per-step telemetry (for plots and video) in the result.
        frame_rate_hz: Video frames per simulated second kept when recording.
        observer: Makes the robot's observer from the models and the simulation state (what the robot knows
            about the object, :mod:`pickplace.task.observe`); default: the config's profile's (the simulator's
            truth in the ideal profile, the sensors in the realistic one). The result's figures are measured on
            the truth either way.

    Returns:
        The :class:`EpisodeResult`; a failed pick or place is reported in it, not raised.

    Raises:
        ConfigError: the configuration or the seed is invalid (nothing has run).
    """
    config = config if config is not None else EpisodeConfig()
    if not isinstance(config, EpisodeConfig):
        raise ConfigError("config", config, "must be an EpisodeConfig")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError("seed", seed, "must be an integer >= 0")
    if config.task is not None:
        raise ConfigError("task", config.task.kind, "a task with several objects runs with "
                                                    "pickplace.task.task_episode.run_task")
    t0 = time.perf_counter()
    robot = config.profile.plant(build(config.scene), np.random.default_rng([seed, 3]))
    apply_model_faults(robot, config.faults)
    data = robot.make_data()
    config = dataclasses.replace(config, planner=dataclasses.replace(config.planner, seed=seed))  # as it runs
    recorder = TelemetryRecorder(robot, frame_rate_hz, config.scene.goal_pos_m) if record else None
    noise_rng = np.random.default_rng([seed, 1])  # the sensor-noise stream, independent of the planner's
    if observer is not None:
        sensed = observer(robot, data)
    elif config.profile.realistic:  # the camera's calibration and noise: a stream of their own
        sensed = config.profile.observer(robot, data, np.random.default_rng([seed, 2]))
    else:
        sensed = None
    loop = config.profile.control_loop(np.random.default_rng([seed, 4]))
    machine = PickPlaceMachine(robot, data, config.machine, config.control, config.planner, config.timing, config.ik,
                               recorder, config.faults, noise_rng, sensed, loop)
    t_sim0 = time.perf_counter()
    try:
        out = machine.run()
    finally:
        if sensed is not None and hasattr(sensed, "close"):
            sensed.close()
    wall = time.perf_counter() - t0
    sim_wall = time.perf_counter() - t_sim0
    result = _result(out, config, seed, wall, machine.monitor.t / sim_wall if sim_wall > 0 else math.nan,
                     recorder.freeze() if recorder is not None else None)
    log.info("episode seed %d: %s in %.3f s simulated, %.3f s wall", seed,
             "success" if result.success else f"FAILED in {result.failure_phase}: {result.failure_reason}",
             result.cycle_time_s, wall)
    return result


def _by_segment(segments: list[SegmentPlan], attr: str) -> dict[str, Any]:
    return {s.name: getattr(s, attr) for s in segments}


def _result(out: MachineOutcome, config: EpisodeConfig, seed: int, wall: float, rtf: float,
            telemetry: Telemetry | None) -> EpisodeResult:
    return EpisodeResult(
        success=out.phase is Phase.DONE,
        failure_phase=out.failure_phase.value if out.failure_phase is not None else None,
        failure_reason=out.failure_reason,
        failure_kind=out.failure_kind,
        seed=seed,
        cycle_time_s=out.cycle_time_s,
        wall_time_s=wall,
        real_time_factor=rtf,
        phase_durations_s=dict(out.phase_durations_s),
        phase_timeline=tuple(out.timeline),
        plan_time_s=_by_segment(out.segments, "plan_time_s"),
        retime_time_s=_by_segment(out.segments, "retime_time_s"),
        waypoints_raw=_by_segment(out.segments, "waypoints_raw"),
        waypoints_shortcut=_by_segment(out.segments, "waypoints_shortcut"),
        trajectory_duration_s=_by_segment(out.segments, "duration_s"),
        slowdown_for_grip=_by_segment(out.segments, "slowdown"),
        place_error_xy_m=out.place_error_xy_m,
        place_error_z_m=out.place_error_z_m,
        place_error_yaw_rad=out.place_error_yaw_rad,
        final_place_error_xy_m=out.final_place_error_xy_m,
        ik_position_error_m=out.ik_position_error_m,
        ik_orientation_error_rad=out.ik_orientation_error_rad,
        tracking_error_max_rad=out.tracking_total.joint_error_max_rad,
        tracking_error_rms_rad=out.tracking_total.joint_error_rms_rad,
        tcp_tracking_error_max_m=out.tracking_total.tcp_position_error_max_m,
        tcp_orientation_error_max_rad=out.tracking_total.tcp_orientation_error_max_rad,
        tracking_by_phase=dict(out.tracking),
        grip_force_n=out.grip_force_n,
        lift_grip_force_n=out.lift_grip_force_n,
        lift_load_n=out.lift_load_n,
        force_closure=out.force_closure,
        grasp_margin=out.grasp_margin,
        grasp_approach=out.grasp_approach,
        grasp_tilt_rad=out.grasp_tilt_rad,
        grasp_width_m=out.grasp_width_m,
        grasps_tried=out.grasps_tried,
        slip_max_m=out.slip_max_m,
        torque_saturation_events=out.torque_saturation_events,
        unexpected_contacts=tuple(out.unexpected_contacts),
        retries=len(out.recoveries),  # each recovery (regrasp, replan, payload correction) is one retry
        recoveries=tuple(out.recoveries),
        measured_mass_kg=out.lift_load_n / 9.81,
        pose_estimates=tuple(out.estimates),
        limit_violations=out.limits.violations,
        joint_speed_ratio_max=out.limits.speed_ratio_max,
        joint_acceleration_ratio_max=out.limits.acceleration_ratio_max,
        torque_ratio_max=out.limits.torque_ratio_max,
        limit_violations_by_phase=dict(out.limits.violations_by_phase),
        limit_worst=out.limits.worst,
        hold_limit_violations=out.limits.hold_violations,
        hold_limit_worst=out.limits.hold_worst,
        approach_line_deviation_max_m=out.approach_line_deviation_max_m,
        place_line_deviation_max_m=out.place_line_deviation_max_m,
        config=config,
        telemetry=telemetry,
    )


__all__ = ["EpisodeConfig", "EpisodeResult", "read_toml", "run_episode"]
