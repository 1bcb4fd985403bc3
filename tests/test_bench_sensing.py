"""The sensing benchmark: its grid, its aggregation, its errors on bad options, and one tiny run of real episodes.

No assertion depends on one CPU's floating point or on timings: the tiny run checks structure and ranges only.
"""

from __future__ import annotations

import json
import math

import pytest

from pickplace.errors import ConfigError
from pickplace.eval.bench import sensing as bench
from pickplace.perception.camera import CameraConfig


def test_grid_is_sorted_shares_the_default_point_and_scales_both_sigmas() -> None:
    cfg = bench.SensingBenchConfig(subpixel_px=(0.32, 0.08, 0.08), calibration_scales=(2.0, 0.0, 1.0), trials=1)
    assert cfg.subpixel_px == (0.08, 0.32)
    assert cfg.calibration_scales == (0.0, 1.0, 2.0)
    points = cfg.points()
    assert points["depth_noise"] == ((0.08, 1.0), (0.32, 1.0))
    assert points["calibration"] == ((0.08, 0.0), (0.08, 1.0), (0.08, 2.0))
    assert len(cfg.distinct_points()) == 4  # (0.08, x1) is run once for both sweeps
    cam, base = cfg.camera_at(0.32, 2.0), CameraConfig()
    assert cam.subpixel_px == 0.32
    assert cam.calibration_position_sigma_m == pytest.approx(2 * base.calibration_position_sigma_m)
    assert cam.calibration_angle_sigma_rad == pytest.approx(2 * base.calibration_angle_sigma_rad)
    assert cfg.camera_at(0.08, 0.0).calibration_position_sigma_m == 0.0


def test_trials_are_paired_across_grid_points() -> None:
    """Trial i has the same scene and seed at every point; only the camera differs."""
    cfg = bench.SensingBenchConfig(subpixel_px=(0.08, 0.32), calibration_scales=(1.0,), trials=3)
    trials, where = bench.make_trials(cfg)
    assert len(trials) == 6 and set(where.values()) == {(0.08, 1.0), (0.32, 1.0)}
    by_point: dict[tuple[float, float], list] = {}
    for t in sorted(trials, key=lambda t: t.index):
        by_point.setdefault(where[t.index], []).append(t)
    a, b = by_point[(0.08, 1.0)], by_point[(0.32, 1.0)]
    for ta, tb in zip(a, b, strict=True):
        assert ta.seed == tb.seed
        assert ta.config.scene == tb.config.scene
        assert ta.config.profile.realistic and tb.config.profile.realistic
        assert (ta.config.profile.camera.subpixel_px, tb.config.profile.camera.subpixel_px) == (0.08, 0.32)
    assert len({t.seed for t in a}) == 3  # the trials differ from each other


def test_summary_of_lines() -> None:
    """Place error over successes only; estimates of every trial; worker failures counted; Wilson interval."""
    ok = {"trial": 0, "success": True, "place_error_xy_m": 0.003, "wall_time_s": 5.0, "failure_phase": None,
          "failure_kind": None, "pose_estimates": [["IDLE", "resting", 0.004, -0.01], ["DESCEND_PLACE", "in hand",
                                                                                      0.001, 0.002]]}
    bad = {"trial": 1, "success": False, "place_error_xy_m": 0.05, "wall_time_s": 7.0, "failure_phase": "RELEASE",
           "failure_kind": "PlaceFailed", "pose_estimates": [["IDLE", "resting", 0.008, 0.02]]}
    crashed = {"trial": 2, "success": False, "place_error_xy_m": None, "wall_time_s": 1.0, "failure_phase": "WORKER",
               "failure_kind": "WorkerCrashed", "pose_estimates": None}
    p = bench.summarize_point([ok, bad, crashed], CameraConfig(), 1.0, 0.8)
    assert (p.trials, p.successes, p.worker_failures) == (3, 1, 1)
    assert p.success_rate == pytest.approx(1 / 3)
    assert 0.0 < p.success_rate_ci95[0] < 1 / 3 < p.success_rate_ci95[1] < 1.0
    assert p.place_error_xy_m.n == 1 and p.place_error_xy_m.rms == pytest.approx(0.003)
    assert p.estimate_position_error_m["resting"].n == 2
    assert p.estimate_position_error_m["resting"].max == pytest.approx(0.008)
    assert p.estimate_yaw_error_rad["resting"].max == pytest.approx(0.02)  # absolute values
    assert p.estimate_position_error_m["in hand"].n == 1
    assert p.failures == {"RELEASE: PlaceFailed": 1, "WORKER: WorkerCrashed": 1}
    assert set(p.failure_examples) == set(p.failures)
    assert p.failure_examples["RELEASE: PlaceFailed"].startswith("trial 1:")
    assert p.depth_sigma_m == pytest.approx(0.8**2 * 0.08 / (CameraConfig().focal_px * 0.05))


@pytest.mark.parametrize(("changes", "field"), [
    ({"trials": -1}, "sensing.trials"),
    ({"workers": 0}, "sensing.workers"),
    ({"subpixel_px": ()}, "sensing.subpixel_px"),
    ({"subpixel_px": (0.08, 3.0)}, "sensing.subpixel_px[1]"),
    ({"calibration_scales": (-1.0,)}, "sensing.calibration_scales[0]"),
])
def test_bad_config_names_the_field(changes: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        bench.SensingBenchConfig(**changes)
    assert info.value.field == field


@pytest.mark.parametrize(("argv", "option"), [
    (["--trials", "-3"], "--trials"),
    (["--workers", "0"], "--workers"),
    (["--subpixel-px", "-0.1"], "--subpixel-px"),
    (["--calibration-scale", "100"], "--calibration-scale"),
    (["--plot", "out.pdf"], "--plot"),
])
def test_bad_option_is_a_clear_error(argv: list[str], option: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        bench.main(argv)
    assert info.value.code == 2
    assert option in capsys.readouterr().err


@pytest.mark.slow  # two whole realistic episodes (~11 s); the summary logic above is tested without them
def test_quick_run(tmp_path) -> None:
    """Two grid points x 1 trial of real realistic episodes, on 2 spawned workers."""
    cfg = bench.SensingBenchConfig(subpixel_px=(0.08, 0.32), calibration_scales=(1.0,), trials=1, workers=2)
    seen: list[int] = []
    result = bench.run(cfg, on_result=lambda line: seen.append(line["trial"]))
    assert sorted(seen) == [0, 1] and result.episodes == 2
    assert [p.subpixel_px for p in result.sweeps["depth_noise"]] == [0.08, 0.32]
    assert [p.calibration_scale for p in result.sweeps["calibration"]] == [1.0]
    assert result.sweeps["calibration"][0] is result.sweeps["depth_noise"][0]  # the shared default point
    for p in result.sweeps["depth_noise"]:
        assert p.trials == 1 and 0 <= p.successes <= 1
        assert 0.0 <= p.success_rate <= 1.0
        assert 0.0 <= p.success_rate_ci95[0] <= p.success_rate <= p.success_rate_ci95[1] <= 1.0
        assert p.place_error_xy_m.n == p.successes
        if p.successes:
            assert math.isfinite(p.place_error_xy_m.rms) and 0.0 <= p.place_error_xy_m.rms < 0.05
            assert p.estimate_position_error_m["resting"].n >= 1  # the first look, at least
            assert 0.0 <= p.estimate_position_error_m["resting"].p95 < 0.05
        assert p.worker_failures == 0, p.failures
    a, b = result.sweeps["depth_noise"]
    assert a.depth_sigma_m < b.depth_sigma_m
    data = json.loads(json.dumps(result.to_dict()))
    assert data["grid"]["distinct_points"] == [[0.08, 1.0], [0.32, 1.0]]
    assert data["camera_defaults"]["subpixel_px"] == 0.08 and "machine" in data and "conditions" in data
    out = bench.write_plot(result, tmp_path / "sensing.png")
    assert out.stat().st_size > 10_000
