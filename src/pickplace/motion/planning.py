"""Joint-space motion planning: lazy bidirectional RRT-Connect (or RRT*) with shortcut smoothing, against an
abstract validity checker.

The planner only sees a :class:`ValidityChecker` (the MuJoCo collision checker satisfies it), joint
bounds and two configurations. Distances and costs are joint-space L2 norms (rad); edge collision
checks interpolate so that consecutive checked configurations are at most ``edge_resolution_rad``
apart in max-norm (per joint). The trees live in numpy arrays; nearest/near queries are
vectorised; edge checks go through the checker's batch call, coarse to fine (bisection order).

:func:`plan` tries the straight segment, then (default, ``PlannerConfig.search = "connect"``) grows two trees, one
from each end, the RRT-Connect way, checking only their nodes; where they meet, the path through them is pulled
taut (as :func:`pull` does; a path edge found invalid is cut out of its tree and the search goes on), then random
shortcuts and a greedy waypoint removal shorten it (as :func:`shortcut` does). All of it is lazy: each candidate
segment, of the pull and of the shortcuts, is checked coarsely (every :data:`_COARSE_GAP` steps of the
resolution), and only the segments of the result are then checked at the resolution, each on its own points (a
failure there is remembered, also against the segment it is a piece of, and the pull and shortcutting redone).
Collision checks are the cost: a valid segment costs its full length in checks, a blocked one usually a few, so
the checks are spent on the segments of the returned path and on cheap rejections, not on the corners of the
pulled path that the shortcuts cut away. That pulled path is therefore not checked at the resolution, and
RRT-Connect returns its result as ``path_raw`` too. ``search = "rrtstar"`` (or ``stop_at_first_solution = False``,
the anytime mode) grows an RRT* tree from the start instead.

Every returned path is valid at the stated resolution: along each of its segments, configurations checked valid
lie at most ``edge_resolution_rad`` apart (both ends included). RRT-Connect's path is checked on exactly the
configurations that :func:`path_valid` visits; RRT*'s tree path too, and its shortcut path on a segment the planner
checked or a piece of one (shortcuts join points inside checked segments). When ``edge_resolution_rad`` is coarser
than ``verify_resolution_rad``, the path is also re-checked at the latter (and planned again at it if that fails).

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
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from pickplace.errors import ConfigError, PlanningFailed, SearchExhausted
from pickplace.world.config import check_int, check_range

logger = logging.getLogger(__name__)

_CHUNK = 256  # random numbers are drawn in chunks of this many iterations, independent of `iterations`
_SHORTCUT_CHUNK = 8  # random shortcuts looked at together (the outcome is that of one at a time)
_EPS = 1e-12


class ValidityChecker(Protocol):
    """What the planner needs from a collision checker.

    A checker may also have ``first_invalid(qs) -> int`` (the index of the first invalid configuration of qs, in
    order, or -1; stopping there): the lazy search uses it to find which edge of a path is blocked, and falls
    back to one ``are_valid`` batch without it.
    """

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
    """Search and shortcutting parameters. Angles in rad, times in s.

    Attributes:
        iterations: Maximum search iterations (one sample each). 6000 as in the reference design.
        step_size_rad: Maximum extension per RRT step, joint-space **L2** norm (rad).
        goal_bias: RRT* only: probability of sampling the goal instead of a random configuration (RRT-Connect
            grows a tree from the goal instead).
        rewire_radius_rad: RRT* only: neighbour radius (L2, rad); an upper cap when ``shrink_radius``.
        shrink_radius: RRT* only: shrink the radius as ``gamma * (log n / n)^(1/d)`` (gamma from the sampling
            volume, the usual RRT* bound), capped at ``rewire_radius_rad``.
        edge_resolution_rad: Max-norm spacing (rad per joint) of the configurations checked along an
            edge during the search and shortcutting. Coarse is fast; the checker's safety margin covers
            the motion between checks, and the final path is verified at ``verify_resolution_rad``.
        verify_resolution_rad: When edges are checked more coarsely than this, the returned path is
            re-checked at this spacing; if it fails, the search and shortcutting are redone at this
            resolution (so every returned path is checked at least this finely).
        time_budget_s: Wall-clock budget of the tree search (shortcutting not included) (s).
        seed: Seed of the ``numpy.random.Generator``.
        stop_at_first_solution: Return the first path found (then rely on shortcutting); if False, RRT* keeps
            sampling and rewiring until iterations or time budget run out (anytime; whatever ``search`` says).
        shortcut_iterations: Random shortcut attempts before the greedy waypoint-removal pass (30: on the obstacle
            transfer, over 150 seeded queries, 50 gave a 0.7 % shorter path for 6 % more collision checks).
        shortcut_min_gain_rad: A random shortcut is only checked when it would shorten the path by at
            least this much (rad, L2). Checking a valid shortcut costs as much as its length in collision
            checks, so gains below the edge resolution are not worth their checks.
        shortcut_min_gain_ratio: ... and by at least this fraction of its own length: a shortcut that gains 0.05
            rad over 1 rad costs 100 checks for 5 % (0.1: on the obstacle transfer, over 150 seeded queries, 24 %
            fewer checks than 0, for a 3 % longer path; 0.2: 15 % fewer again for 1.4 % longer, and 6-12 % fewer
            for 1-2.5 % longer on the shelf, bins and slot problems; the robot's motion time outweighs the planning
            time saved).
        sample_in_box: Sample uniformly in the box spanned by start and goal, expanded by
            ``box_margin_rad`` on every joint and clipped to the joint bounds, instead of in the
            full bounds (which may be ±2π wide). A path that must leave this box will not be found.
        box_margin_rad: Margin of the sampling box (rad per joint).
        retries: Searches tried again when one ends without a path (:class:`~pickplace.errors.SearchExhausted`),
            each with the next seed, ``retry_growth`` times the time budget and iterations of the one before and
            twice its box margin. The budget is wall-clock time, so a search on a loaded machine may run out
            where it would succeed on an idle one; a second, larger search costs time only when the first fails.
        retry_growth: Growth of the time budget and iterations per retry.
        search: ``"connect"``: lazy bidirectional RRT-Connect, then :func:`pull` (see the module docstring);
            ``"rrtstar"``: RRT* from the start, stopping at its first solution unless ``stop_at_first_solution``
            is False.

    The defaults (step 0.4, radius cap 0.8 = 2 steps, box sampling with a 1 rad margin) gave the fewest
    checked configurations on 6-D toy problems; full ±π sampling often exhausts 6000 iterations there. On the
    obstacle transfer, RRT-Connect's step of 0.4 checked fewer configurations than 0.2, 0.7, 1.0 or 1.5.
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
    shortcut_iterations: int = 30
    shortcut_min_gain_rad: float = 0.01
    shortcut_min_gain_ratio: float = 0.1
    sample_in_box: bool = True
    box_margin_rad: float = 1.0
    retries: int = 1
    retry_growth: float = 3.0
    search: str = "connect"

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
        if self.search not in SEARCHES:
            raise ConfigError("planner.search", self.search, f"must be one of {', '.join(SEARCHES)}")


SEARCHES = ("connect", "rrtstar")
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
    "shortcut_min_gain_ratio": (0.0, 10.0, False, ""),
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
        path_raw: Tree path (K, n) from start to goal (rad): RRT*'s; with RRT-Connect (``search = "connect"``),
            whose pulled path is only checked lazily, the shortcut path (as ``path``).
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


@functools.lru_cache(maxsize=4096)
def _fractions(steps: int) -> np.ndarray:
    """Fractions k / steps (steps + 1, 1) of a segment of ``steps`` steps in coarse-to-fine order: 0 and 1 first, then
    the interior (see :func:`_coarse_to_fine`); read-only."""
    out = (_coarse_to_fine(steps + 1) / steps)[:, None]
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=4096)
def _coarse_count(steps: int, gap: int) -> int:
    """How many of the interior points of a segment of ``steps`` steps, taken in coarse-to-fine order
    (:func:`_fractions` after its two ends), it takes until no two neighbouring checked points (ends included) are
    more than ``gap`` steps apart."""
    if steps <= gap:
        return 0
    checked = np.zeros(steps + 1, dtype=bool)
    order = _coarse_to_fine(steps + 1)
    lo = hi = 2
    while hi < len(order):  # bisect on the prefix length: the widest gap only shrinks as points are added
        checked[:] = False
        checked[order[:hi]] = True
        if int(np.diff(np.flatnonzero(checked)).max()) <= gap:
            break
        lo, hi = hi, min(len(order), 2 * hi)
    while lo < hi:
        mid = (lo + hi) // 2
        checked[:] = False
        checked[order[:mid]] = True
        if int(np.diff(np.flatnonzero(checked)).max()) <= gap:
            hi = mid
        else:
            lo = mid + 1
    return hi - 2


def segment_valid(checker: ValidityChecker, qa: np.ndarray, qb: np.ndarray, resolution_rad: float) -> bool:
    """Whether the straight joint-space segment qa (n,) -> qb (n,) is valid, both ends included.

    Checked configurations are at most ``resolution_rad`` apart in max-norm, in coarse-to-fine (bisection)
    order, and the check stops at the first collision, so a blocked segment costs few checks.
    """
    delta = qb - qa
    steps = max(1, math.ceil(float(np.abs(delta).max()) / resolution_rad))
    pts = qa + _fractions(steps) * delta  # the points qa + (k / steps) delta of _densify, plus qa, coarse to fine
    pts[1] = qb  # (k = steps)
    return bool(checker.all_valid(pts))


def _interior_valid(checker: ValidityChecker, qa: np.ndarray, qb: np.ndarray, resolution_rad: float) -> bool:
    """:func:`segment_valid` for a segment whose two ends are already known valid: only the points between them."""
    delta = qb - qa
    steps = math.ceil(float(np.abs(delta).max()) / resolution_rad)
    if steps <= 1:
        return True
    return bool(checker.all_valid(qa + _fractions(steps)[2:] * delta))


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
    start, goal, lo, hi = arrays
    n = lo.size
    if any(a.shape != (n,) for a in arrays) or not np.isfinite(arrays).all():
        for name, a in zip(("start", "goal", "lower bounds", "upper bounds"), arrays, strict=True):
            if a.shape != (n,) or not np.isfinite(a).all():
                raise PlanningFailed(f"{name} must be a finite vector of shape ({n},), got {a.tolist()}")
    if n == 0 or (lo >= hi).any():
        raise PlanningFailed(f"joint bounds must satisfy lower < upper, got {lo.tolist()} / {hi.tolist()}")
    for end, q in (("start", start), ("goal", goal)):
        if (q < lo).any() or (q > hi).any():
            out = np.flatnonzero((q < lo) | (q > hi))
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
            cfg: PlannerConfig, rng: np.random.Generator, t0: float
            ) -> tuple[np.ndarray, np.ndarray, int, int, float]:
    """The configured tree search from start to goal, then shortcutting. Returns (tree path (K, n), shortcut path
    (L, n), iterations used, tree size, end of the search (``time.perf_counter``))."""
    if cfg.search == "connect" and cfg.stop_at_first_solution:
        return _rrt_connect(checker, start, goal, lo, hi, cfg, rng, t0)
    raw, used, n = _rrt_star(checker, start, goal, lo, hi, cfg, rng, t0)
    t1 = time.perf_counter()
    return raw, shortcut(checker, raw, cfg, rng), used, n, t1


def _rrt_star(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray, lo: np.ndarray, hi: np.ndarray,
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
            if _interior_valid(checker, nodes[near[j]], q_new, res):  # both ends are valid nodes
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
            elif dg <= max(step, radius) and _interior_valid(checker, q_new, goal, res):
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


def _first_invalid(checker: ValidityChecker, qs: np.ndarray) -> int:
    """Index of the first invalid configuration of qs (M, n), in order, or -1: the checker's own
    ``first_invalid`` (which stops there) if it has one, else one ``are_valid`` batch."""
    first = getattr(checker, "first_invalid", None)
    if first is not None:
        return int(first(qs))
    bad = np.flatnonzero(~np.asarray(checker.are_valid(qs), dtype=bool))
    return int(bad[0]) if bad.size else -1


class _Tree:
    """One tree of the bidirectional search: nodes (rad) in an array that grows by doubling (cut nodes sit at
    infinity), parents and children in lists."""

    def __init__(self, root: np.ndarray, capacity: int) -> None:
        self.nodes = np.empty((capacity, root.size))
        self.nodes[0] = root
        self.ones = np.ones(root.size)
        self.parent: list[int] = [-1]
        self.children: list[list[int]] = [[]]
        self.n = 1

    def nearest(self, q: np.ndarray) -> tuple[int, float]:
        """(index, L2 distance) of the live node nearest to q (n,)."""
        diff = self.nodes[: self.n] - q
        diff *= diff
        d2 = diff @ self.ones  # (faster than einsum for the few nodes of a lazy search)
        i = int(d2.argmin())
        return i, math.sqrt(d2[i])

    def add(self, q: np.ndarray, parent: int) -> int:
        if self.n == len(self.nodes):
            self.nodes = np.vstack([self.nodes, np.empty_like(self.nodes)])
        i = self.n
        self.nodes[i] = q
        self.parent.append(parent)
        self.children.append([])
        self.children[parent].append(i)
        self.n += 1
        return i

    def chain(self, i: int) -> list[int]:
        """Node indices from node i up to the root."""
        out = [i]
        while out[-1] != 0:
            out.append(self.parent[out[-1]])
        return out

    def cut(self, i: int) -> int:
        """Remove node i and everything below it; returns how many nodes went."""
        self.children[self.parent[i]].remove(i)
        gone, stack = [], [i]
        while stack:
            k = stack.pop()
            gone.append(k)
            stack.extend(self.children[k])
            self.children[k] = []
        self.nodes[gone] = np.inf  # out of every nearest-node query (no live node refers to them)
        return len(gone)


def _rrt_connect(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 cfg: PlannerConfig, rng: np.random.Generator, t0: float
                 ) -> tuple[np.ndarray, np.ndarray, int, int, float]:
    """Bidirectional RRT-Connect with lazy edge checking, then the path pulled taut and shortcut.

    Each iteration extends one tree by one step towards a sample and then greedily extends the other tree, step
    after step, towards the new node (Kuffner & LaValle 2000), the two trees taking turns. Only the new nodes
    are checked while the trees grow. When the trees meet, the midpoints of the path's edges not looked at yet are
    checked first (all together); then :func:`_pull_and_shortcut` makes the path taut and shortcuts it, checking
    the candidate segments coarsely and those of the result at ``edge_resolution_rad``. An edge found invalid is
    cut out of its tree with everything below it, and the search goes on (as LazyRRT / LazyPRM do). What is known
    about a segment is kept for the next meeting (:class:`_Segments`).

    Returns:
        (shortcut path (L, n) twice (the pulled path is not checked at the resolution), iterations used, nodes of
        both trees, when the trees met for the last time (``time.perf_counter``)).
    """
    d = start.size
    lo, hi = sampling_bounds(start, goal, lo, hi, cfg)
    span = hi - lo
    trees = (_Tree(start, 256), _Tree(goal, 256))
    step, res, budget = cfg.step_size_rad, cfg.edge_resolution_rad, cfg.time_budget_s
    samples = np.empty((0, d))
    used = 0
    segs = _Segments(checker, res, _COARSE_GAP, exact_pieces=True)
    draws = np.sort(rng.random((cfg.shortcut_iterations, 2)), axis=1)  # the shortcuts', drawn before the samples

    def extend(tree: _Tree, i: int, target: np.ndarray, dist: float) -> tuple[int, bool]:
        """One step from node i towards target: (new node or -1 if its configuration is invalid, target reached)."""
        if dist <= step:
            q_new, reached = target, True  # (add copies it into the tree)
        else:
            base = tree.nodes[i]
            q_new, reached = base + (target - base) * (step / dist), False
        if not checker.is_valid(q_new):
            return -1, False
        return tree.add(q_new, i), reached

    for it in range(cfg.iterations):
        k = it % _CHUNK
        if k == 0:
            samples = lo + span * rng.random((_CHUNK, d))
        if time.perf_counter() - t0 > budget:
            break
        used = it + 1
        grow, other = trees[it % 2], trees[1 - it % 2]
        i, dist = grow.nearest(samples[k])
        if dist < _EPS:
            continue
        new, _ = extend(grow, i, samples[k], dist)
        if new < 0:
            continue
        target = grow.nodes[new]
        j, dist = other.nearest(target)
        reached = dist < _EPS
        target_list = target.tolist()  # (math.dist is faster on lists)
        while not reached:
            j_new, reached = extend(other, j, target, dist)
            if j_new < 0:
                break
            j, dist = j_new, math.dist(target_list, other.nodes[j_new].tolist())
        if not reached:
            continue
        # The trees meet at target. Pull the path through them taut and shortcut it, lazily (the candidate segments
        # checked coarsely, those of the result then at the edge resolution); a path edge that is itself invalid
        # is cut out of its tree with everything below it.
        a, b = (grow.chain(new), other.chain(j)) if grow is trees[0] else (other.chain(j), grow.chain(new))
        a = a[::-1]  # start tree: root .. meeting node; goal tree b: meeting node .. root
        path = np.vstack([trees[0].nodes[a], trees[1].nodes[b[1:]]])
        # First the midpoint of every edge not looked at yet: a path through an obstacle is usually given away by
        # one, for a few checks, before pulling spends checks on segments that would be thrown away with it.
        e = segs.first_invalid_midpoint(path)
        if e >= 0:
            tree, c = (trees[0], a[e + 1]) if e + 1 < len(a) else (trees[1], b[e + 1 - len(a)])
            tree.cut(c)
            continue
        t_met = time.perf_counter()
        # (start -> goal is the segment plan() found blocked)
        taut, short, bad = _pull_and_shortcut(segs, path, cfg, draws, blocked={(0, len(path) - 1)})
        if taut is None or short is None:
            tree, c = (trees[0], a[bad + 1]) if bad + 1 < len(a) else (trees[1], b[bad + 1 - len(a)])
            tree.cut(c)
            continue
        logger.debug("RRT-Connect: path at iteration %d, %d -> %d -> %d waypoints, trees of %d + %d nodes", used,
                     len(path), len(taut), len(short), trees[0].n, trees[1].n)
        return short, short, used, trees[0].n + trees[1].n, t_met
    raise SearchExhausted(
        f"RRT-Connect found no path after {used} of {cfg.iterations} iterations in "
        f"{time.perf_counter() - t0:.3f} s (budget {cfg.time_budget_s:g} s), trees of {trees[0].n} + "
        f"{trees[1].n} nodes"
    )


class _Segments:
    """What is known about the straight segments between valid configurations at one resolution: for each, how many
    of its interior points (in coarse-to-fine order, :func:`_fractions`) were found valid, or that it is blocked.

    Lazy checking rests on it: a candidate segment is first checked only coarsely (:meth:`check` with
    ``coarse=True``: its points up to a spacing of ``coarse_gap`` steps), and the segments of the final path are
    then completed (:meth:`complete`). A segment checked coarsely and later dropped cost only its coarse points; a
    segment completed later is never checked twice at a point. A piece of a segment (:meth:`set_piece`, the ends of a
    shortcut) found blocked blocks its segment too; it is valid at the resolution if its segment is, unless
    ``exact_pieces`` (RRT-Connect's: then it is checked on its own points). Keys are the two ends' bytes, in order.
    """

    def __init__(self, checker: ValidityChecker, resolution_rad: float, coarse_gap: int,
                 exact_pieces: bool = False) -> None:
        self.checker, self.res, self.gap, self.exact_pieces = checker, resolution_rad, coarse_gap, exact_pieces
        # per segment: interior points found valid, in coarse-to-fine order; or _FULL (all of them, or a piece of
        # such a segment unless exact_pieces); or _BLOCKED (an interior point found invalid)
        self.state: dict[bytes, int] = {}
        self.parent: dict[bytes, bytes] = {}  # a piece of a segment (shortcut ends): the segment it lies on
        # the index of the first invalid configuration of a batch, or -1 (:func:`_first_invalid`, resolved once)
        first = getattr(checker, "first_invalid", None)
        self.first_invalid = first if first is not None else functools.partial(_first_invalid, checker)

    def check(self, qa: np.ndarray, qb: np.ndarray, coarse: bool) -> bool:
        """Whether the segment qa (n,) -> qb (n,), whose ends are valid, passes: all its interior points, or with
        ``coarse`` those up to the coarse spacing; only the points not checked before are checked."""
        key = qa.tobytes() + qb.tobytes()
        done = self.state.get(key, 0)
        if done == _FULL:
            return True
        if done < 0:
            return False
        delta = qb - qa
        steps = math.ceil(max(map(abs, delta.tolist())) / self.res)
        total = steps - 1
        want = _coarse_count(steps, self.gap) if coarse else total  # (_coarse_count <= total)
        if done < want:
            if self.first_invalid(qa + _fractions(steps)[2 + done: 2 + want] * delta) >= 0:
                self.block(key)
                return False
            done = want
        if done >= total:
            self.state[key] = _FULL
        elif done:
            self.state[key] = done
        return True

    def block(self, key: bytes) -> None:
        """Record the segment ``key`` as blocked, and the segments it is a piece of (they hold its invalid point), up
        to one checked valid at the resolution (the point lies between two of its checked ones)."""
        state, parent = self.state, self.parent
        while key is not None and state.get(key, 0) not in (_BLOCKED, _FULL):
            state[key] = _BLOCKED
            key = parent.get(key)

    def first_invalid_midpoint(self, path: np.ndarray) -> int:
        """Check the first interior point (the midpoint, as :func:`_fractions` orders them: step ``steps // 2`` of
        ``steps``) of every edge of path (K, n) not looked at yet, all in one batch, stopping at the first invalid
        one; record the others. Returns the index of the edge found invalid (then recorded as blocked), or -1."""
        raw = np.ascontiguousarray(path).tobytes()
        width = path.itemsize * path.shape[1]
        keys = [raw[e * width: (e + 2) * width] for e in range(len(path) - 1)]  # (path is C-contiguous)
        state = self.state
        fresh = [e for e, key in enumerate(keys) if key not in state]
        if not fresh:
            return -1
        qa = path[fresh]
        delta = path[np.add(fresh, 1)] - qa
        steps = np.ceil(np.abs(delta).max(axis=1) / self.res)
        inner = np.flatnonzero(steps > 1)  # (an edge of one step has no interior)
        if inner.size:
            half = np.floor(steps[inner] / 2) / steps[inner]
            bad = self.first_invalid(qa[inner] + half[:, None] * delta[inner])
            if bad >= 0:
                e = fresh[int(inner[bad])]
                state[keys[e]] = _BLOCKED
                return e
        for e, n in zip(fresh, steps.tolist(), strict=True):
            state[keys[e]] = _FULL if n <= 2 else 1  # (the midpoint was the whole interior, or there is none)
        return -1

    def complete(self, qa: np.ndarray, qb: np.ndarray) -> bool:
        """:meth:`check` of every interior point."""
        return self.check(qa, qb, coarse=False)

    def is_full(self, qa: np.ndarray, qb: np.ndarray) -> bool:
        """Whether every interior point of qa -> qb is known valid."""
        return self.state.get(qa.tobytes() + qb.tobytes()) == _FULL

    def set_full(self, qa: np.ndarray, qb: np.ndarray) -> None:
        """Record qa -> qb as valid at the resolution (an edge checked elsewhere, or a piece of a valid segment)."""
        self.state[qa.tobytes() + qb.tobytes()] = _FULL

    def set_piece(self, pa: np.ndarray, pb: np.ndarray, qa: np.ndarray, qb: np.ndarray) -> None:
        """Record qa -> qb as a piece of the segment pa -> pb: found blocked, it blocks that one too (unless that one
        was checked at the resolution); valid at the resolution if that one is, unless ``exact_pieces`` (then a piece
        is checked on its own points, the configurations a re-check of the path at the resolution visits)."""
        key, whole = qa.tobytes() + qb.tobytes(), pa.tobytes() + pb.tobytes()
        if key == whole:
            return
        if not self.exact_pieces and self.state.get(whole) == _FULL:
            self.state[key] = _FULL
        else:
            self.parent[key] = whole


_FULL = 1 << 62  # _Segments.state of a segment whose interior points are all known valid
_BLOCKED = -1  # ... and of one found blocked


# lazy pulls and shortcuts whose result failed its completion before one that checks fully (5: on the obstacle
# transfer and the shelf, cage, bins and slot problems, 20 seeded queries each, as few or fewer checks than 2 or 3)
_LAZY_ATTEMPTS = 5
_COARSE_GAP = 8  # a candidate segment is first checked every 8 steps of the edge resolution (0.08 rad by default)


def pull(checker: ValidityChecker, path: np.ndarray, resolution_rad: float, known: list[bool] | None = None,
         blocked: set[tuple[int, int]] | frozenset[tuple[int, int]] = frozenset()
         ) -> tuple[np.ndarray | None, int, list[int]]:
    """Pull a path (K, n) whose waypoints are valid (its edges need not be) taut: from each kept waypoint i, jump to a
    later waypoint, as far as possible, that the straight segment from i reaches validly at ``resolution_rad``.

    The later waypoints are first looked at coarsely (every :data:`_COARSE_GAP` steps of the resolution), farthest
    first: an invalid segment usually shows after a few checks (coarse to fine), so the farthest candidate that passes
    costs little to find; it is then checked at the resolution, and kept. A valid segment costs its full length,
    and every valid segment found is kept: the checks are spent on the returned path. When the candidate fails at the
    resolution (an obstacle thinner than the coarse spacing), the later waypoints i + (K - 1 - i), i + (K - 1 - i) / 2,
    i + (K - 1 - i) / 4, ..., i + 1 are tried in turn at the resolution instead, so that a path with many waypoints
    past such obstacles costs O(K log K) segment checks at the resolution, not O(K^2).

    Args:
        checker: The validity checker.
        path: Waypoints (K, n) (rad), each valid.
        resolution_rad: Max-norm spacing of the checks (rad).
        known: Per edge (K - 1,), True if edge i (waypoint i -> i + 1) is already known valid (not checked again).
        blocked: Waypoint pairs (i, j) already known not to be joinable (not tried).

    Returns:
        (the taut path (L, n), or None if an edge of ``path`` is invalid; that edge's index i, or -1; the indices of
        the edges of ``path`` found valid on the way).
    """
    segs = _Segments(checker, resolution_rad, _COARSE_GAP)
    for e, ok in enumerate(known or []):
        if ok:
            segs.set_full(path[e], path[e + 1])
    taut, bad = _pull(segs, path, blocked)
    valid = [e for e in range(len(path) - 1) if not (known and known[e]) and segs.is_full(path[e], path[e + 1])]
    return taut, bad, valid


def _pull(segs: _Segments, path: np.ndarray,
          blocked: set[tuple[int, int]] | frozenset[tuple[int, int]] = frozenset(),
          coarse: bool = False) -> tuple[np.ndarray | None, int]:
    """:func:`pull` on a segment record: from each kept waypoint i, the later waypoints are looked at coarsely,
    farthest first, and the farthest that passes is then checked at the resolution; if that fails (an obstacle
    thinner than the coarse spacing), waypoint i goes on in :func:`pull`'s order (halving distances). With
    ``coarse``, the farthest that passes coarsely is kept as it is (its check is completed later, if the result
    keeps it). Returns (the taut path or None, the index of the edge of ``path`` found blocked or -1)."""
    k_last = len(path) - 1
    out, i = [0], 0
    while i < k_last:
        j = -1
        for cand in range(k_last, i, -1):  # farthest first, coarsely: a blocked candidate costs a few checks
            if (i, cand) not in blocked and segs.check(path[i], path[cand], True):
                if coarse or segs.complete(path[i], path[cand]):
                    j = cand
                break
        gap = k_last - i
        while j < 0 and gap >= 1:
            cand = i + gap
            gap = 0 if gap == 1 else (gap + 1) // 2
            if (i, cand) not in blocked and segs.complete(path[i], path[cand]):  # waypoints are valid
                j = cand
        if j < 0:  # even the edge to the next waypoint is invalid
            return None, i
        out.append(j)
        i = j
    return path[out].copy(), -1


def _without_repeats(path: np.ndarray) -> np.ndarray:
    """path (K, n) without waypoints equal to the one before (no zero-length segment)."""
    return path[np.concatenate([[True], np.any(np.diff(path, axis=0) != 0.0, axis=1)])]


def _shortcut_pass(segs: _Segments, path: np.ndarray, config: PlannerConfig, draws: np.ndarray,
                   coarse: bool) -> np.ndarray:
    """The random shortcuts (``draws`` (m, 2), sorted pairs in [0, 1)) and the greedy waypoint removal of
    :func:`shortcut` on a path whose segments ``segs`` passed, each candidate checked coarsely if ``coarse``."""
    first_invalid = segs.first_invalid
    path = _without_repeats(np.array(path, dtype=float))
    min_gain, ratio = max(config.shortcut_min_gain_rad, _EPS), 1.0 + config.shortcut_min_gain_ratio
    k = 0  # the next draw; the draws before it are spent
    while k < len(draws) and len(path) > 2:
        # The remaining draws against the current path at once; the path only changes when a shortcut is taken,
        # and the draws after that one are then looked at on the new path: the outcome of taking them one by one.
        steps = path[1:] - path[:-1]
        seg_len = np.sqrt(np.einsum("ij,ij->i", steps, steps))
        cum = np.concatenate(([0.0], seg_len.cumsum()))
        arc = draws[k:] * cum[-1]  # (m, 2) arc lengths
        ij = np.minimum(cum.searchsorted(arc, side="right") - 1, len(path) - 2)
        pts = path[ij] + steps[ij] * ((arc - cum[ij]) / seg_len[ij])[:, :, None]  # (m, 2, n): p1, p2
        gap = pts[:, 1] - pts[:, 0]
        worth = ((ij[:, 0] != ij[:, 1])
                 & (np.sqrt(np.einsum("ij,ij->i", gap, gap)) * ratio <= arc[:, 1] - arc[:, 0] - min_gain))
        taken = -1
        for c in np.flatnonzero(worth).tolist():
            # path[i] -> p1 and p2 -> path[j + 1] are pieces of path segments; only p1 -> p2 is new. (Its ends
            # last: they lie on segments that passed, so they are rarely what is invalid.)
            if segs.check(pts[c, 0], pts[c, 1], coarse) and first_invalid(pts[c]) < 0:
                taken = c
                break
        if taken < 0:
            break
        k += taken + 1
        i, j = ij[taken].tolist()
        a, b = pts[taken]
        # A piece of a segment checked at the resolution is checked at it too: any point on it lies as close to a
        # checked configuration as before.
        segs.set_piece(path[i], path[i + 1], path[i], a)
        segs.set_piece(path[j], path[j + 1], b, path[j + 1])
        pieces = [path[: i + 1]]
        if a.tobytes() != path[i].tobytes():  # (a draw exactly on a waypoint: no zero-length segment)
            pieces.append(a[None])
        if b.tobytes() != path[j + 1].tobytes():
            pieces.append(b[None])
        pieces.append(path[j + 1:])
        path = np.concatenate(pieces)
    removed = True
    rows = path.tolist()  # (math.dist is faster on lists)
    while removed:
        removed = False
        k = 1
        while k < len(rows) - 1:
            ra, rk, rb = rows[k - 1], rows[k], rows[k + 1]
            if math.dist(ra, rb) <= math.dist(ra, rk) + math.dist(rk, rb) and segs.check(path[k - 1], path[k + 1],
                                                                                       coarse):
                path = np.delete(path, k, axis=0)  # (waypoints are valid)
                del rows[k]
                removed = True
                continue
            k += 1
    return path


def _completed(segs: _Segments, path: np.ndarray) -> bool:
    """Complete the check of every segment of path (K, n) that is not yet checked at the resolution; False at the
    first one found invalid (then recorded as blocked)."""
    return all(segs.complete(path[e], path[e + 1]) for e in range(len(path) - 1))


def _pull_and_shortcut(segs: _Segments, path: np.ndarray, config: PlannerConfig, draws: np.ndarray,
                       blocked: set[tuple[int, int]] | frozenset[tuple[int, int]] = frozenset(),
                       pull_first: bool = True) -> tuple[np.ndarray | None, np.ndarray | None, int]:
    """Pull the path (K, n) taut (if ``pull_first``; :func:`_pull`), then shortcut it, lazily: every candidate segment
    (of the pull and of the shortcuts) is checked coarsely, and only the segments of the result are then checked at
    the resolution. When one of those fails, it is recorded as blocked (with the segment it is a piece of) and the
    pull and the shortcutting are redone (what passed before costs nothing again); after :data:`_LAZY_ATTEMPTS` such
    failures, once more with every candidate checked at the resolution as it is tried.

    (A candidate checked fully costs its whole length; most candidates that pass, and the corners of the pulled path,
    are cut away by a later shortcut, so checking them only coarsely until the end saves most of their checks.)

    Returns:
        (the taut path, the shortcut path, -1), or (None, None, the index of an edge of ``path`` found blocked)
        when even the edges of ``path`` cannot join its waypoints. The shortcut path's segments are all checked at
        the resolution; the taut path's only where they were needed (all of them after the last attempt).
    """
    taut = path
    for attempt in range(_LAZY_ATTEMPTS + 1):
        coarse = attempt < _LAZY_ATTEMPTS
        if pull_first:
            pulled, bad = _pull(segs, path, blocked, coarse)
            if pulled is None:
                return None, None, bad
            taut = pulled
        short = _shortcut_pass(segs, taut, config, draws, coarse)
        if _completed(segs, short):
            return taut, short, -1
        if not coarse:  # a piece of a segment checked at the resolution failed on its own points: keep the taut path
            logger.debug("shortcut: a piece of a checked segment failed at the resolution; the taut path is kept")
            return taut, taut, -1
        logger.debug("lazy shortcut: a segment of the result failed at the resolution (attempt %d)", attempt + 1)
    raise AssertionError("unreachable: the last attempt returns")


def shortcut(checker: ValidityChecker, path: np.ndarray, config: PlannerConfig,
             rng: np.random.Generator) -> np.ndarray:
    """Shorten a valid path (K, n) (rad); returns a valid path (L, n) with the same ends and no higher cost.

    First ``config.shortcut_iterations`` random shortcuts: two points drawn uniformly along the path's
    arc length (possibly mid-segment) are joined if the straight segment between them is valid and
    shorter by ``shortcut_min_gain_rad`` and by ``shortcut_min_gain_ratio`` of its length (the partial segments
    to their neighbouring waypoints are pieces of checked segments). Then a greedy pass removes every
    intermediate waypoint whose neighbours can be joined directly, until none can. Deterministic given rng.

    Checking is lazy: a candidate is checked coarsely (every :data:`_COARSE_GAP` steps of
    ``config.edge_resolution_rad``), the result's new segments then at the resolution; if one of them fails, the
    shortcutting is redone knowing it (see :func:`_pull_and_shortcut`).
    """
    path = _without_repeats(np.array(path, dtype=float))
    segs = _Segments(checker, config.edge_resolution_rad, _COARSE_GAP)
    for e in range(len(path) - 1):
        segs.set_full(path[e], path[e + 1])
    draws = np.sort(rng.random((config.shortcut_iterations, 2)), axis=1)
    _, short, _ = _pull_and_shortcut(segs, path, config, draws, pull_first=False)
    assert short is not None
    return short


def plan(checker: ValidityChecker, q_start: np.ndarray, q_goal: np.ndarray, lower: np.ndarray,
         upper: np.ndarray, config: PlannerConfig | None = None) -> PlanResult:
    """Plan a collision-free joint-space path from q_start (n,) to q_goal (n,) within [lower, upper] (n,).

    Tries the straight segment first (status DIRECT), else searches (``config.search``) and shortcuts the path.

    Raises:
        PlanningFailed: start/goal outside the bounds (naming the joint and value) or in collision
            (naming the end and the colliding geoms), or no path within the iteration/time budget.
    """
    cfg = config if config is not None else PlannerConfig()
    t0 = time.perf_counter()
    start, goal, lo, hi = _inputs(checker, q_start, q_goal, lower, upper)
    if _interior_valid(checker, start, goal, min(cfg.edge_resolution_rad, cfg.verify_resolution_rad)):
        path = np.vstack([start, goal])
        path.setflags(write=False)
        cost = path_cost(path)
        logger.debug("plan: direct segment is valid (cost %.4f rad)", cost)
        return PlanResult(path, path, cost, cost, 0, 2, time.perf_counter() - t0, 0.0, PlanStatus.DIRECT)
    failures: list[str] = []
    for attempt in _retries(cfg):
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
    cost = path_cost(short)
    cost_raw = cost if raw is short else path_cost(raw)
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
    return list(_retries(cfg))


def _retries(cfg: PlannerConfig) -> Iterator[PlannerConfig]:
    """:func:`retry_configs` one at a time (a retry's config is only made if it is needed)."""
    last = cfg
    yield last
    for _ in range(cfg.retries):
        last = replace(last, seed=last.seed + 1, time_budget_s=last.time_budget_s * cfg.retry_growth,
                       iterations=min(int(last.iterations * cfg.retry_growth), _MAX_ITERATIONS),
                       box_margin_rad=min(2.0 * last.box_margin_rad, _FLOAT_FIELDS["box_margin_rad"][1]))
        yield last


def _search_and_shortcut(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray, lo: np.ndarray,
                         hi: np.ndarray, cfg: PlannerConfig) -> tuple[np.ndarray, np.ndarray, int, int, float, float]:
    """One search with its own seed and budget, then shortcutting (redone at ``verify_resolution_rad`` if the
    path fails that check). Returns (tree path, shortcut path, iterations, tree size, end of search, end of
    shortcutting) (times from ``time.perf_counter``)."""
    t0 = time.perf_counter()
    raw, short, used, n, t1 = _search(checker, start, goal, lo, hi, cfg, np.random.default_rng(cfg.seed), t0)
    t2 = time.perf_counter()
    # Edges checked at least as finely as the verification need no second pass.
    if cfg.edge_resolution_rad > cfg.verify_resolution_rad and not path_valid(checker, short,
                                                                               cfg.verify_resolution_rad):
        logger.info("plan: path fails the check at %.3g rad; redoing at that resolution", cfg.verify_resolution_rad)
        fine = replace(cfg, edge_resolution_rad=cfg.verify_resolution_rad)
        raw, short, used, n, t1 = _search(checker, start, goal, lo, hi, fine, np.random.default_rng(cfg.seed), t0)
        t2 = time.perf_counter()
    return raw, short, used, n, t1, t2


__all__ = ["PlanResult", "PlanStatus", "PlannerConfig", "ValidityChecker", "path_cost", "path_valid", "plan",
           "retry_configs", "sampling_bounds", "segment_valid", "shortcut"]
