"""The planning benchmark compares like with like: its box rows give OMPL exactly the box pickplace samples in.

No assertion here depends on timings or on one CPU's floating point: the box is compared with its definition
(plain IEEE arithmetic, correctly rounded everywhere), and the sampling test draws from a seeded PCG64.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from pickplace.errors import ConfigError, PlanningFailed
from pickplace.eval.bench import planning as bench
from pickplace.motion import planning


class _RecordingChecker:
    """Valid only at the two ends; records every configuration checked one at a time."""

    def __init__(self, start: np.ndarray, goal: np.ndarray) -> None:
        self.ends = (start, goal)
        self.seen: list[np.ndarray] = []

    def is_valid(self, q: np.ndarray) -> bool:
        self.seen.append(np.array(q, dtype=float))
        return any(np.array_equal(q, end) for end in self.ends)

    def are_valid(self, qs: np.ndarray) -> np.ndarray:
        return np.array([any(np.array_equal(q, end) for end in self.ends) for q in qs], dtype=bool)

    def all_valid(self, qs: np.ndarray) -> bool:
        return bool(self.are_valid(qs).all())

    def colliding_pairs(self, q: np.ndarray) -> list[tuple[str, str]]:
        return []


def _box_by_definition(start: list[float], goal: list[float], lower: list[float], upper: list[float],
                       margin: float) -> tuple[list[float], list[float]]:
    """pickplace's sampling box, joint by joint in plain Python floats."""
    lo = [max(lj, min(s, g) - margin) for s, g, lj in zip(start, goal, lower, strict=True)]
    hi = [min(uj, max(s, g) + margin) for s, g, uj in zip(start, goal, upper, strict=True)]
    return lo, hi


def test_sampling_box_is_the_region_pickplace_samples() -> None:
    """Every configuration pickplace's RRT* samples lies in bench.sampling_box, and the samples reach all its faces.

    2-D toy clipped by the joint bounds on two faces (x low, y high); a step of π exceeds every distance from the
    start within the box and the checker rejects everything but the ends, so each sample is checked as drawn.
    """
    start, goal = np.array([0.0, 0.0]), np.array([0.5, 2.0])
    lower, upper = np.array([-0.8, -3.0]), np.array([3.0, 2.5])
    cfg = replace(bench.PICKPLACE_CONFIG, goal_bias=0.0, step_size_rad=math.pi, iterations=300, time_budget_s=60.0)
    lo, hi = bench.sampling_box(start, goal, lower, upper, cfg)
    assert lo.tolist() == [-0.8, -1.0] and hi.tolist() == [1.5, 2.5]  # margin 1 rad, clipped on two faces
    assert float(np.linalg.norm(np.maximum(np.abs(lo - start), np.abs(hi - start)))) < cfg.step_size_rad
    checker = _RecordingChecker(start, goal)
    with pytest.raises(PlanningFailed):
        planning.plan(checker, start, goal, lower, upper, cfg)
    samples = np.array(checker.seen[2:])  # after the start and goal validity checks
    assert len(samples) == cfg.iterations
    tol = 1e-12
    assert np.all(samples >= lo - tol) and np.all(samples <= hi + tol)
    span = hi - lo
    assert np.all(samples.min(axis=0) - lo < 0.03 * span) and np.all(hi - samples.max(axis=0) < 0.03 * span)


def test_sampling_box_follows_the_config_and_contains_the_ends() -> None:
    start, goal = np.array([0.1, -6.0, 3.0]), np.array([0.3, -5.9, 2.0])
    lower, upper = np.array([-2 * np.pi, -2 * np.pi, -np.pi]), np.array([2 * np.pi, 2 * np.pi, np.pi])
    lo, hi = bench.sampling_box(start, goal, lower, upper)
    want = _box_by_definition(start.tolist(), goal.tolist(), lower.tolist(), upper.tolist(), 1.0)
    assert (lo.tolist(), hi.tolist()) == want
    assert lo[1] == lower[1] and hi[2] == upper[2]  # clipped
    assert np.all(lo <= np.minimum(start, goal)) and np.all(hi >= np.maximum(start, goal))
    full = bench.sampling_box(start, goal, lower, upper, replace(bench.PICKPLACE_CONFIG, sample_in_box=False))
    assert full[0].tolist() == lower.tolist() and full[1].tolist() == upper.tolist()
    with pytest.raises(ConfigError, match=r"bench\.goal"):
        bench.sampling_box(start, np.array([0.3, -5.9, 4.0]), lower, upper)  # goal beyond the joint bounds


def test_ompl_space_has_exactly_the_requested_bounds() -> None:
    pytest.importorskip("ompl")
    ompl = bench.load_ompl(True)
    assert ompl is not None
    start, goal = np.array([0.1, -6.0, 3.0, 0.2, 0.0, 1.0]), np.array([0.3, -5.9, 2.0, 0.1, -0.5, 1.1])
    lower, upper = np.full(6, -2 * np.pi), np.full(6, 2 * np.pi)
    lo, hi = bench.sampling_box(start, goal, lower, upper)
    space = bench.ompl_space(ompl, lo, hi)
    bounds = space.getBounds()
    assert list(bounds.low) == lo.tolist() and list(bounds.high) == hi.tolist()
    for q in (start, goal):
        state = space.allocState()
        for j in range(6):
            state[j] = float(q[j])
        assert space.satisfiesBounds(state)


def test_json_rows_say_where_each_planner_samples(capsys: pytest.CaptureFixture[str]) -> None:
    """One short query per row: the box rows report exactly pickplace's box, the others the joint bounds."""
    pytest.importorskip("ompl")
    assert bench.main(["--json", "--queries", "1", "--budget", "0.05"]) == 0
    result = json.loads(capsys.readouterr().out)
    margin = result["pickplace"]["box_margin_rad"]
    assert margin == planning.PlannerConfig().box_margin_rad
    names = ["pickplace", "ompl-rrtconnect", "ompl-rrtconnect-box", "ompl-rrtstar", "ompl-rrtstar-box"]
    assert [seg["scene"] for seg in result["segments"]] == ["default", "default", "obstacle", "obstacle", "shelf",
                                                            "cage", "bins", "slot"]
    for seg in result["segments"]:
        rows = {r["planner"]: r for r in result["rows"]
                if (r["scene"], r["segment"]) == (seg["scene"], seg["segment"])}
        assert list(rows) == names
        box = _box_by_definition(seg["start_rad"], seg["goal_rad"], seg["joint_lower_rad"],
                                 seg["joint_upper_rad"], margin)
        full = (seg["joint_lower_rad"], seg["joint_upper_rad"])
        for name, row in rows.items():
            in_box = name == "pickplace" or name.endswith("-box")
            assert row["sampling"] == (bench.SAMPLING_BOX if in_box else bench.SAMPLING_FULL)
            assert (row["sampling_lower_rad"], row["sampling_upper_rad"]) == (box if in_box else full)
            lo, hi = np.array(row["sampling_lower_rad"]), np.array(row["sampling_upper_rad"])
            for q in (np.array(seg["start_rad"]), np.array(seg["goal_rad"])):
                assert np.all(lo <= q) and np.all(q <= hi)
        for key, _, _ in bench.RATIOS:
            assert key in rows["pickplace"]
    assert result["sampling"]["ompl-rrtstar-box"] == "box ±1 rad around start/goal"
    assert result["sampling"]["ompl-rrtstar"] == "full joint bounds"


def test_scenes_can_be_chosen_and_unknown_ones_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    """``--scenes`` runs only the named scenes (here one harder problem, pickplace alone) and names the valid ones
    when given an unknown one."""
    assert bench.main(["--json", "--queries", "1", "--budget", "30", "--no-ompl", "--scenes", "slot"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert [(r["scene"], r["planner"]) for r in result["rows"]] == [("slot", "pickplace")]
    assert result["rows"][0]["success_rate"] == 1.0 and result["rows"][0]["dense_valid_rate"] == 1.0
    assert result["pickplace"]["search"] == "connect"
    with pytest.raises(SystemExit):
        bench.main(["--scenes", "kitchen"])
    assert "choose from default, obstacle, shelf, cage, bins, slot" in capsys.readouterr().err


def test_anytime_planners_run_after_the_others_and_the_first_planner_rotates() -> None:
    """The planners that stop at their first solution take turns, the first rotating from seed to seed, and the RRT*
    rows (which spend their whole budget and fill the caches) run after them, so that no planner always follows
    them."""
    runners = [(spec, spec.name) for spec in (bench.PICKPLACE, *bench.OMPL_PLANNERS)]
    groups = bench.query_groups(runners)  # type: ignore[arg-type]
    assert [[spec.name for spec, _ in g] for g in groups] == [
        ["pickplace", "ompl-rrtconnect", "ompl-rrtconnect-box"], ["ompl-rrtstar", "ompl-rrtstar-box"]]
    firsts = [bench.rotated(groups[0], seed)[0][0].name for seed in range(6)]
    assert firsts == ["pickplace", "ompl-rrtconnect", "ompl-rrtconnect-box"] * 2
    assert all(sorted(s.name for s, _ in bench.rotated(groups[0], seed)) == sorted(s.name for s, _ in groups[0])
               for seed in range(6))
    assert bench.query_groups(runners[:1]) == [runners[:1]]  # --no-ompl: pickplace alone
