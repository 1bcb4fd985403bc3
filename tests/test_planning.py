"""Tests of the planner (lazy RRT-Connect, RRT*) and shortcutting against toy configuration-space checkers."""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import replace

import numpy as np
import pytest

from pickplace.errors import ConfigError, PlanningFailed, SearchExhausted
from pickplace.motion.planning import (
    SEARCHES,
    PlannerConfig,
    PlanStatus,
    ValidityChecker,
    path_cost,
    path_valid,
    plan,
    pull,
    retry_configs,
    segment_valid,
    shortcut,
)


class BoxWorld:
    """Configuration space whose obstacles are named axis-aligned boxes (closed); counts checked configs."""

    def __init__(self, boxes: list[tuple[str, list[float], list[float]]]) -> None:
        self.names = [name for name, _, _ in boxes]
        self.lo = np.array([lo for _, lo, _ in boxes], dtype=float)  # (B, n)
        self.hi = np.array([hi for _, _, hi in boxes], dtype=float)
        self.checked = 0

    def _inside(self, qs: np.ndarray) -> np.ndarray:
        qs = np.atleast_2d(qs)
        return np.all((qs[:, None, :] >= self.lo) & (qs[:, None, :] <= self.hi), axis=2)  # (M, B)

    def are_valid(self, qs: np.ndarray) -> np.ndarray:
        self.checked += len(qs)
        return ~self._inside(qs).any(axis=1)

    def is_valid(self, q: np.ndarray) -> bool:
        return bool(self.are_valid(np.asarray(q)[None])[0])

    def all_valid(self, qs: np.ndarray) -> bool:
        return bool(self.are_valid(qs).all())

    def colliding_pairs(self, q: np.ndarray) -> list[tuple[str, str]]:
        return [("arm", self.names[b]) for b in np.flatnonzero(self._inside(q)[0])]

    def shrunk(self, margin: float) -> BoxWorld:
        """The same world with every box shrunk by margin on each side (for independent re-checks)."""
        return BoxWorld([(n, list(lo + margin), list(hi - margin))
                         for n, lo, hi in zip(self.names, self.lo, self.hi, strict=True)])


PI = math.pi
LO6, HI6 = np.full(6, -PI), np.full(6, PI)
FREE6: list[float] = [-10.0] * 6


def wall_6d() -> BoxWorld:
    """A wall q0 in [-0.2, 0.2] across the 6-D space, except a gap q1 in (0.5, 1.0)."""
    below = ("wall_below", [-0.2, -10.0, *FREE6[2:]], [0.2, 0.5, *[10.0] * 4])
    above = ("wall_above", [-0.2, 1.0, *FREE6[2:]], [0.2, 10.0, *[10.0] * 4])
    return BoxWorld([below, above])


START6 = np.array([-1.0, 0.0, 0.3, -0.5, 0.2, 0.1])
GOAL6 = np.array([1.0, 0.0, -0.2, 0.4, -0.3, 0.6])

LO2, HI2 = np.array([-3.0, -3.0]), np.array([3.0, 3.0])
START2, GOAL2 = np.array([-2.5, -2.5]), np.array([2.5, 2.5])


def maze_2d() -> BoxWorld:
    """Two staggered walls: go over the first (x = -1.4), under the second (x = 1.4)."""
    return BoxWorld([("wall_a", [-1.5, -3.0], [-1.3, 1.5]), ("wall_b", [1.3, -1.5], [1.5, 3.0])])


def assert_truly_valid(world: BoxWorld, path: np.ndarray) -> None:
    """Independent check: re-check the path densely every 0.01 rad, and at 1 mrad against boxes shrunk by
    the worst-case gap a 0.01 rad sampling leaves (0.005 rad per joint, plus slack)."""
    assert path_valid(world, path, 0.01)
    fine = world.shrunk(0.006)
    for qa, qb in itertools.pairwise(path):
        m = int(np.ceil(np.abs(qb - qa).max() / 0.001)) + 1
        assert fine.are_valid(np.linspace(qa, qb, m)).all()


def assert_within_half_resolution_of_valid(world: BoxWorld, path: np.ndarray) -> None:
    """What the planner promises of every path it returns, checked independently: along each segment, valid
    configurations at most 0.01 rad apart (max-norm), so every point of it within 0.005 rad of a valid one, i.e.
    outside every box shrunk by that much (by 0.006: slack). Checked every 1 mrad."""
    fine = world.shrunk(0.006)
    for qa, qb in itertools.pairwise(path):
        m = int(np.ceil(np.abs(qb - qa).max() / 0.001)) + 1
        assert fine.are_valid(np.linspace(qa, qb, m)).all()


def test_toy_checker_satisfies_protocol() -> None:
    world: ValidityChecker = wall_6d()
    assert world.is_valid(START6) and not world.is_valid(np.zeros(6))


def test_direct_path_when_free() -> None:
    world = BoxWorld([("far_box", [2.0] * 6, [3.0] * 6)])
    res = plan(world, START6, GOAL6, LO6, HI6, PlannerConfig())
    assert res.status is PlanStatus.DIRECT
    assert res.path.shape == (2, 6) and res.path_raw.shape == (2, 6)
    np.testing.assert_array_equal(res.path[0], START6)
    np.testing.assert_array_equal(res.path[-1], GOAL6)
    assert res.cost_rad == pytest.approx(np.linalg.norm(GOAL6 - START6))


def test_wall_6d_solved_valid_and_short() -> None:
    world = wall_6d()
    assert not segment_valid(world, START6, GOAL6, 0.01)
    res = plan(world, START6, GOAL6, LO6, HI6, PlannerConfig(seed=3, time_budget_s=30.0))
    assert res.status is PlanStatus.SOLVED
    for path in (res.path_raw, res.path):
        np.testing.assert_array_equal(path[0], START6)
        np.testing.assert_array_equal(path[-1], GOAL6)
        assert_truly_valid(world, path)
    assert res.cost_rad <= res.cost_raw_rad
    assert res.cost_rad == pytest.approx(path_cost(res.path))
    assert len(res.path) <= 6
    assert res.nodes >= 2


def test_maze_2d_solved() -> None:
    world = maze_2d()
    res = plan(world, START2, GOAL2, LO2, HI2, PlannerConfig(seed=1, time_budget_s=30.0))
    assert res.status is PlanStatus.SOLVED
    assert_truly_valid(world, res.path_raw)
    assert_truly_valid(world, res.path)
    assert res.cost_rad <= res.cost_raw_rad
    assert len(res.path) <= 8  # two corners, each usually rounded by two waypoints


def test_anytime_improves_2d() -> None:
    """The anytime mode is RRT*'s: it keeps rewiring after RRT*'s first solution and ends with a cheaper tree path."""
    world = maze_2d()
    first = plan(world, START2, GOAL2, LO2, HI2, PlannerConfig(seed=2, time_budget_s=30.0, search="rrtstar"))
    cfg = PlannerConfig(seed=2, time_budget_s=30.0, stop_at_first_solution=False, iterations=1500)
    more = plan(world, START2, GOAL2, LO2, HI2, cfg)
    assert more.status is PlanStatus.REFINED
    assert more.iterations == 1500 > first.iterations
    assert more.cost_raw_rad <= first.cost_raw_rad
    assert more.cost_raw_rad < first.cost_raw_rad  # deterministic: this seed does improve
    assert_truly_valid(world, more.path)


@pytest.mark.parametrize("end", ["start", "goal"])
def test_invalid_end_names_colliding_geoms(end: str) -> None:
    world = wall_6d()
    bad = np.array([0.0, -1.0, 0.0, 0.0, 0.0, 0.0])  # inside wall_below
    q_start, q_goal = (bad, GOAL6) if end == "start" else (START6, bad)
    with pytest.raises(PlanningFailed, match=end) as info:
        plan(world, q_start, q_goal, LO6, HI6)
    assert "arm <-> wall_below" in str(info.value)


def test_out_of_bounds_names_joint_and_value() -> None:
    q_goal = GOAL6.copy()
    q_goal[4] = 3.5
    with pytest.raises(PlanningFailed, match=r"goal .*joint 4 = 3\.5000"):
        plan(wall_6d(), START6, q_goal, LO6, HI6)


def test_enclosed_goal_fails_within_budget() -> None:
    walls = ENCLOSURE_2D
    for search, trees in (("connect", r"trees of \d+ \+ \d+ nodes"), ("rrtstar", r"tree of \d+ nodes")):
        cfg = PlannerConfig(iterations=300, time_budget_s=5.0, search=search)
        with pytest.raises(PlanningFailed, match=r"300 of 300 iterations.*" + trees):
            plan(BoxWorld(walls), START2, np.array([1.5, 1.5]), LO2, HI2, cfg)


ENCLOSURE_2D = [("left", [0.8, 0.8], [1.0, 2.2]), ("right", [2.0, 0.8], [2.2, 2.2]),
                ("bottom", [0.8, 0.8], [2.2, 1.0]), ("top", [0.8, 2.0], [2.2, 2.2])]


def test_time_budget_stops_search() -> None:
    """A search that cannot succeed within its iterations (the goal is walled in) is ended by the clock, on any
    machine. (The maze at a step of 0.01 rad, used here before, is solved within the retry's 0.15 s once the
    search is fast enough.)"""
    cfg = PlannerConfig(iterations=1_000_000, time_budget_s=0.05, step_size_rad=0.01)
    with pytest.raises(PlanningFailed, match=r"budget 0\.05 s"):
        plan(BoxWorld(ENCLOSURE_2D), START2, np.array([1.5, 1.5]), LO2, HI2, cfg)


def test_a_search_that_runs_out_is_tried_again_with_the_next_seed_and_more_budget() -> None:
    """100 iterations never get through the maze; the retry (next seed, 20 times the iterations) does, and a
    search that can never succeed reports every attempt."""
    cfg = PlannerConfig(seed=3, iterations=100, time_budget_s=30.0, retries=0)
    with pytest.raises(SearchExhausted, match=r"100 of 100 iterations"):
        plan(maze_2d(), START2, GOAL2, LO2, HI2, cfg)
    retried = replace(cfg, retries=1, retry_growth=20.0)
    assert [(c.seed, c.iterations, c.time_budget_s, c.box_margin_rad) for c in retry_configs(retried)] == [
        (3, 100, 30.0, 1.0), (4, 2000, 600.0, 2.0)]
    res = plan(maze_2d(), START2, GOAL2, LO2, HI2, retried)
    assert 100 < res.iterations <= 2000
    assert path_valid(maze_2d(), res.path, 0.01)
    walls = [("left", [0.8, 0.8], [1.0, 2.2]), ("right", [2.0, 0.8], [2.2, 2.2]),
             ("bottom", [0.8, 0.8], [2.2, 1.0]), ("top", [0.8, 2.0], [2.2, 2.2])]
    with pytest.raises(SearchExhausted, match=r"seed 0: .*100 of 100 .*; then seed 1: .*300 of 300 .*; then seed 2"):
        plan(BoxWorld(walls), START2, np.array([1.5, 1.5]), LO2, HI2,
             PlannerConfig(iterations=100, time_budget_s=30.0, retries=2))


def test_same_seed_is_bit_identical_and_seeds_differ() -> None:
    world = wall_6d()
    cfgs = [PlannerConfig(seed=s, time_budget_s=30.0) for s in (5, 5, 6)]
    runs = [plan(world, START6, GOAL6, LO6, HI6, cfg) for cfg in cfgs]
    assert np.array_equal(runs[0].path_raw, runs[1].path_raw)
    assert np.array_equal(runs[0].path, runs[1].path)
    assert runs[0].iterations == runs[1].iterations and runs[0].nodes == runs[1].nodes
    assert not np.array_equal(runs[0].path_raw, runs[2].path_raw)


def test_shortcut_straightens_free_zigzag_deterministically() -> None:
    world = BoxWorld([("far_box", [5.0, 5.0], [6.0, 6.0])])
    zigzag = np.array([[0.0, 0.0], [0.5, 1.0], [1.0, -1.0], [1.5, 1.0], [2.0, 0.0]])
    cfg = PlannerConfig(shortcut_iterations=20)
    a = shortcut(world, zigzag, cfg, np.random.default_rng(0))
    b = shortcut(world, zigzag, cfg, np.random.default_rng(0))
    assert np.array_equal(a, b)
    np.testing.assert_array_equal(a, zigzag[[0, -1]])


def test_shortcut_keeps_needed_corner_and_never_increases_cost() -> None:
    world = BoxWorld([("block", [0.5, -3.0], [1.5, 1.0])])
    detour = np.array([[0.0, 0.0], [0.0, 1.5], [0.5, 1.5], [1.0, 1.5], [2.0, 1.5], [2.0, 0.0]])
    out = shortcut(world, detour, PlannerConfig(shortcut_iterations=0), np.random.default_rng(0))
    assert path_cost(out) <= path_cost(detour)
    assert len(out) == 4  # the collinear waypoints go; the two corners around the block stay
    assert_truly_valid(world, out)


def test_lazy_shortcuts_past_a_wall_thinner_than_the_coarse_spacing_are_caught_at_the_resolution(
        caplog: pytest.LogCaptureFixture) -> None:
    """A wall 0.015 rad thick, thinner than the 0.08 rad of the coarse check, stands inside the corner of a path
    that goes over it: shortcuts across the corner pass the coarse check, fail when the result is completed at 0.01
    rad, and are redone; the path returned keeps over the wall (truly valid), and its cost does not grow."""
    world = BoxWorld([("thin", [0.995, -2.0], [1.01, 0.9])])
    corner = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]])
    caplog.set_level(logging.DEBUG, logger="pickplace.motion.planning")
    for seed in range(5):
        world.checked = 0
        out = shortcut(world, corner, PlannerConfig(shortcut_iterations=30), np.random.default_rng(seed))
        assert path_cost(out) <= path_cost(corner)
        assert_truly_valid(world, out)
        top = out[np.argmin(np.abs(out[:, 0] - 1.0))]
        assert top[1] > 0.9  # (the wall's top)
    assert "failed at the resolution" in caplog.text  # the coarse check let a shortcut through; the completion not
    coarse_only = BoxWorld([("thin", [0.995, -2.0], [1.01, 0.9])])
    qa, qb = np.array([0.5, 0.5]), np.array([1.5, 0.5])  # crosses the wall: 100 steps; coarse points every 8
    assert not segment_valid(coarse_only, qa, qb, 0.01)
    assert coarse_only.are_valid(qa + np.arange(0, 101, 8)[:, None] / 100 * (qb - qa)).all()


def test_segment_and_path_valid_detect_thin_wall() -> None:
    world = BoxWorld([("thin", [0.5, -1.0], [0.515, 1.0])])
    qa, qb = np.array([0.0, 0.0]), np.array([1.0, 0.0])
    assert not segment_valid(world, qa, qb, 0.01)
    assert not path_valid(world, np.array([qa, [0.7, 0.0], qb]), 0.01)
    assert segment_valid(world, qa, np.array([0.4, 0.3]), 0.01)


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("planner.step_size_rad", {"step_size_rad": -0.1}),
        ("planner.step_size_rad", {"step_size_rad": float("nan")}),
        ("planner.iterations", {"iterations": 0}),
        ("planner.goal_bias", {"goal_bias": 1.5}),
        ("planner.edge_resolution_rad", {"edge_resolution_rad": 0.0}),
        ("planner.time_budget_s", {"time_budget_s": float("inf")}),
        ("planner.seed", {"seed": -1}),
        ("planner.stop_at_first_solution", {"stop_at_first_solution": "yes"}),
        ("planner.search", {"search": "prm"}),
        ("planner.shortcut_min_gain_ratio", {"shortcut_min_gain_ratio": -0.1}),
    ],
)
def test_bad_config_names_field(field: str, kwargs: dict[str, object]) -> None:
    with pytest.raises(ConfigError, match=field) as info:
        PlannerConfig(**kwargs)  # type: ignore[arg-type]
    assert info.value.field == field


# --------------------------------------------------------------------------- #
# the lazy bidirectional search (RRT-Connect + pull), on random problems
# --------------------------------------------------------------------------- #


def random_walls(seed: int, dim: int) -> tuple[BoxWorld, np.ndarray, np.ndarray]:
    """A seeded random problem that always has a solution: one or two walls across joint 0, each 0.02-0.2 rad thick
    (mostly thinner than the 0.4 rad step, so a search that checked only its nodes would step through them), each
    with a gap 0.6-1 rad wide along joint 1 at a random place; start and goal on either side. Solvable within the
    joint bounds (±π): the tests sample there (not in the box around start and goal, which may miss a gap)."""
    rng = np.random.default_rng(seed)
    boxes = []
    xs = np.sort(rng.uniform(-1.5, 1.5, rng.integers(1, 3)))
    for w, x in enumerate(xs):
        thick, gap, at = rng.uniform(0.02, 0.2), rng.uniform(0.6, 1.0), rng.uniform(-2.0, 1.0)
        rest_lo, rest_hi = [-10.0] * (dim - 2), [10.0] * (dim - 2)
        boxes.append((f"wall{w}_below", [x, -10.0, *rest_lo], [x + thick, at, *rest_hi]))
        boxes.append((f"wall{w}_above", [x, at + gap, *rest_lo], [x + thick, 10.0, *rest_hi]))
    start = np.concatenate([[-2.8], rng.uniform(-2.5, 2.5, dim - 1)])
    goal = np.concatenate([[2.8], rng.uniform(-2.5, 2.5, dim - 1)])
    return BoxWorld(boxes), start, goal


RANDOM_CASES = [(seed, dim) for dim in (2, 3, 6) for seed in range(6)]


@pytest.mark.parametrize(("seed", "dim"), RANDOM_CASES)
def test_lazy_search_returns_paths_valid_at_the_resolution(seed: int, dim: int) -> None:
    """Whatever the lazy search skipped while growing, the path it returns was checked: the tree path exactly at the
    edge resolution (path_valid visits the very configurations the planner checked), the shortcut path within half
    the resolution of checked configurations (pieces of checked segments), both re-checked independently."""
    world, start, goal = random_walls(seed, dim)
    lo, hi = np.full(dim, -PI), np.full(dim, PI)
    assert world.is_valid(start) and world.is_valid(goal)
    res = plan(world, start, goal, lo, hi, PlannerConfig(seed=seed, time_budget_s=60.0, sample_in_box=False))
    assert res.status is (PlanStatus.DIRECT if segment_valid(world, start, goal, 0.01) else PlanStatus.SOLVED)
    for path in (res.path_raw, res.path):
        np.testing.assert_array_equal(path[0], start)
        np.testing.assert_array_equal(path[-1], goal)
        assert np.all(path >= lo) and np.all(path <= hi)
    assert path_valid(world, res.path_raw, 0.01)
    for path in (res.path_raw, res.path):
        assert_within_half_resolution_of_valid(world, path)
    assert res.cost_rad <= res.cost_raw_rad + 1e-12


@pytest.mark.parametrize(("seed", "dim"), RANDOM_CASES[::4])
@pytest.mark.parametrize("search", SEARCHES)
def test_the_same_seed_gives_the_same_path_bit_for_bit(seed: int, dim: int, search: str) -> None:
    world, start, goal = random_walls(seed, dim)
    lo, hi = np.full(dim, -PI), np.full(dim, PI)
    runs = [plan(world, start, goal, lo, hi, PlannerConfig(seed=s, time_budget_s=60.0, sample_in_box=False,
                                                           search=search)) for s in (seed, seed, seed + 1)]
    assert runs[0].path_raw.tobytes() == runs[1].path_raw.tobytes()
    assert runs[0].path.tobytes() == runs[1].path.tobytes()
    assert (runs[0].iterations, runs[0].nodes) == (runs[1].iterations, runs[1].nodes)
    assert runs[0].path_raw.shape != runs[2].path_raw.shape or not np.array_equal(runs[0].path_raw, runs[2].path_raw)


@pytest.mark.parametrize("search", SEARCHES)
def test_both_searches_go_through_the_6d_wall(search: str) -> None:
    world = wall_6d()
    res = plan(world, START6, GOAL6, LO6, HI6, PlannerConfig(seed=1, time_budget_s=30.0, search=search))
    assert res.status is PlanStatus.SOLVED
    assert_truly_valid(world, res.path)
    gap = (res.path[:, 1] > 0.5) & (res.path[:, 1] < 1.0)
    assert gap.any()  # some waypoint lies in the gap of the wall


class StoppingWorld(BoxWorld):
    """A BoxWorld whose batch checks stop at the first invalid configuration and count only what they checked,
    as the MuJoCo checker does (``first_invalid``)."""

    def first_invalid(self, qs: np.ndarray) -> int:
        qs = np.atleast_2d(qs)
        bad = np.flatnonzero(self._inside(qs).any(axis=1))
        k = int(bad[0]) if bad.size else -1
        self.checked += k + 1 if k >= 0 else len(qs)
        return k

    def all_valid(self, qs: np.ndarray) -> bool:
        return self.first_invalid(qs) < 0


def test_lazy_search_checks_fewer_configurations_than_rrt_star() -> None:
    """On the 6-D wall, the lazy search spends fewer checks than the eager RRT* for a path as short after
    shortcutting (both seeded; a property of the algorithms on this problem, not of one CPU: counts summed over
    five seeds, with a wide margin)."""
    checks, costs = {}, {}
    for search in SEARCHES:
        checks[search], costs[search] = 0, []
        for seed in range(5):
            world = StoppingWorld([(n, list(lo), list(hi)) for n, lo, hi in zip(wall_6d().names, wall_6d().lo,
                                                                                 wall_6d().hi, strict=True)])
            res = plan(world, START6, GOAL6, LO6, HI6, PlannerConfig(seed=seed, time_budget_s=30.0, search=search))
            checks[search] += world.checked
            costs[search].append(res.cost_rad)
    print(f"\nchecks over five seeds: {checks}; median cost {np.median(costs['connect']):.3f} (connect), "
          f"{np.median(costs['rrtstar']):.3f} (rrtstar)")
    assert checks["connect"] < 0.7 * checks["rrtstar"]
    assert np.median(costs["connect"]) < 1.1 * np.median(costs["rrtstar"])


class CountingWorld(BoxWorld):
    """A BoxWorld that records every configuration it checks."""

    def __init__(self, boxes: list[tuple[str, list[float], list[float]]]) -> None:
        super().__init__(boxes)
        self.seen: list[np.ndarray] = []

    def are_valid(self, qs: np.ndarray) -> np.ndarray:
        self.seen.extend(np.atleast_2d(qs))
        return super().are_valid(qs)


def test_pull_keeps_the_farthest_visible_waypoints() -> None:
    world = CountingWorld([("block", [0.9, -1.0], [1.1, 0.5])])
    path = np.array([[0.0, 0.0], [0.5, 0.4], [0.8, 0.7], [1.2, 0.7], [1.5, 0.4], [2.0, 0.0], [2.5, 0.1]])
    taut, bad, _ = pull(world, path, 0.01)
    assert bad == -1 and taut is not None
    # the block hides the last waypoint from the start, not waypoint 3 (the segment to it passes over the block,
    # 2.5 cm above its top), which sees the last one
    np.testing.assert_array_equal(taut, path[[0, 3, 6]])
    # no waypoint is checked again: they are valid by contract
    assert not any(np.array_equal(q, w) for q in world.seen for w in path)
    assert_truly_valid(world, taut)


def test_pull_reports_an_invalid_edge_and_skips_known_ones() -> None:
    world = CountingWorld([("thin", [0.99, -1.0], [1.01, 1.0])])
    path = np.array([[0.0, 0.0], [0.5, 0.0], [1.5, 0.0], [2.0, 0.0]])  # edge 1 crosses the thin wall
    taut, bad, valid = pull(world, path, 0.01)
    assert taut is None and bad == 1 and valid == [0]
    checked = len(world.seen)
    world.seen.clear()
    _, bad, valid = pull(world, path, 0.01, known=[True, False, True])
    assert bad == 1 and valid == []
    assert checked - len(world.seen) == 49  # the interior of edge 0 (0.5 rad every 0.01 rad) was not checked again
    free = np.array([[0.0, 0.0], [0.3, 0.5], [0.6, -0.5], [0.9, 0.5], [1.2, 0.0]])
    taut, bad, _ = pull(BoxWorld([("far", [5.0, 5.0], [6.0, 6.0])]), free, 0.01)
    np.testing.assert_array_equal(taut, free[[0, -1]])


class StoppingCountingWorld(StoppingWorld):
    """A StoppingWorld that records every configuration it checks (up to the first invalid one of a batch)."""

    def __init__(self, boxes: list[tuple[str, list[float], list[float]]]) -> None:
        super().__init__(boxes)
        self.seen: list[np.ndarray] = []

    def first_invalid(self, qs: np.ndarray) -> int:
        qs = np.atleast_2d(qs)
        k = super().first_invalid(qs)
        self.seen.extend(qs if k < 0 else qs[: k + 1])
        return k


def test_pull_checks_no_configuration_twice_and_checks_what_it_keeps_at_the_resolution() -> None:
    """The pull looks at candidates coarsely, farthest first, then checks the one it keeps at the resolution: each
    configuration is checked at most once, the kept segments' every configuration at the resolution is among those
    checked, and the far waypoints hidden behind a wall thinner than the coarse spacing (0.015 against 0.08 rad)
    are not kept."""
    world = StoppingCountingWorld([("thin", [1.02, 0.2], [1.035, 2.0])])  # hides the far waypoints from the start
    path = np.array([[0.0, 0.0], [0.6, 0.1], [1.2, 0.1], [1.6, 0.5], [2.0, 1.0]])
    taut, bad, _ = pull(world, path, 0.01)
    assert bad == -1 and taut is not None
    seen = np.array(world.seen)
    assert len(np.unique(seen, axis=0)) == len(seen)  # nothing checked twice
    for qa, qb in itertools.pairwise(taut):
        steps = math.ceil(float(np.abs(qb - qa).max()) / 0.01)
        for k in range(1, steps):
            assert np.any(np.all(np.isclose(seen, qa + k / steps * (qb - qa), rtol=0.0, atol=1e-12), axis=1))
    assert_truly_valid(world, taut)
    assert not segment_valid(world, path[0], path[4], 0.01)  # (the far waypoint is hidden, by 0.015 rad)


def thin_walls(seed: int, dim: int) -> tuple[StoppingCountingWorld, np.ndarray, np.ndarray]:
    """random_walls with walls 0.012 to 0.05 rad thick, thinner than the coarse spacing of the lazy checks
    (0.08 rad), in a world that records what it checks."""
    rng = np.random.default_rng(1000 + seed)
    boxes = []
    for w, x in enumerate(np.sort(rng.uniform(-1.5, 1.5, rng.integers(1, 4)))):
        thick, gap, at = rng.uniform(0.012, 0.05), rng.uniform(0.5, 0.9), rng.uniform(-2.0, 1.0)
        rest_lo, rest_hi = [-10.0] * (dim - 2), [10.0] * (dim - 2)
        boxes.append((f"wall{w}_below", [x, -10.0, *rest_lo], [x + thick, at, *rest_hi]))
        boxes.append((f"wall{w}_above", [x, at + gap, *rest_lo], [x + thick, 10.0, *rest_hi]))
    start = np.concatenate([[-2.8], rng.uniform(-2.5, 2.5, dim - 1)])
    goal = np.concatenate([[2.8], rng.uniform(-2.5, 2.5, dim - 1)])
    return StoppingCountingWorld(boxes), start, goal


@pytest.mark.parametrize(("seed", "dim"), [(seed, dim) for dim in (2, 3, 6) for seed in (0, 2, 3, 5, 6, 7)])
def test_connect_checks_its_path_on_the_very_configurations_a_recheck_visits(seed: int, dim: int) -> None:
    """RRT-Connect pulls and shortcuts lazily, past walls thinner than its coarse spacing: every segment of the path
    it returns (also as path_raw) was checked on exactly the configurations path_valid visits at the resolution
    (not only within half the resolution of checked ones), and the path is valid when re-checked densely."""
    world, start, goal = thin_walls(seed, dim)
    lo, hi = np.full(dim, -PI), np.full(dim, PI)
    assert world.is_valid(start) and world.is_valid(goal)
    res = plan(world, start, goal, lo, hi, PlannerConfig(seed=seed, time_budget_s=60.0, sample_in_box=False))
    np.testing.assert_array_equal(res.path_raw, res.path)
    if res.status is PlanStatus.DIRECT:
        return
    seen = {q.tobytes() for q in world.seen}
    for qa, qb in itertools.pairwise(res.path):
        steps = math.ceil(float(np.abs(qb - qa).max()) / 0.01)
        for k in range(1, steps):
            assert (qa + k / steps * (qb - qa)).tobytes() in seen, (k, steps)  # (the planner's very arithmetic)
    assert_truly_valid(world, res.path)
    assert res.cost_rad == pytest.approx(path_cost(res.path))
