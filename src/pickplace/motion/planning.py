"""Joint-space motion planning: RRT* with shortcut smoothing, against an abstract validity checker.

The planner only sees a :class:`ValidityChecker` (the MuJoCo collision checker satisfies it), joint
bounds and two configurations. Distances and costs are joint-space L2 norms (rad); edge collision
checks interpolate so that consecutive checked configurations are at most ``edge_resolution_rad``
apart in max-norm (per joint). The tree lives in preallocated numpy arrays; nearest/near queries are
vectorised; edge checks go through the checker's batch call.

Determinism: a ``numpy.random.Generator`` seeded with ``PlannerConfig.seed`` is the only randomness,
drawn in fixed-size chunks, so equal inputs give bit-identical results whenever the search is ended
by the iteration limit or by the first solution, not by the wall-clock ``time_budget_s``.
"""

from __future__ import annotations

import enum
import functools
import logging
import math
import time
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from pickplace.errors import ConfigError, PlanningFailed, SearchExhausted
from pickplace.world.config import check_int, check_range

logger = logging.getLogger(__name__)

_CHUNK = 256  # random numbers are drawn in chunks of this many iterations, independent of `iterations`
_EPS = 1e-12


class ValidityChecker(Protocol):
    """What the planner needs from a collision checker."""

    def is_valid(self, q: np.ndarray) -> bool:
        """Whether one configuration q (n,) (rad) is collision-free."""
        ...

    def are_valid(self, qs: np.ndarray) -> np.ndarray:
        """Validity (M,) bool of a batch of configurations qs (M, n) (rad)."""
        ...

    def all_valid(self, qs: np.ndarray) -> bool:
        """Whether every configuration of qs (M, n) is valid; stops at the first invalid one."""
        ...

    def colliding_pairs(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Names of the colliding geom pairs at q (n,), for error messages."""
        ...


@dataclass(frozen=True)
class PlannerConfig:
    """RRT* and shortcutting parameters. Angles in rad, times in s.

    Attributes:
        iterations: Maximum RRT* iterations (one sample each). 6000 as in the reference design.
        step_size_rad: Maximum extension per RRT step, joint-space **L2** norm (rad).
        goal_bias: Probability of sampling the goal instead of a random configuration.
        rewire_radius_rad: RRT* neighbour radius (L2, rad); an upper cap when ``shrink_radius``.
        shrink_radius: Shrink the radius as ``gamma * (log n / n)^(1/d)`` (gamma from the sampling
            volume, the usual RRT* bound), capped at ``rewire_radius_rad``.
        edge_resolution_rad: Max-norm spacing (rad per joint) of the configurations checked along an
            edge during the search and shortcutting. Coarse is fast; the checker's safety margin covers
            the motion between checks, and the final path is verified at ``verify_resolution_rad``.
        verify_resolution_rad: When edges are checked more coarsely than this, the returned path is
            re-checked at this spacing; if it fails, the search and shortcutting are redone at this
            resolution (so every returned path is checked at least this finely).
        time_budget_s: Wall-clock budget of the tree search (shortcutting not included) (s).
        seed: Seed of the ``numpy.random.Generator``.
        stop_at_first_solution: Return as soon as the goal joins the tree (then rely on shortcutting);
            if False keep sampling and rewiring until iterations or time budget run out (anytime).
        shortcut_iterations: Random shortcut attempts before the greedy waypoint-removal pass.
        shortcut_min_gain_rad: A random shortcut is only checked when it would shorten the path by at
            least this much (rad, L2). Checking a valid shortcut costs as much as its length in collision
            checks, so gains below the edge resolution are not worth their checks.
        sample_in_box: Sample uniformly in the box spanned by start and goal, expanded by
            ``box_margin_rad`` on every joint and clipped to the joint bounds, instead of in the
            full bounds (which may be ±2π wide). A path that must leave this box will not be found.
        box_margin_rad: Margin of the sampling box (rad per joint).
        retries: Searches tried again when one ends without a path (:class:`~pickplace.errors.SearchExhausted`),
            each with the next seed, ``retry_growth`` times the time budget and iterations of the one before and
            twice its box margin. The budget is wall-clock time, so a search on a loaded machine may run out
            where it would succeed on an idle one; a second, larger search costs time only when the first fails.
        retry_growth: Growth of the time budget and iterations per retry.

    The defaults (step 0.4, radius cap 0.8 = 2 steps, box sampling with a 1 rad margin) gave the fewest
    checked configurations on 6-D toy problems; full ±π sampling often exhausts 6000 iterations there.
    """

    iterations: int = 6000
    step_size_rad: float = 0.4
    goal_bias: float = 0.1
    rewire_radius_rad: float = 0.8
    shrink_radius: bool = True
    edge_resolution_rad: float = 0.01
    verify_resolution_rad: float = 0.01
    time_budget_s: float = 1.0
    seed: int = 0
    stop_at_first_solution: bool = True
    shortcut_iterations: int = 50
    shortcut_min_gain_rad: float = 0.01
    sample_in_box: bool = True
    box_margin_rad: float = 1.0
    retries: int = 1
    retry_growth: float = 3.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for name, (lo, hi) in _INT_FIELDS.items():
            set_(self, name, check_int(f"planner.{name}", getattr(self, name), lo, hi))
        for name, (lo, hi, lo_open, unit) in _FLOAT_FIELDS.items():
            set_(self, name, check_range(f"planner.{name}", getattr(self, name), lo, hi, lo_open=lo_open,
                                         unit=unit))
        for name in ("shrink_radius", "stop_at_first_solution", "sample_in_box"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"planner.{name}", getattr(self, name), "must be true or false")


_MAX_ITERATIONS = 1_000_000
_INT_FIELDS: dict[str, tuple[int, int | None]] = {
    "iterations": (1, _MAX_ITERATIONS), "seed": (0, None), "shortcut_iterations": (0, 100_000), "retries": (0, 10)}
_FLOAT_FIELDS: dict[str, tuple[float, float, bool, str]] = {  # field: (lo, hi, lo_open, unit)
    "step_size_rad": (0.0, math.pi, True, "rad"),
    "goal_bias": (0.0, 1.0, False, ""),
    "rewire_radius_rad": (0.0, 10.0, True, "rad"),
    "edge_resolution_rad": (1e-4, 0.2, False, "rad"),
    "verify_resolution_rad": (1e-4, 0.1, False, "rad"),
    "time_budget_s": (0.0, 3600.0, True, "s"),
    "box_margin_rad": (0.0, 10.0, False, "rad"),
    "shortcut_min_gain_rad": (0.0, 1.0, False, "rad"),
    "retry_growth": (1.0, 100.0, False, ""),
}


class PlanStatus(enum.Enum):
    """How a path was found."""

    DIRECT = "direct"  # the straight start-goal segment is valid
    SOLVED = "solved"  # RRT* stopped at its first solution
    REFINED = "refined"  # RRT* kept improving until the iteration limit or the time budget


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A planned joint-space path (arrays are read-only).

    Attributes:
        path_raw: Tree path (K, n) from start to goal (rad).
        path: Shortcut path (L, n) from start to goal (rad), L <= K in practice.
        cost_raw_rad: Sum of L2 segment lengths of ``path_raw`` (rad).
        cost_rad: Sum of L2 segment lengths of ``path`` (rad), <= ``cost_raw_rad``.
        iterations: RRT* iterations used (0 for DIRECT).
        nodes: Tree size when the search ended (2 for DIRECT).
        plan_time_s: Time from the call to the end of the tree search (s).
        shortcut_time_s: Time spent shortcutting (s).
        status: How the path was found.
    """

    path_raw: np.ndarray
    path: np.ndarray
    cost_raw_rad: float
    cost_rad: float
    iterations: int
    nodes: int
    plan_time_s: float
    shortcut_time_s: float
    status: PlanStatus


def path_cost(path: np.ndarray) -> float:
    """Sum of the joint-space L2 lengths of the segments of path (K, n) (rad)."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def _densify(qa: np.ndarray, qb: np.ndarray, res: float) -> np.ndarray:
    """Points along segments qa[i] -> qb[i] (m, n), excluding each qa[i] and including each qb[i].

    Segment i gets s_i = max(1, ceil(max|qb[i] - qa[i]| / res)) points qa + (k / s_i)(qb - qa), k = 1..s_i,
    the last one set to qb[i] exactly. Returns (sum s_i, n), segment by segment.
    """
    delta = qb - qa
    steps = np.maximum(1, np.ceil(np.abs(delta).max(axis=1) / res)).astype(np.int64)
    seg = np.repeat(np.arange(steps.size), steps)
    ends = np.cumsum(steps)
    k = np.arange(1, int(ends[-1]) + 1) - np.repeat(ends - steps, steps)
    pts = qa[seg] + (k / steps[seg])[:, None] * delta[seg]
    pts[ends - 1] = qb
    return pts


@functools.lru_cache(maxsize=4096)
def _coarse_to_fine(n: int) -> np.ndarray:
    """Indices 0..n-1 ordered ends first, then by bisection (midpoints of ever finer halvings); read-only."""
    order = [0, n - 1] if n > 1 else [0]
    seen = set(order)
    step = n - 1
    while step > 1:
        for k in range(step // 2, n, step):
            if k not in seen:
                seen.add(k)
                order.append(k)
        step //= 2
    order.extend(k for k in range(n) if k not in seen)
    out = np.array(order)
    out.setflags(write=False)
    return out


def segment_valid(checker: ValidityChecker, qa: np.ndarray, qb: np.ndarray, resolution_rad: float) -> bool:
    """Whether the straight joint-space segment qa (n,) -> qb (n,) is valid, both ends included.

    Checked configurations are at most ``resolution_rad`` apart in max-norm, in coarse-to-fine (bisection)
    order, and the check stops at the first collision, so a blocked segment costs few checks.
    """
    delta = qb - qa
    steps = max(1, math.ceil(float(np.abs(delta).max()) / resolution_rad))
    pts = qa + (np.arange(steps + 1) / steps)[:, None] * delta  # the same points as _densify, plus qa
    pts[-1] = qb
    return bool(checker.all_valid(pts[_coarse_to_fine(len(pts))]))


def path_valid(checker: ValidityChecker, path: np.ndarray, resolution_rad: float) -> bool:
    """Whether every segment of path (K, n) is valid, checked at ``resolution_rad`` max-norm."""
    path = np.asarray(path, dtype=float)
    if len(path) == 1:
        return bool(checker.is_valid(path[0]))
    pts = np.vstack([path[:1], _densify(path[:-1], path[1:], resolution_rad)])
    return bool(checker.all_valid(pts[_coarse_to_fine(len(pts))]))


def _inputs(checker: ValidityChecker, q_start: np.ndarray, q_goal: np.ndarray, lower: np.ndarray,
            upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Copy the inputs to float arrays and validate them; raise PlanningFailed naming what is wrong."""
    arrays = [np.array(a, dtype=float) for a in (q_start, q_goal, lower, upper)]
    n = arrays[2].size
    for name, a in zip(("start", "goal", "lower bounds", "upper bounds"), arrays, strict=True):
        if a.shape != (n,) or not np.isfinite(a).all():
            raise PlanningFailed(f"{name} must be a finite vector of shape ({n},), got {a.tolist()}")
    start, goal, lo, hi = arrays
    if n == 0 or np.any(lo >= hi):
        raise PlanningFailed(f"joint bounds must satisfy lower < upper, got {lo.tolist()} / {hi.tolist()}")
    for end, q in (("start", start), ("goal", goal)):
        out = np.flatnonzero((q < lo) | (q > hi))
        if out.size:
            what = "; ".join(f"joint {j} = {q[j]:.4f} rad not in [{lo[j]:.4f}, {hi[j]:.4f}]" for j in out)
            raise PlanningFailed(f"{end} configuration is outside the joint bounds: {what}")
    for end, q in (("start", start), ("goal", goal)):
        if not checker.is_valid(q):
            names = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(q)) or "no pair reported"
            raise PlanningFailed(f"{end} configuration is in collision: {names}")
    return start, goal, lo, hi


def _shift_subtree(parent: np.ndarray, cost: np.ndarray, n: int, root: int, delta: float) -> None:
    """Add delta to the cost of root and of all its descendants among the first n nodes."""
    cost[root] += delta
    member = np.zeros(n + 1, dtype=bool)  # member[-1] (the root's parent -1) stays False
    frontier = np.array([root])
    while frontier.size:
        member[:] = False
        member[frontier] = True
        frontier = np.flatnonzero(member[parent[:n]])
        cost[frontier] += delta


def sampling_bounds(start: np.ndarray, goal: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    config: PlannerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Where the RRT* samples between ``start`` and ``goal`` (n,) within the joint bounds ``[lower, upper]`` (n,).

    With ``config.sample_in_box``: the box spanned by start and goal, widened by ``config.box_margin_rad`` on
    every joint and clipped to the joint bounds (start and goal within the bounds stay inside it); otherwise the
    joint bounds.

    Returns:
        (lower (n,), upper (n,)) of the sampling region (rad).
    """
    if not config.sample_in_box:
        return np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    lo = np.maximum(lower, np.minimum(start, goal) - config.box_margin_rad)
    hi = np.minimum(upper, np.maximum(start, goal) + config.box_margin_rad)
    return lo, hi


def _search(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            cfg: PlannerConfig, rng: np.random.Generator, t0: float) -> tuple[np.ndarray, int, int]:
    """RRT* from start to goal. Returns (tree path (K, n), iterations used, tree size)."""
    d = start.size
    lo, hi = sampling_bounds(start, goal, lo, hi, cfg)
    span = hi - lo
    unit_ball = math.pi ** (d / 2) / math.gamma(d / 2 + 1)
    gamma = 2.0 * (1.0 + 1.0 / d) ** (1.0 / d) * (float(np.prod(span)) / unit_ball) ** (1.0 / d)
    cap = cfg.iterations + 2
    nodes = np.empty((cap, d))
    parent = np.full(cap, -1, dtype=np.int64)
    cost = np.zeros(cap)
    nodes[0] = start
    n, goal_idx, used, res, step = 1, -1, 0, cfg.edge_resolution_rad, cfg.step_size_rad
    samples, goal_draws = np.empty((0, d)), np.empty(0)
    for it in range(cfg.iterations):
        k = it % _CHUNK
        if k == 0:
            samples = lo + span * rng.random((_CHUNK, d))
            goal_draws = rng.random(_CHUNK)
        if time.perf_counter() - t0 > cfg.time_budget_s:
            break
        used = it + 1
        q_rand = goal if goal_idx < 0 and goal_draws[k] < cfg.goal_bias else samples[k]
        diff = nodes[:n] - q_rand
        d2 = np.einsum("ij,ij->i", diff, diff)
        i_near = int(np.argmin(d2))
        dist = math.sqrt(d2[i_near])
        if dist < _EPS:
            continue
        q_near = nodes[i_near]
        q_new = q_rand.copy() if dist <= step else q_near + (q_rand - q_near) * (step / dist)
        if not checker.is_valid(q_new):
            continue
        diff = nodes[:n] - q_new
        dn = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        radius = cfg.rewire_radius_rad
        if cfg.shrink_radius:
            radius = min(radius, gamma * (math.log(n + 1) / (n + 1)) ** (1.0 / d))
        near = np.flatnonzero(dn <= radius)
        if dn[i_near] > radius:
            near = np.append(near, i_near)
        # choose parent: the cheapest neighbour with a valid edge; give up (like RRT) if the nearest fails
        best, best_cost = -1, math.inf
        via = cost[near] + dn[near]
        for j in np.argsort(via, kind="stable"):
            if segment_valid(checker, nodes[near[j]], q_new, res):
                best, best_cost = int(near[j]), float(via[j])
                break
            if near[j] == i_near:
                break
        if best < 0:
            continue
        new = n
        nodes[new], parent[new], cost[new] = q_new, best, best_cost
        n += 1
        # rewire: neighbours reached more cheaply through the new node (one batched check for all edges)
        cand = near[best_cost + dn[near] < cost[near] - _EPS]
        if cand.size:
            ok = checker.are_valid(_densify(np.broadcast_to(q_new, (cand.size, d)), nodes[cand], res))
            lengths = np.maximum(1, np.ceil(np.abs(nodes[cand] - q_new).max(axis=1) / res)).astype(np.int64)
            ok = np.logical_and.reduceat(ok, np.cumsum(lengths) - lengths)
            for c in cand[ok]:
                delta = best_cost + dn[c] - cost[c]  # re-evaluated: an earlier rewire may have lowered it
                if delta < -_EPS:
                    parent[c] = new
                    _shift_subtree(parent, cost, n, int(c), delta)
        if goal_idx < 0:
            dg = float(np.linalg.norm(goal - q_new))
            if dg < _EPS:
                goal_idx = new
            elif dg <= max(step, radius) and segment_valid(checker, q_new, goal, res):
                goal_idx = n
                nodes[n], parent[n], cost[n] = goal, new, best_cost + dg
                n += 1
            if goal_idx >= 0:
                logger.debug("RRT*: first solution at iteration %d, cost %.4f rad, %d nodes",
                             used, cost[goal_idx], n)
                if cfg.stop_at_first_solution:
                    break
    if goal_idx < 0:
        raise SearchExhausted(
            f"RRT* found no path after {used} of {cfg.iterations} iterations in "
            f"{time.perf_counter() - t0:.3f} s (budget {cfg.time_budget_s:g} s), tree of {n} nodes"
        )
    chain = [goal_idx]
    while chain[-1] != 0:
        chain.append(int(parent[chain[-1]]))
    return nodes[chain[::-1]].copy(), used, n


def shortcut(checker: ValidityChecker, path: np.ndarray, config: PlannerConfig,
             rng: np.random.Generator) -> np.ndarray:
    """Shorten a valid path (K, n) (rad); returns a valid path (L, n) with the same ends and no higher cost.

    First ``config.shortcut_iterations`` random shortcuts: two points drawn uniformly along the path's
    arc length (possibly mid-segment) are joined if the straight segment between them is valid and
    shorter (the partial segments to their neighbouring waypoints are pieces of checked segments). Then a
    greedy pass removes every intermediate waypoint whose neighbours can be joined directly, until none
    can. Deterministic given rng.
    """
    path = np.array(path, dtype=float)
    res = config.edge_resolution_rad
    for _ in range(config.shortcut_iterations):
        if len(path) <= 2:
            break
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        s1, s2 = np.sort(rng.random(2)) * cum[-1]
        i, j = np.minimum(np.searchsorted(cum, [s1, s2], side="right") - 1, len(path) - 2)
        if i == j:
            continue
        p1 = path[i] + (path[i + 1] - path[i]) * ((s1 - cum[i]) / (cum[i + 1] - cum[i]))
        p2 = path[j] + (path[j + 1] - path[j]) * ((s2 - cum[j]) / (cum[j + 1] - cum[j]))
        if np.linalg.norm(p2 - p1) > s2 - s1 - max(config.shortcut_min_gain_rad, _EPS):
            continue
        # path[i] -> p1 and p2 -> path[j + 1] are pieces of segments already checked at this resolution: any
        # point on them lies as close to a checked configuration as before, so only p1 -> p2 is new.
        if segment_valid(checker, p1, p2, res):
            path = np.vstack([path[: i + 1], p1, p2, path[j + 1:]])
            path = path[np.concatenate([[True], np.any(np.diff(path, axis=0) != 0.0, axis=1)])]  # exact dups
    removed = True
    while removed:
        removed = False
        k = 1
        while k < len(path) - 1:
            direct = np.linalg.norm(path[k + 1] - path[k - 1])
            detour = np.linalg.norm(path[k] - path[k - 1]) + np.linalg.norm(path[k + 1] - path[k])
            if direct <= detour and segment_valid(checker, path[k - 1], path[k + 1], res):
                path = np.delete(path, k, axis=0)
                removed = True
            else:
                k += 1
    return path


def plan(checker: ValidityChecker, q_start: np.ndarray, q_goal: np.ndarray, lower: np.ndarray,
         upper: np.ndarray, config: PlannerConfig | None = None) -> PlanResult:
    """Plan a collision-free joint-space path from q_start (n,) to q_goal (n,) within [lower, upper] (n,).

    Tries the straight segment first (status DIRECT), else runs RRT* and shortcuts its path.

    Raises:
        PlanningFailed: start/goal outside the bounds (naming the joint and value) or in collision
            (naming the end and the colliding geoms), or no path within the iteration/time budget.
    """
    cfg = config if config is not None else PlannerConfig()
    t0 = time.perf_counter()
    start, goal, lo, hi = _inputs(checker, q_start, q_goal, lower, upper)
    if segment_valid(checker, start, goal, min(cfg.edge_resolution_rad, cfg.verify_resolution_rad)):
        path = np.vstack([start, goal])
        path.setflags(write=False)
        cost = path_cost(path)
        logger.debug("plan: direct segment is valid (cost %.4f rad)", cost)
        return PlanResult(path, path, cost, cost, 0, 2, time.perf_counter() - t0, 0.0, PlanStatus.DIRECT)
    failures: list[str] = []
    for attempt in retry_configs(cfg):
        try:
            raw, short, used, n, t1, t2 = _search_and_shortcut(checker, start, goal, lo, hi, attempt)
            break
        except SearchExhausted as exc:
            failures.append(f"seed {attempt.seed}: {exc}")
            logger.info("plan: %s", failures[-1])
    else:
        raise SearchExhausted("; then ".join(failures))
    if failures:
        logger.info("plan: solved by retry %d (seed %d)", len(failures), attempt.seed)
        cfg = attempt
    t1, t2 = t1 - t0, t2 - t0
    cost_raw, cost = path_cost(raw), path_cost(short)
    if cost > cost_raw:  # cannot happen beyond rounding; keep the promise anyway
        short, cost = raw.copy(), cost_raw
    raw.setflags(write=False)
    short.setflags(write=False)
    status = PlanStatus.SOLVED if cfg.stop_at_first_solution else PlanStatus.REFINED
    logger.debug("plan: %s after %d iterations, %d nodes, %.4f s; cost %.4f -> %.4f rad (%d -> %d waypoints) "
                 "in %.4f s", status.value, used, n, t1, cost_raw, cost, len(raw), len(short), t2 - t1)
    return PlanResult(raw, short, cost_raw, cost, used, n, t1, t2 - t1, status)


def retry_configs(cfg: PlannerConfig) -> list[PlannerConfig]:
    """The searches :func:`plan` tries in turn: ``cfg``, then ``cfg.retries`` more, each with the next seed,
    ``cfg.retry_growth`` times the time budget and iterations of the one before (iterations capped at the
    field's bound) and twice its box margin."""
    out = [cfg]
    for _ in range(cfg.retries):
        last = out[-1]
        out.append(replace(last, seed=last.seed + 1, time_budget_s=last.time_budget_s * cfg.retry_growth,
                           iterations=min(int(last.iterations * cfg.retry_growth), _MAX_ITERATIONS),
                           box_margin_rad=min(2.0 * last.box_margin_rad, _FLOAT_FIELDS["box_margin_rad"][1])))
    return out


def _search_and_shortcut(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray, lo: np.ndarray,
                         hi: np.ndarray, cfg: PlannerConfig) -> tuple[np.ndarray, np.ndarray, int, int, float, float]:
    """One RRT* search with its own seed and budget, then shortcutting (redone at ``verify_resolution_rad`` if the
    path fails that check). Returns (tree path, shortcut path, iterations, tree size, end of search, end of
    shortcutting) (times from ``time.perf_counter``)."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(cfg.seed)
    raw, used, n = _search(checker, start, goal, lo, hi, cfg, rng, t0)
    t1 = time.perf_counter()
    short = shortcut(checker, raw, cfg, rng)
    t2 = time.perf_counter()
    # Edges checked at least as finely as the verification need no second pass.
    if cfg.edge_resolution_rad > cfg.verify_resolution_rad and not path_valid(checker, short,
                                                                               cfg.verify_resolution_rad):
        logger.info("plan: path fails the check at %.3g rad; redoing at that resolution", cfg.verify_resolution_rad)
        fine = replace(cfg, edge_resolution_rad=cfg.verify_resolution_rad)
        rng = np.random.default_rng(cfg.seed)
        raw, used, n = _search(checker, start, goal, lo, hi, fine, rng, t0)
        t1 = time.perf_counter()
        short = shortcut(checker, raw, fine, rng)
        t2 = time.perf_counter()
    return raw, short, used, n, t1, t2


__all__ = ["PlanResult", "PlanStatus", "PlannerConfig", "ValidityChecker", "path_cost", "path_valid", "plan",
           "retry_configs", "sampling_bounds", "segment_valid", "shortcut"]
