"""Evaluation campaigns: many randomized episodes, on local processes or a Ray cluster, persisted and resumable.

A campaign is a base :class:`~pickplace.task.episode.EpisodeConfig`, a :class:`RandomizationSpec` (ranges of the
object's start, yaw, mass, size and friction and of the goal) and a number of trials. Trial ``i`` draws its
scene and its episode seed from the campaign seed and ``i`` only, not from the number of trials, the workers or
the backend, so any trial can be re-run alone (:func:`trial_config`, or ``pickplace run --config
OUT/trials/trial_0007.toml --seed S`` with the file written for every failed trial).

:func:`run_campaign` writes into the output directory ``OUT`` (see :mod:`pickplace.eval.campaign.store`):
``campaign.json``, ``results.jsonl`` (one line per finished trial, fsynced), ``trials/trial_0007.toml`` per failed
trial and ``summary.json`` (the :class:`CampaignSummary`). Killing the campaign (even ``kill -9``) loses at most
the trials that were running: ``resume=True`` (the CLI's ``--resume``) reads ``results.jsonl``, drops a last line
cut short by the kill, and runs only the trials not recorded yet.

The trials run on long-lived local worker processes or Ray actors (:mod:`pickplace.eval.campaign.backends`); a trial
whose worker crashes, hangs past the per-trial timeout (counted from the moment a worker that is up takes it) or
raises is recorded as a failed trial of phase ``WORKER``. The library never prints: progress goes to an
``on_progress`` callback (the CLI draws a progress bar).

The package, by floor (an import only goes down): :mod:`~pickplace.eval.campaign.spec` (randomization, campaign config,
trials), :mod:`~pickplace.eval.campaign.store` (the output directory: results file, TOML, resume),
:mod:`~pickplace.eval.campaign.summary` (the figures), :mod:`~pickplace.eval.campaign.ray_cluster` (joining Ray) and
:mod:`~pickplace.eval.campaign.backends` (local processes, Ray actors), and this module (:func:`run_campaign`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pickplace.errors import ConfigError
from pickplace.eval.campaign.backends import run_local, run_ray
from pickplace.eval.campaign.ray_cluster import RAY_HINT, ray_session
from pickplace.eval.campaign.spec import (
    SIDECAR_KEY,
    WORKER_PHASE,
    CampaignConfig,
    CampaignError,
    RandomizationSpec,
    RunFn,
    Trial,
    apply_params,
    execute_trial,
    make_trial,
    trial_config,
    trial_seed,
)
from pickplace.eval.campaign.store import (
    CAMPAIGN_FILE,
    FORMAT_VERSION,
    RESULTS_FILE,
    SUMMARY_FILE,
    TRIALS_DIR,
    WALL_TIME_FIELDS,
    ResultsWriter,
    TrialRecord,
    episode_config_toml,
    load_campaign,
    load_campaign_toml,
    load_records,
    read_results,
    reproduce_command,
    strip_wall_times,
    toml_dumps,
    trial_toml_path,
    write_atomic,
)
from pickplace.eval.campaign.summary import (
    CampaignSummary,
    FailedTrial,
    FailureGroup,
    RetryCount,
    normalize_reason,
    summarize,
    wilson_interval,
)
from pickplace.task.task_episode import run_trial

log = logging.getLogger(__name__)


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
    run_fn: RunFn = run_trial,
    on_sidecar: Callable[[int, Any], None] | None = None,
) -> CampaignRun:
    """Run (or complete) a campaign, persisting every trial as it finishes.

    Args:
        campaign: What to run.
        out_dir: Output directory (created); see the module docstring for its files.
        resume: Complete the campaign recorded in ``out_dir`` (its base config, randomization and seed must
            match ``campaign``; the number of trials may grow). Without it, ``out_dir`` must hold no results.
        backend: ``"local"`` (processes on this machine) or ``"ray"``.
        ray_address: Ray cluster to join (``backend="ray"``): ``"host:port"`` of its head, or ``"auto"`` (the
            cluster running on this machine); None starts a local Ray instance with ``campaign.workers`` CPUs (or
            every core). A cluster with token authentication is joined with the token found as Ray finds it
            (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH``, ``~/.ray/auth_token``); see
            :mod:`pickplace.eval.campaign.ray_cluster`.
        on_progress: Called in this process at the start and after each finished trial.
        run_fn: The trial function run in the workers: ``run_fn(config, seed) -> EpisodeResult`` (or a
            ``TaskResult`` for a task, :func:`~pickplace.task.task_episode.run_trial`, the default); must be
            picklable (a module-level function). Tests pass their own to inject crashes and hangs.
        on_sidecar: Called in this process with ``(trial index, sidecar)`` for each finished trial whose results
            line carries a :data:`~pickplace.eval.campaign.spec.SIDECAR_KEY` entry (what ``run_fn``'s result put
            there besides its figures), before the trial's line is written; the entry itself is never written to
            ``results.jsonl``.

    Returns:
        The :class:`CampaignRun` (the summary is also written to ``OUT/summary.json``).

    Raises:
        ConfigError: ``out_dir`` holds results and ``resume`` is False, or holds another campaign.
        CampaignError: a worker could not start, Ray is missing, or the Ray cluster cannot be joined (one line
            saying why and what to set).
    """
    if backend not in ("local", "ray"):
        raise ConfigError("backend", backend, "must be 'local' or 'ray'")
    t0 = time.monotonic()
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError("out", str(out), f"cannot be created as a directory: {exc.strerror or exc}") from None
    writer = ResultsWriter(out / RESULTS_FILE)  # locked: one campaign at a time in a directory
    try:
        recorded = _prepare_dir(campaign, out, resume)
        writer.cut_partial_line()
        return _run(campaign, out, writer, recorded, backend, ray_address, on_progress, run_fn, t0, on_sidecar)
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
    write_atomic(campaign_path, json.dumps({"format": FORMAT_VERSION, **campaign.identity(),
                                              "trials": campaign.trials}, indent=2) + "\n")
    recorded: dict[int, TrialRecord] = {}
    for r in existing:
        if r.trial in recorded:
            log.warning("%s: trial %d is recorded twice; keeping the first", results_path, r.trial)
        elif r.trial < campaign.trials:
            recorded[r.trial] = r
    return recorded


def _run(campaign: CampaignConfig, out: Path, writer: ResultsWriter, recorded: dict[int, TrialRecord],
         backend: str, ray_address: str | None, on_progress: Callable[[CampaignProgress], None] | None,
         run_fn: RunFn, t0: float, on_sidecar: Callable[[int, Any], None] | None = None) -> CampaignRun:
    """Run the trials not in ``recorded``, appending each to ``writer`` as it finishes; write the summary."""
    todo = [make_trial(campaign, i) for i in range(campaign.trials) if i not in recorded]
    with contextlib.ExitStack() as stack:
        # Ray first: a cluster that cannot be joined stops the campaign before anything reports progress
        ray = stack.enter_context(ray_session(ray_address, campaign.workers)) if todo and backend == "ray" else None
        return _run_trials(campaign, out, writer, recorded, todo, ray, on_progress, run_fn, t0, on_sidecar)


def _run_trials(campaign: CampaignConfig, out: Path, writer: ResultsWriter, recorded: dict[int, TrialRecord],
                todo: list[Trial], ray: Any, on_progress: Callable[[CampaignProgress], None] | None, run_fn: RunFn,
                t0: float, on_sidecar: Callable[[int, Any], None] | None = None) -> CampaignRun:
    """Run ``todo`` (on Ray if ``ray`` is the initialized module, else locally); write the summary."""
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
        sidecar = line.pop(SIDECAR_KEY, None)
        record = TrialRecord.from_line(line)
        if record.trial in recorded:  # cannot happen with one writer; never write a duplicate
            log.warning("trial %d finished twice; keeping the first result", record.trial)
            return
        if sidecar is not None and on_sidecar is not None:  # before the line: a resumed campaign skips the trial
            on_sidecar(record.trial, sidecar)
        if not record.success:
            trial = by_index[record.trial]
            path = trial_toml_path(out, trial.index)
            path.parent.mkdir(exist_ok=True)
            header = (f"pickplace campaign trial {trial.index} (seed {trial.seed}): failed in "
                      f"{record.failure_phase}: {record.failure_reason}\n"
                      f"reproduce: {reproduce_command(path, trial.seed)}")
            write_atomic(path, episode_config_toml(trial.config, header))
        writer.append(line)
        recorded[record.trial] = record
        done += 1
        successes += record.success
        if on_progress is not None:
            on_progress(CampaignProgress(done, campaign.trials, successes, resumed, record))

    workers = campaign.workers
    if todo:
        if ray is not None:
            run_ray(ray, todo, run_fn, workers, campaign.timeout_s, on_result, on_ready)
        else:
            run_local(todo, run_fn, workers or os.cpu_count() or 1, campaign.timeout_s, on_result, on_ready)

    records = tuple(recorded[i] for i in sorted(recorded))
    summary = summarize(records, out)
    write_atomic(out / SUMMARY_FILE, json.dumps(summary.to_dict(), indent=2) + "\n")
    elapsed = time.monotonic() - t0
    log.info("campaign: %d/%d successes; %d trials run in %.1f s", summary.successes, summary.trials,
             len(todo), elapsed)
    return CampaignRun(summary, records, out, len(todo), elapsed, startup_s)


__all__ = [
    "CAMPAIGN_FILE",
    "RAY_HINT",
    "RESULTS_FILE",
    "SIDECAR_KEY",
    "SUMMARY_FILE",
    "TRIALS_DIR",
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
    "RetryCount",
    "RunFn",
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
