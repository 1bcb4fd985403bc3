"""The figures of a campaign from its records: success rate with its interval, errors, failures grouped."""

from __future__ import annotations

import dataclasses
import math
import re
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pickplace.eval.campaign.spec import WORKER_PHASE
from pickplace.eval.campaign.store import TrialRecord, json_ready, reproduce_command, trial_toml_path
from pickplace.task.machine import Phase

_Z95 = 1.959963984540054  # standard normal quantile of 0.975
#: The phase in which an episode fails before the arm moves (the scene is observed and every target solved first).
BEFORE_MOTION_PHASE = Phase.IDLE.value


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
class RetryCount:
    """One bin of the retries histogram.

    Attributes:
        retries: Recoveries an episode used (regrasp, re-pick, replan, payload correction).
        trials: Trials whose episode used exactly that many.
    """

    retries: int
    trials: int


@dataclass(frozen=True)
class ObjectStats:
    """The figures of the trials of one object (campaigns that draw the object per trial).

    Attributes:
        name: The object's name.
        trials: Its trials.
        successes: Its successful trials.
        rejected: Its trials rejected before the arm moved (IDLE: it cannot be held, no grasp reaches it).
        success_rate_attempted: successes / (trials - rejected): how often the episodes the robot started
            succeeded.
        success_rate_attempted_ci95: 95% Wilson interval of that rate.
        place_error_xy_rms_m: RMS horizontal place error of its successes (m).
        grasps: Successful trials per approach of the executed grasp (``top``, ``tilted``, ``side``).
    """

    name: str
    trials: int
    successes: int
    rejected: int
    success_rate_attempted: float
    success_rate_attempted_ci95: tuple[float, float]
    place_error_xy_rms_m: float
    grasps: dict[str, int]


@dataclass(frozen=True)
class CampaignSummary:
    """Figures of a campaign. Lengths in m, times in s, angles in rad; NaN where there is nothing to measure.

    In a task campaign, the per-episode figures (place error, cycle time, planning, tracking) are those of every
    pick and place of its trials (of its successful trials for the place error and the cycle time).

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
        tracking_error_max_rad: Largest joint tracking error of any trial, over every joint loop of every phase
            (trajectories and holds).
        tcp_tracking_error_max_m: Largest tcp position error of any trial's Cartesian moves (descend, lift, set
            down, retract).
        wall_time_mean_s: Mean wall time of a trial (in its worker).
        successes_with_recovery: Successful trials whose episode needed at least one recovery (``retries >= 1``).
        retries_histogram: Trials per number of retries, by increasing retries, over every trial whose episode
            ran (all trials but the worker failures, which have no episode): the counts add up to
            ``trials - worker_failures``.
        failed_before_motion: Failed trials rejected before the arm moved: failed in ``IDLE``, where the object is
            observed and the four targets solved (unreachable or blocked targets); nothing was simulated.
        failed_before_motion_rate: failed_before_motion / trials.
        failed_after_motion: Failed trials whose episode failed in a phase after ``IDLE``, from the approach's
            planning on (grasp, slip, collision, place check...); worker failures are not counted here.
        failed_after_motion_rate: failed_after_motion / trials.
        worker_failures: Trials recorded as failed by their worker (exception, crash, timeout: phase ``WORKER``).
            ``trials = successes + failed_before_motion + failed_after_motion + worker_failures``.
        worker_failure_rate: worker_failures / trials.
        failures: Failures grouped by phase, kind and reason, most frequent first.
        failed_trials: Every failed trial with its reproduce command, by index.
        success_rate_attempted: successes / (trials - failed_before_motion): the rate of the episodes in which
            the arm moved.
        success_rate_attempted_ci95: 95% Wilson interval of that rate.
        by_object: The figures per object, by name (one entry when every trial has the same object); empty for a
            task campaign (see ``failures_by_object``).
        task_time_mean_s: A task campaign's mean simulated task time of its successful trials (s); NaN otherwise.
        task_time_per_object_mean_s: The same per object of the task (s).
        failures_by_object: Failed trials per object (its library name): a task's the object whose pick and place
            failed (``"task"`` for a failure between them).
        limit_violations: Physics steps (1 ms) of the arms' motions at which a joint was over its speed or
            acceleration limit or a motor's torque at its limit, summed over every episode that measured them
            (``EpisodeResult.limit_violations``; records written before it count none).
        trials_over_limits: Trials with at least one such step.
        joint_limit_ratio_max: The largest ratio of a joint's speed, acceleration or torque to its limit in any
            motion of any episode (1 or more: at or past a limit); NaN if none measured it.
        approach_line_deviation_max_m: Largest distance of the tcp from its straight line in a final approach to a
            grasp, over every episode (m).
        place_line_deviation_max_m: The same in a set-down (m).
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
    tcp_tracking_error_max_m: float
    wall_time_mean_s: float
    successes_with_recovery: int
    retries_histogram: tuple[RetryCount, ...]
    failed_before_motion: int
    failed_before_motion_rate: float
    failed_after_motion: int
    failed_after_motion_rate: float
    worker_failures: int
    worker_failure_rate: float
    failures: tuple[FailureGroup, ...]
    failed_trials: tuple[FailedTrial, ...]
    success_rate_attempted: float = math.nan
    success_rate_attempted_ci95: tuple[float, float] = (math.nan, math.nan)
    by_object: tuple[ObjectStats, ...] = ()
    task_time_mean_s: float = math.nan
    task_time_per_object_mean_s: float = math.nan
    failures_by_object: dict[str, int] = dataclasses.field(default_factory=dict)
    limit_violations: int = 0
    trials_over_limits: int = 0
    joint_limit_ratio_max: float = math.nan
    approach_line_deviation_max_m: float = math.nan
    place_line_deviation_max_m: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (NaN becomes None)."""
        return json_ready(dataclasses.asdict(self))


def _finite(values: Iterable[Any]) -> np.ndarray:
    arr = np.array([v for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)], dtype=float)
    return arr[np.isfinite(arr)]


def _stat(values: np.ndarray, fn: Callable[[np.ndarray], Any]) -> float:
    return float(fn(values)) if values.size else math.nan


def retries_of(record: TrialRecord) -> int | None:
    """Recoveries the trial's episode used, or None for a worker failure (no episode ran to count them)."""
    value = record.result.get("retries")
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    recoveries = record.result.get("recoveries")
    return len(recoveries) if isinstance(recoveries, list | tuple) else None


def summarize(records: Sequence[TrialRecord], out_dir: str | Path = "OUT") -> CampaignSummary:
    """The figures of a campaign from its records (one per trial).

    Args:
        records: The trial records.
        out_dir: The campaign's output directory, as the reproduce commands should name it.
    """
    n = len(records)
    ok = [r for r in records if r.success]
    k = len(ok)
    ok_episodes = [e for r in ok for e in episodes(r)]
    all_episodes = [e for r in records for e in episodes(r)]
    place = _finite(e.get("place_error_xy_m") for e in ok_episodes)
    cycle = _finite(e.get("cycle_time_s") for e in ok_episodes)
    plan = _finite(v for e in all_episodes for v in (e.get("plan_time_s") or {}).values())
    tracking = _finite(e.get("tracking_error_max_rad") for e in all_episodes)
    tcp_tracking = _finite(e.get("tcp_tracking_error_max_m") for e in all_episodes)
    wall = _finite(r.result.get("wall_time_s") for r in records)
    over = [sum(v for v in (e.get("limit_violations") for e in episodes(r)) if isinstance(v, int)) for r in records]
    ratios = _finite(e.get(k) for e in all_episodes
                     for k in ("joint_speed_ratio_max", "joint_acceleration_ratio_max", "torque_ratio_max"))
    approach_line = _finite(e.get("approach_line_deviation_max_m") for e in all_episodes)
    place_line = _finite(e.get("place_line_deviation_max_m") for e in all_episodes)

    failed = sorted((r for r in records if not r.success), key=lambda r: r.trial)
    worker = sum(r.failure_phase == WORKER_PHASE for r in failed)
    before = sum(r.failure_phase == BEFORE_MOTION_PHASE for r in failed)
    after = len(failed) - worker - before
    retries = [x for x in map(retries_of, records) if x is not None]
    histogram = tuple(RetryCount(x, retries.count(x)) for x in sorted(set(retries)))
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
    attempted = n - before
    tasks = any(is_task(r) for r in records)
    task_time = _finite(r.result.get("total_time_s") for r in ok if is_task(r))
    per_object = _finite(r.result.get("total_time_s") / max(1, len(r.result.get("objects") or ()))
                         for r in ok if is_task(r) and isinstance(r.result.get("total_time_s"), float))
    by_failure = Counter(failed_object(r) for r in failed)
    return CampaignSummary(
        task_time_mean_s=_stat(task_time, np.mean),
        task_time_per_object_mean_s=_stat(per_object, np.mean),
        failures_by_object=dict(sorted(by_failure.items(), key=lambda kv: (-kv[1], kv[0]))),
        success_rate_attempted=k / attempted if attempted else math.nan,
        success_rate_attempted_ci95=wilson_interval(k, attempted),
        by_object=() if tasks else _by_object(records),
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
        tcp_tracking_error_max_m=_stat(tcp_tracking, np.max),
        wall_time_mean_s=_stat(wall, np.mean),
        successes_with_recovery=sum((retries_of(r) or 0) >= 1 for r in ok),
        retries_histogram=histogram,
        failed_before_motion=before,
        failed_before_motion_rate=before / n if n else math.nan,
        failed_after_motion=after,
        failed_after_motion_rate=after / n if n else math.nan,
        worker_failures=worker,
        worker_failure_rate=worker / n if n else math.nan,
        failures=failure_groups,
        failed_trials=failed_trials,
        limit_violations=sum(over),
        trials_over_limits=sum(n > 0 for n in over),
        joint_limit_ratio_max=_stat(ratios, np.max),
        approach_line_deviation_max_m=_stat(approach_line, np.max),
        place_line_deviation_max_m=_stat(place_line, np.max),
    )


def episodes(record: TrialRecord) -> list[dict[str, Any]]:
    """The pick and places a trial ran, each as an ``EpisodeResult`` dict: the trial's own, or a task's picks."""
    if is_task(record):
        return [p for p in record.result.get("picks") or [] if isinstance(p, dict)]
    return [record.result]


def is_task(record: TrialRecord) -> bool:
    """Whether the trial ran a task with several objects (its record is a ``TaskResult``)."""
    return "order_policy" in record.result


def failed_object(record: TrialRecord) -> str:
    """The library name of the object a failed trial failed with: a task's failing object (its trailing ``_N``
    dropped), ``"task"`` when the task failed between pick and places; the trial's object otherwise."""
    if not is_task(record):
        return object_name(record)
    name = record.result.get("failure_object")
    if not isinstance(name, str):
        return "task"
    base, _, tail = name.rpartition("_")
    return base if base and tail.isdigit() else name


def object_name(record: TrialRecord) -> str:
    """The name of the object a trial ran with ("?" if its record does not say)."""
    config = record.result.get("config") or {}
    obj = config.get("scene", {}).get("object") if isinstance(config.get("scene"), dict) else None
    obj = obj if isinstance(obj, dict) else config.get("object")
    name = obj.get("name") if isinstance(obj, dict) else None
    return name if isinstance(name, str) else str(record.params.get("object", "?"))


def _by_object(records: Sequence[TrialRecord]) -> tuple[ObjectStats, ...]:
    groups: dict[str, list[TrialRecord]] = {}
    for r in records:
        groups.setdefault(object_name(r), []).append(r)
    out = []
    for name in sorted(groups):
        rs = groups[name]
        ok = [r for r in rs if r.success]
        rejected = sum(r.failure_phase == BEFORE_MOTION_PHASE for r in rs if not r.success)
        attempted = len(rs) - rejected
        place = _finite(r.result.get("place_error_xy_m") for r in ok)
        grasps: dict[str, int] = {}
        for r in ok:
            kind = str(r.result.get("grasp_approach") or "?")
            grasps[kind] = grasps.get(kind, 0) + 1
        out.append(ObjectStats(name, len(rs), len(ok), rejected, len(ok) / attempted if attempted else math.nan,
                               wilson_interval(len(ok), attempted),
                               _stat(place, lambda a: np.sqrt(np.mean(a**2))), dict(sorted(grasps.items()))))
    return tuple(out)


__all__ = [
    "BEFORE_MOTION_PHASE",
    "CampaignSummary",
    "FailedTrial",
    "FailureGroup",
    "ObjectStats",
    "RetryCount",
    "episodes",
    "failed_object",
    "is_task",
    "normalize_reason",
    "object_name",
    "retries_of",
    "summarize",
    "wilson_interval",
]
