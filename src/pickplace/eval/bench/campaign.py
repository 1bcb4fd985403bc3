"""Campaign benchmark: trials per second with 1 and 2 local workers in the same run, and a 50-trial campaign.

Measured in one run, on the default randomization:

* scaling: the same ``--trials`` trials (campaign seed 0) run with 1 worker, then with 2, ``--repeats`` times
  interleaved (the machines are shared and noisy; the best round of each is kept). Throughput is given both
  steady-state (trials / (wall time - worker start-up), start-up being the time until every worker process
  has imported pickplace) and end to end (trials / wall time); the ratio is 2 workers over 1;
* the wall time of a ``--campaign``-trial campaign (default 50) on 2 workers, end to end, with its successes;
* a baseline of the machine itself, measured in the same run: bare ``mujoco.mj_step`` loops on the default scene
  in 1 process, then in 2 processes at once (a ``multiprocessing`` pool, no campaign machinery). Its ratio is
  what this machine gives to two simultaneous simulations (shared caches, memory bandwidth, host neighbours);
  the campaign's ratio divided by it is the efficiency of the campaign's own machinery.

With ``--memory``, instead: the resident memory of every worker over a long campaign (``--trials``, default 2000,
on ``--workers``, default 4), read from ``/proc`` after every finished trial (Linux). Each worker is judged from
the moment it has run ``--warmup`` trials (default 100; the campaign has then run ``warmup x workers``) to the
end: its growth in per cent, which stays flat once its caches are full
(:func:`~pickplace.eval.campaign.spec.release_freed_memory` says what grew before).

Usage: ``python benchmarks/campaign.py [--json] [--trials K] [--repeats R] [--campaign N] [--quick]``;
``python benchmarks/campaign.py --memory [--json] [--trials N] [--workers W] [--warmup K]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pickplace.eval.bench import machine_info
from pickplace.eval.campaign import CampaignConfig, CampaignRun, run_campaign


def _mj_steps(steps: int) -> float:
    """Wall time (s) of ``steps`` bare ``mj_step`` calls on the default scene (run in a pool worker)."""
    import time

    import mujoco

    from pickplace.robot.model import build

    robot = build()
    d = robot.make_data()
    mujoco.mj_step(robot.mj, d)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(robot.mj, d)
    return time.perf_counter() - t0


def machine_baseline(steps: int = 100_000, repeats: int = 1) -> dict[str, Any]:
    """Throughput ratio of bare simulation in 2 processes at once over 1 process (best of ``repeats``)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    one, two = [], []
    for _ in range(repeats):
        with ctx.Pool(1) as pool:
            one.append(pool.map(_mj_steps, [steps])[0])
        with ctx.Pool(2) as pool:
            two.append(max(pool.map(_mj_steps, [steps, steps], chunksize=1)))
    t1, t2 = min(one), min(two)
    return {"steps_per_process": steps, "us_per_step_1_process": t1 / steps * 1e6,
            "us_per_step_2_processes": t2 / steps * 1e6, "ratio": 2 * t1 / t2}


def _once(trials: int, workers: int, seed: int = 0) -> CampaignRun:
    with tempfile.TemporaryDirectory(prefix="pickplace-bench-") as tmp:
        return run_campaign(CampaignConfig(trials=trials, seed=seed, workers=workers), Path(tmp) / "out")


def _throughput(run: CampaignRun) -> dict[str, Any]:
    steady = run.elapsed_s - run.startup_s
    return {"trials": run.trials_run, "wall_s": run.elapsed_s, "startup_s": run.startup_s,
            "trials_per_s": run.trials_run / steady if steady > 0 else float("nan"),
            "trials_per_s_end_to_end": run.trials_run / run.elapsed_s, "successes": run.summary.successes,
            "wall_time_mean_s": run.summary.wall_time_mean_s}


def run(trials: int = 20, repeats: int = 1, campaign: int = 50) -> dict[str, Any]:
    """Run the benchmark; returns one JSON-serialisable dict."""
    rounds: dict[int, list[dict[str, Any]]] = {1: [], 2: []}
    for _ in range(repeats):
        for workers in (1, 2):
            rounds[workers].append(_throughput(_once(trials, workers)))
    best = {w: max(rs, key=lambda r: r["trials_per_s"]) for w, rs in rounds.items()}
    big = _once(campaign, 2)
    baseline = machine_baseline(repeats=repeats)
    ratio = best[2]["trials_per_s"] / best[1]["trials_per_s"]
    return {
        "scaling": {
            "trials": trials,
            "repeats": repeats,
            "workers_1": best[1],
            "workers_2": best[2],
            "ratio": ratio,
            "efficiency_vs_machine_baseline": ratio / baseline["ratio"],
            "ratio_end_to_end": best[2]["trials_per_s_end_to_end"] / best[1]["trials_per_s_end_to_end"],
        },
        "campaign": {"trials": campaign, "workers": 2, "wall_s": big.elapsed_s, "startup_s": big.startup_s,
                     "successes": big.summary.successes, "success_rate": big.summary.success_rate,
                     "trials_per_s": campaign / big.elapsed_s},
        "machine_baseline_mj_step": baseline,
        "machine": machine_info(),
    }


# --------------------------------------------------------------------------- #
# workers' memory over a long campaign
# --------------------------------------------------------------------------- #


def _rss_mb(pid: int) -> float | None:
    """Resident memory of process ``pid`` (MB), or None if it is gone (Linux ``/proc``)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def _worker_pids() -> list[int]:
    """The campaign's local worker processes: this process's children started by ``multiprocessing.spawn``."""
    import os

    kids: list[int] = []
    try:
        for tid in os.listdir(f"/proc/{os.getpid()}/task"):
            with open(f"/proc/{os.getpid()}/task/{tid}/children") as f:
                kids += [int(x) for x in f.read().split()]
    except OSError:
        return []
    workers = []
    for pid in kids:
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if b"spawn_main" in f.read():
                    workers.append(pid)
        except OSError:
            continue
    return workers


def memory(trials: int = 2000, workers: int = 4, warmup: int = 100, seed: int = 0,
           progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run a ``trials``-trial campaign (default randomization) on ``workers`` local workers and sample every
    worker's resident memory after each finished trial; returns one JSON-serialisable dict.

    Workers are fed one trial at a time, so each has run about ``done / workers`` trials when the campaign has run
    ``done``; a worker is judged from the first sample with ``done >= warmup * workers`` to its last sample: the
    median of the last tenth of those samples against the median of the first tenth.
    """
    import os
    import time

    from pickplace.eval.campaign import CampaignProgress

    if not os.path.isdir("/proc/self/task"):
        raise RuntimeError("the memory benchmark reads /proc (Linux)")
    samples: list[dict[str, Any]] = []
    t0 = time.monotonic()

    def sample(p: CampaignProgress) -> None:
        rss = {pid: _rss_mb(pid) for pid in _worker_pids()}
        samples.append({"done": p.done, "t_s": time.monotonic() - t0,
                        "rss_mb": {str(k): v for k, v in rss.items() if v is not None}})
        if progress is not None and p.done % 50 == 0 and p.done:
            progress(f"{p.done}/{p.total} trials: workers' RSS " + ", ".join(f"{v:.0f}" for v in rss.values() if v)
                     + " MB")

    with tempfile.TemporaryDirectory(prefix="pickplace-bench-") as tmp:
        run = run_campaign(CampaignConfig(trials=trials, seed=seed, workers=workers), Path(tmp) / "out",
                           on_progress=sample)
    start = warmup * workers
    per_worker: dict[str, Any] = {}
    for pid in sorted({k for s in samples for k in s["rss_mb"]}, key=int):
        series = [(s["done"], s["rss_mb"][pid]) for s in samples if pid in s["rss_mb"]]
        after = [r for d, r in series if d >= start]
        row: dict[str, Any] = {"first_mb": series[0][1], "last_mb": series[-1][1],
                               "peak_mb": max(r for _, r in series), "samples": len(series),
                               "series": [[d, round(r, 1)] for d, r in series]}
        if after:  # a sample is taken after any worker's trial, and a worker's memory varies by ±5 % trial to trial
            k = max(1, len(after) // 10)
            row["after_warmup_mb"] = float(np.median(after[:k]))
            row["end_mb"] = float(np.median(after[-k:]))
            row["growth_after_warmup_pct"] = (row["end_mb"] / row["after_warmup_mb"] - 1.0) * 100.0
        per_worker[pid] = row
    growths = [w["growth_after_warmup_pct"] for w in per_worker.values() if "growth_after_warmup_pct" in w]
    totals = [(s["done"], sum(s["rss_mb"].values())) for s in samples if s["rss_mb"]]
    return {
        "trials": trials, "workers": workers, "warmup_trials_per_worker": warmup,
        "successes": run.summary.successes, "worker_failures": run.summary.worker_failures,
        "wall_s": run.elapsed_s, "trials_per_s": trials / run.elapsed_s,
        "per_worker": per_worker, "max_growth_after_warmup_pct": max(growths) if growths else None,
        "total_rss_mb": {"first": totals[0][1] if totals else None,
                         "at_warmup": next((t for d, t in totals if d >= start), None),
                         "last": totals[-1][1] if totals else None},
        "total_curve": [[d, round(t, 1)] for d, t in totals[:: max(1, trials // 100)]],
        "machine": machine_info(),
    }


def print_memory(result: dict[str, Any]) -> None:
    """Render the memory result as a rich table."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    t = Table(title=f"Workers' resident memory over a {result['trials']}-trial campaign on {result['workers']} "
                    f"workers (judged after {result['warmup_trials_per_worker']} trials each)")
    for col in ("worker", "first (MB)", "after warm-up (MB)", "end (MB)", "peak (MB)", "growth after warm-up"):
        t.add_column(col, justify="right")
    for pid, w in result["per_worker"].items():
        growth = f"{w['growth_after_warmup_pct']:+.1f} %" if "growth_after_warmup_pct" in w else "—"
        t.add_row(pid, f"{w['first_mb']:.0f}", f"{w.get('after_warmup_mb', float('nan')):.0f}",
                  f"{w.get('end_mb', w['last_mb']):.0f}",
                  f"{w['peak_mb']:.0f}", growth)
    console.print(t)
    tot = result["total_rss_mb"]
    console.print(f"all workers: {tot['first']:.0f} MB at the first trial, {tot['at_warmup'] or float('nan'):.0f} MB "
                  f"after warm-up, {tot['last']:.0f} MB at the end; {result['successes']}/{result['trials']} "
                  f"successes, {result['worker_failures']} worker failures, {result['trials_per_s']:.2f} trials/s",
                  highlight=False)


def print_table(result: dict[str, Any]) -> None:
    """Render the result as a rich table."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    sc = result["scaling"]
    t = Table(title=f"Campaign throughput, {sc['trials']} trials (best of {sc['repeats']} interleaved rounds)")
    for col in ("workers", "trials/s (steady)", "trials/s (end to end)", "start-up (s)", "wall (s)", "successes"):
        t.add_column(col, justify="right")
    for w in (1, 2):
        r = sc[f"workers_{w}"]
        t.add_row(str(w), f"{r['trials_per_s']:.2f}", f"{r['trials_per_s_end_to_end']:.2f}", f"{r['startup_s']:.2f}",
                  f"{r['wall_s']:.1f}", f"{r['successes']}/{r['trials']}")
    t.add_row("ratio 2/1", f"{sc['ratio']:.2f}×", f"{sc['ratio_end_to_end']:.2f}×", "", "", "")
    console.print(t)
    b = result["machine_baseline_mj_step"]
    console.print(f"machine baseline (bare mj_step, same run): {b['us_per_step_1_process']:.1f} µs/step alone, "
                  f"{b['us_per_step_2_processes']:.1f} µs/step with 2 processes at once: ratio {b['ratio']:.2f}×; "
                  f"campaign efficiency {sc['efficiency_vs_machine_baseline']:.0%} of it", highlight=False)
    c = result["campaign"]
    console.print(f"{c['trials']}-trial campaign on {c['workers']} workers: {c['wall_s']:.1f} s wall "
                  f"({c['startup_s']:.1f} s start-up, {c['trials_per_s']:.2f} trials/s), "
                  f"{c['successes']}/{c['trials']} successes; 1-min load average "
                  f"{result['machine']['load_average_1min']:.2f} on {result['machine']['cpu_count']} cores",
                  highlight=False)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a rich table, or one JSON object with ``--json``. Returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--trials", type=int, default=None,
                        help="trials per scaling run (default 20); with --memory: of the campaign (default 2000)")
    parser.add_argument("--repeats", type=int, default=1, help="interleaved 1/2-worker rounds; the best is kept")
    parser.add_argument("--campaign", type=int, default=50, help="trials of the timed campaign (default 50)")
    parser.add_argument("--quick", action="store_true", help="6 trials per scaling run, a 10-trial campaign")
    parser.add_argument("--memory", action="store_true",
                        help="instead: every worker's resident memory over a long campaign (--trials, default 2000)")
    parser.add_argument("--workers", type=int, default=4, help="with --memory: local workers (default 4)")
    parser.add_argument("--warmup", type=int, default=100,
                        help="with --memory: trials per worker before its growth is judged (default 100)")
    args = parser.parse_args(argv)
    if args.memory:
        trials = 2000 if args.trials is None else args.trials
        if trials < 1 or args.workers < 1 or args.warmup < 0:
            parser.error("--trials and --workers must be >= 1 and --warmup >= 0")
        echo = None if args.json else (lambda line: print(line, file=sys.stderr, flush=True))
        mem = memory(trials, args.workers, args.warmup, progress=echo)
        if args.json:
            print(json.dumps(mem))
        else:
            print_memory(mem)
        return 0
    args.trials = 20 if args.trials is None else args.trials
    if args.quick:
        args.trials, args.campaign = 6, 10
    if args.trials < 2 or args.repeats < 1 or args.campaign < 1:
        parser.error("--trials must be >= 2, --repeats >= 1 and --campaign >= 1")
    result = run(args.trials, args.repeats, args.campaign)
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
