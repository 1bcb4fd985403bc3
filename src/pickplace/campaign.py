"""Evaluation campaigns: many randomized episodes, on local processes or a Ray cluster, persisted and resumable.

A campaign is a base :class:`~pickplace.episode.EpisodeConfig`, a :class:`RandomizationSpec` (ranges of the
cube's start, yaw, mass, size and friction and of the goal) and a number of trials. Trial ``i`` draws its
scene and its episode seed from ``numpy.random.SeedSequence(campaign_seed, spawn_key=(i, ...))``: they depend
on the campaign seed and ``i`` only, not on the number of trials, the workers or the backend, so any trial
can be re-run alone (:func:`trial_config`, or ``pickplace run --config OUT/trials/trial_0007.toml --seed S``
with the file this module writes for every failed trial).

Layout of the output directory ``OUT``:

* ``campaign.json``: the base config, the randomization, the campaign seed and the number of trials;
* ``results.jsonl``: one line per finished trial, ``{"trial": i, "params": {...}, **EpisodeResult.to_dict()}``,
  appended by the parent process only (one writer, holding an ``flock`` on the file so that a second campaign
  cannot write into the same directory), with one ``write`` and an ``fsync`` as soon as the trial finishes;
* ``trials/trial_0007.toml``: the full episode config of each failed trial (with the command reproducing it);
* ``summary.json``: the :class:`CampaignSummary`.

Killing the campaign (even ``kill -9``) loses at most the trials that were running: ``resume=True`` (the
CLI's ``--resume``) reads ``results.jsonl``, drops a last line cut short by the kill, and runs only the trials
not recorded yet.

Backends. Local (default): one long-lived worker process per core (``spawn`` context), fed one trial at a
time through a pipe; the parent waits on the pipes and the process sentinels with the nearest per-trial
deadline as timeout. A trial whose worker dies (segfault, ``os._exit``, OOM kill) or runs past the per-trial
wall-clock timeout (the worker is then killed) is recorded as a failed trial of phase ``WORKER`` with the
reason, and a fresh worker takes the slot; an exception raised by the episode is caught in the worker and
recorded the same way. Workers are spawned (not forked), so a script that runs a campaign must do so under
``if __name__ == "__main__":``. Ray (``backend="ray"``): the same trial function as a Ray task
(``max_retries=0``, at most ``workers`` in flight, the timeout counted from submission), with
``ray.cancel(force=True)`` on timeout; Ray is imported only then (``pip install 'pickplace[ray]'``). On a
cluster, every node needs pickplace installed.

The library never prints: progress goes to an ``on_progress`` callback (the CLI draws a progress bar).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import math
import multiprocessing as mp
import os
import re
import signal
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pickplace.config import MAX_CUBE_SIZE_M, MIN_CUBE_SIZE_M, check_int, check_range, check_vector
from pickplace.episode import EpisodeConfig, EpisodeResult, read_toml, run_episode
from pickplace.errors import ConfigError, PickPlaceError

log = logging.getLogger(__name__)

#: The phase recorded for a trial whose worker raised, crashed or timed out.
WORKER_PHASE = "WORKER"
#: EpisodeResult fields that measure wall-clock time: they differ between two runs of the same trial.
WALL_TIME_FIELDS = ("wall_time_s", "real_time_factor", "plan_time_s", "retime_time_s")
#: The pip command that installs Ray.
RAY_HINT = "pip install 'pickplace[ray]'"
#: File names inside a campaign's output directory.
RESULTS_FILE = "results.jsonl"
SUMMARY_FILE = "summary.json"
CAMPAIGN_FILE = "campaign.json"
TRIALS_DIR = "trials"

_FORMAT_VERSION = 1
_Z95 = 1.959963984540054  # standard normal quantile of 0.975


class CampaignError(PickPlaceError):
    """A campaign cannot run: a worker process failed to start, or an optional package is missing."""


# --------------------------------------------------------------------------- #
# randomization
# --------------------------------------------------------------------------- #

Range = tuple[float, float]

#: Per field of RandomizationSpec: (bounds of the range, unit, scene field it changes, offset or absolute).
_SPEC_FIELDS: dict[str, tuple[float, float, str, str]] = {
    "cube_dx_m": (-0.5, 0.5, "m", "offset"),
    "cube_dy_m": (-0.5, 0.5, "m", "offset"),
    "cube_dyaw_rad": (-math.pi, math.pi, "rad", "offset"),
    "goal_dx_m": (-0.5, 0.5, "m", "offset"),
    "goal_dy_m": (-0.5, 0.5, "m", "offset"),
    "goal_dyaw_rad": (-math.pi, math.pi, "rad", "offset"),
    "cube_mass_kg": (1e-3, 5.0, "kg", "absolute"),
    "cube_size_m": (MIN_CUBE_SIZE_M, MAX_CUBE_SIZE_M, "m", "absolute"),
    "cube_friction": (0.05, 5.0, "", "absolute"),
    "transport_push_n": (0.0, 200.0, "N", "perturbation"),
    "pad_friction_scale": (0.0, 5.0, "", "fault"),
    "cube_mass_scale": (0.01, 50.0, "", "fault"),
    "joint_noise_rad": (0.0, 0.05, "rad", "fault"),
}
#: The first fields of _SPEC_FIELDS; the push's direction and start are drawn right after them, and any field
#: added later after those, so that adding a field never changes the values of the existing ones.
_N_FIRST_FIELDS = 10
#: Duration of a randomized transport push when the base config's faults do not set one (s).
PUSH_DURATION_S = 0.05
#: Window, after the transport trajectory starts, in which a randomized push starts (s).
PUSH_START_S = (0.05, 0.5)


@dataclass(frozen=True)
class RandomizationSpec:
    """Ranges ``(lo, hi)`` sampled uniformly per trial; ``None`` keeps the base config's value.

    The ``d`` fields are offsets added to the base config's value; the others replace it.

    Attributes:
        cube_dx_m: Offset of the cube's start x (m).
        cube_dy_m: Offset of the cube's start y (m).
        cube_dyaw_rad: Offset of the cube's start yaw (rad).
        goal_dx_m: Offset of the goal x (m).
        goal_dy_m: Offset of the goal y (m).
        goal_dyaw_rad: Offset of the goal yaw (rad).
        cube_mass_kg: Cube mass (kg).
        cube_size_m: Cube edge length (m).
        cube_friction: Friction coefficient of every contact with the cube.
        transport_push_n: Magnitude of a push on the carried cube (N), off by default. Its direction is drawn
            uniformly on the sphere and its start uniformly in ``PUSH_START_S`` after the transport starts;
            it lasts the base config's ``faults.transport_push_s``, or ``PUSH_DURATION_S``.
        pad_friction_scale: The ``faults.pad_friction_scale`` of each trial, off by default.
        cube_mass_scale: The ``faults.cube_mass_scale`` of each trial (true / believed mass), off by default.
        joint_noise_rad: The ``faults.joint_noise_rad`` of each trial (rad), off by default.
    """

    cube_dx_m: Range | None = (-0.05, 0.05)
    cube_dy_m: Range | None = (-0.05, 0.05)
    cube_dyaw_rad: Range | None = (-math.pi / 4, math.pi / 4)
    goal_dx_m: Range | None = (-0.05, 0.05)
    goal_dy_m: Range | None = (-0.05, 0.05)
    goal_dyaw_rad: Range | None = (0.0, 0.0)
    cube_mass_kg: Range | None = (0.05, 0.5)
    cube_size_m: Range | None = (0.03, 0.05)
    cube_friction: Range | None = (0.6, 1.5)
    transport_push_n: Range | None = None
    pad_friction_scale: Range | None = None
    cube_mass_scale: Range | None = None
    joint_noise_rad: Range | None = None

    def __post_init__(self) -> None:
        for name, (lo, hi, unit, _) in _SPEC_FIELDS.items():
            value = getattr(self, name)
            if value is None:
                continue
            rng = check_vector(f"randomization.{name}", value, 2, lo, hi, unit=unit)
            if rng[0] > rng[1]:
                raise ConfigError(f"randomization.{name}", value, "must be a range (lo, hi) with lo <= hi")
            object.__setattr__(self, name, rng)

    @classmethod
    def off(cls) -> RandomizationSpec:
        """No randomization: every trial runs the base config (only the episode seed changes)."""
        return cls(**dict.fromkeys(_SPEC_FIELDS))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RandomizationSpec:
        """Build from a ``[randomization]`` table: ``name = [lo, hi]``, or ``name = false`` to keep the base value.

        Fields not given keep their defaults.
        """
        if not isinstance(data, Mapping):
            raise ConfigError("randomization", data, "must be a table of keys")
        changes: dict[str, Any] = {}
        for key, value in data.items():
            if key not in _SPEC_FIELDS:
                raise ConfigError(f"randomization.{key}", value, f"unknown key; allowed: {', '.join(_SPEC_FIELDS)}")
            if value is False:
                changes[key] = None
            elif isinstance(value, (list, tuple)):
                changes[key] = tuple(value)
            else:
                raise ConfigError(f"randomization.{key}", value,
                                  "must be a range of two numbers lo <= hi (e.g. [0.05, 0.5]) or false")
        return cls(**changes)

    def to_dict(self) -> dict[str, list[float] | bool]:
        """Plain data, the inverse of :meth:`from_dict` (``false`` for a field that is not randomized)."""
        return {name: list(getattr(self, name)) if getattr(self, name) is not None else False
                for name in _SPEC_FIELDS}

    def active(self) -> list[str]:
        """Names of the randomized fields (those not ``None``)."""
        return [name for name in _SPEC_FIELDS if getattr(self, name) is not None]

    def sample(self, rng: np.random.Generator) -> dict[str, float]:
        """One draw: randomized field name -> value (the same number of draws whatever is randomized)."""
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
        return out


def apply_params(base: EpisodeConfig, params: Mapping[str, float]) -> EpisodeConfig:
    """The base config with sampled parameters (names of :class:`RandomizationSpec` fields) applied."""
    sc = base.scene
    changes: dict[str, Any] = {}
    if "cube_dx_m" in params or "cube_dy_m" in params:
        changes["cube_start_xy_m"] = (sc.cube_start_xy_m[0] + params.get("cube_dx_m", 0.0),
                                      sc.cube_start_xy_m[1] + params.get("cube_dy_m", 0.0))
    if "goal_dx_m" in params or "goal_dy_m" in params:
        changes["goal_xy_m"] = (sc.goal_xy_m[0] + params.get("goal_dx_m", 0.0),
                                sc.goal_xy_m[1] + params.get("goal_dy_m", 0.0))
    if "cube_dyaw_rad" in params:
        changes["cube_yaw_rad"] = sc.cube_yaw_rad + params["cube_dyaw_rad"]
    if "goal_dyaw_rad" in params:
        changes["goal_yaw_rad"] = sc.goal_yaw_rad + params["goal_dyaw_rad"]
    for name in ("cube_mass_kg", "cube_size_m", "cube_friction"):
        if name in params:
            changes[name] = params[name]
    config = base.with_scene(**changes) if changes else base
    if "transport_push_n" in params:
        az, el, mag = params["push_azimuth_rad"], params["push_elevation_rad"], params["transport_push_n"]
        force = (mag * math.cos(el) * math.cos(az), mag * math.cos(el) * math.sin(az), mag * math.sin(el))
        faults = dataclasses.replace(base.faults, transport_push_n=force, transport_push_start_s=params["push_start_s"],
                                     transport_push_s=base.faults.transport_push_s or PUSH_DURATION_S)
        config = dataclasses.replace(config, faults=faults)
    faults = {name: params[name] for name in ("pad_friction_scale", "cube_mass_scale", "joint_noise_rad")
              if name in params}
    if faults:
        config = dataclasses.replace(config, faults=dataclasses.replace(config.faults, **faults))
    return config


#: Which randomization fields move each scene field (to name them in errors).
_SCENE_TO_SPEC = {
    "scene.cube_start_xy_m": ("cube_dx_m", "cube_dy_m", "cube_size_m"),
    "scene.goal_xy_m": ("goal_dx_m", "goal_dy_m", "cube_size_m"),
    "scene.cube_yaw_rad": ("cube_dyaw_rad",),
    "scene.goal_yaw_rad": ("goal_dyaw_rad",),
}


def _check_extremes(base: EpisodeConfig, spec: RandomizationSpec) -> None:
    """Every corner of the randomization box gives a valid scene, with the cube on the table at start and goal."""
    active = [name for name in spec.active() if _SPEC_FIELDS[name][3] in ("offset", "absolute")]  # scene fields
    for corner in range(1 << len(active)):
        params = {name: getattr(spec, name)[(corner >> k) & 1] for k, name in enumerate(active)}
        try:
            apply_params(base, params).scene.check_goal_on_table()
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
        workers: Trials running at once (local processes, or Ray tasks in flight); None: every core
            (``os.cpu_count()`` locally, the cluster's CPUs on Ray).
        timeout_s: Per-trial wall-clock limit (s); a trial over it is killed and recorded as failed.
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
    params: dict[str, float]
    config: EpisodeConfig


def trial_seed(campaign_seed: int, index: int) -> int:
    """Episode seed of trial ``index`` (in [0, 2**32)): a function of the campaign seed and the index only."""
    ss = np.random.SeedSequence(campaign_seed, spawn_key=(index, 0))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def make_trial(campaign: CampaignConfig, index: int) -> Trial:
    """Trial ``index`` of ``campaign``: its sampled parameters, config and seed."""
    check_int("trial", index, 0)
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(index, 1)))
    params = campaign.randomization.sample(rng)
    return Trial(index, trial_seed(campaign.seed, index), params, apply_params(campaign.base, params))


def trial_config(campaign: CampaignConfig, index: int) -> tuple[EpisodeConfig, int]:
    """``(config, seed)`` of trial ``index``: ``run_episode(config, seed)`` re-runs it alone, exactly."""
    t = make_trial(campaign, index)
    return t.config, t.seed


RunFn = Callable[[EpisodeConfig, int], EpisodeResult]


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


# --------------------------------------------------------------------------- #
# records and persistence
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class TrialRecord:
    """One line of ``results.jsonl``.

    Attributes:
        trial: Trial index.
        params: The sampled parameters.
        result: ``EpisodeResult.to_dict()`` (for a ``WORKER`` failure: the same keys, None where nothing was
            measured).
    """

    trial: int
    params: dict[str, float]
    result: dict[str, Any]

    @classmethod
    def from_line(cls, line: Mapping[str, Any]) -> TrialRecord:
        """Parse one decoded JSON line."""
        data = dict(line)
        trial = data.pop("trial")
        params = data.pop("params")
        if not isinstance(trial, int) or not isinstance(params, dict) or "success" not in data:
            raise ValueError("not a trial record")
        return cls(trial, params, data)

    def to_line(self) -> dict[str, Any]:
        """The JSON object written to ``results.jsonl``."""
        return {"trial": self.trial, "params": self.params, **self.result}

    @property
    def success(self) -> bool:
        """The episode succeeded."""
        return bool(self.result.get("success"))

    @property
    def seed(self) -> int:
        """The episode seed."""
        return int(self.result["seed"])

    @property
    def failure_phase(self) -> str | None:
        """Phase that failed (``WORKER`` for a crash, a timeout or an exception)."""
        return self.result.get("failure_phase")

    @property
    def failure_kind(self) -> str | None:
        """The error behind the failure."""
        return self.result.get("failure_kind")

    @property
    def failure_reason(self) -> str | None:
        """What failed, with the numbers."""
        return self.result.get("failure_reason")


def read_results(path: str | Path) -> list[TrialRecord]:
    """The records of ``results.jsonl`` in file order.

    A last line without its newline (cut short by a kill) is ignored; an undecodable complete line is skipped
    with a warning (its trial is then run again on resume).
    """
    p = Path(path)
    if not p.exists():
        return []
    raw = p.read_bytes()
    lines = raw.split(b"\n")
    if lines and lines[-1]:
        log.warning("%s: ignoring a truncated last line (%d bytes)", p, len(lines[-1]))
    records = []
    for n, line in enumerate(lines[:-1], start=1):
        if not line.strip():
            continue
        try:
            records.append(TrialRecord.from_line(json.loads(line)))
        except (ValueError, KeyError, TypeError) as exc:
            log.warning("%s:%d: skipping an unreadable line (%s)", p, n, exc)
    return records


class _ResultsWriter:
    """Appends records to ``results.jsonl``: one ``write`` per line, then fsync (single writer: the parent).

    Opening it takes an exclusive lock on the file (``flock``, released by the kernel even on ``kill -9``), so
    that two campaigns never write into one directory at once.
    """

    def __init__(self, path: Path) -> None:
        self._path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not on Windows
            return
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._fd)
            raise ConfigError("out", str(path.parent), "is in use by another running campaign "
                              f"({path.name} is locked)") from None

    def cut_partial_line(self) -> None:
        """A kill while writing can leave a partial last line: cut it, or the next line would be glued to it."""
        size = os.fstat(self._fd).st_size
        if size:
            data = self._path.read_bytes()
            keep = data.rfind(b"\n") + 1
            if keep != size:
                os.ftruncate(self._fd, keep)

    def append(self, line: Mapping[str, Any]) -> None:
        data = (json.dumps(_json_ready(line), allow_nan=False, separators=(",", ":"), default=_json_default)
                + "\n").encode()
        os.write(self._fd, data)
        os.fsync(self._fd)

    def close(self) -> None:
        os.close(self._fd)


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


# --------------------------------------------------------------------------- #
# TOML (the trial files; no extra dependency)
# --------------------------------------------------------------------------- #

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.match(key) else json.dumps(key)


def _toml_value(value: Any) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def toml_dumps(data: Mapping[str, Any], _prefix: str = "") -> str:
    """TOML text of nested mappings of scalars and lists (``None`` values are left out: the default applies)."""
    scalars = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in data.items()
               if v is not None and not isinstance(v, Mapping)]
    out = []
    if scalars:
        out.append(("" if not _prefix else f"[{_prefix}]\n") + "\n".join(scalars) + "\n")
    for k, v in data.items():
        if isinstance(v, Mapping):
            out.append(toml_dumps(v, f"{_prefix}.{_toml_key(k)}" if _prefix else _toml_key(k)))
    return "\n".join(out)


def episode_config_toml(config: EpisodeConfig, header: str = "") -> str:
    """The full episode config as TOML for ``pickplace run --config`` (floats written exactly)."""
    tables = {name: dataclasses.asdict(getattr(config, name)) for name in config.to_dict()}
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    return comment + ("\n" if comment else "") + toml_dumps(tables)


def trial_toml_path(out_dir: str | Path, index: int) -> Path:
    """Where the config of trial ``index`` is written."""
    return Path(out_dir) / TRIALS_DIR / f"trial_{index:04d}.toml"


def reproduce_command(config_path: str | Path, seed: int) -> str:
    """The command that re-runs one trial alone."""
    return f"pickplace run --config {config_path} --seed {seed}"


def load_campaign_toml(path: str | Path) -> tuple[EpisodeConfig, RandomizationSpec]:
    """Load an episode config TOML that may also hold a ``[randomization]`` table.

    Returns:
        The episode config (without the randomization table) and the spec (defaults if the table is absent).
    """
    data = read_toml(path)
    spec = RandomizationSpec.from_dict(data.pop("randomization", {}))
    return EpisodeConfig.from_dict(data), spec


def load_campaign(out_dir: str | Path, *, workers: int | None = None, timeout_s: float = 60.0,
                  trials: int | None = None) -> CampaignConfig:
    """The campaign recorded in ``OUT/campaign.json`` (to resume it without repeating its options)."""
    p = Path(out_dir) / CAMPAIGN_FILE
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError("out", str(out_dir), f"holds no campaign ({p}: {exc.strerror or exc})") from None
    except json.JSONDecodeError as exc:
        raise ConfigError("out", str(p), f"is not valid JSON: {exc}") from None
    return CampaignConfig(EpisodeConfig.from_dict(data["base"]), RandomizationSpec.from_dict(data["randomization"]),
                          trials if trials is not None else data["trials"], data["seed"], workers, timeout_s)


# --------------------------------------------------------------------------- #
# summary
# --------------------------------------------------------------------------- #

_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def normalize_reason(reason: str | None) -> str:
    """A failure reason with its numbers replaced by ``#``, so that similar failures group together."""
    return _NUMBER.sub("#", reason or "")


def wilson_interval(successes: int, trials: int, z: float = _Z95) -> tuple[float, float]:
    """Wilson score interval of a success rate (95% by default); (0, 1) for no trials."""
    if trials <= 0:
        return (0.0, 1.0)
    p = successes / trials
    z2 = z * z
    denom = 1.0 + z2 / trials
    centre = (p + z2 / (2 * trials)) / denom
    half = z * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials)) / denom
    lo = 0.0 if successes == 0 else max(0.0, centre - half)  # exact ends (rounding gives 1 - 1e-16)
    hi = 1.0 if successes == trials else min(1.0, centre + half)
    return (lo, hi)


@dataclass(frozen=True)
class FailureGroup:
    """Failures sharing a phase, an error kind and a reason (numbers aside).

    Attributes:
        phase: The failed phase.
        kind: The error kind.
        reason: The reason with numbers replaced by ``#``.
        count: How many trials.
        trials: Their indices.
        example: One full reason, with its numbers.
    """

    phase: str
    kind: str
    reason: str
    count: int
    trials: tuple[int, ...]
    example: str


@dataclass(frozen=True)
class FailedTrial:
    """One failed trial and the command that reproduces it.

    Attributes:
        trial: Index.
        seed: Episode seed.
        phase: Failed phase.
        kind: Error kind.
        reason: Full reason.
        config_path: The trial's config TOML.
        command: ``pickplace run --config ... --seed ...``.
    """

    trial: int
    seed: int
    phase: str
    kind: str
    reason: str
    config_path: str
    command: str


@dataclass(frozen=True)
class CampaignSummary:
    """Figures of a campaign. Lengths in m, times in s, angles in rad; NaN where there is nothing to measure.

    Attributes:
        trials: Recorded trials.
        successes: Successful trials.
        success_rate: successes / trials.
        success_rate_ci95: 95% Wilson score interval of the success rate.
        place_error_xy_rms_m: RMS horizontal place error of the successful trials.
        place_error_xy_p95_m: Its 95th percentile.
        cycle_time_mean_s: Mean simulated cycle time of the successful trials.
        cycle_time_p95_s: Its 95th percentile.
        plan_time_median_s: Median wall time of planning one segment (every segment of every trial).
        plan_time_p95_s: Its 95th percentile.
        tracking_error_max_rad: Largest joint tracking error of any trial.
        wall_time_mean_s: Mean wall time of a trial (in its worker).
        worker_failures: Trials recorded as failed by their worker (exception, crash, timeout).
        failures: Failures grouped by phase, kind and reason, most frequent first.
        failed_trials: Every failed trial with its reproduce command, by index.
    """

    trials: int
    successes: int
    success_rate: float
    success_rate_ci95: tuple[float, float]
    place_error_xy_rms_m: float
    place_error_xy_p95_m: float
    cycle_time_mean_s: float
    cycle_time_p95_s: float
    plan_time_median_s: float
    plan_time_p95_s: float
    tracking_error_max_rad: float
    wall_time_mean_s: float
    worker_failures: int
    failures: tuple[FailureGroup, ...]
    failed_trials: tuple[FailedTrial, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (NaN becomes None)."""
        return _json_ready(dataclasses.asdict(self))


def _json_ready(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _json_default(value: Any) -> Any:
    """numpy scalars and arrays in a results line become plain numbers and lists."""
    if isinstance(value, np.generic):
        return _json_ready(value.item())
    if isinstance(value, np.ndarray):
        return _json_ready(value.tolist())
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def _finite(values: Iterable[Any]) -> np.ndarray:
    arr = np.array([v for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)], dtype=float)
    return arr[np.isfinite(arr)]


def _stat(values: np.ndarray, fn: Callable[[np.ndarray], Any]) -> float:
    return float(fn(values)) if values.size else math.nan


def summarize(records: Sequence[TrialRecord], out_dir: str | Path = "OUT") -> CampaignSummary:
    """The figures of a campaign from its records (one per trial).

    Args:
        records: The trial records.
        out_dir: The campaign's output directory, as the reproduce commands should name it.
    """
    n = len(records)
    ok = [r for r in records if r.success]
    k = len(ok)
    place = _finite(r.result.get("place_error_xy_m") for r in ok)
    cycle = _finite(r.result.get("cycle_time_s") for r in ok)
    plan = _finite(v for r in records for v in (r.result.get("plan_time_s") or {}).values())
    tracking = _finite(r.result.get("tracking_error_max_rad") for r in records)
    wall = _finite(r.result.get("wall_time_s") for r in records)

    failed = sorted((r for r in records if not r.success), key=lambda r: r.trial)
    groups: dict[tuple[str, str, str], list[TrialRecord]] = {}
    for r in failed:
        key = (r.failure_phase or "?", r.failure_kind or "?", normalize_reason(r.failure_reason))
        groups.setdefault(key, []).append(r)
    failure_groups = tuple(
        FailureGroup(phase, kind, reason, len(rs), tuple(r.trial for r in rs), rs[0].failure_reason or "")
        for (phase, kind, reason), rs in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0]))
    )
    failed_trials = tuple(
        FailedTrial(r.trial, r.seed, r.failure_phase or "?", r.failure_kind or "?", r.failure_reason or "",
                    str(trial_toml_path(out_dir, r.trial)),
                    reproduce_command(trial_toml_path(out_dir, r.trial), r.seed))
        for r in failed
    )
    return CampaignSummary(
        trials=n,
        successes=k,
        success_rate=k / n if n else math.nan,
        success_rate_ci95=wilson_interval(k, n),
        place_error_xy_rms_m=_stat(place, lambda a: np.sqrt(np.mean(a**2))),
        place_error_xy_p95_m=_stat(place, lambda a: np.percentile(a, 95)),
        cycle_time_mean_s=_stat(cycle, np.mean),
        cycle_time_p95_s=_stat(cycle, lambda a: np.percentile(a, 95)),
        plan_time_median_s=_stat(plan, np.median),
        plan_time_p95_s=_stat(plan, lambda a: np.percentile(a, 95)),
        tracking_error_max_rad=_stat(tracking, np.max),
        wall_time_mean_s=_stat(wall, np.mean),
        worker_failures=sum(r.failure_phase == WORKER_PHASE for r in failed),
        failures=failure_groups,
        failed_trials=failed_trials,
    )


# --------------------------------------------------------------------------- #
# backends
# --------------------------------------------------------------------------- #

OnResult = Callable[[dict[str, Any]], None]


@dataclass
class _Slot:
    """One local worker process and the trial it runs."""

    proc: Any  # multiprocessing.process.BaseProcess
    conn: Connection
    ready: bool = False
    trial: Trial | None = None
    started: float = 0.0


def _worker_main(conn: Connection, run_fn: RunFn) -> None:
    """Loop of a local worker: receive a trial, run it, send its results line; stop on None or EOF."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    conn.send(("ready", os.getpid()))
    while True:
        try:
            trial = conn.recv()
        except (EOFError, OSError):
            return
        if trial is None:
            return
        line = execute_trial(run_fn, trial)
        try:
            conn.send(("done", line))
        except OSError:
            return


def _exit_reason(exitcode: int | None) -> str:
    if exitcode is None:
        return "the worker process vanished"
    if exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the worker process was killed by {name} (signal {-exitcode})"
    return f"the worker process exited with code {exitcode}"


def _run_local(trials: Sequence[Trial], run_fn: RunFn, workers: int, timeout_s: float, on_result: OnResult,
               on_ready: Callable[[], None]) -> None:
    """Run the trials on ``workers`` local processes; call ``on_result`` (in this process) per finished trial."""
    ctx = mp.get_context("spawn")

    def start() -> _Slot:
        parent, child = ctx.Pipe(duplex=True)
        proc = ctx.Process(target=_worker_main, args=(child, run_fn), name="pickplace-worker", daemon=True)
        proc.start()
        child.close()
        return _Slot(proc, parent)

    queue = deque(trials)
    slots = [start() for _ in range(min(workers, len(queue)))]
    announced = False

    def retire(slot: _Slot, kind: str, reason: str) -> None:
        """The slot's worker is gone (or killed): record its trial, start a fresh worker if work remains."""
        slot.conn.close()
        slot.proc.join(5.0)
        if slot.trial is not None:
            t = slot.trial
            log.warning("trial %d: %s", t.index, reason)
            on_result(worker_failure(t, kind, reason, time.monotonic() - slot.started))
        elif not slot.ready:
            raise CampaignError(f"a worker process failed to start: {_exit_reason(slot.proc.exitcode)} (see its "
                                "traceback above; workers are spawned, so a script that runs a campaign must "
                                "do so under `if __name__ == '__main__':`)")
        slots.remove(slot)
        if queue and len(slots) < workers:
            slots.append(start())

    try:
        while queue or any(s.trial is not None for s in slots):
            now = time.monotonic()
            for s in list(slots):
                if s.ready and s.trial is None and queue:
                    t = queue.popleft()
                    try:
                        s.conn.send(t)
                    except OSError:
                        queue.appendleft(t)
                        retire(s, "WorkerCrashed", _exit_reason(s.proc.exitcode))
                        continue
                    s.trial, s.started = t, now
            deadlines = [s.started + timeout_s for s in slots if s.trial is not None]
            wait([s.conn for s in slots] + [s.proc.sentinel for s in slots],
                 timeout=max(0.0, min(deadlines) - now) if deadlines else None)
            for s in list(slots):
                if s.conn.poll():
                    try:
                        tag, payload = s.conn.recv()
                    except (EOFError, OSError):
                        s.proc.join(5.0)
                        retire(s, "WorkerCrashed", _exit_reason(s.proc.exitcode))
                        continue
                    if tag == "ready":
                        s.ready = True
                        if not announced and all(x.ready for x in slots):
                            announced = True
                            on_ready()
                    else:
                        s.trial = None
                        on_result(payload)
                elif not s.proc.is_alive():
                    retire(s, "WorkerCrashed", _exit_reason(s.proc.exitcode))
                elif s.trial is not None and time.monotonic() - s.started > timeout_s:
                    s.proc.kill()
                    retire(s, "WorkerTimeout",
                           f"the trial ran past the per-trial timeout of {timeout_s:g} s (worker killed)")
    finally:
        for s in slots:
            with contextlib.suppress(OSError):
                s.conn.send(None)
        deadline = time.monotonic() + 5.0
        for s in slots:
            if s.trial is not None:  # interrupted mid-trial: do not wait for the episode to end
                s.proc.kill()
            s.proc.join(max(0.0, deadline - time.monotonic()))
            if s.proc.is_alive():
                s.proc.kill()
                s.proc.join()
            s.conn.close()


def _import_ray() -> Any:
    try:
        import ray
    except ImportError as exc:
        raise CampaignError(f"the Ray backend needs Ray, which is not installed ({exc}): {RAY_HINT}") from None
    return ray


_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _ray_error_reason(exc: Exception) -> str:
    """The informative line of a Ray error: its last line of text (Ray puts the cause last), without colours."""
    lines = [ln.strip() for ln in _ANSI.sub("", str(exc)).splitlines()]
    lines = [ln for ln in lines if ln and not set(ln) <= set("^~ ")]
    return lines[-1] if lines else type(exc).__name__


def _run_ray(trials: Sequence[Trial], run_fn: RunFn, workers: int | None, timeout_s: float, address: str | None,
             on_result: OnResult, on_ready: Callable[[], None]) -> None:
    """Run the trials as Ray tasks (a local instance if ``address`` is None, else the cluster at ``address``)."""
    ray = _import_ray()
    started_here = not ray.is_initialized()
    if started_here:
        opts: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        try:
            if address is None:
                ray.init(num_cpus=workers or os.cpu_count() or 1, **opts)
            else:
                ray.init(address=address, **opts)
        except Exception as exc:  # Ray raises ConnectionError, RuntimeError, ValueError...
            where = f"join the Ray cluster at {address!r}" if address else "start a local Ray instance"
            raise CampaignError(f"cannot {where}: {type(exc).__name__}: {exc}") from exc
    try:
        limit = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=0)(execute_trial)
        fn_ref = ray.put(run_fn)
        queue = deque(trials)
        running: dict[Any, tuple[Trial, float]] = {}
        on_ready()
        while queue or running:
            while queue and len(running) < limit:
                t = queue.popleft()
                running[task.remote(fn_ref, t)] = (t, time.monotonic())
            now = time.monotonic()
            next_deadline = min(start for _, start in running.values()) + timeout_s
            ready, _ = ray.wait(list(running), num_returns=1, timeout=max(0.0, next_deadline - now))
            if ready:
                ready, _ = ray.wait(list(running), num_returns=len(running), timeout=0)
            for ref in ready:
                t, start = running.pop(ref)
                try:
                    line = ray.get(ref)
                except Exception as exc:  # the task died (crashed worker, lost node): record the trial as failed
                    kind = "WorkerCrashed" if "WorkerCrashed" in type(exc).__name__ else type(exc).__name__
                    reason = _ray_error_reason(exc)
                    log.warning("trial %d: %s", t.index, reason)
                    line = worker_failure(t, kind, f"the Ray task failed: {reason}", time.monotonic() - start)
                on_result(line)
            now = time.monotonic()
            for ref, (t, start) in list(running.items()):
                if now - start > timeout_s:
                    ray.cancel(ref, force=True)
                    del running[ref]
                    on_result(worker_failure(
                        t, "WorkerTimeout", f"the trial ran past the per-trial timeout of {timeout_s:g} s "
                        "(Ray task cancelled)", now - start))
    finally:
        if started_here:
            ray.shutdown()


# --------------------------------------------------------------------------- #
# the campaign
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class CampaignProgress:
    """Progress of a running campaign, passed to the ``on_progress`` callback.

    Attributes:
        done: Trials recorded (including those recorded before a resume).
        total: Trials of the campaign.
        successes: Successful trials among those recorded.
        resumed: Trials that were already recorded when this run started.
        last: The record just added (None for the first call, before any trial ran).
    """

    done: int
    total: int
    successes: int
    resumed: int
    last: TrialRecord | None


@dataclass(frozen=True)
class CampaignRun:
    """What :func:`run_campaign` did.

    Attributes:
        summary: The campaign's figures (all recorded trials).
        records: Every record of trials 0 .. N-1, by index.
        out_dir: The output directory.
        trials_run: Trials run by this call (the others were already recorded).
        elapsed_s: Wall time of this call (s).
        startup_s: Wall time until every worker was ready (s), from the start of this call.
    """

    summary: CampaignSummary
    records: tuple[TrialRecord, ...]
    out_dir: Path
    trials_run: int
    elapsed_s: float
    startup_s: float


def run_campaign(
    campaign: CampaignConfig,
    out_dir: str | Path,
    *,
    resume: bool = False,
    backend: Literal["local", "ray"] = "local",
    ray_address: str | None = None,
    on_progress: Callable[[CampaignProgress], None] | None = None,
    run_fn: RunFn = run_episode,
) -> CampaignRun:
    """Run (or complete) a campaign, persisting every trial as it finishes.

    Args:
        campaign: What to run.
        out_dir: Output directory (created); see the module docstring for its files.
        resume: Complete the campaign recorded in ``out_dir`` (its base config, randomization and seed must
            match ``campaign``; the number of trials may grow). Without it, ``out_dir`` must hold no results.
        backend: ``"local"`` (processes on this machine) or ``"ray"``.
        ray_address: Ray cluster to join (``backend="ray"``); None starts a local Ray instance with
            ``campaign.workers`` CPUs (or every core).
        on_progress: Called in this process at the start and after each finished trial.
        run_fn: The episode function run in the workers: ``run_fn(config, seed) -> EpisodeResult``; must be
            picklable (a module-level function). Tests pass their own to inject crashes and hangs.

    Returns:
        The :class:`CampaignRun` (the summary is also written to ``OUT/summary.json``).

    Raises:
        ConfigError: ``out_dir`` holds results and ``resume`` is False, or holds another campaign.
        CampaignError: a worker process could not start, or Ray is missing.
    """
    if backend not in ("local", "ray"):
        raise ConfigError("backend", backend, "must be 'local' or 'ray'")
    t0 = time.monotonic()
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError("out", str(out), f"cannot be created as a directory: {exc.strerror or exc}") from None
    writer = _ResultsWriter(out / RESULTS_FILE)  # locked: one campaign at a time in a directory
    try:
        recorded = _prepare_dir(campaign, out, resume)
        writer.cut_partial_line()
        return _run(campaign, out, writer, recorded, backend, ray_address, on_progress, run_fn, t0)
    finally:
        writer.close()


def _prepare_dir(campaign: CampaignConfig, out: Path, resume: bool) -> dict[int, TrialRecord]:
    """Check the output directory against the campaign, record the campaign, return the trials already done."""
    results_path = out / RESULTS_FILE
    campaign_path = out / CAMPAIGN_FILE
    existing = read_results(results_path)
    if existing and not resume:
        raise ConfigError("out", str(out), f"already holds {len(existing)} results; resume the campaign "
                          "(--resume) or choose another directory")
    if campaign_path.exists() and existing:
        try:
            stored = json.loads(campaign_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ConfigError("out", str(campaign_path), f"cannot be read: {exc}") from None
        mine = json.loads(json.dumps(campaign.identity()))
        for key, value in mine.items():
            if stored.get(key) != value:
                raise ConfigError(f"campaign.{key}", "(this campaign's)", f"differs from the one recorded in "
                                  f"{campaign_path}: resume it with the same config, randomization and seed")
    _write_atomic(campaign_path, json.dumps({"format": _FORMAT_VERSION, **campaign.identity(),
                                              "trials": campaign.trials}, indent=2) + "\n")
    recorded: dict[int, TrialRecord] = {}
    for r in existing:
        if r.trial in recorded:
            log.warning("%s: trial %d is recorded twice; keeping the first", results_path, r.trial)
        elif r.trial < campaign.trials:
            recorded[r.trial] = r
    return recorded


def _run(campaign: CampaignConfig, out: Path, writer: _ResultsWriter, recorded: dict[int, TrialRecord],
         backend: str, ray_address: str | None, on_progress: Callable[[CampaignProgress], None] | None,
         run_fn: RunFn, t0: float) -> CampaignRun:
    """Run the trials not in ``recorded``, appending each to ``writer`` as it finishes; write the summary."""
    todo = [make_trial(campaign, i) for i in range(campaign.trials) if i not in recorded]
    by_index = {t.index: t for t in todo}
    resumed = len(recorded)
    successes = sum(r.success for r in recorded.values())
    done = resumed
    if on_progress is not None:
        on_progress(CampaignProgress(done, campaign.trials, successes, resumed, None))
    log.info("campaign: %d trials, %d already recorded, %d to run", campaign.trials, resumed, len(todo))

    startup_s = 0.0

    def on_ready() -> None:
        nonlocal startup_s
        startup_s = time.monotonic() - t0

    def on_result(line: dict[str, Any]) -> None:
        nonlocal done, successes
        record = TrialRecord.from_line(line)
        if record.trial in recorded:  # cannot happen with one writer; never write a duplicate
            log.warning("trial %d finished twice; keeping the first result", record.trial)
            return
        if not record.success:
            trial = by_index[record.trial]
            path = trial_toml_path(out, trial.index)
            path.parent.mkdir(exist_ok=True)
            header = (f"pickplace campaign trial {trial.index} (seed {trial.seed}): failed in "
                      f"{record.failure_phase}: {record.failure_reason}\n"
                      f"reproduce: {reproduce_command(path, trial.seed)}")
            _write_atomic(path, episode_config_toml(trial.config, header))
        writer.append(line)
        recorded[record.trial] = record
        done += 1
        successes += record.success
        if on_progress is not None:
            on_progress(CampaignProgress(done, campaign.trials, successes, resumed, record))

    workers = campaign.workers
    if todo:
        if backend == "ray":
            _run_ray(todo, run_fn, workers, campaign.timeout_s, ray_address, on_result, on_ready)
        else:
            _run_local(todo, run_fn, workers or os.cpu_count() or 1, campaign.timeout_s, on_result, on_ready)

    records = tuple(recorded[i] for i in sorted(recorded))
    summary = summarize(records, out)
    _write_atomic(out / SUMMARY_FILE, json.dumps(summary.to_dict(), indent=2) + "\n")
    elapsed = time.monotonic() - t0
    log.info("campaign: %d/%d successes; %d trials run in %.1f s", summary.successes, summary.trials,
             len(todo), elapsed)
    return CampaignRun(summary, records, out, len(todo), elapsed, startup_s)


def load_records(out_dir: str | Path) -> tuple[TrialRecord, ...]:
    """The records of a campaign's output directory, one per trial (the first if a trial appears twice), by index."""
    seen: dict[int, TrialRecord] = {}
    for r in read_results(Path(out_dir) / RESULTS_FILE):
        seen.setdefault(r.trial, r)
    return tuple(seen[i] for i in sorted(seen))


def strip_wall_times(result: Mapping[str, Any]) -> dict[str, Any]:
    """A result dict without the fields that measure wall-clock time (to compare two runs of one trial)."""
    return {k: v for k, v in result.items() if k not in WALL_TIME_FIELDS}


__all__ = [
    "CAMPAIGN_FILE",
    "RAY_HINT",
    "RESULTS_FILE",
    "SUMMARY_FILE",
    "WALL_TIME_FIELDS",
    "WORKER_PHASE",
    "CampaignConfig",
    "CampaignError",
    "CampaignProgress",
    "CampaignRun",
    "CampaignSummary",
    "FailedTrial",
    "FailureGroup",
    "RandomizationSpec",
    "Trial",
    "TrialRecord",
    "apply_params",
    "episode_config_toml",
    "execute_trial",
    "load_campaign",
    "load_campaign_toml",
    "load_records",
    "make_trial",
    "normalize_reason",
    "read_results",
    "reproduce_command",
    "run_campaign",
    "strip_wall_times",
    "summarize",
    "toml_dumps",
    "trial_config",
    "trial_seed",
    "trial_toml_path",
    "wilson_interval",
]
