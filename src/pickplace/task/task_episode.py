"""A task with several objects, run and measured: one pick and place after another on one arm, in one simulation.

``run_task(config, seed)`` builds the world with every object, asks the task planner
(:class:`~pickplace.task.tasks.TaskPlanner`) for the next pick and place from the poses the robot observes, runs
it as a :class:`~pickplace.task.skill.PickPlaceSkill` focused on that object (every other object is an obstacle
to its IK, planning and per-step contact monitor), checks after it that no other object was knocked, and at the
end measures every object against what the task wanted. Each pick and place is reported like an episode
(:class:`~pickplace.task.episode.EpisodeResult`), the task as a :class:`TaskResult`.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import ConfigError
from pickplace.grasping.targets import object_yaw, yaw_error
from pickplace.robot import gripper
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import Robot, build
from pickplace.task.arm import Arm
from pickplace.task.episode import EpisodeConfig, EpisodeResult, _plain, _result, run_episode
from pickplace.task.faults import FaultConfig
from pickplace.task.observe import SimulatorObserver
from pickplace.task.phases import Phase
from pickplace.task.skill import PickPlaceSkill
from pickplace.task.tasks import Pick, TaskKind, TaskPlanner, TaskStuck, bottom_z_m, check_reachable, top_z_m
from pickplace.task.telemetry import Telemetry, TelemetryRecorder
from pickplace.world.config import SceneConfig

log = logging.getLogger(__name__)

#: The failure phase of a task that failed between its pick and places (no pick could start, a knocked object not
#: repaired, an object not where the task wants it at the end).
TASK_PHASE = "TASK"
#: Goals the task planner chooses (any free spot of their kind will do), not the task's own: a pick to one is
#: refused (fails in IDLE) if it would turn the object over on the way, and another spot is tried, up to
#: ``SPOTS_TRIED``; then the spots again, turning allowed (slowed down: :data:`~pickplace.task.arm.TURN_OVER_SLOWDOWN`).
SPOT_LABELS = ("bin", "buffer")
#: Most bin or buffer spots tried for one object whose pick cannot start at the first one.
SPOTS_TRIED = 5


@dataclass(frozen=True)
class Knock:
    """An object that moved while another was handled.

    Attributes:
        pick: Index of the pick and place during which it moved.
        name: The object that moved.
        by: The object being handled then.
        shift_m: How far its origin moved (m).
        turn_rad: How far it turned (rad).
        was_done: It was already where the task wants it (placed, in the tower, in the bin).
        repaired: It was picked and placed again.
    """

    pick: int
    name: str
    by: str
    shift_m: float
    turn_rad: float
    was_done: bool
    repaired: bool = False


@dataclass(frozen=True)
class ObjectOutcome:
    """Where one object ended, measured on the simulator's truth after the last release has settled.

    Attributes:
        name: The object.
        ok: It is where the task wants it.
        xy_error_m: Horizontal error (m): from its goal (place), from the level below, or the tower's spot for the
            bottom level (stack); NaN for clear.
        yaw_error_rad: Yaw error (rad, modulo its symmetry), against the same reference; NaN for clear.
        z_error_m: Height error (m): of its lowest point above the surface below it (place, stack) or the bin's
            floor (clear).
        note: Why it is not ok, or ``""``.
    """

    name: str
    ok: bool
    xy_error_m: float
    yaw_error_rad: float
    z_error_m: float
    note: str = ""


@dataclass(frozen=True)
class _Failure:
    """Why a task failed: the reason, the object concerned (or None), the failing pick's phase (None: between
    picks, :data:`TASK_PHASE`) and the error's kind."""

    reason: str
    object: str | None
    phase: str | None
    kind: str


@dataclass(frozen=True, eq=False)
class TaskResult:
    """What one task did, measured. Lengths in m, angles in rad, times in s.

    Attributes:
        success: Every object ended where the task wants it (:attr:`objects`), every pick and place that was
            needed succeeded, and no knocked object was left unrepaired.
        kind: ``place``, ``stack`` or ``clear``.
        order_policy: ``planned`` or ``listed``.
        failure_reason: Why the task failed, or None.
        failure_object: The object whose pick and place failed, or None.
        failure_phase: Its phase that failed; :data:`TASK_PHASE` for a failure between pick and places; None.
        failure_kind: The error behind the failure, or None.
        seed: The task's seed.
        order: ``(object, goal label)`` of each pick and place, in the order run (``goal``, ``buffer``, ``bin``,
            ``level N``).
        picks: One record per pick and place that ran, as for an episode (its clock starts at its own IDLE).
        pick_spans_s: ``(start_s, duration_s)`` of each pick and place on the task's clock (s): from its IDLE to
            the end of the settling after its release (``machine.stable_after_release_s``), the next one's start.
        skipped: One line per pick that could not start where it was chosen (no grasp or spot reached there)
            and was put back.
        knocked: Objects moved while another was handled.
        objects: Where every object ended.
        total_time_s: Simulated time of the whole task (s), the settling after the last release included.
        time_per_object_s: Simulated time of each object's pick and places (s), buffer moves included.
        wall_time_s: Wall-clock time of the whole task (s).
        real_time_factor: Simulated seconds per wall-clock second.
        config: The configuration it ran with.
        telemetry: Per-step samples of the whole task (only when asked for; not serialized).
    """

    success: bool
    kind: str
    order_policy: str
    failure_reason: str | None
    failure_object: str | None
    failure_phase: str | None
    failure_kind: str | None
    seed: int
    order: tuple[tuple[str, str], ...]
    picks: tuple[EpisodeResult, ...]
    pick_spans_s: tuple[tuple[float, float], ...]
    skipped: tuple[str, ...]
    knocked: tuple[Knock, ...]
    objects: tuple[ObjectOutcome, ...]
    total_time_s: float
    time_per_object_s: dict[str, float]
    wall_time_s: float
    real_time_factor: float
    config: EpisodeConfig
    telemetry: Telemetry | None = field(default=None, repr=False)

    @property
    def time_per_pick_s(self) -> float:
        """Mean simulated time per object (s): the total over the number of objects."""
        return self.total_time_s / max(1, len(self.objects))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (NaN becomes None; the telemetry is left out; each pick's config is the task's)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "telemetry":
                continue
            if f.name == "config":
                out[f.name] = value.to_dict()
            elif f.name == "picks":
                out[f.name] = [{k: v for k, v in p.to_dict().items() if k != "config"} for p in value]
            else:
                out[f.name] = _plain(value)
        return out


class _Measure:
    """Reads every object's pose: what the robot observes (the ideal observer: the simulation's own state)."""

    def __init__(self, robot: Robot, d: mujoco.MjData) -> None:
        world = robot.world_scene
        self.observers = {o.name: SimulatorObserver(robot.focus(_view(world, o.name), o.name), d)
                          for o in world.objects}

    def poses(self) -> dict[str, pin.SE3]:
        return {name: obs.observe() for name, obs in self.observers.items()}


def _view(world: SceneConfig, name: str, T_world_object: pin.SE3 | None = None, pick: Pick | None = None
          ) -> SceneConfig:
    """The world seen as one pick and place of the object ``name``: its start where it is, its goal the pick's.

    Raises:
        ConfigError: where it is, it cannot be picked (off the table, on the wall), or the goal is invalid.
    """
    o = next(x for x in world.objects if x.name == name)
    start_xy, start_yaw = o.start_xy_m, o.start_yaw_rad
    if T_world_object is not None:
        start_xy = (float(T_world_object.translation[0]), float(T_world_object.translation[1]))
        start_yaw = object_yaw(T_world_object.rotation)
    goal_xy, goal_yaw = (o.goal_xy_m if o.goal_xy_m is not None else world.goal_xy_m), o.goal_yaw_rad
    goal_z, support = None, ""
    if pick is not None:
        goal_xy, goal_yaw, support = pick.goal.xy_m, pick.goal.yaw_rad, pick.goal.support
        goal_z = pick.goal.surface_z_m if pick.goal.surface_z_m != world.table_height_m else None
    return dataclasses.replace(
        world, object=o.object, start_xy_m=start_xy, start_yaw_rad=start_yaw, goal_xy_m=goal_xy,
        goal_yaw_rad=float(math.remainder(goal_yaw, 2 * math.pi)), goal_z_m=goal_z, goal_support=support, others=(),
        obstacle_xy_m=world.obstacle_centre_xy_m if world.obstacle else world.obstacle_xy_m)


def run_task(config: EpisodeConfig, seed: int = 0, *, record: bool = False, frame_rate_hz: float = 30.0,
             step_hook: Callable[[mujoco.MjData, int, float], None] | None = None) -> TaskResult:
    """Run a task with several objects in simulation and measure it.

    Args:
        config: The configuration; ``config.task`` says what to do, ``config.scene`` has the objects.
        seed: Seed of the task's random streams (the planner's).
        record: Keep per-step telemetry of the whole task in the result.
        frame_rate_hz: Video frames per simulated second kept when recording.
        step_hook: Called after every simulation step with the data, the index of the running pick and place
            and the task's time (s): tests use it to disturb the world.

    Returns:
        The :class:`TaskResult`; a failed task is reported in it, not raised.

    Raises:
        ConfigError: the configuration or the seed is invalid (nothing has run).
    """
    if not isinstance(config, EpisodeConfig) or config.task is None:
        raise ConfigError("task", getattr(config, "task", None), "run_task needs a config with a [task] table")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError("seed", seed, "must be an integer >= 0")
    if config.profile.realistic:
        raise ConfigError("profile.name", config.profile.name, "tasks with several objects run in the ideal profile "
                                                              "(the camera's segmentation takes one object)")
    if config.faults != FaultConfig():
        raise ConfigError("faults", "...", "faults are injected into single pick and places (run_episode), not tasks")
    task = config.task
    task.check_scene(config.scene)
    check_reachable(config.scene, task.kind, config.machine.planning_margin_m)
    t_wall0 = time.perf_counter()
    world = config.scene
    robot = build(world)
    d = robot.make_data()
    config = dataclasses.replace(config, planner=dataclasses.replace(config.planner, seed=seed))
    planner = TaskPlanner(world, task, config.machine.place_tolerance_xy_m, config.machine.place_tolerance_yaw_rad)
    recorder = TelemetryRecorder(robot, frame_rate_hz, world.goal_pos_m) if record else None
    measure = _Measure(robot, d)
    run = _TaskRun(config, seed, robot, d, planner, recorder, measure, step_hook)
    t_sim0 = time.perf_counter()
    run.run()
    wall = time.perf_counter() - t_wall0
    sim_wall = time.perf_counter() - t_sim0
    objects = run.final_outcomes()
    success = run.failure is None and all(o.ok for o in objects)
    failure = run.failure
    if failure is None and not success:
        bad = next(o for o in objects if not o.ok)
        failure = _Failure(f"{bad.name}: {bad.note}", bad.name, None, "TaskIncomplete")
    result = TaskResult(
        success=success, kind=task.kind, order_policy=task.order,
        failure_reason=failure.reason if failure else None, failure_object=failure.object if failure else None,
        failure_phase=(failure.phase or TASK_PHASE) if failure else None,
        failure_kind=failure.kind if failure else None,
        seed=seed, order=tuple(run.order), picks=tuple(run.picks), pick_spans_s=tuple(run.spans),
        skipped=tuple(run.skipped),
        knocked=tuple(run.knocks), objects=objects, total_time_s=run.t,
        time_per_object_s=dict(run.time_per_object), wall_time_s=wall,
        real_time_factor=run.t / sim_wall if sim_wall > 0 else math.nan, config=config,
        telemetry=recorder.freeze() if recorder is not None else None)
    log.info("task %s seed %d: %s in %.2f s simulated, %.2f s wall", task.kind, seed,
             "success" if success else f"FAILED: {result.failure_reason}", run.t, wall)
    return result


def _did_not_start(result: EpisodeResult) -> bool:
    """Whether a pick and place failed before the arm moved, for want of a grasp or a place that reaches, or of a
    path to the grasp (planned before the first motion)."""
    if result.failure_phase == Phase.IDLE.value and result.failure_kind in _NOT_STARTED:
        return True
    phases = [p for p, *_ in result.phase_timeline]
    return (result.failure_phase == Phase.PLAN_APPROACH.value and result.failure_kind in _PLANNING_FAILED
            and phases == [Phase.IDLE.value, Phase.PLAN_APPROACH.value])


#: Failures of IDLE that leave everything as it was: no grasp or place reaches, or the chosen goal does not suit
#: the object (a spot the planner chose on the bin's wall).
_NOT_STARTED = ("UnreachableTarget", "TurnsOver", "ConfigError", "InsideObstacle")
#: The planner's failures (:class:`~pickplace.errors.PlanningFailed` and its kinds), and a planned path the time
#: scaling could not keep clear (:class:`~pickplace.errors.TimingFailed`).
_PLANNING_FAILED = ("PlanningFailed", "SearchExhausted", "TimingFailed")


class _TaskRun:
    """The loop of one task: choose, run, check for knocks, until done or failed."""

    def __init__(self, config: EpisodeConfig, seed: int, robot: Robot, d: mujoco.MjData, planner: TaskPlanner,
                 recorder: TelemetryRecorder | None, measure: _Measure,
                 step_hook: Callable[[mujoco.MjData, int, float], None] | None) -> None:
        self.config, self.seed, self.robot, self.d = config, seed, robot, d
        self.task = config.task
        assert self.task is not None
        self.planner, self.recorder, self.measure, self.step_hook = planner, recorder, measure, step_hook
        self.world = robot.world_scene
        self.t = 0.0
        self.order: list[tuple[str, str]] = []
        self.picks: list[EpisodeResult] = []
        self.spans: list[tuple[float, float]] = []
        self.skipped: list[str] = []
        self.knocks: list[Knock] = []
        self.time_per_object: dict[str, float] = {o.name: 0.0 for o in self.world.objects}
        self.count: dict[str, int] = dict.fromkeys(self.time_per_object, 0)
        self.failure: _Failure | None = None
        self.loop_rng = np.random.default_rng([seed, 4])
        #: Objects whose spots may be reached by turning them over (none of ``SPOTS_TRIED`` spots kept them upright)
        self.turn_over: set[str] = set()

    def run(self) -> None:
        skip: set[str] = set()
        spots_excluded: dict[str, list[tuple[float, float]]] = {}
        while True:
            poses = self.measure.poses()
            try:
                pick = self.planner.next_pick(poses, skip)
            except TaskStuck as exc:
                self.failure = _Failure(str(exc), None, None, "TaskStuck")
                return
            if pick is None:
                return
            chosen = self._other_spot(pick, poses, spots_excluded.get(pick.name, []))
            if chosen is None:  # every spot tried
                if spots_excluded.get(pick.name) and self._turning_allowed(pick.name):
                    spots_excluded[pick.name].clear()
                    continue
                skip.add(pick.name)  # another object first
                continue
            pick = chosen
            if self.count[pick.name] >= self.task.max_picks_per_object:
                self.failure = _Failure(f"the {pick.name} was picked {self.count[pick.name]} times (task."
                                f"max_picks_per_object) and is still not done", pick.name, None, "TaskStuck")
                return
            try:
                view = _view(self.world, pick.name, poses[pick.name], pick)
            except ConfigError as exc:
                self.failure = _Failure(f"the {pick.name} cannot be picked and placed from where it is: {exc}",
                                        pick.name, None, type(exc).__name__)
                return
            result = self._run_pick(pick, view)
            after = self.measure.poses()
            knocked = self._knocks(pick, poses, after)
            if not result.success:
                if _did_not_start(result):
                    # nothing moved: this pick cannot start from here; try another spot, or another object first
                    self.skipped.append(f"{pick.name} -> {pick.goal.label}: {result.failure_reason}")
                    log.info("task: the %s cannot start (%s); trying another", pick.name, result.failure_reason)
                    self.planner.buffered.discard(pick.name)
                    if pick.goal.label in SPOT_LABELS:
                        excluded = spots_excluded.setdefault(pick.name, [])
                        excluded.append(pick.goal.xy_m)
                        if len(excluded) < SPOTS_TRIED:
                            continue
                        if self._turning_allowed(pick.name):
                            excluded.clear()
                            continue
                    skip.add(pick.name)
                    continue
                if self._can_retry(pick.name, after):  # it rests where it can be picked again: the task goes on
                    log.info("task: the %s's pick and place failed in %s (%s); it rests on %s, taking it again",
                             pick.name, result.failure_phase, result.failure_reason, "the bin's floor"
                             if self.planner.in_bin(pick.name, after[pick.name]) else "the table")
                    if knocked and not self._repair(knocked, after):
                        return
                    continue
                self.failure = _Failure(f"the {pick.name}'s pick and place failed in {result.failure_phase}: "
                                        f"{result.failure_reason}", pick.name, result.failure_phase,
                                        result.failure_kind or "PickPlaceError")
                return
            skip.clear()
            spots_excluded.pop(pick.name, None)
            self.turn_over.discard(pick.name)
            self.planner.placed(pick, after)
            if knocked and not self._repair(knocked, after):
                return

    def _turning_allowed(self, name: str) -> bool:
        """After no spot kept the object upright on the way: the spots again, turning it allowed (once); whether
        that is new."""
        if name in self.turn_over:
            return False
        log.info("task: no spot keeps the %s upright on the way; trying them again, turning it", name)
        self.turn_over.add(name)
        return True

    def _can_retry(self, name: str, poses: dict[str, pin.SE3]) -> bool:
        """Whether a failed pick and place can be taken again: tries are left, the hand is empty, and the object
        rests (on the table, or on the bin's floor) within 5 mm of the surface, upright as it can be grasped."""
        if self.count[name] >= self.task.max_picks_per_object:
            return False
        if np.any(gripper.pad_forces(self.robot, self.d) > 0.0):
            return False
        o, T = self.planner.objects[name], poses[name]
        obs = self.measure.observers[name]
        if float(np.linalg.norm(obs.object_velocity()[:3])) > 0.01:
            return False
        surface = self.world.table_height_m
        if self.world.bin is not None and self.planner.in_bin(name, T):
            surface = self.world.bin.floor_z_m(self.world.table_height_m)
        upright = float(np.linalg.norm(pin.log3(T.rotation @ rot_z(-object_yaw(T.rotation)))))
        return abs(bottom_z_m(o, T) - surface) <= 0.005 and upright < 0.1

    def _other_spot(self, pick: Pick, poses: dict[str, pin.SE3], excluded: list[tuple[float, float]]) -> Pick | None:
        """The pick with a spot not tried before (bin and buffer spots); None if no spot is left."""
        if not excluded or pick.goal.label not in SPOT_LABELS:
            return pick
        finder = self.planner.bin_spot if pick.goal.label == "bin" else self.planner.buffer_spot
        goal = finder(pick.name, poses, exclude=excluded)
        return None if goal is None else Pick(pick.name, goal)

    def _run_pick(self, pick: Pick, view: SceneConfig) -> EpisodeResult:
        """One pick and place of ``pick`` on the shared simulation; the task's clock advances by its cycle."""
        cfg = self.config
        robot = self.robot.focus(view, pick.name)
        index = len(self.picks)
        log.info("task pick %d: the %s to %s (%.3f, %.3f) m", index + 1, pick.name, pick.goal.label, *pick.goal.xy_m)
        if self.recorder is not None:
            self.recorder.robot = robot
            self.recorder.goal_pos_m = view.goal_pos_m
        arm = Arm(robot, self.d, cfg.machine, cfg.control, cfg.planner, cfg.timing, self.recorder,
                  loop=cfg.profile.control_loop(self.loop_rng))
        monitor = arm.monitor
        t0 = self.t
        monitor.t = t0
        if self.step_hook is not None:
            hook, inner = self.step_hook, monitor.injector

            class _Hooked:  # the monitor calls its injector after every step
                def step(self, d: mujoco.MjData, phase: str, t: float) -> None:
                    if inner is not None:
                        inner.step(d, phase, t)
                    hook(d, index, t)

            monitor.injector = _Hooked()  # type: ignore[assignment]
        t_wall = time.perf_counter()
        try:
            turn_over = pick.goal.label not in SPOT_LABELS or pick.name in self.turn_over
            out = PickPlaceSkill(arm, cfg.ik, turn_over=turn_over).run()
        except ConfigError as exc:  # the goal the planner chose does not suit this object (nothing has moved)
            out = arm.out
            out.phase, out.failure_phase, out.failure_reason = Phase.FAILED, Phase.IDLE, str(exc)
            out.failure_kind = type(exc).__name__
        wall = time.perf_counter() - t_wall
        self.t = monitor.t
        out.cycle_time_s -= t0
        out.timeline = [(p, s - t0, dur, o) for p, s, dur, o in out.timeline]
        view_cfg = dataclasses.replace(cfg, scene=view, task=None)
        result = _result(out, view_cfg, self.seed, wall, (self.t - t0) / wall if wall > 0 else math.nan, None)
        if not _did_not_start(result):  # a pick that could not start moved nothing: it is only noted as skipped
            self.picks.append(result)
            self.spans.append((t0, self.t - t0))
            self.order.append((pick.name, pick.goal.label))
            self.count[pick.name] += 1
            self.time_per_object[pick.name] += self.t - t0
        return result

    def _knocks(self, pick: Pick, before: dict[str, pin.SE3], after: dict[str, pin.SE3]) -> list[Knock]:
        """Every other object that moved more than the knock tolerance during ``pick``."""
        out = []
        for name, T0 in before.items():
            if name == pick.name:
                continue
            T1 = after[name]
            shift = float(np.linalg.norm(T1.translation - T0.translation))
            turn = float(np.linalg.norm(pin.log3(T0.rotation.T @ T1.rotation)))
            if shift > self.task.knock_tolerance_m or turn > self.task.knock_tolerance_rad:
                knock = Knock(len(self.picks) - 1, name, pick.name, shift, turn, self.planner.done(name, before))
                log.warning("task: the %s moved %.1f mm and turned %.1f deg while the %s was handled", name,
                            shift * 1e3, math.degrees(turn), pick.name)
                out.append(knock)
        return out

    def _repair(self, knocked: list[Knock], after: dict[str, pin.SE3]) -> bool:
        """Re-queue knocked objects that were done (or fail the task if repairs are off); whether to go on."""
        lost = self.planner.check_tower(after) if self.task.kind == TaskKind.STACK else 0
        for k in knocked:
            repaired = k.was_done and self.task.repair
            self.knocks.append(dataclasses.replace(k, repaired=repaired))
            if k.was_done and not self.task.repair:
                self.failure = _Failure(f"the {k.name} was knocked ({k.shift_m * 1e3:.1f} mm, "
                                        f"{math.degrees(k.turn_rad):.1f} deg) while the {k.by} was handled", k.name,
                                        None, "ObjectKnocked")
                return False
        if lost:
            log.info("task: %d level(s) of the tower fell; they will be stacked again", lost)
        return True

    def final_outcomes(self) -> tuple[ObjectOutcome, ...]:
        """Where every object ended (the simulator's truth: a measurement of the task)."""
        poses = self.measure.poses()
        planner, task = self.planner, self.task
        objects = planner.objects
        out = []
        if task.kind == TaskKind.STACK:
            tower = list(planner.tower)
            for k, name in enumerate(tower):
                T = poses[name]
                o = objects[name]
                if k == 0:
                    ref_xy, R_ref = np.asarray(task.stack_xy_m), rot_z(task.stack_yaw_rad)
                    surface = self.world.table_height_m
                else:
                    below = poses[tower[k - 1]]
                    ref_xy, R_ref = below.translation[:2], below.rotation
                    surface = top_z_m(objects[tower[k - 1]], below)
                xy = float(np.hypot(*(T.translation[:2] - ref_xy)))
                yaw = yaw_error(T.rotation, R_ref, o.object.yaw_period_rad)
                z = bottom_z_m(o, T) - surface
                limit_xy = task.level_tolerance_xy_m if k > 0 else self.config.machine.place_tolerance_xy_m
                ok = xy <= limit_xy and abs(yaw) <= (task.level_tolerance_yaw_rad if k > 0 else math.inf) \
                    and abs(z) <= 0.003
                note = "" if ok else (f"level {k + 1} is {xy * 1e3:.2f} mm and {math.degrees(yaw):.2f} deg off the "
                                      f"one below, {z * 1e3:.1f} mm above it")
                out.append(ObjectOutcome(name, ok, xy, yaw, z, note))
            for name in objects:
                if name not in tower:
                    out.append(ObjectOutcome(name, False, math.nan, math.nan, math.nan, "not in the tower"))
            return tuple(out)
        for name, o in objects.items():
            T = poses[name]
            if task.kind == TaskKind.CLEAR:
                assert self.world.bin is not None
                z = bottom_z_m(o, T) - self.world.bin.floor_z_m(self.world.table_height_m)
                ok = planner.in_bin(name, T)
                out.append(ObjectOutcome(name, ok, math.nan, math.nan, z, "" if ok else "not inside the bin"))
                continue
            assert o.goal_xy_m is not None
            xy = float(np.hypot(*(T.translation[:2] - np.asarray(o.goal_xy_m))))
            yaw = yaw_error(T.rotation, rot_z(o.goal_yaw_rad), o.object.yaw_period_rad)
            z = bottom_z_m(o, T) - self.world.table_height_m
            ok = planner.done(name, poses) and abs(z) <= self.config.machine.place_tolerance_z_m
            out.append(ObjectOutcome(name, ok, xy, yaw, z, "" if ok else
                                     f"{xy * 1e3:.2f} mm and {math.degrees(yaw):.2f} deg from its goal"))
        return tuple(out)


def run_trial(config: EpisodeConfig, seed: int = 0) -> EpisodeResult | TaskResult:
    """One pick and place (:func:`~pickplace.task.episode.run_episode`) or, with a ``[task]``, a task
    (:func:`run_task`): what a campaign's trial runs."""
    return run_task(config, seed) if config.task is not None else run_episode(config, seed)


__all__ = ["TASK_PHASE", "Knock", "ObjectOutcome", "TaskResult", "run_task", "run_trial"]
