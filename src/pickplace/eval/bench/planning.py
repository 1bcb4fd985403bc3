"""Planning benchmark: pickplace's planner against OMPL's RRTConnect and RRT*, on the pick-and-place segments and
on harder problems.

Scenes (``--scenes``, default all):

* ``default``, ``obstacle``: the pick-and-place segments of the default scene and of the obstacle scene (a wall
  between start and goal): ``home->pregrasp`` (gripper open, object resting) and ``pregrasp->preplace`` (object
  carried), checker margin 1 cm.
* ``shelf``, ``cage``, ``bins``, ``slot``: harder problems for this UR5e in the manner of public motion-planning
  benchmarks (:mod:`~pickplace.eval.bench.planning_problems`): scenes of fixed boxes, ends solved by IK, the hand
  free, checker margin 1 cm.

Every planner solves each segment once per seed with the same :class:`CollisionChecker` and the same time budget.
Each final path is then retimed with TOPP-RA (``TimingConfig.ur5e()``) and re-checked every 0.01 rad at margin 0.

Where each planner samples (each row's ``sampling``, with the bounds in ``sampling_lower_rad`` and
``sampling_upper_rad``, (6,) rad):

* ``pickplace``: ``"box ±1 rad around start/goal"``, the box spanned by start and goal, widened by
  ``PlannerConfig.box_margin_rad`` (1 rad) on every joint and clipped to the joint bounds
  (``PlannerConfig.sample_in_box``). It only samples when the straight segment is blocked: of the default and
  obstacle segments, only the obstacle scene's ``pregrasp->preplace`` is (the others are solved by their direct
  edge); every harder problem is.
* ``ompl-rrtconnect``, ``ompl-rrtstar``: ``"full joint bounds"`` (±2π, ±π for the elbow), OMPL's usual setup.
* ``ompl-rrtconnect-box``, ``ompl-rrtstar-box``: the same two OMPL planners with the state space bounds set
  to exactly pickplace's box for that segment (:func:`sampling_box`, the same expression as the planner's),
  so the sampling region is like for like. Start, goal, checker, budget, seeds, edge resolution and
  simplification are those of the full-bounds rows. OMPL derives its default range from the space's
  extent, so the box rows extend by a shorter step than the full-bounds rows unless ``--ompl-range`` is
  given; every row reports the step it used in ``range_rad`` (L2; pickplace: ``step_size_rad``).

How the planners are set up (read the numbers with this in mind):

* ``pickplace``: ``planning.plan(PlannerConfig(seed, time_budget_s=budget, retries=0))``, the planner's defaults:
  it tries the straight segment first, then grows lazy bidirectional RRT-Connect trees in the box above (only
  their nodes checked), pulls the path where they meet taut (checking the segments it keeps), then shortcuts.
  Edges are checked every 0.01 rad per joint (max-norm, ``edge_resolution_rad``).
* OMPL: ``RealVectorStateSpace(6)`` with the row's bounds, validity = our ``is_valid`` through a Python
  callback, edges checked by OMPL's discrete motion validator every 0.01 rad of **L2** distance
  (``setStateValidityCheckingResolution(0.01 / max extent)`` of that space): every joint then moves at most
  0.01 rad between checks, as in our planner, but diagonal edges get up to √6 times more checks than ours.
  The range (max extension) is OMPL's default, 0.2 × the space's max extent, unless ``--ompl-range`` is
  given. RRTConnect stops at its first solution; RRT* (path-length objective) uses the whole budget. Both
  paths are simplified with ``partialShortcutPath`` (random shortcuts between points on the path, like
  ours), repeated while it improves (at most 5 rounds), then ``reduceVertices`` likewise; no B-spline
  smoothing, which would multiply the waypoints. OMPL's RNG is seeded with ``seed + 1`` (it rejects 0)
  before each query.
* The queries of a segment run seed by seed, every planner in turn (not one planner's 20 queries, then the
  next's), so that a slow spell of a shared machine hits every planner alike and the ratios hold. The planners
  that stop at their first solution (pickplace and the two RRTConnect rows) take turns among themselves, the
  first of them rotating from seed to seed; the RRT* rows, which spend their whole budget, run after them, seed by
  seed as well. A planner run right after a 1 s RRT* query finds the processor's caches filled with RRT*'s tree:
  in the earlier fixed order (pickplace first after the previous seed's two RRT* rows) that made pickplace's
  obstacle transfer 1.5 times as slow as the same query run again right after (4.8 against 3.2 ms).
* Total and solve times and checks are over all queries (a failure costs what it spent); simplification
  time, costs, waypoints, TOPP-RA numbers and ``dense_valid_rate`` are over the successful queries.
* Ratios, measured in the same run and carried by the ``pickplace`` rows:
  ``time_ratio_vs_ompl_rrtconnect[_box]`` (pickplace's median time ÷ OMPL RRTConnect's, full bounds or box)
  and ``cost_ratio_vs_ompl_rrtstar[_box]`` (pickplace's median cost after shortcutting ÷ OMPL RRT*'s after
  simplification; None when that RRT* solved no query).

Usage: ``python benchmarks/planning.py [--json] [--queries N] [--budget S] [--no-ompl] [--quick]
[--scenes a,b] [--ompl-range R]``.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass, replace
from importlib.metadata import PackageNotFoundError, version
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from pickplace.errors import ConfigError, PlanningFailed, TimingFailed
from pickplace.eval.bench import machine_info, planning_problems
from pickplace.grasping.configurations import solve_grasp_configurations
from pickplace.motion import planning
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot.model import build
from pickplace.world.config import SceneConfig

if TYPE_CHECKING:
    from rich.console import Console

logger = logging.getLogger(__name__)

#: The planner's defaults, except no retry (a retry would spend more than the budget the others get); each query
#: replaces seed and budget.
PICKPLACE_CONFIG = planning.PlannerConfig(retries=0)
EDGE_RES_RAD = PICKPLACE_CONFIG.edge_resolution_rad  # 0.01 rad, also the dense re-check spacing
CHECK_CONFIGS, CHECK_SPREAD_RAD = 2000, 0.5  # collision-cost sample: home + U(-0.5, 0.5) rad per joint
OMPL_SIMPLIFY_ROUNDS = 5
SAMPLING_FULL = "full joint bounds"
SAMPLING_BOX = f"box ±{PICKPLACE_CONFIG.box_margin_rad:g} rad around start/goal"
#: The scenes, in order: the pick-and-place segments of the default and obstacle scenes, then the harder problems.
SCENES = ("default", "obstacle", *(p.name for p in planning_problems.problems()))


@dataclass(frozen=True)
class PlannerSpec:
    """One benchmarked planner: its row name, algorithm and sampling region.

    Attributes:
        name: Row label, e.g. ``"ompl-rrtstar-box"``.
        algorithm: ``"pickplace"``, ``"rrtconnect"`` or ``"rrtstar"``.
        box: Sample in pickplace's box around start and goal (:func:`sampling_box`) instead of the full
            joint bounds. pickplace's own planner always does (``PlannerConfig.sample_in_box``).
    """

    name: str
    algorithm: str
    box: bool

    @property
    def sampling(self) -> str:
        """The sampling region in words, as written in the row."""
        return SAMPLING_BOX if self.box else SAMPLING_FULL


PICKPLACE = PlannerSpec("pickplace", "pickplace", PICKPLACE_CONFIG.sample_in_box)
OMPL_PLANNERS = (PlannerSpec("ompl-rrtconnect", "rrtconnect", False),
                 PlannerSpec("ompl-rrtconnect-box", "rrtconnect", True),
                 PlannerSpec("ompl-rrtstar", "rrtstar", False),
                 PlannerSpec("ompl-rrtstar-box", "rrtstar", True))
RATIOS = (  # (key in pickplace's row, measure compared, reference planner): pickplace's value ÷ the reference's
    ("time_ratio_vs_ompl_rrtconnect", "time_median_s", "ompl-rrtconnect"),
    ("time_ratio_vs_ompl_rrtconnect_box", "time_median_s", "ompl-rrtconnect-box"),
    ("cost_ratio_vs_ompl_rrtstar", "cost_shortcut_rad", "ompl-rrtstar"),
    ("cost_ratio_vs_ompl_rrtstar_box", "cost_shortcut_rad", "ompl-rrtstar-box"),
)


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
    """One query: raw and final paths (K, 6) (None on failure), times (s), collision checks, and the planner's
    extension step ``range_rad`` (L2, rad)."""

    path_raw: np.ndarray | None
    path: np.ndarray | None
    time_s: float
    solve_s: float
    simplify_s: float
    checks: int
    range_rad: float


def sampling_box(start: np.ndarray, goal: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 config: planning.PlannerConfig = PICKPLACE_CONFIG) -> tuple[np.ndarray, np.ndarray]:
    """The box pickplace's RRT* samples in between start (n,) and goal (n,) within [lower, upper] (n,) (rad).

    The planner's own region (:func:`pickplace.motion.planning.sampling_bounds`): the start-goal box widened by
    ``config.box_margin_rad`` on every joint and clipped to the joint bounds; the joint bounds themselves if
    ``config.sample_in_box`` is off. Widening and clipping never move a bound past an end that lies within
    the joint bounds (``x - m <= x`` holds in floating point too), so start and goal are inside the box;
    that is checked.

    Returns:
        (lower (n,), upper (n,)) of the box (rad), new float arrays.

    Raises:
        ConfigError: start or goal outside the box, i.e. outside the joint bounds.
    """
    start, goal, lower, upper = (np.array(a, dtype=float) for a in (start, goal, lower, upper))
    lo, hi = (np.array(a, dtype=float) for a in planning.sampling_bounds(start, goal, lower, upper, config))
    for end, q in (("start", start), ("goal", goal)):
        if np.any(q < lo) or np.any(q > hi):
            raise ConfigError(f"bench.{end}", q.tolist(), f"must lie within the sampling box {lo.tolist()} .. "
                                                          f"{hi.tolist()} rad (within the joint bounds)")
    return lo, hi


def planner_bounds(seg: Segment, planner: PlannerSpec) -> tuple[np.ndarray, np.ndarray]:
    """Where a planner samples on a segment: (lower (6,), upper (6,)) (rad), pickplace's box or the joint bounds."""
    if planner.box:
        return sampling_box(seg.start, seg.goal, seg.lower, seg.upper)
    return seg.lower.copy(), seg.upper.copy()


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


def problem_segments(names: Collection[str] | None = None) -> list[Segment]:
    """The harder problems (:mod:`~pickplace.eval.bench.planning_problems`) as segments, the free hand's checkers
    (margin 1 cm, and 0 for the dense re-check); only those named in ``names`` if given."""
    out = []
    for problem in planning_problems.problems():
        if names is not None and problem.name not in names:
            continue
        robot = build(problem.scene)
        checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.01))
        start, goal = planning_problems.solve_ends(robot, problem, checker)
        out.append(Segment(problem.name, problem.segment, start, goal, robot.arm_lower, robot.arm_upper, checker,
                           CollisionChecker(robot, CollisionPolicy(margin_m=0.0))))
    return out


def run_pickplace(seg: Segment, seed: int, budget: float) -> Outcome:
    """Our planner (tree search + shortcutting) on one seeded query."""
    cfg = replace(PICKPLACE_CONFIG, seed=seed, time_budget_s=budget)
    seg.checker.checks = 0
    t0 = time.perf_counter()
    try:
        r = planning.plan(seg.checker, seg.start, seg.goal, seg.lower, seg.upper, cfg)
    except PlanningFailed:
        spent = time.perf_counter() - t0
        return Outcome(None, None, spent, spent, 0.0, seg.checker.checks, cfg.step_size_rad)
    spent = time.perf_counter() - t0
    return Outcome(np.asarray(r.path_raw), np.asarray(r.path), spent, r.plan_time_s, r.shortcut_time_s,
                   seg.checker.checks, cfg.step_size_rad)


def ompl_space(ompl: dict[str, ModuleType], lower: np.ndarray, upper: np.ndarray) -> Any:
    """An OMPL ``RealVectorStateSpace`` with exactly the bounds lower (n,), upper (n,) (rad).

    Raises:
        ConfigError: the space does not report back exactly these bounds.
    """
    ob = ompl["base"]
    n = len(lower)
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for j in range(n):
        bounds.setLow(j, float(lower[j]))
        bounds.setHigh(j, float(upper[j]))
    space.setBounds(bounds)
    got = space.getBounds()
    if list(got.low) != [float(v) for v in lower] or list(got.high) != [float(v) for v in upper]:
        raise ConfigError("bench.ompl_bounds", (list(got.low), list(got.high)),
                          f"must equal the requested bounds {list(lower)} .. {list(upper)}")
    return space


def run_ompl(ompl: dict[str, ModuleType], seg: Segment, seed: int, budget: float, algorithm: str,
             bounds: tuple[np.ndarray, np.ndarray], range_rad: float | None) -> Outcome:
    """OMPL RRTConnect or RRT* plus PathSimplifier on one seeded query (only exact solutions count).

    Args:
        ompl: The modules from :func:`load_ompl`.
        seg: The segment (start, goal, checker).
        seed: Query seed; OMPL's RNG gets ``seed + 1``.
        budget: Solve time budget (s).
        algorithm: ``"rrtconnect"`` or ``"rrtstar"``.
        bounds: (lower (6,), upper (6,)) of the state space (rad): the joint bounds or pickplace's box.
        range_rad: The planner's range (L2, rad); None for OMPL's default (0.2 × the space's max extent).

    Raises:
        ConfigError: start or goal outside the state space bounds (OMPL would skip it silently).
    """
    ob, og, ou = ompl["base"], ompl["geometric"], ompl["util"]
    ou.setLogLevel(ou.LOG_NONE)  # re-seeding after the first query logs an error, but it does reseed
    ou.RNG.setSeed(seed + 1)
    ou.setLogLevel(ou.LOG_WARN)  # OMPL writes info messages to stdout
    space = ompl_space(ompl, *bounds)
    si = ob.SpaceInformation(space)
    is_valid = seg.checker.is_valid
    si.setStateValidityChecker(lambda s: is_valid(np.array([s[0], s[1], s[2], s[3], s[4], s[5]])))
    si.setStateValidityCheckingResolution(EDGE_RES_RAD / space.getMaximumExtent())
    si.setup()
    start, goal = space.allocState(), space.allocState()
    for j in range(6):
        start[j], goal[j] = float(seg.start[j]), float(seg.goal[j])
    for end, state, q in (("start", start, seg.start), ("goal", goal, seg.goal)):
        if not space.satisfiesBounds(state):
            raise ConfigError(f"bench.{end}", q.tolist(), f"must lie within OMPL's state space bounds {bounds}")
    pdef = ob.ProblemDefinition(si)
    pdef.setStartAndGoalStates(start, goal)
    pdef.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    algo = og.RRTConnect(si) if algorithm == "rrtconnect" else og.RRTstar(si)
    if range_rad:
        algo.setRange(range_rad)
    algo.setProblemDefinition(pdef)
    seg.checker.checks = 0
    t0 = time.perf_counter()
    algo.setup()
    algo.solve(budget)
    solve_s = time.perf_counter() - t0
    used_range = float(algo.getRange())
    if not pdef.hasExactSolution():
        return Outcome(None, None, solve_s, solve_s, 0.0, seg.checker.checks, used_range)
    path = pdef.getSolutionPath()
    raw = _states(path)
    simplifier = og.PathSimplifier(si)
    t1 = time.perf_counter()
    for step in (simplifier.partialShortcutPath, simplifier.reduceVertices):
        for _ in range(OMPL_SIMPLIFY_ROUNDS):
            if not step(path):
                break
    simplify_s = time.perf_counter() - t1
    return Outcome(raw, _states(path), solve_s + simplify_s, solve_s, simplify_s, seg.checker.checks, used_range)


def _states(path: Any) -> np.ndarray:
    """The states of an OMPL PathGeometric as an array (K, 6) (rad)."""
    return np.array([[s[j] for j in range(6)] for s in path.getStates()])


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def measure(seg: Segment, planner: PlannerSpec, bounds: tuple[np.ndarray, np.ndarray],
            outs: list[Outcome]) -> dict[str, Any]:
    """Retime and densely re-check each final path of a planner's queries, and summarize them into one row.

    Args:
        seg: The segment.
        planner: The planner the row is about (name and sampling region).
        bounds: (lower (6,), upper (6,)) (rad) of the region the planner samples in, reported in the row.
        outs: The outcome of each seeded query.
    """
    ok = [o for o in outs if o.path is not None]
    toppra_s, duration_s, dense = [], [], []
    for o in ok:
        dense.append(planning.path_valid(seg.dense_checker, o.path, EDGE_RES_RAD))
        try:
            traj = retime(o.path, TimingConfig.ur5e())
        except (TimingFailed, ConfigError) as exc:
            logger.warning("%s %s %s: retime failed: %s", seg.scene, seg.name, planner.name, exc)
            continue
        toppra_s.append(traj.retime_time_s)
        duration_s.append(traj.duration_s)
    times = [o.time_s for o in outs]
    ranges = sorted({o.range_rad for o in outs})
    return {
        "scene": seg.scene, "segment": seg.name, "planner": planner.name,
        "sampling": planner.sampling,
        "sampling_lower_rad": [float(v) for v in bounds[0]], "sampling_upper_rad": [float(v) for v in bounds[1]],
        "range_rad": ranges[0] if len(ranges) == 1 else ranges,
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


def add_ratios(rows: list[dict[str, Any]]) -> None:
    """Give each ``pickplace-rrtstar`` row its ratios to the OMPL rows of the same segment (:data:`RATIOS`).

    A ratio is None when the reference row is missing (``--no-ompl``) or has no value (solved nothing).
    """
    for row in rows:
        if row["planner"] != PICKPLACE.name:
            continue
        for key, measured, reference in RATIOS:
            ref = next((r for r in rows if r["planner"] == reference and r["scene"] == row["scene"]
                        and r["segment"] == row["segment"]), None)
            ours, theirs = row[measured], ref and ref[measured]
            row[key] = ours / theirs if ours is not None and theirs else None


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


def query_groups(runners: list[tuple[PlannerSpec, Callable[[int], Outcome]]]
                 ) -> list[list[tuple[PlannerSpec, Callable[[int], Outcome]]]]:
    """The planners in the order their queries run: those that stop at their first solution, then the anytime ones
    (RRT*, which spend their whole budget); empty groups left out."""
    first = [r for r in runners if r[0].algorithm != "rrtstar"]
    anytime = [r for r in runners if r[0].algorithm == "rrtstar"]
    return [g for g in (first, anytime) if g]


def rotated(group: list[Any], seed: int) -> list[Any]:
    """The group's planners in turn for one seed, starting from the ``seed``-th (mod its size), so that no planner
    always runs first, right after the previous seed's last."""
    k = seed % len(group)
    return group[k:] + group[:k]


def load_ompl(wanted: bool) -> dict[str, ModuleType] | None:
    """The OMPL modules, or None if not wanted or not installed (then a warning is logged)."""
    if not wanted:
        return None
    try:
        from ompl import base, geometric, util
    except ImportError:
        logger.warning("OMPL not installed, its rows are skipped: pip install -e '.[bench]'")
        return None
    return {"base": base, "geometric": geometric, "util": util}


def _version(package: str) -> str:
    try:
        return version(package)
    except PackageNotFoundError:
        return "unknown"


def _fmt(value: Any, spec: str) -> str:
    if isinstance(value, list):  # several values where one was expected (e.g. range_rad)
        return "/".join(format(v, spec) for v in value)
    return "—" if value is None else format(value, spec)


def print_ratios(console: Console, rows: list[dict[str, Any]]) -> None:
    """Render pickplace's ratios to the OMPL rows of the same segment (:data:`RATIOS`) as a rich table."""
    from rich.table import Table

    ratios = Table(title="pickplace ÷ OMPL in the same run: median time ÷ RRTConnect's, cost after shortcutting "
                         "÷ RRT*'s", title_justify="left")
    for header in ("scene", "segment", "t ÷ rrtconnect", "t ÷ rrtconnect-box", "cost ÷ rrtstar",
                   "cost ÷ rrtstar-box"):
        ratios.add_column(header, justify="left" if header in ("scene", "segment") else "right", no_wrap=True)
    for row in rows:
        if row["planner"] == PICKPLACE.name:
            ratios.add_row(row["scene"], row["segment"], *(_fmt(row.get(key), ".2f") for key, _, _ in RATIOS))
    console.print(ratios)


def print_table(result: dict[str, Any]) -> None:
    """Render the rows as a rich table, pickplace's ratios to OMPL as a second one, then the check cost."""
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(Console().width, 220))
    machine = result["machine"]
    table = Table(title=f"Planning benchmark: {result['queries']} queries, budget {result['budget_s']:g} s, "
                        f"{machine['platform']}, {machine['cpu_count']} CPUs, 1-min load "
                        f"{machine['load_average_1min']:.2f}", title_justify="left")
    columns = [("scene", "scene", "s"), ("segment", "segment", "s"), ("planner", "planner", "s"),
               ("sampling", "sampling", "s"), ("range_rad", "range", ".2f"),
               ("success_rate", "ok", ".2f"), ("time_median_s", "t med s", ".4f"), ("time_p95_s", "t p95 s", ".4f"),
               ("solve_time_median_s", "solve s", ".4f"), ("simplify_time_median_s", "simpl s", ".4f"),
               ("cost_raw_rad", "cost raw", ".3f"), ("cost_shortcut_rad", "cost", ".3f"),
               ("waypoints_raw", "wp raw", ".1f"), ("waypoints", "wp", ".1f"), ("checks_median", "checks", ".0f"),
               ("toppra_time_median_s", "toppra s", ".4f"), ("trajectory_duration_median_s", "dur s", ".3f"),
               ("dense_valid_rate", "dense ok", ".2f")]
    for _, header, spec in columns:
        table.add_column(header, justify="left" if spec == "s" else "right", no_wrap=True)
    for row in result["rows"]:
        table.add_row(*(_fmt(row.get(key), spec) for key, _, spec in columns))
    console.print(table)
    if result["ompl"] is not None:
        print_ratios(console, result["rows"])
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
    parser.add_argument("--scenes", default=",".join(SCENES),
                        help=f"comma-separated scenes to run (default: all of {', '.join(SCENES)})")
    parser.add_argument("--ompl-range", type=float, default=None,
                        help="OMPL planners' range (rad, L2), full-bounds and box rows alike; "
                             "default: OMPL's 0.2 x max extent of each row's state space")
    args = parser.parse_args(argv)
    queries, budget = (3, 0.2) if args.quick else (args.queries, args.budget)
    if queries < 1 or budget <= 0:
        parser.error("--queries must be >= 1 and --budget > 0")
    if args.ompl_range is not None and args.ompl_range <= 0:
        parser.error("--ompl-range must be > 0")
    wanted = [name.strip() for name in args.scenes.split(",") if name.strip()]
    unknown = sorted(set(wanted) - set(SCENES))
    if unknown or not wanted:
        parser.error(f"--scenes: unknown {', '.join(unknown) or '(none given)'}; choose from {', '.join(SCENES)}")
    ompl = load_ompl(not args.no_ompl)
    segs = [seg for name, scene in (("default", SceneConfig()), ("obstacle", SceneConfig(obstacle=True)))
            if name in wanted for seg in segments(name, scene)]
    segs += problem_segments(wanted)
    home = build(SceneConfig()).home_q
    by_checker = [check_cost(seg, home) for seg in segs]
    rows: list[dict[str, Any]] = []
    for seg in segs:
        runners: list[tuple[PlannerSpec, Callable[[int], Outcome]]] = [
            (PICKPLACE, lambda seed, seg=seg: run_pickplace(seg, seed, budget))]
        if ompl is not None:
            runners += [(spec, lambda seed, seg=seg, spec=spec: run_ompl(
                ompl, seg, seed, budget, spec.algorithm, planner_bounds(seg, spec), args.ompl_range))
                        for spec in OMPL_PLANNERS]
        # seed by seed, every planner in turn: a slow spell of this shared machine hits them all alike. The planners
        # that stop at their first solution take turns, the first rotating; the anytime RRT* rows come after.
        outs: dict[str, list[Outcome]] = {spec.name: [] for spec, _ in runners}
        for group in query_groups(runners):
            for seed in range(queries):
                for spec, run in rotated(group, seed):
                    outs[spec.name].append(run(seed))
        for spec, _ in runners:
            rows.append(measure(seg, spec, planner_bounds(seg, spec), outs[spec.name]))
        print(f"done: {seg.scene} {seg.name}", file=sys.stderr)
    add_ratios(rows)
    result = {
        "rows": rows,
        "segments": [{"scene": seg.scene, "segment": seg.name, "start_rad": seg.start.tolist(),
                      "goal_rad": seg.goal.tolist(), "joint_lower_rad": seg.lower.tolist(),
                      "joint_upper_rad": seg.upper.tolist()} for seg in segs],
        "sampling": {spec.name: spec.sampling for spec in (PICKPLACE, *OMPL_PLANNERS)},
        "pickplace": {"search": PICKPLACE_CONFIG.search, "sample_in_box": PICKPLACE_CONFIG.sample_in_box,
                      "box_margin_rad": PICKPLACE_CONFIG.box_margin_rad,
                      "step_size_rad": PICKPLACE_CONFIG.step_size_rad, "edge_resolution_rad": EDGE_RES_RAD},
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
