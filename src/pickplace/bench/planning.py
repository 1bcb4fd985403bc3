"""Planning benchmark: pickplace's RRT* against OMPL's RRTConnect and RRT* on the pick-and-place segments.

On the default scene and the obstacle scene (a wall between start and goal) every planner solves two
segments once per seed: ``home->pregrasp`` (gripper open, cube resting) and ``pregrasp->preplace`` (cube
carried), with the same kind of :class:`CollisionChecker` (margin 1 cm) and the same time budget. Each final
path is then retimed with TOPP-RA (``TimingConfig.ur5e()``) and re-checked every 0.01 rad at margin 0.

How the planners are set up (read the numbers with this in mind):

* ``pickplace-rrtstar``: ``planning.plan(PlannerConfig(seed, time_budget_s=budget))``. It tries the
  straight segment first, samples in the start-goal box widened by 1 rad, stops at the first solution,
  then shortcuts. Edges are checked every 0.01 rad per joint (max-norm, ``edge_resolution_rad``).
* OMPL: ``RealVectorStateSpace(6)`` with the joint bounds, validity = our ``is_valid`` through a Python
  callback, edges checked by OMPL's discrete motion validator every 0.01 rad of **L2** distance
  (``setStateValidityCheckingResolution(0.01 / max extent)``): every joint then moves at most 0.01 rad
  between checks, as in our planner, but diagonal edges get up to √6 times more checks than ours. The range
  (max extension) is OMPL's default, 0.2 × max extent, unless ``--ompl-range`` is given. RRTConnect stops
  at its first solution; RRT* (path-length objective) uses the whole budget. Both paths are simplified
  with ``partialShortcutPath`` (random shortcuts between points on the path, like ours), repeated while it
  improves (at most 5 rounds), then ``reduceVertices`` likewise; no B-spline smoothing, which would
  multiply the waypoints. OMPL's RNG is seeded with ``seed + 1`` (it rejects 0) before each query.
* Total and solve times and checks are over all queries (a failure costs what it spent); simplification
  time, costs, waypoints, TOPP-RA numbers and ``dense_valid_rate`` are over the successful queries.

Usage: ``python benchmarks/planning.py [--json] [--queries N] [--budget S] [--no-ompl] [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from types import ModuleType
from typing import Any

import numpy as np

from pickplace import planning
from pickplace.bench import machine_info
from pickplace.collision import CollisionChecker, CollisionPolicy
from pickplace.config import SceneConfig
from pickplace.configurations import solve_grasp_configurations
from pickplace.errors import ConfigError, PlanningFailed, TimingFailed
from pickplace.model import build
from pickplace.timing import TimingConfig, retime

EDGE_RES_RAD = planning.PlannerConfig().edge_resolution_rad  # 0.01 rad, also the dense re-check spacing
CHECK_CONFIGS, CHECK_SPREAD_RAD = 2000, 0.5  # collision-cost sample: home + U(-0.5, 0.5) rad per joint
OMPL_SIMPLIFY_ROUNDS = 5


@dataclass(frozen=True, eq=False)
class Segment:
    """One planning problem: ends (6,) and bounds (6,) (rad), the planners' checker and the margin-0 one."""

    scene: str
    name: str
    start: np.ndarray
    goal: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    checker: CollisionChecker
    dense_checker: CollisionChecker


@dataclass(frozen=True)
class Outcome:
    """One query: raw and final paths (K, 6) (None on failure), times (s) and collision checks."""

    path_raw: np.ndarray | None
    path: np.ndarray | None
    time_s: float
    solve_s: float
    simplify_s: float
    checks: int


def segments(scene_name: str, scene: SceneConfig) -> list[Segment]:
    """The two benchmarked segments of a scene, with their IK ends and checkers."""
    robot = build(scene)
    configs = solve_grasp_configurations(robot)
    def free(margin_m: float) -> CollisionChecker:
        return CollisionChecker(robot, CollisionPolicy(margin_m=margin_m))

    out = []
    for name, make, a, b in (("home->pregrasp", free, robot.home_q, configs.pregrasp.q),
                             ("pregrasp->preplace", lambda mg: configs.carrying_checker(robot, mg),
                              configs.pregrasp.q, configs.preplace.q)):
        out.append(Segment(scene_name, name, np.asarray(a, float), np.asarray(b, float), robot.arm_lower,
                           robot.arm_upper, make(0.01), make(0.0)))
    return out


def run_pickplace(seg: Segment, seed: int, budget: float) -> Outcome:
    """Our planner (tree search + shortcutting) on one seeded query."""
    seg.checker.checks = 0
    t0 = time.perf_counter()
    try:
        r = planning.plan(seg.checker, seg.start, seg.goal, seg.lower, seg.upper,
                          planning.PlannerConfig(seed=seed, time_budget_s=budget))
    except PlanningFailed:
        spent = time.perf_counter() - t0
        return Outcome(None, None, spent, spent, 0.0, seg.checker.checks)
    spent = time.perf_counter() - t0
    return Outcome(np.asarray(r.path_raw), np.asarray(r.path), spent, r.plan_time_s, r.shortcut_time_s,
                   seg.checker.checks)


def run_ompl(ompl: dict[str, ModuleType], seg: Segment, seed: int, budget: float, planner: str,
             range_rad: float | None) -> Outcome:
    """OMPL RRTConnect or RRT* plus PathSimplifier on one seeded query (only exact solutions count)."""
    ob, og, ou = ompl["base"], ompl["geometric"], ompl["util"]
    ou.setLogLevel(ou.LOG_NONE)  # re-seeding after the first query logs an error, but it does reseed
    ou.RNG.setSeed(seed + 1)
    ou.setLogLevel(ou.LOG_WARN)  # OMPL writes info messages to stdout
    space = ob.RealVectorStateSpace(6)
    bounds = ob.RealVectorBounds(6)
    for j in range(6):
        bounds.setLow(j, float(seg.lower[j]))
        bounds.setHigh(j, float(seg.upper[j]))
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    is_valid = seg.checker.is_valid
    si.setStateValidityChecker(lambda s: is_valid(np.array([s[0], s[1], s[2], s[3], s[4], s[5]])))
    si.setStateValidityCheckingResolution(EDGE_RES_RAD / space.getMaximumExtent())
    si.setup()
    start, goal = space.allocState(), space.allocState()
    for j in range(6):
        start[j], goal[j] = float(seg.start[j]), float(seg.goal[j])
    pdef = ob.ProblemDefinition(si)
    pdef.setStartAndGoalStates(start, goal)
    pdef.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    algo = og.RRTConnect(si) if planner == "ompl-rrtconnect" else og.RRTstar(si)
    if range_rad:
        algo.setRange(range_rad)
    algo.setProblemDefinition(pdef)
    seg.checker.checks = 0
    t0 = time.perf_counter()
    algo.setup()
    algo.solve(budget)
    solve_s = time.perf_counter() - t0
    if not pdef.hasExactSolution():
        return Outcome(None, None, solve_s, solve_s, 0.0, seg.checker.checks)
    path = pdef.getSolutionPath()
    raw = _states(path)
    simplifier = og.PathSimplifier(si)
    t1 = time.perf_counter()
    for step in (simplifier.partialShortcutPath, simplifier.reduceVertices):
        for _ in range(OMPL_SIMPLIFY_ROUNDS):
            if not step(path):
                break
    simplify_s = time.perf_counter() - t1
    return Outcome(raw, _states(path), solve_s + simplify_s, solve_s, simplify_s, seg.checker.checks)


def _states(path: Any) -> np.ndarray:
    """The states of an OMPL PathGeometric as an array (K, 6) (rad)."""
    return np.array([[s[j] for j in range(6)] for s in path.getStates()])


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def measure(seg: Segment, planner: str, seeds: range, run: Callable[[int], Outcome]) -> dict[str, Any]:
    """Run every seed, retime and densely re-check each final path, and summarize into one row."""
    outs = [run(seed) for seed in seeds]
    ok = [o for o in outs if o.path is not None]
    toppra_s, duration_s, dense = [], [], []
    for o in ok:
        dense.append(planning.path_valid(seg.dense_checker, o.path, EDGE_RES_RAD))
        try:
            traj = retime(o.path, TimingConfig.ur5e())
        except (TimingFailed, ConfigError) as exc:
            print(f"warning: {seg.scene} {seg.name} {planner}: retime failed: {exc}", file=sys.stderr)
            continue
        toppra_s.append(traj.retime_time_s)
        duration_s.append(traj.duration_s)
    times = [o.time_s for o in outs]
    return {
        "scene": seg.scene, "segment": seg.name, "planner": planner,
        "success_rate": len(ok) / len(outs),
        "time_median_s": _median(times), "time_p95_s": float(np.percentile(times, 95)),
        "solve_time_median_s": _median([o.solve_s for o in outs]),
        "simplify_time_median_s": _median([o.simplify_s for o in ok]),
        "cost_raw_rad": _median([planning.path_cost(o.path_raw) for o in ok]),
        "cost_shortcut_rad": _median([planning.path_cost(o.path) for o in ok]),
        "waypoints": _median([len(o.path) for o in ok]),
        "waypoints_raw": _median([len(o.path_raw) for o in ok]),
        "checks_median": _median([o.checks for o in outs]),
        "toppra_time_median_s": _median(toppra_s),
        "trajectory_duration_median_s": _median(duration_s),
        "dense_valid_rate": float(np.mean(dense)) if dense else None,
    }


def check_cost(seg: Segment, home: np.ndarray) -> dict[str, Any]:
    """Median µs of one ``is_valid`` and µs per configuration of ``are_valid``, on configurations near home."""
    qs = home + np.random.default_rng(0).uniform(-CHECK_SPREAD_RAD, CHECK_SPREAD_RAD, (CHECK_CONFIGS, home.size))
    single = np.empty(len(qs))
    for i, q in enumerate(qs):
        t = time.perf_counter()
        seg.checker.is_valid(q)
        single[i] = time.perf_counter() - t
    t = time.perf_counter()
    valid = seg.checker.are_valid(qs)
    batch = time.perf_counter() - t
    return {"scene": seg.scene, "segment": seg.name, "check_us_single": 1e6 * float(np.median(single)),
            "check_us_batch": 1e6 * batch / len(qs), "valid_fraction": float(valid.mean())}


def load_ompl(wanted: bool) -> dict[str, ModuleType] | None:
    """The OMPL modules, or None if not wanted or not installed (then say so on stderr)."""
    if not wanted:
        return None
    try:
        from ompl import base, geometric, util
    except ImportError:
        print("OMPL not installed: pip install -e '.[bench]'", file=sys.stderr)
        return None
    return {"base": base, "geometric": geometric, "util": util}


def _version(package: str) -> str:
    try:
        return version(package)
    except PackageNotFoundError:
        return "unknown"


def _fmt(value: Any, spec: str) -> str:
    return "—" if value is None else format(value, spec)


def print_table(result: dict[str, Any]) -> None:
    """Render the rows as a rich table, then the collision-check cost on one line."""
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(Console().width, 200))
    machine = result["machine"]
    table = Table(title=f"Planning benchmark: {result['queries']} queries, budget {result['budget_s']:g} s, "
                        f"{machine['platform']}, {machine['cpu_count']} CPUs", title_justify="left")
    columns = [("scene", "scene", "s"), ("segment", "segment", "s"), ("planner", "planner", "s"),
               ("success_rate", "ok", ".2f"), ("time_median_s", "t med s", ".4f"), ("time_p95_s", "t p95 s", ".4f"),
               ("solve_time_median_s", "solve s", ".4f"), ("simplify_time_median_s", "simpl s", ".4f"),
               ("cost_raw_rad", "cost raw", ".3f"), ("cost_shortcut_rad", "cost", ".3f"),
               ("cost_ratio_vs_ompl_rrtstar", "÷ompl*", ".2f"), ("waypoints_raw", "wp raw", ".1f"),
               ("waypoints", "wp", ".1f"), ("checks_median", "checks", ".0f"),
               ("toppra_time_median_s", "toppra s", ".4f"), ("trajectory_duration_median_s", "dur s", ".3f"),
               ("dense_valid_rate", "dense ok", ".2f")]
    for _, header, spec in columns:
        table.add_column(header, justify="left" if spec == "s" else "right", no_wrap=True)
    for row in result["rows"]:
        table.add_row(*(_fmt(row.get(key), spec) for key, _, spec in columns))
    console.print(table)
    checks = "; ".join(f"{c['scene']} {c['segment']}: {c['check_us_single']:.1f} µs single, "
                       f"{c['check_us_batch']:.1f} µs/config batch" for c in result["collision_check"]["by_checker"])
    console.print(f"Collision check cost ({CHECK_CONFIGS} configurations within ±{CHECK_SPREAD_RAD} rad of home): "
                  f"{checks}")


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a rich table, or one JSON object with ``--json``. Returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=20, help="seeded queries per row (seeds 0..N-1)")
    parser.add_argument("--budget", type=float, default=1.0, help="planning time budget per query (s)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    parser.add_argument("--no-ompl", action="store_true", help="skip the OMPL planners")
    parser.add_argument("--quick", action="store_true", help="smoke test: 3 queries, 0.2 s budget")
    parser.add_argument("--ompl-range", type=float, default=None,
                        help="OMPL planners' range (rad, L2); default: OMPL's 0.2 x max extent")
    args = parser.parse_args(argv)
    queries, budget = (3, 0.2) if args.quick else (args.queries, args.budget)
    if queries < 1 or budget <= 0:
        parser.error("--queries must be >= 1 and --budget > 0")
    ompl = load_ompl(not args.no_ompl)
    segs = [seg for name, scene in (("default", SceneConfig()), ("obstacle", SceneConfig(obstacle=True)))
            for seg in segments(name, scene)]
    home = segs[0].start
    by_checker = [check_cost(seg, home) for seg in segs]
    rows: list[dict[str, Any]] = []
    for seg in segs:
        runners: dict[str, Callable[[int], Outcome]] = {
            "pickplace-rrtstar": lambda seed, seg=seg: run_pickplace(seg, seed, budget)}
        if ompl is not None:
            for name in ("ompl-rrtconnect", "ompl-rrtstar"):
                runners[name] = lambda seed, seg=seg, name=name: run_ompl(ompl, seg, seed, budget, name,
                                                                          args.ompl_range)
        for planner, run in runners.items():
            rows.append(measure(seg, planner, range(queries), run))
            print(f"done: {seg.scene} {seg.name} {planner}", file=sys.stderr)
    for row in rows:
        if row["planner"] == "pickplace-rrtstar":
            ref = next((r for r in rows if r["planner"] == "ompl-rrtstar" and r["scene"] == row["scene"]
                        and r["segment"] == row["segment"]), None)
            ours, theirs = row["cost_shortcut_rad"], ref and ref["cost_shortcut_rad"]
            row["cost_ratio_vs_ompl_rrtstar"] = ours / theirs if ours is not None and theirs else None
    result = {
        "rows": rows,
        "collision_check": {"configs": CHECK_CONFIGS, "spread_rad": CHECK_SPREAD_RAD,
                            "check_us_single": by_checker[0]["check_us_single"],
                            "check_us_batch": by_checker[0]["check_us_batch"], "by_checker": by_checker},
        "budget_s": budget,
        "queries": queries,
        "machine": machine_info(),
        "ompl": None if ompl is None else {"version": _version("ompl"), "range_rad": args.ompl_range or "default",
                                           "edge_resolution_l2_rad": EDGE_RES_RAD},
    }
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
