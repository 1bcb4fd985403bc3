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

Usage: ``python benchmarks/campaign.py [--json] [--trials K] [--repeats R] [--campaign N] [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

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
    parser.add_argument("--trials", type=int, default=20, help="trials per scaling run (default 20)")
    parser.add_argument("--repeats", type=int, default=1, help="interleaved 1/2-worker rounds; the best is kept")
    parser.add_argument("--campaign", type=int, default=50, help="trials of the timed campaign (default 50)")
    parser.add_argument("--quick", action="store_true", help="6 trials per scaling run, a 10-trial campaign")
    args = parser.parse_args(argv)
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
