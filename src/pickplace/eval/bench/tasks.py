"""Task benchmark: the three task types over randomized trials, the planned order against the listed one on the
same trials.

Trials (ideal profile, each drawn from its trial seed with :func:`~pickplace.task.tasks.random_task_scene`):

* ``stack``: three 40 mm cubes, starts and yaws (within ±45°) at random, the tower at the fixed
  ``TaskConfig.stack_xy_m``;
* ``place``: four library objects at random, the first two trading places (each one's goal is the other's
  start: a swap), the others to random free goals;
* ``clear``: five library objects at random into the default bin.

Each trial runs twice, in the planned order and in the listed order; success (with its 95 % Wilson interval),
the task time (simulated, total and per object), picks per task, and each failure (seed, object, phase,
reason) are reported per task type and order.

Usage: ``pickplace bench tasks [--json] [--trials N] [--kinds stack,place,clear] [--orders planned,listed]
[--workers W] [--seed S]`` (``benchmarks/tasks.py`` is the same).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import numpy as np

from pickplace.eval.bench import machine_info

#: Per task type: how many objects, and which library objects to draw from (None: the whole library).
TRIALS = {"stack": (3, ("cube",)), "place": (4, None), "clear": (5, None)}


def trial(args: tuple[str, str, int]) -> dict[str, Any]:
    """One task trial ``(kind, order, seed)`` -> its figures (run in a pool worker)."""
    import logging

    from pickplace.task.episode import EpisodeConfig
    from pickplace.task.task_episode import run_task
    from pickplace.task.tasks import TaskConfig, random_task_scene

    logging.disable(logging.WARNING)
    kind, order, seed = args
    n, names = TRIALS[kind]
    scene = random_task_scene(kind, n, np.random.default_rng([seed, 7]), names=names)
    r = run_task(EpisodeConfig(scene=scene, task=TaskConfig(kind=kind, order=order)), seed)
    return {"kind": kind, "order": order, "seed": seed, "success": r.success, "objects": [o.name for o in r.objects],
            "sequence": [f"{n}->{label}" for n, label in r.order], "picks": len(r.picks),
            "total_time_s": r.total_time_s, "time_per_object_s": r.time_per_pick_s, "wall_time_s": r.wall_time_s,
            "failure_object": r.failure_object, "failure_phase": r.failure_phase, "failure_kind": r.failure_kind,
            "failure_reason": r.failure_reason, "knocked": [k.name for k in r.knocked],
            "level_xy_max_m": max((o.xy_error_m for o in r.objects[1:] if kind == "stack"), default=math.nan),
            "level_yaw_max_rad": max((abs(o.yaw_error_rad) for o in r.objects[1:] if kind == "stack"),
                                     default=math.nan)}


def run(trials: int = 20, kinds: tuple[str, ...] = ("stack", "place", "clear"),
        orders: tuple[str, ...] = ("planned", "listed"), workers: int = 2, seed: int = 0) -> dict[str, Any]:
    """Every (kind, order) over the same ``trials`` trial seeds; the figures per (kind, order)."""
    import multiprocessing as mp

    from pickplace.eval.campaign.summary import wilson_interval

    jobs = [(k, o, seed * 100_000 + i) for k in kinds for i in range(trials) for o in orders]
    with mp.get_context("spawn").Pool(workers) as pool:
        rows = pool.map(trial, jobs, chunksize=1)
    out: dict[str, Any] = {"machine": machine_info(), "trials": trials, "workers": workers, "seed": seed,
                           "results": {}}
    for k in kinds:
        for o in orders:
            mine = [r for r in rows if r["kind"] == k and r["order"] == o]
            ok = [r for r in mine if r["success"]]
            lo, hi = wilson_interval(len(ok), len(mine))
            out["results"][f"{k}/{o}"] = {
                "successes": len(ok), "trials": len(mine), "wilson95": [lo, hi],
                "task_time_s_mean": float(np.mean([r["total_time_s"] for r in ok])) if ok else math.nan,
                "time_per_object_s_mean": float(np.mean([r["time_per_object_s"] for r in ok])) if ok else math.nan,
                "picks_mean": float(np.mean([r["picks"] for r in ok])) if ok else math.nan,
                "wall_time_s_mean": float(np.mean([r["wall_time_s"] for r in mine])),
                "level_xy_max_m": max((r["level_xy_max_m"] for r in ok), default=math.nan),
                "level_yaw_max_rad": max((r["level_yaw_max_rad"] for r in ok), default=math.nan),
                "failures": [{key: r[key] for key in ("seed", "objects", "sequence", "failure_object",
                                                      "failure_phase", "failure_kind", "failure_reason")}
                             for r in mine if not r["success"]],
            }
    out["rows"] = rows
    return out


def print_table(result: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"Tasks, ideal profile, {result['trials']} trials each (the same trials in both orders)")
    for col in ("task / order", "success", "Wilson 95 %", "task time (s)", "per object (s)", "picks"):
        t.add_column(col, justify="left" if col == "task / order" else "right")
    for name, r in result["results"].items():
        lo, hi = r["wilson95"]
        t.add_row(name, f"{r['successes']}/{r['trials']}", f"{lo * 100:.1f}–{hi * 100:.1f} %",
                  f"{r['task_time_s_mean']:.2f}", f"{r['time_per_object_s_mean']:.2f}", f"{r['picks_mean']:.2f}")
    console = Console()
    console.print(t)
    for name, r in result["results"].items():
        for f in r["failures"]:
            console.print(f"{name} seed {f['seed']}: {f['failure_kind']} ({f['failure_object']}, "
                          f"{f['failure_phase']}): {f['failure_reason']}", highlight=False, markup=False)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="pickplace bench tasks", description=__doc__.split("\n\n")[0])
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--trials", type=int, default=20, help="trials per task type (default 20)")
    p.add_argument("--kinds", default="stack,place,clear", help="task types, comma separated")
    p.add_argument("--orders", default="planned,listed", help="orders, comma separated")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--seed", type=int, default=0, help="trial seeds start at SEED * 100000")
    a = p.parse_args(argv)
    kinds = tuple(k for k in a.kinds.split(",") if k)
    orders = tuple(o for o in a.orders.split(",") if o)
    for k in kinds:
        if k not in TRIALS:
            p.error(f"--kinds: {k!r} is not one of {', '.join(TRIALS)}")
    for o in orders:
        if o not in ("planned", "listed"):
            p.error(f"--orders: {o!r} is not planned or listed")
    result = run(a.trials, kinds, orders, a.workers, a.seed)
    if a.json:
        print(json.dumps(result, indent=2, default=float))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
