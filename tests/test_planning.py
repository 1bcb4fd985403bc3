"""Tests of the RRT* planner and shortcutting against toy configuration-space checkers."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from pickplace.errors import ConfigError, PlanningFailed, SearchExhausted
from pickplace.motion.planning import (
    PlannerConfig,
    PlanStatus,
    ValidityChecker,
    path_cost,
    path_valid,
    plan,
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
    assert res.nodes <= res.iterations + 2


def test_maze_2d_solved() -> None:
    world = maze_2d()
    res = plan(world, START2, GOAL2, LO2, HI2, PlannerConfig(seed=1, time_budget_s=30.0))
    assert res.status is PlanStatus.SOLVED
    assert_truly_valid(world, res.path_raw)
    assert_truly_valid(world, res.path)
    assert res.cost_rad <= res.cost_raw_rad
    assert len(res.path) <= 8  # two corners, each usually rounded by two waypoints


def test_anytime_improves_2d() -> None:
    world = maze_2d()
    first = plan(world, START2, GOAL2, LO2, HI2, PlannerConfig(seed=2, time_budget_s=30.0))
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
    walls = [("left", [0.8, 0.8], [1.0, 2.2]), ("right", [2.0, 0.8], [2.2, 2.2]),
             ("bottom", [0.8, 0.8], [2.2, 1.0]), ("top", [0.8, 2.0], [2.2, 2.2])]
    cfg = PlannerConfig(iterations=300, time_budget_s=5.0)
    with pytest.raises(PlanningFailed, match=r"300 of 300 iterations.*tree of \d+ nodes"):
        plan(BoxWorld(walls), START2, np.array([1.5, 1.5]), LO2, HI2, cfg)


def test_time_budget_stops_search() -> None:
    cfg = PlannerConfig(iterations=1_000_000, time_budget_s=0.05, step_size_rad=0.01)
    with pytest.raises(PlanningFailed, match=r"budget 0\.05 s"):
        plan(maze_2d(), START2, GOAL2, LO2, HI2, cfg)


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
    ],
)
def test_bad_config_names_field(field: str, kwargs: dict[str, object]) -> None:
    with pytest.raises(ConfigError, match=field) as info:
        PlannerConfig(**kwargs)  # type: ignore[arg-type]
    assert info.value.field == field
