"""Tests of :mod:`pickplace.eval.campaign`, ``pickplace eval`` and ``pickplace report``.

Seeds, validation and the summary's figures are checked without running episodes; the rest runs real episodes
(about 0.7 s each on an idle machine) on 2 worker processes: a small campaign and its summary, the reproduce
command of a failed trial, a campaign killed with SIGKILL and resumed, a worker that crashes / hangs / raises,
and the Ray backend against the local one (skipped when Ray is not installed). Joining a Ray cluster started
with ``ray start`` is tested in ``test_campaign_ray_cluster.py``. The two isolation tests (each waits out a
30 s trial limit) and the 50-trial smoke campaign are ``-m slow``.

Nothing here depends on the machine's speed: the only wall-clock limits are far above what they bound (a
normal trial gets 20 s or more; the hanging trial can never finish), and two runs of a trial are compared
with each other on the same machine, never with numbers recorded elsewhere.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from pickplace.cli import main
from pickplace.errors import ConfigError
from pickplace.eval.campaign import (
    RAY_HINT,
    RESULTS_FILE,
    SUMMARY_FILE,
    WORKER_PHASE,
    CampaignConfig,
    CampaignError,
    CampaignProgress,
    CampaignRun,
    RandomizationSpec,
    RetryCount,
    TrialRecord,
    apply_params,
    episode_config_toml,
    load_campaign_toml,
    make_trial,
    normalize_reason,
    read_results,
    run_campaign,
    strip_wall_times,
    summarize,
    trial_config,
    trial_seed,
    trial_toml_path,
    wilson_interval,
)
from pickplace.task.episode import EpisodeConfig, EpisodeResult, run_episode

SEED = 11
SUMMARY_KEYS = {
    "trials", "successes", "success_rate", "success_rate_ci95", "place_error_xy_rms_m", "place_error_xy_p95_m",
    "cycle_time_mean_s", "cycle_time_p95_s", "plan_time_median_s", "plan_time_p95_s", "tracking_error_max_rad",
    "tcp_tracking_error_max_m", "wall_time_mean_s", "successes_with_recovery", "retries_histogram",
    "failed_before_motion", "failed_before_motion_rate", "failed_after_motion", "failed_after_motion_rate",
    "worker_failures", "worker_failure_rate", "failures", "failed_trials", "success_rate_attempted",
    "success_rate_attempted_ci95", "by_object", "task_time_mean_s", "task_time_per_object_mean_s", "failures_by_object",
    "limit_violations", "trials_over_limits", "joint_limit_ratio_max", "approach_line_deviation_max_m",
    "place_line_deviation_max_m",
}
#: Per-trial limit of the isolation tests (s): far above a normal trial (~0.7 s on an idle machine, 4-5 s with both
#: cores kept busy by two other processes), counted only once a worker that is up takes the trial; the hanging trial
#: never finishes whatever the limit.
ISOLATION_TIMEOUT_S = 30.0

# --------------------------------------------------------------------------- #
# seeds, sampling, validation, files (no episodes)
# --------------------------------------------------------------------------- #


def test_trial_seeds_depend_on_campaign_seed_and_index_only() -> None:
    """Trial i's seed and scene do not depend on the number of trials or workers; they differ between trials."""
    small = CampaignConfig(trials=3, seed=SEED, workers=1)
    large = CampaignConfig(trials=5000, seed=SEED, workers=2)
    for i in range(3):
        a, b = make_trial(small, i), make_trial(large, i)
        assert a.seed == b.seed == trial_seed(SEED, i)
        assert a.params == b.params
        assert a.config == b.config
    seeds = {trial_seed(SEED, i) for i in range(1000)}
    assert len(seeds) == 1000
    assert trial_seed(0, 0) == 4088532484  # pinned: a change here breaks every recorded campaign's reproduction
    assert trial_seed(SEED, 0) != trial_seed(SEED + 1, 0)


def test_samples_stay_in_their_ranges_and_disabling_one_keeps_the_others() -> None:
    spec = RandomizationSpec()
    campaign = CampaignConfig(randomization=spec, trials=200, seed=SEED)
    base = campaign.base.scene
    for i in range(200):
        t = make_trial(campaign, i)
        for name, value in t.params.items():
            lo, hi = getattr(spec, name)
            assert lo <= value <= hi, name
        sc = t.config.scene
        assert sc.start_xy_m[0] == pytest.approx(base.start_xy_m[0] + t.params["start_dx_m"], abs=1e-15)
        assert sc.goal_xy_m[1] == pytest.approx(base.goal_xy_m[1] + t.params["goal_dy_m"], abs=1e-15)
        assert sc.object.mass_kg == pytest.approx(base.object.mass_kg * t.params["object_mass_scale"], rel=1e-12)
        assert sc.start_yaw_rad == pytest.approx(t.params["start_dyaw_rad"], abs=1e-15)
    no_mass = CampaignConfig(randomization=RandomizationSpec(object_mass_scale=None), trials=5, seed=SEED)
    for i in range(5):
        a, b = make_trial(campaign, i), make_trial(no_mass, i)
        assert "object_mass_scale" not in b.params
        assert b.config.scene.object.mass_kg == campaign.base.scene.object.mass_kg
        assert b.params["object_friction"] == a.params["object_friction"]
    off = CampaignConfig(randomization=RandomizationSpec.off(), trials=2)
    assert make_trial(off, 1).config == off.base
    assert make_trial(off, 1).params == {}


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: RandomizationSpec(object_mass_scale=(0.5, 0.1)), "randomization.object_mass_scale"),
        (lambda: RandomizationSpec(object_size_scale=(0.01, 1.5)), "randomization.object_size_scale[0]"),
        (lambda: RandomizationSpec(object_friction=(0.6,)), "randomization.object_friction"),
        (lambda: RandomizationSpec(goal_dx_m=(0.0, math.nan)), "randomization.goal_dx_m[1]"),
        (lambda: RandomizationSpec.from_dict({"cube_mas_kg": [0.1, 0.2]}), "randomization.cube_mas_kg"),
        (lambda: RandomizationSpec.from_dict({"cube_mass_kg": 0.2}), "randomization.cube_mass_kg"),
        (lambda: CampaignConfig(randomization=RandomizationSpec(start_dx_m=(-0.3, 0.3))),
         "randomization.start_dx_m/start_dy_m/object_size_scale"),
        (lambda: CampaignConfig(trials=0), "campaign.trials"),
        (lambda: CampaignConfig(workers=0), "campaign.workers"),
        (lambda: CampaignConfig(timeout_s=-1.0), "campaign.timeout_s"),
        (lambda: CampaignConfig(seed=-1), "campaign.seed"),
    ],
)
def test_invalid_spec_and_campaign_name_the_field(make, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        make()
    assert info.value.field == field
    assert field in str(info.value)


def test_campaign_toml_with_a_randomization_table(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text("[scene]\ncube_mass_kg = 0.3\n\n[planner]\ntime_budget_s = 0.5\n\n"
                    "[randomization]\ncube_dx_m = [-0.02, 0.01]\ncube_mass_kg = false\n")
    base, spec = load_campaign_toml(path)
    assert base.scene.object.mass_kg == 0.3
    assert base.planner.time_budget_s == 0.5
    assert spec.start_dx_m == (-0.02, 0.01)
    assert spec.object_mass_scale is None
    assert spec.object_friction == RandomizationSpec().object_friction
    assert RandomizationSpec.from_dict(spec.to_dict()) == spec
    path.write_text("[randomization]\nfriction = [0.5, 1.0]\n")
    with pytest.raises(ConfigError, match=r"randomization\.friction .*allowed: .*object_friction"):
        load_campaign_toml(path)


def test_trial_toml_round_trips_the_config_exactly(tmp_path: Path) -> None:
    config, _ = trial_config(CampaignConfig(seed=SEED), 3)
    path = tmp_path / "t.toml"
    path.write_text(episode_config_toml(config, "a header\nover two lines"))
    assert EpisodeConfig.from_toml(path) == config


def test_wilson_interval_and_reason_normalization() -> None:
    lo, hi = wilson_interval(50, 50)
    assert (lo, hi) == (pytest.approx(0.92865, abs=1e-5), 1.0)
    lo, hi = wilson_interval(0, 10)
    assert (lo, hi) == (0.0, pytest.approx(0.27753, abs=1e-5))
    lo, hi = wilson_interval(495, 500)
    assert lo == pytest.approx(0.97680, abs=1e-4) and hi == pytest.approx(0.99574, abs=1e-4)
    a = normalize_reason("cube 3.21 mm from the goal (tolerance 0.10 mm), slip 1e-3 m")
    b = normalize_reason("cube 12 mm from the goal (tolerance 0.10 mm), slip -2.5E+01 m")
    assert a == b == "cube # mm from the goal (tolerance # mm), slip # m"


def _record(trial: int, success: bool, phase: str | None = None, retries: int | None = 0) -> TrialRecord:
    """A hand-built record: ``retries`` recoveries (None: a worker failure, which has no count)."""
    result = {"success": success, "seed": 100 + trial, "failure_phase": phase,
              "failure_kind": None if phase is None else f"{phase.title()}Error",
              "failure_reason": None if phase is None else f"failed in {phase} after {trial}.5 s",
              "retries": retries, "recoveries": None if retries is None else [f"recovery {k}" for k in range(retries)]}
    return TrialRecord(trial, {}, result)


def test_summary_counts_recoveries_retries_and_when_trials_failed() -> None:
    """Known counts: 5 successes (3 after a recovery), 2 rejected in IDLE, 1 failed after moving, 1 worker crash."""
    older = TrialRecord(8, {}, {"success": True, "seed": 108, "recoveries": ["regrasp"]})  # no "retries" key
    records = [_record(0, True), _record(1, True, retries=1), _record(2, True, retries=2), _record(3, True),
               _record(4, False, "IDLE"), _record(5, False, "IDLE"), _record(6, False, "CLOSE", retries=1),
               _record(7, False, WORKER_PHASE, retries=None), older]
    s = summarize(records)
    assert (s.trials, s.successes, s.successes_with_recovery) == (9, 5, 3)
    assert s.retries_histogram == (RetryCount(0, 4), RetryCount(1, 3), RetryCount(2, 1))
    assert sum(b.trials for b in s.retries_histogram) == s.trials - s.worker_failures  # every episode that ran
    assert (s.failed_before_motion, s.failed_after_motion, s.worker_failures) == (2, 1, 1)
    assert s.successes + s.failed_before_motion + s.failed_after_motion + s.worker_failures == s.trials
    assert s.failed_before_motion_rate == pytest.approx(2 / 9)
    assert s.failed_after_motion_rate == pytest.approx(1 / 9)
    assert s.worker_failure_rate == pytest.approx(1 / 9)
    # the rate of the attempted trials: the 2 rejected in IDLE are left out (the worker crash is not)
    assert s.success_rate_attempted == pytest.approx(5 / 7)
    assert s.success_rate_attempted_ci95 == pytest.approx(wilson_interval(5, 7))
    data = json.loads(json.dumps(s.to_dict()))
    assert set(data) == SUMMARY_KEYS
    assert data["retries_histogram"] == [{"retries": 0, "trials": 4}, {"retries": 1, "trials": 3},
                                         {"retries": 2, "trials": 1}]
    empty = summarize([])
    assert empty.retries_histogram == () and empty.successes_with_recovery == 0
    assert math.isnan(empty.failed_before_motion_rate) and math.isnan(empty.worker_failure_rate)


def test_results_reader_ignores_a_cut_last_line(tmp_path: Path) -> None:
    line = {"trial": 0, "params": {}, "success": True, "seed": 1}
    path = tmp_path / RESULTS_FILE
    path.write_text(json.dumps(line) + "\n" + "not json\n" + '{"trial": 1, "par')
    records = read_results(path)
    assert [r.trial for r in records] == [0]
    assert records[0] == TrialRecord(0, {}, {"success": True, "seed": 1})


def test_one_campaign_at_a_time_in_a_directory(tmp_path: Path) -> None:
    """The parent locks results.jsonl (flock): a second campaign into the same directory is refused."""
    fcntl = pytest.importorskip("fcntl")
    (tmp_path / RESULTS_FILE).touch()
    with (tmp_path / RESULTS_FILE).open("ab") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(ConfigError, match="in use by another running campaign"):
            run_campaign(CampaignConfig(trials=1, workers=1), tmp_path, resume=True)


# --------------------------------------------------------------------------- #
# campaigns with real episodes
# --------------------------------------------------------------------------- #


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> CampaignRun:
    """4 randomized trials on 2 local workers (the progress callback's calls are checked here too)."""
    out = tmp_path_factory.mktemp("small")
    events: list[CampaignProgress] = []
    run = run_campaign(CampaignConfig(trials=4, seed=SEED, workers=2), out, on_progress=events.append)
    assert [(e.done, e.total, e.resumed) for e in events] == [(i, 4, 0) for i in range(5)]
    assert events[0].last is None and all(e.last is not None for e in events[1:])
    assert [e.successes for e in events] == [sum(x.last.success for x in events[1 : i + 1]) for i in range(5)]
    return run


def _lines(path: Path) -> list[dict]:
    return [json.loads(s) for s in path.read_text().splitlines()]


def test_small_campaign_writes_results_and_summary(small: CampaignRun) -> None:
    lines = _lines(small.out_dir / RESULTS_FILE)
    assert sorted(line["trial"] for line in lines) == [0, 1, 2, 3]
    campaign = CampaignConfig(trials=4, seed=SEED, workers=2)
    for line in lines:
        t = make_trial(campaign, line["trial"])
        assert line["seed"] == t.seed
        assert line["params"] == t.params
        assert EpisodeConfig.from_dict(line["config"]).scene == t.config.scene
        assert line["success"] is True, line["failure_reason"]
    summary = json.loads((small.out_dir / SUMMARY_FILE).read_text())
    assert set(summary) == SUMMARY_KEYS
    assert summary["trials"] == 4 and summary["successes"] == 4
    assert summary["success_rate_ci95"][0] == pytest.approx(wilson_interval(4, 4)[0])
    assert 0 < summary["place_error_xy_rms_m"] < 0.003
    assert summary["place_error_xy_p95_m"] < 0.003
    assert 1.0 < summary["cycle_time_mean_s"] <= summary["cycle_time_p95_s"] < 20.0
    assert 0 < summary["plan_time_median_s"] <= summary["plan_time_p95_s"]
    assert 0 < summary["tracking_error_max_rad"] < 0.1
    # every straight move is part of a joint trajectory (the ideal profile moves on between the phases): no
    # Cartesian move to measure; every 1 ms step of the motions within the joints' limits, the tcp on its lines
    assert summary["tcp_tracking_error_max_m"] is None
    assert summary["limit_violations"] == summary["trials_over_limits"] == 0
    assert 0.5 < summary["joint_limit_ratio_max"] <= 1.0
    assert 0 < summary["approach_line_deviation_max_m"] <= 1e-3 and 0 < summary["place_line_deviation_max_m"] <= 1e-3
    assert summary["wall_time_mean_s"] > 0
    assert summary["failures"] == [] and summary["failed_trials"] == []
    assert 0 <= summary["successes_with_recovery"] <= 4
    assert sum(b["trials"] for b in summary["retries_histogram"]) == 4
    assert summary["failed_before_motion"] == summary["failed_after_motion"] == summary["worker_failures"] == 0
    assert small.trials_run == 4


def test_completed_campaign_refuses_to_run_again_without_resume(small: CampaignRun) -> None:
    campaign = CampaignConfig(trials=4, seed=SEED, workers=2)
    with pytest.raises(ConfigError, match="already holds 4 results"):
        run_campaign(campaign, small.out_dir)
    again = run_campaign(campaign, small.out_dir, resume=True)  # nothing left to run: no worker starts
    assert again.trials_run == 0 and again.summary == small.summary
    with pytest.raises(ConfigError, match=r"campaign\.seed"):
        run_campaign(CampaignConfig(trials=4, seed=SEED + 1), small.out_dir, resume=True)


def test_report_writes_plots_and_markdown(small: CampaignRun, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib", reason="pickplace report needs matplotlib (the video extra)")
    assert main(["report", str(small.out_dir)]) == 0
    pngs = sorted(p.name for p in (small.out_dir / "plots").glob("*.png"))
    assert pngs == ["cycle_time_hist.png", "failure_reasons.png", "place_error_hist.png", "success_vs_params.png"]
    for name in pngs:
        data = (small.out_dir / "plots" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    md = (small.out_dir / "report.md").read_text()
    for name in pngs:
        assert f"(plots/{name})" in md
    assert "95% Wilson" in md and "4/4" in md
    assert "## Recoveries" in md and "| retries | trials |" in md
    assert "0 failed before the arm moved" in md and "successes that needed a recovery" in md
    assert "report.md" in capsys.readouterr().out


def test_failed_trial_is_reproduced_by_its_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Requiring 100 N per pad fails every trial at CLOSE, after the arm moved; the printed command reproduces it.

    The pads squeeze 20 N each at the actuator's force limit (40 N), so no trial can pass on any machine (a
    place tolerance at its 0.1 mm minimum would not do: place errors of ~0.2 mm RMS can fall below it).
    """
    path = tmp_path / "strict.toml"
    path.write_text("[machine]\nmin_pad_force_n = 100.0\nmax_retries = 0\n\n[randomization]\n"
                    "cube_mass_kg = [0.1, 0.2]\n")
    out = tmp_path / "out"
    assert main(["eval", "--config", str(path), "--trials", "2", "--workers", "2", "--seed", "5",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / SUMMARY_FILE).read_text())
    assert summary["successes"] == 0 and len(summary["failed_trials"]) == 2
    failed = summary["failed_trials"][1]
    assert failed["command"] == f"pickplace run --config {trial_toml_path(out, 1)} --seed {failed['seed']}"
    assert failed["command"] in printed
    assert summary["failures"][0]["count"] == 2  # the two reasons differ only in their numbers
    assert summary["failures"][0]["phase"] == "CLOSE"
    assert (summary["failed_after_motion"], summary["failed_before_motion"], summary["worker_failures"]) == (2, 0, 0)
    assert summary["retries_histogram"] == [{"retries": 0, "trials": 2}]
    assert "failed after the arm moved" in printed and "retries" in printed
    record = next(line for line in _lines(out / RESULTS_FILE) if line["trial"] == 1)
    assert record["failure_kind"] == failed["kind"] and record["failure_phase"] == failed["phase"] != WORKER_PHASE

    argv = [*failed["command"].split()[1:], "--json"]
    assert main(argv) == 1  # `pickplace run` exits 1 on a failed episode
    rerun = json.loads(capsys.readouterr().out)
    expected = {k: v for k, v in record.items() if k not in ("trial", "params")}
    assert strip_wall_times(rerun) == strip_wall_times(expected)


@pytest.mark.slow  # two 20-trial runs with a kill between them: ~20 s
def test_sigkill_then_resume_completes_without_duplicates(tmp_path: Path) -> None:
    n = 8
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "pickplace", "eval", "--trials", str(n), "--workers", "2", "--seed", "3",
           "--out", str(out)]
    log = tmp_path / "stderr.txt"
    with log.open("wb") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
    results = out / RESULTS_FILE
    try:
        deadline = time.monotonic() + 300  # a bound on a broken run, not a budget: ~10 s idle, ~30 s on a busy machine
        while not (results.exists() and results.read_bytes().count(b"\n") >= 2):
            assert proc.poll() is None, log.read_text()
            assert time.monotonic() < deadline, "no results after 300 s"
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the parent and its workers, at once
        proc.wait()
    before = results.read_bytes()
    done_before = [json.loads(s) for s in before.split(b"\n")[:-1]]
    assert 2 <= len(done_before) < n
    with results.open("ab") as f:  # the worst case of a kill: a line cut in the middle
        f.write(b'{"trial": 7, "params": {"cube_d')

    assert main(["eval", "--resume", "--out", str(out), "--workers", "2"]) == 0
    after = results.read_bytes()
    lines = _lines(results)
    trials = [line["trial"] for line in lines]
    assert sorted(trials) == list(range(n))  # every trial once: none lost, none duplicated
    complete = before[: before.rfind(b"\n") + 1]
    assert after.startswith(complete)  # the trials recorded before the kill were not re-run
    assert all(line["success"] for line in lines)
    assert json.loads((out / SUMMARY_FILE).read_text())["trials"] == n


# Trials whose episode function misbehaves, for the isolation test (picked by their seeds; module-level so
# that the spawned workers can unpickle the function).
CRASH_SEED, HANG_SEED, RAISE_SEED = (trial_seed(SEED, i) for i in (1, 2, 3))


def misbehaving_episode(config: EpisodeConfig, seed: int) -> EpisodeResult:
    """run_episode, except that trial 1's worker dies, trial 2 hangs forever and trial 3 raises."""
    if seed == CRASH_SEED:
        os._exit(3)
    if seed == HANG_SEED:
        threading.Event().wait()  # nothing ever sets it: only the timeout ends this trial
    if seed == RAISE_SEED:
        raise RuntimeError("injected failure 42")
    return run_episode(config, seed)


def _check_isolation(run: CampaignRun, small: CampaignRun, timeout_s: float) -> None:
    """Trials 0 and 4 succeed as in the plain campaign; 1 (crash), 2 (hang), 3 (raise) are failed with reasons."""
    by_trial = {r.trial: r for r in run.records}
    assert sorted(by_trial) == [0, 1, 2, 3, 4]
    good = {r.trial: r for r in small.records}
    for i in (0, 4):
        assert by_trial[i].success, by_trial[i].failure_reason
        if i in good:
            assert strip_wall_times(by_trial[i].result) == strip_wall_times(good[i].result)
    crash, hang, exc = by_trial[1], by_trial[2], by_trial[3]
    assert (crash.failure_phase, crash.failure_kind) == (WORKER_PHASE, "WorkerCrashed"), crash.failure_reason
    assert (hang.failure_phase, hang.failure_kind) == (WORKER_PHASE, "WorkerTimeout")
    assert f"timeout of {timeout_s:g} s" in (hang.failure_reason or "")
    assert timeout_s <= hang.result["wall_time_s"] < timeout_s + 60  # killed once past its limit
    assert (exc.failure_phase, exc.failure_kind) == (WORKER_PHASE, "RuntimeError")
    assert "injected failure 42" in (exc.failure_reason or "")
    assert run.summary.worker_failures == 3
    assert sum(b.trials for b in run.summary.retries_histogram) == 2  # the two trials whose episode ran
    assert {(g.kind, g.count) for g in run.summary.failures} == {("WorkerCrashed", 1), ("WorkerTimeout", 1),
                                                                   ("RuntimeError", 1)}
    for i in (1, 2, 3):
        assert trial_toml_path(run.out_dir, i).exists()
    assert len(_lines(run.out_dir / RESULTS_FILE)) == 5


@pytest.mark.slow
def test_worker_crash_hang_and_exception_are_isolated(small: CampaignRun, tmp_path: Path) -> None:
    run = run_campaign(CampaignConfig(trials=5, seed=SEED, workers=2, timeout_s=ISOLATION_TIMEOUT_S),
                       tmp_path / "faulty", run_fn=misbehaving_episode)
    _check_isolation(run, small, ISOLATION_TIMEOUT_S)
    assert "exited with code 3" in (run.records[1].failure_reason or "")


@pytest.fixture
def ray_tag(monkeypatch: pytest.MonkeyPatch) -> str:
    """A tag in this process's environment, inherited by every process of the local Ray instance it starts (so
    that leftovers are found by it, whatever other Ray sessions run on the machine)."""
    tag = f"{os.getpid()}-{time.monotonic_ns()}"
    monkeypatch.setenv("PICKPLACE_TEST_RAY_TAG", tag)
    return tag


def _tagged_pids(tag: str) -> set[int]:
    """Processes other than this one whose environment holds ``tag`` (zombies excluded)."""
    needle = f"PICKPLACE_TEST_RAY_TAG={tag}".encode()
    pids = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                if needle in (entry / "environ").read_bytes().split(b"\0") and \
                        (entry / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                    pids.add(int(entry.name))
            except (OSError, IndexError):
                continue
    return pids


def _assert_ray_is_gone(tag: str) -> None:
    deadline = time.monotonic() + 60  # Ray's processes exit on their own after shutdown; slower on a busy machine
    while (left := _tagged_pids(tag)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, f"Ray left processes behind: {sorted(left)}"


def test_missing_ray_is_one_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now raises ImportError
    with pytest.raises(CampaignError, match=re.escape(RAY_HINT)):
        run_campaign(CampaignConfig(trials=1, workers=1), tmp_path, backend="ray")
    assert main(["eval", "--ray", "--trials", "1", "--out", str(tmp_path / "cli")]) == 1


@pytest.mark.slow  # starts a local Ray instance: ~17 s
@pytest.mark.skipif(sys.platform != "linux", reason="checks leftover processes through /proc")
def test_ray_backend_gives_the_local_results(small: CampaignRun, tmp_path: Path, ray_tag: str) -> None:
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'pickplace[ray]')")
    run = run_campaign(CampaignConfig(trials=4, seed=SEED, workers=2), tmp_path / "ray", backend="ray")
    assert not ray.is_initialized()
    assert [r.trial for r in run.records] == [0, 1, 2, 3]
    for mine, local in zip(run.records, small.records, strict=True):
        assert mine.params == local.params
        assert strip_wall_times(mine.result) == strip_wall_times(local.result)
    _assert_ray_is_gone(ray_tag)


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="checks leftover processes through /proc")
def test_ray_worker_crash_hang_and_exception_are_isolated(small: CampaignRun, tmp_path: Path, ray_tag: str) -> None:
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'pickplace[ray]')")
    from ray import cloudpickle

    module = sys.modules[__name__]
    cloudpickle.register_pickle_by_value(module)  # Ray's workers cannot import this test module by name
    try:
        run = run_campaign(CampaignConfig(trials=5, seed=SEED, workers=2, timeout_s=ISOLATION_TIMEOUT_S),
                           tmp_path / "ray-faulty", backend="ray", run_fn=misbehaving_episode)
    finally:
        cloudpickle.unregister_pickle_by_value(module)
    _check_isolation(run, small, ISOLATION_TIMEOUT_S)
    assert "Ray worker died" in (run.records[1].failure_reason or "")
    _assert_ray_is_gone(ray_tag)  # the killed (hung) worker too


@pytest.mark.slow
def test_smoke_campaign_of_50_trials(tmp_path: Path) -> None:
    """The acceptance campaign: 50 randomized trials on 2 workers, at least 49 successes."""
    run = run_campaign(CampaignConfig(trials=50, seed=0, workers=2), tmp_path / "smoke")
    assert run.summary.successes >= 49, run.summary.failures



def test_fault_ranges_are_sampled_into_the_trial_faults_without_moving_the_other_draws() -> None:
    """Randomized fault scales land in each trial's [faults]; turning them on changes no other parameter."""
    base_spec = RandomizationSpec(transport_push_n=(0.0, 40.0))
    faulted = RandomizationSpec(transport_push_n=(0.0, 40.0), pad_friction_scale=(0.3, 1.0),
                                true_mass_scale=(1.0, 2.0), joint_noise_rad=(0.0, 1e-4))
    a = base_spec.sample(np.random.default_rng(11))
    b = faulted.sample(np.random.default_rng(11))
    assert {k: b[k] for k in a} == a  # same scene and push draws
    assert 0.3 <= b["pad_friction_scale"] <= 1.0 and 1.0 <= b["true_mass_scale"] <= 2.0
    config = apply_params(EpisodeConfig(), b)
    assert config.faults.pad_friction_scale == b["pad_friction_scale"]
    assert config.faults.true_mass_scale == b["true_mass_scale"]
    assert config.faults.joint_noise_rad == b["joint_noise_rad"]
    assert np.linalg.norm(config.faults.transport_push_n) == pytest.approx(b["transport_push_n"])
    with pytest.raises(ConfigError, match=r"randomization\.pad_friction_scale"):
        RandomizationSpec(pad_friction_scale=(-1.0, 1.0))


def test_objects_are_drawn_from_the_library_without_changing_the_other_draws() -> None:
    from pickplace.eval.campaign import RandomizationSpec
    from pickplace.world.objects import LIBRARY

    plain = RandomizationSpec()
    mixed = RandomizationSpec(objects=("cube", "soda_can", "tennis_ball"))
    seen = set()
    for i in range(30):
        a = plain.sample(np.random.default_rng(i))
        b = mixed.sample(np.random.default_rng(i))
        assert {k: v for k, v in b.items() if k != "object"} == a
        seen.add(b["object"])
    assert seen == {"cube", "soda_can", "tennis_ball"}
    assert RandomizationSpec.from_dict({"objects": ["mug", "cube"]}).objects == ("mug", "cube")
    assert RandomizationSpec.from_dict(mixed.to_dict()) == mixed
    assert "objects" not in plain.to_dict()  # the identity of earlier campaigns is unchanged
    with pytest.raises(ConfigError, match=r"randomization\.objects.*teapot.*must be one of"):
        RandomizationSpec(objects=("cube", "teapot"))
    assert set(LIBRARY) >= set(mixed.objects)


def test_a_start_drawn_inside_the_wall_is_drawn_again() -> None:
    from pickplace.eval.campaign import CampaignConfig, RandomizationSpec, make_trial

    base = EpisodeConfig().with_scene(obstacle=True, obstacle_xy_m=(0.40, 0.10), start_xy_m=(0.40, 0.20))
    spec = RandomizationSpec.off()
    spec = dataclasses.replace(spec, start_dy_m=(-0.15, 0.05), objects=("cube", "sugar_box"))
    campaign = CampaignConfig(base=base, randomization=spec, trials=40, seed=3)
    redrawn = 0
    for i in range(40):
        trial = make_trial(campaign, i)
        trial.config.scene.check_start_clear_of_obstacle()  # never inside the wall
        rng = np.random.default_rng(np.random.SeedSequence(3, spawn_key=(i, 1)))
        redrawn += spec.sample(rng) != trial.params
        assert make_trial(campaign, i) == trial  # the redraws come from the trial's own stream
    assert redrawn > 0
