"""The environment benchmark (``pickplace bench env``): a tiny run through the CLI whose figures are positive and
finite, the comparison with robosuite skipped with its reason when there is no robosuite Python (or when it cannot
import robosuite), the ratios' arithmetic, and, where ``make bench-env`` has made robosuite's venv, a tiny
comparison.

No assertion depends on a timing's value: the machine is shared; only signs, finiteness and structure are checked.
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path

import pytest

from pickplace.cli import main
from pickplace.eval.bench import env as bench

pytest.importorskip("gymnasium")  # the environments need it (the gym extra)

ROBOSUITE_PYTHON = Path(__file__).resolve().parents[1] / bench.DEFAULT_ROBOSUITE_PYTHON


def _positive(x: float) -> bool:
    return isinstance(x, float) and math.isfinite(x) and x > 0


def _check_low_level(rows: list[dict], rates: tuple[float, ...], steps_at_20: int) -> None:
    assert [(r["mode"], r["rate_hz"]) for r in rows] == [(m, rate) for rate in rates for m in ("cartesian", "joint")]
    for r in rows:
        assert r["steps"] == max(4, round(steps_at_20 * r["rate_hz"] / 20.0)), r
        for key in ("steps_per_s", "real_time_factor", "physics_steps_per_s", "bare_mj_step_per_s",
                    "cost_vs_bare_mj_step", "reset_s_mean"):
            assert _positive(r[key]), (key, r)
        assert r["physics_steps_per_step"] == round(1000 / r["rate_hz"])  # 1 kHz physics
        # the real-time factor is the steps per second over the rate: both from the same timed steps
        assert r["real_time_factor"] == pytest.approx(r["steps_per_s"] / r["rate_hz"])
        assert len(r["rounds_steps_per_s"]) == 4 and all(_positive(x) for x in r["rounds_steps_per_s"])


def test_cli_json_runs_and_skips_the_comparison_without_robosuite(capsys) -> None:
    assert main(["bench", "env", "--episodes", "1", "--steps", "5", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    _check_low_level(result["low_level"], (20.0, 50.0), 5)
    s = result["skill_level"]
    assert s["episodes"] == 1 and s["seeds"] == [0, 0] and s["successes"] in (0, 1)
    assert _positive(s["steps_per_s"]) and _positive(s["real_time_factor"]) and _positive(s["sim_s"])
    lo, hi = s["wilson95"]
    assert 0.0 <= lo <= s["success_rate"] <= hi <= 1.0
    assert len(s["failures"]) == 1 - s["successes"]
    assert result["robosuite"] is None
    assert "--robosuite" in result["comparison"]["skipped"] and result["comparison"]["ratios"] == []
    assert result["machine"]["cpu_count"] >= 1 and "commit" in result["machine"]


def test_table_says_why_the_comparison_is_skipped(capsys) -> None:
    assert main(["bench", "env", "--episodes", "0", "--steps", "1", "--rounds", "1", "--rate", "20",
                 "--robosuite", "/nonexistent/bin/python"]) == 0
    out = capsys.readouterr().out
    assert "pickplace cartesian 20 Hz" in out and "pickplace joint 20 Hz" in out
    assert "comparison skipped" in out and "/nonexistent/bin/python" in out and "make bench-env" in out


@pytest.mark.skipif(importlib.util.find_spec("robosuite") is not None, reason="robosuite is in pickplace's venv")
def test_a_python_without_robosuite_is_skipped_with_the_import_error() -> None:
    """The worker runs in the given Python; pickplace's own has no robosuite, so the worker reports the import's
    failure and pickplace's figures are still measured."""
    result = bench.run(episodes=0, steps=1, rates_hz=(20.0,), rounds=1, robosuite=sys.executable)
    assert result["robosuite"] is None
    assert "importing robosuite failed" in result["comparison"]["skipped"]
    assert "ModuleNotFoundError" in result["comparison"]["skipped"]
    assert all(_positive(r["steps_per_s"]) for r in result["low_level"])


def test_block_split_covers_every_step() -> None:
    for total, rounds in ((5, 4), (12, 4), (1, 1), (2000, 3)):
        blocks = [bench._block_steps(total, rounds, r) for r in range(rounds)]
        assert sum(blocks) == total and min(blocks) >= 1 and max(blocks) - min(blocks) <= 1


def test_ratios_are_pickplace_over_robosuite_at_the_same_rate() -> None:
    low = [{"mode": "cartesian", "rate_hz": 20.0, "steps_per_s": 100.0, "real_time_factor": 5.0,
            "rounds_steps_per_s": [90.0, 110.0]},
           {"mode": "joint", "rate_hz": 25.0, "steps_per_s": 250.0, "real_time_factor": 10.0,
            "rounds_steps_per_s": [250.0, 250.0]}]
    theirs = [{"rate_hz": 20.0, "steps_per_s": 50.0, "real_time_factor": 2.5, "rounds_steps_per_s": [60.0, 40.0]},
              {"rate_hz": 500.0, "steps_per_s": 1000.0, "real_time_factor": 2.0, "rounds_steps_per_s": [1e3, 1e3]}]
    skill = {"real_time_factor": 5.0, "episodes": 3,  # round 0 ran seed 0 (RTF 9), round 1 seeds 1 and 2 (RTF 4)
             "rows": [{"sim_s": 9.0, "step_wall_s": 1.0}, {"sim_s": 4.0, "step_wall_s": 0.5},
                      {"sim_s": 4.0, "step_wall_s": 1.5}]}
    result = {"low_level": low, "skill_level": skill, "robosuite": {"rates": theirs}}
    comp = bench._comparison(result, None)
    assert comp["skipped"] is None
    rows = {r["pickplace"]: r for r in comp["ratios"]}
    assert set(rows) == {"low level, cartesian, 20 Hz", "skill level"}  # no robosuite at 25 Hz: no ratio
    c = rows["low level, cartesian, 20 Hz"]
    assert c["steps_per_s_ratio"] == pytest.approx(2.0) and c["real_time_factor_ratio"] == pytest.approx(2.0)
    assert c["rounds_min"] == pytest.approx(1.5) and c["rounds_max"] == pytest.approx(2.75)
    assert c["rounds_median"] == pytest.approx((1.5 + 2.75) / 2)
    sk = rows["skill level"]  # against robosuite's 20 Hz rounds: RTF 3 and 2
    assert sk["real_time_factor_ratio"] == pytest.approx(2.0) and sk["steps_per_s_ratio"] is None
    assert (sk["rounds_min"], sk["rounds_median"], sk["rounds_max"]) == pytest.approx((2.0, 2.5, 3.0))
    result["robosuite"] = None
    assert bench._comparison(result, "why")["skipped"] == "why"


@pytest.mark.skipif(not ROBOSUITE_PYTHON.is_file(), reason=f"no {bench.DEFAULT_ROBOSUITE_PYTHON} (make bench-env)")
def test_robosuite_side_by_side() -> None:
    """With robosuite's venv: a tiny interleaved run, robosuite's figures and the ratios positive and finite."""
    result = bench.run(episodes=0, steps=2, rates_hz=(20.0,), rounds=2, robosuite=str(ROBOSUITE_PYTHON),
                       robosuite_rates_hz=(20.0,))
    assert result["comparison"]["skipped"] is None, result["comparison"]["skipped"]
    rs = result["robosuite"]
    assert rs["versions"]["robosuite"].startswith("1.5") and rs["controller"]["arm"] == "OSC_POSE"
    (r,) = rs["rates"]
    assert r["steps"] == 2 and r["physics_steps_per_step"] == 25  # 500 Hz physics under 20 Hz control
    assert _positive(r["steps_per_s"]) and _positive(r["real_time_factor"]) and _positive(r["bare_mj_step_per_s"])
    assert len(result["comparison"]["ratios"]) == 2
    assert all(_positive(x["steps_per_s_ratio"]) for x in result["comparison"]["ratios"])
    assert _positive(rs["engine_cross_check"]["pickplace_mujoco_over_robosuite_mujoco"])
