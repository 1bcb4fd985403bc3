"""What a campaign runs: the randomization, the campaign config, and its trials.

Trial ``i`` draws its scene and its episode seed from ``numpy.random.SeedSequence(campaign_seed, spawn_key=(i,
...))``: they depend on the campaign seed and ``i`` only, not on the number of trials, the workers or the
backend, so any trial can be re-run alone (:func:`trial_config`). :func:`execute_trial` runs one trial in a
worker and turns it into its results line; an exception raised by the episode becomes a failed trial of phase
``WORKER``.
"""

from __future__ import annotations

import ctypes
import dataclasses
import itertools
import logging
import math
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pickplace.errors import ConfigError, InsideObstacle, PickPlaceError
from pickplace.task.episode import EpisodeConfig, EpisodeResult
from pickplace.task.task_episode import TaskResult
from pickplace.world.config import check_int, check_range, check_vector
from pickplace.world.objects import LIBRARY, ObjectConfig, library_object, scaled

log = logging.getLogger(__name__)

#: The phase recorded for a trial whose worker raised, crashed or timed out.
WORKER_PHASE = "WORKER"
#: A results line may carry, under this key, what a trial produced besides its figures (e.g. a recorded
#: demonstration, :mod:`pickplace.eval.dataset`): the parent takes it out before the line is written
#: (:func:`~pickplace.eval.campaign.run_campaign`'s ``on_sidecar``).
SIDECAR_KEY = "sidecar"


class CampaignError(PickPlaceError):
    """A campaign cannot run: a worker failed to start, a Ray cluster cannot be joined, or a package is missing."""


# --------------------------------------------------------------------------- #
# randomization
# --------------------------------------------------------------------------- #

Range = tuple[float, float]

#: Per field of RandomizationSpec: (bounds of the range, unit, what it changes).
_SPEC_FIELDS: dict[str, tuple[float, float, str, str]] = {
    "start_dx_m": (-0.5, 0.5, "m", "offset"),
    "start_dy_m": (-0.5, 0.5, "m", "offset"),
    "start_dyaw_rad": (-math.pi, math.pi, "rad", "offset"),
    "goal_dx_m": (-0.5, 0.5, "m", "offset"),
    "goal_dy_m": (-0.5, 0.5, "m", "offset"),
    "goal_dyaw_rad": (-math.pi, math.pi, "rad", "offset"),
    "object_mass_scale": (1e-3, 100.0, "", "object"),
    "object_size_scale": (0.1, 5.0, "", "object"),
    "object_friction": (0.05, 5.0, "", "object"),
    "transport_push_n": (0.0, 200.0, "N", "perturbation"),
    "pad_friction_scale": (0.0, 5.0, "", "fault"),
    "true_mass_scale": (0.01, 50.0, "", "fault"),
    "joint_noise_rad": (0.0, 0.05, "rad", "fault"),
    "object_mass_kg": (1e-3, 50.0, "kg", "object"),
}
#: ``[randomization]`` keys of earlier versions: old name -> field, and how a range converts (``None``: as is;
#: ``"mass"``: divided by the base object's mass; ``"edge"``: divided by the base cube's edge).
LEGACY_SPEC_KEYS: dict[str, tuple[str, str | None]] = {
    "cube_dx_m": ("start_dx_m", None), "cube_dy_m": ("start_dy_m", None), "cube_dyaw_rad": ("start_dyaw_rad", None),
    "cube_mass_kg": ("object_mass_scale", "mass"), "cube_size_m": ("object_size_scale", "edge"),
    "cube_friction": ("object_friction", None), "cube_mass_scale": ("true_mass_scale", None),
}
#: Fields added after the first campaigns: in :meth:`RandomizationSpec.to_dict` only when set.
_NEWER_FIELDS = ("object_mass_kg",)
#: The first fields of _SPEC_FIELDS; the push's direction and start are drawn right after them, and any field
#: added later after those, so that adding a field never changes the values of the existing ones.
_N_FIRST_FIELDS = 10
#: Draws of a trial's parameters before giving up when each puts the object inside the obstacle.
MAX_REDRAWS = 1000
#: Duration of a randomized transport push when the base config's faults do not set one (s).
PUSH_DURATION_S = 0.05
#: Window, after the transport trajectory starts, in which a randomized push starts (s).
PUSH_START_S = (0.05, 0.5)


@dataclass(frozen=True)
class RandomizationSpec:
    """Ranges ``(lo, hi)`` sampled uniformly per trial; ``None`` keeps the base config's value.

    The ``d`` fields are offsets added to the base config's value, the ``scale`` fields multiply it, the others
    replace it. The defaults are ranges around the base object: for the 40 mm, 150 g cube they are the same
    draws as the cube-only ranges of earlier versions (mass 0.05-0.5 kg, edge 30-50 mm).

    Attributes:
        start_dx_m: Offset of the object's start x (m).
        start_dy_m: Offset of the object's start y (m).
        start_dyaw_rad: Offset of the object's start yaw (rad).
        goal_dx_m: Offset of the goal x (m).
        goal_dy_m: Offset of the goal y (m).
        goal_dyaw_rad: Offset of the goal yaw (rad).
        object_mass_scale: The object's mass relative to the base config's.
        object_size_scale: Every dimension of the object relative to the base config's.
        object_friction: Friction coefficient of every contact with the object.
        transport_push_n: Magnitude of a push on the carried object (N), off by default. Its direction is drawn
            uniformly on the sphere and its start uniformly in ``PUSH_START_S`` after the transport starts;
            it lasts the base config's ``faults.transport_push_s``, or ``PUSH_DURATION_S``.
        pad_friction_scale: The ``faults.pad_friction_scale`` of each trial, off by default.
        true_mass_scale: The ``faults.true_mass_scale`` of each trial (true / believed mass), off by default.
        joint_noise_rad: The ``faults.joint_noise_rad`` of each trial (rad), off by default.
        object_mass_kg: The object's mass (kg), whatever the base object's (e.g. for a mix of objects); off by
            default; not with ``object_mass_scale``.
        objects: Names of library objects, one drawn uniformly per trial to replace the base config's object
            (before its mass, size and friction are scaled); ``None`` (default): the base config's object. Its
            draw comes after every other, so adding it changes none of their values. In a task campaign: the
            library objects the trials' objects are drawn from.
        task_objects: In a task campaign (the base config has a ``[task]``): the range ``(lo, hi)`` of the number
            of objects per trial, both included; ``None``: as many as the base config has (3 if it has one).
            A task campaign draws each trial's objects and their poses whole
            (:func:`~pickplace.task.tasks.random_task_scene`); the single object's ranges above do not apply.
    """

    start_dx_m: Range | None = (-0.05, 0.05)
    start_dy_m: Range | None = (-0.05, 0.05)
    start_dyaw_rad: Range | None = (-math.pi / 4, math.pi / 4)
    goal_dx_m: Range | None = (-0.05, 0.05)
    goal_dy_m: Range | None = (-0.05, 0.05)
    goal_dyaw_rad: Range | None = (0.0, 0.0)
    object_mass_scale: Range | None = (1.0 / 3.0, 10.0 / 3.0)
    object_size_scale: Range | None = (0.75, 1.25)
    object_friction: Range | None = (0.6, 1.5)
    transport_push_n: Range | None = None
    pad_friction_scale: Range | None = None
    true_mass_scale: Range | None = None
    joint_noise_rad: Range | None = None
    object_mass_kg: Range | None = None
    objects: tuple[str, ...] | None = None
    task_objects: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if self.task_objects is not None:
            value = self.task_objects
            if isinstance(value, str) or not isinstance(value, (list, tuple)) or len(value) != 2:
                raise ConfigError("randomization.task_objects", value, "must be a range [lo, hi] of object counts")
            lo = check_int("randomization.task_objects", value[0], 1, 8)
            hi = check_int("randomization.task_objects", value[1], lo, 8)
            object.__setattr__(self, "task_objects", (lo, hi))
        if self.objects is not None:
            if isinstance(self.objects, str) or not isinstance(self.objects, (list, tuple)) or not self.objects:
                raise ConfigError("randomization.objects", self.objects,
                                  f"must be a non-empty list of library objects ({', '.join(LIBRARY)})")
            for name in self.objects:
                if name not in LIBRARY:
                    raise ConfigError("randomization.objects", name, f"must be one of {', '.join(LIBRARY)}")
            object.__setattr__(self, "objects", tuple(self.objects))
        for name, (lo, hi, unit, _) in _SPEC_FIELDS.items():
            value = getattr(self, name)
            if value is None:
                continue
            rng = check_vector(f"randomization.{name}", value, 2, lo, hi, unit=unit)
            if rng[0] > rng[1]:
                raise ConfigError(f"randomization.{name}", value, "must be a range (lo, hi) with lo <= hi")
            object.__setattr__(self, name, rng)
        if self.object_mass_kg is not None and self.object_mass_scale is not None:
            raise ConfigError("randomization.object_mass_kg", self.object_mass_kg,
                              "sets the mass itself: set object_mass_scale = false with it")

    @classmethod
    def off(cls) -> RandomizationSpec:
        """No randomization: every trial runs the base config (only the episode seed changes)."""
        return cls(**dict.fromkeys(_SPEC_FIELDS))  # objects: None by default

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_object: ObjectConfig | None = None) -> RandomizationSpec:
        """Build from a ``[randomization]`` table: ``name = [lo, hi]``, or ``name = false`` to keep the base value.

        Fields not given keep their defaults. The keys of earlier versions (:data:`LEGACY_SPEC_KEYS`) are
        converted: an absolute ``cube_mass_kg`` or ``cube_size_m`` range becomes a scale of ``base_object``.
        """
        if not isinstance(data, Mapping):
            raise ConfigError("randomization", data, "must be a table of keys")
        base_object = base_object if base_object is not None else ObjectConfig()
        changes: dict[str, Any] = {}
        for key, value in data.items():
            if key in ("objects", "task_objects"):
                changes[key] = None if value is False else value
                continue
            name, convert = LEGACY_SPEC_KEYS.get(key, (key, None))
            if name not in _SPEC_FIELDS:
                raise ConfigError(f"randomization.{key}", value,
                                  f"unknown key; allowed: {', '.join(_SPEC_FIELDS)}, objects, task_objects")
            if value is False:
                changes[name] = None
            elif isinstance(value, (list, tuple)):
                changes[name] = _legacy_range(key, value, convert, base_object)
            else:
                raise ConfigError(f"randomization.{key}", value,
                                  "must be a range of two numbers lo <= hi (e.g. [0.5, 2.0]) or false")
        return cls(**changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain data, the inverse of :meth:`from_dict` (``false`` for a field that is not randomized)."""
        out: dict[str, Any] = {name: list(getattr(self, name)) if getattr(self, name) is not None else False
                               for name in _SPEC_FIELDS if name not in _NEWER_FIELDS or getattr(self, name)}
        if self.objects is not None:  # newer fields only when set: earlier campaigns keep their identity
            out["objects"] = list(self.objects)
        if self.task_objects is not None:
            out["task_objects"] = list(self.task_objects)
        return out

    def active(self) -> list[str]:
        """Names of the randomized range fields (those not ``None``)."""
        return [name for name in _SPEC_FIELDS if getattr(self, name) is not None]

    def sample(self, rng: np.random.Generator) -> dict[str, Any]:
        """One draw: randomized field name -> value, and ``object`` -> a library name if ``objects`` is set (the
        same number of draws whatever is randomized)."""
        u = rng.random(len(_SPEC_FIELDS) + 3)  # + the push's direction (2) and start (1)
        first = _N_FIRST_FIELDS
        draws = np.concatenate([u[:first], u[first + 3:]])  # per field, in _SPEC_FIELDS order
        out: dict[str, float] = {}
        for k, name in enumerate(_SPEC_FIELDS):
            r = getattr(self, name)
            if r is not None:
                out[name] = float(r[0] + draws[k] * (r[1] - r[0]))
        if self.transport_push_n is not None:
            a, b, c = u[first:first + 3]
            out["push_azimuth_rad"] = float(2 * math.pi * a)
            out["push_elevation_rad"] = float(math.asin(2 * b - 1))
            out["push_start_s"] = float(PUSH_START_S[0] + c * (PUSH_START_S[1] - PUSH_START_S[0]))
        pick = float(rng.random())
        if self.objects is not None:
            out["object"] = self.objects[min(int(pick * len(self.objects)), len(self.objects) - 1)]
        return out


def _legacy_range(key: str, value: Any, convert: str | None, base: ObjectConfig) -> tuple[float, ...]:
    """A range as given, or an old absolute cube range as a scale of the base object."""
    rng = tuple(value)
    if convert is None:
        return rng
    if convert == "edge":
        if base.kind != "box":
            raise ConfigError(f"randomization.{key}", value, f"is a cube's edge; the object is a {base.kind} "
                                                             "(use object_size_scale)")
        ref = base.size_m[0]
    else:
        ref = base.mass_kg
    try:
        return tuple(float(v) / ref for v in rng)
    except (TypeError, ValueError):
        raise ConfigError(f"randomization.{key}", value, "must be a range of two numbers lo <= hi") from None


def apply_params(base: EpisodeConfig, params: Mapping[str, Any]) -> EpisodeConfig:
    """The base config with sampled parameters (names of :class:`RandomizationSpec` fields) applied."""
    sc = base.scene
    changes: dict[str, Any] = {}
    if "start_dx_m" in params or "start_dy_m" in params:
        changes["start_xy_m"] = (sc.start_xy_m[0] + params.get("start_dx_m", 0.0),
                                 sc.start_xy_m[1] + params.get("start_dy_m", 0.0))
    if "goal_dx_m" in params or "goal_dy_m" in params:
        changes["goal_xy_m"] = (sc.goal_xy_m[0] + params.get("goal_dx_m", 0.0),
                                sc.goal_xy_m[1] + params.get("goal_dy_m", 0.0))
    if "start_dyaw_rad" in params:
        changes["start_yaw_rad"] = sc.start_yaw_rad + params["start_dyaw_rad"]
    if "goal_dyaw_rad" in params:
        changes["goal_yaw_rad"] = sc.goal_yaw_rad + params["goal_dyaw_rad"]
    obj = library_object(params["object"]) if "object" in params else sc.object
    if "object_size_scale" in params:
        obj = scaled(obj, params["object_size_scale"])
    if "object_mass_scale" in params:
        obj = dataclasses.replace(obj, mass_kg=obj.mass_kg * params["object_mass_scale"])
    if "object_mass_kg" in params:
        obj = dataclasses.replace(obj, mass_kg=params["object_mass_kg"])
    if "object_friction" in params:
        obj = dataclasses.replace(obj, friction=params["object_friction"])
    if obj != sc.object:
        changes["object"] = obj
    config = base.with_scene(**changes) if changes else base
    if "transport_push_n" in params:
        az, el, mag = params["push_azimuth_rad"], params["push_elevation_rad"], params["transport_push_n"]
        force = (mag * math.cos(el) * math.cos(az), mag * math.cos(el) * math.sin(az), mag * math.sin(el))
        faults = dataclasses.replace(base.faults, transport_push_n=force, transport_push_start_s=params["push_start_s"],
                                     transport_push_s=base.faults.transport_push_s or PUSH_DURATION_S)
        config = dataclasses.replace(config, faults=faults)
    faults = {name: params[name] for name in ("pad_friction_scale", "true_mass_scale", "joint_noise_rad")
              if name in params}
    if faults:
        config = dataclasses.replace(config, faults=dataclasses.replace(config.faults, **faults))
    return config


#: Which randomization fields move each scene field (to name them in errors).
_SCENE_TO_SPEC = {
    "scene.start_xy_m": ("start_dx_m", "start_dy_m", "object_size_scale"),
    "scene.goal_xy_m": ("goal_dx_m", "goal_dy_m", "object_size_scale"),
    "scene.start_yaw_rad": ("start_dyaw_rad",),
    "scene.goal_yaw_rad": ("goal_dyaw_rad",),
}


def _check_extremes(base: EpisodeConfig, spec: RandomizationSpec) -> None:
    """Every corner of the randomization box gives a valid scene, with the object on the table at start and goal
    (for each of ``objects``). A start inside the obstacle is not an error: the trial draws again
    (:func:`make_trial`)."""
    if base.task is not None:  # a task's trials are drawn whole (make_trial); each is checked as it is drawn
        return
    active = [name for name in spec.active() if _SPEC_FIELDS[name][3] in ("offset", "object")]  # scene fields
    free = dataclasses.replace(base, scene=dataclasses.replace(base.scene, obstacle=False))
    for corner, name in itertools.product(range(1 << len(active)), spec.objects or (None,)):
        params: dict[str, Any] = {name: getattr(spec, name)[(corner >> k) & 1] for k, name in enumerate(active)}
        if name is not None:
            params["object"] = name
        try:
            apply_params(free, params).scene.check_goal_on_table()
        except ConfigError as exc:
            names = [n for n in _SCENE_TO_SPEC.get(exc.field.split("[")[0], ()) if n in active] or active
            raise ConfigError("randomization." + "/".join(names), [getattr(spec, n) for n in names],
                              f"can give an invalid scene around the base config ({exc})") from None


# --------------------------------------------------------------------------- #
# campaign and trials
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class CampaignConfig:
    """What a campaign runs.

    Attributes:
        base: The episode config the trials randomize.
        randomization: What varies between trials.
        trials: Number of trials N (trials 0 .. N-1).
        seed: Campaign seed; trial i's scene and episode seed derive from it and i only.
        workers: Trials running at once (local worker processes, or Ray actors); None: every core
            (``os.cpu_count()`` locally, the cluster's CPUs on Ray).
        timeout_s: Per-trial wall-clock limit (s), counted from the moment a worker that is up (started, pickplace
            imported) takes the trial; a trial over it is killed with its worker and recorded as failed.
    """

    base: EpisodeConfig = field(default_factory=EpisodeConfig)
    randomization: RandomizationSpec = field(default_factory=RandomizationSpec)
    trials: int = 100
    seed: int = 0
    workers: int | None = None
    timeout_s: float = 60.0

    def __post_init__(self) -> None:
        if not isinstance(self.base, EpisodeConfig):
            raise ConfigError("campaign.base", self.base, "must be an EpisodeConfig")
        if not isinstance(self.randomization, RandomizationSpec):
            raise ConfigError("campaign.randomization", self.randomization, "must be a RandomizationSpec")
        object.__setattr__(self, "trials", check_int("campaign.trials", self.trials, 1, 10_000_000))
        object.__setattr__(self, "seed", check_int("campaign.seed", self.seed, 0, 2**63 - 1))
        if self.workers is not None:
            object.__setattr__(self, "workers", check_int("campaign.workers", self.workers, 1, 4096))
        object.__setattr__(self, "timeout_s", check_range("campaign.timeout_s", self.timeout_s, 0.0, 86400.0,
                                                          lo_open=True, unit="s"))
        _check_extremes(self.base, self.randomization)

    def identity(self) -> dict[str, Any]:
        """What defines the trials (base config, randomization, seed): must match to resume a campaign."""
        return {"base": self.base.to_dict(), "randomization": self.randomization.to_dict(), "seed": self.seed}


@dataclass(frozen=True)
class Trial:
    """One trial of a campaign, ready to run.

    Attributes:
        index: Trial index i (0-based).
        seed: The episode's seed.
        params: The sampled parameters (RandomizationSpec field -> value; offsets in m/rad, SI units).
        config: The base config with the parameters applied.
    """

    index: int
    seed: int
    params: dict[str, Any]
    config: EpisodeConfig


def trial_seed(campaign_seed: int, index: int) -> int:
    """Episode seed of trial ``index`` (in [0, 2**32)): a function of the campaign seed and the index only."""
    ss = np.random.SeedSequence(campaign_seed, spawn_key=(index, 0))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def make_trial(campaign: CampaignConfig, index: int) -> Trial:
    """Trial ``index`` of ``campaign``: its sampled parameters, config and seed."""
    check_int("trial", index, 0)
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(index, 1)))
    if campaign.base.task is not None:
        return _task_trial(campaign, index, rng)
    for _ in range(MAX_REDRAWS):
        params = campaign.randomization.sample(rng)
        try:
            config = apply_params(campaign.base, params)
            config.scene.check_goal_on_table()
        except InsideObstacle:
            continue  # drawn inside the wall: draw again from the same stream
        return Trial(index, trial_seed(campaign.seed, index), params, config)
    raise ConfigError("randomization", campaign.randomization.to_dict(),
                      f"put the object inside the obstacle at its start or goal in {MAX_REDRAWS} draws running")


def _task_trial(campaign: CampaignConfig, index: int, rng: np.random.Generator) -> Trial:
    """Trial ``index`` of a task campaign: its objects (how many, which, where) drawn whole."""
    from pickplace.task.tasks import random_task_scene

    base, spec = campaign.base, campaign.randomization
    assert base.task is not None
    count = len(base.scene.objects) if base.scene.others else 3
    lo, hi = spec.task_objects or (count, count)
    n = int(rng.integers(lo, hi + 1))
    plain = dataclasses.replace(base.scene, others=(), bin=None)
    scene = random_task_scene(base.task.kind, n, rng, base=plain, names=spec.objects)
    if base.scene.bin is not None and scene.bin is not None:
        scene = dataclasses.replace(scene, bin=base.scene.bin)
    config = dataclasses.replace(base, scene=scene)
    params = {"task_objects": n, "objects": [o.object.name for o in scene.objects]}
    return Trial(index, trial_seed(campaign.seed, index), params, config)


def trial_config(campaign: CampaignConfig, index: int) -> tuple[EpisodeConfig, int]:
    """``(config, seed)`` of trial ``index``: ``run_episode(config, seed)`` re-runs it alone, exactly."""
    t = make_trial(campaign, index)
    return t.config, t.seed


RunFn = Callable[[EpisodeConfig, int], "EpisodeResult | TaskResult"]


def worker_failure(trial: Trial, kind: str, reason: str, wall_time_s: float) -> dict[str, Any]:
    """The results line of a trial whose worker raised, crashed or timed out (no EpisodeResult)."""
    data: dict[str, Any] = {f.name: None for f in dataclasses.fields(EpisodeResult) if f.name != "telemetry"}
    data.update(success=False, failure_phase=WORKER_PHASE, failure_reason=reason, failure_kind=kind,
                seed=trial.seed, wall_time_s=wall_time_s, config=trial.config.to_dict())
    return {"trial": trial.index, "params": trial.params, **data}


def execute_trial(run_fn: RunFn, trial: Trial) -> dict[str, Any]:
    """Run one trial (in a worker) and return its results line; an exception becomes a ``WORKER`` failure.

    Args:
        run_fn: The episode function (``run_episode``; tests pass a module-level function of their own).
        trial: The trial.
    """
    t0 = time.perf_counter()
    try:
        result = run_fn(trial.config, trial.seed)
        return {"trial": trial.index, "params": trial.params, **result.to_dict()}
    except Exception as exc:  # the worker must survive any trial: the error is the trial's result
        log.error("trial %d raised:\n%s", trial.index, traceback.format_exc())
        return worker_failure(trial, type(exc).__name__, f"the episode raised {type(exc).__name__}: {exc}",
                              time.perf_counter() - t0)
    finally:
        release_freed_memory()


def release_freed_memory() -> bool:
    """Return the memory the C heap holds free to the operating system (glibc's ``malloc_trim(0)``); a worker calls
    it after every trial. Returns whether it could (False off glibc, where it does nothing).

    Why: an episode allocates and frees blocks of megabytes from C: MuJoCo models copied for the collision
    checkers (about 5 MB each, a dozen per episode), their MjData, scene compilations. glibc serves a freed
    block's size from the heap from then on (its mmap threshold rises to it), the heap fragments, and glibc keeps
    the freed pages: measured in one worker, its resident memory rose from 300 MB after the first trial to 540 MB
    after 90 (then slowly on), while the memory still referenced stayed at 250 MB plus the bounded caches (every
    lru_cache was full by then; clearing them all freed 80 MB, all of it the 16 compiled checker models of
    ``motion.collision``). Trimming after each trial keeps the worker at what it references; it takes 1.5-3 ms
    (under 1 % of a trial).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        trim = libc.malloc_trim
    except (OSError, AttributeError):  # not glibc (musl has no malloc_trim)
        return False
    trim(0)
    return True



__all__ = [
    "PUSH_DURATION_S",
    "PUSH_START_S",
    "SIDECAR_KEY",
    "WORKER_PHASE",
    "CampaignConfig",
    "CampaignError",
    "RandomizationSpec",
    "RunFn",
    "Trial",
    "apply_params",
    "execute_trial",
    "make_trial",
    "release_freed_memory",
    "trial_config",
    "trial_seed",
    "worker_failure",
]
