"""Tests of pickplace.motion.timing: TOPP-RA time scaling of joint-space paths."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pickplace.errors import ConfigError, PickPlaceError, TimingFailed
from pickplace.motion.timing import TimingConfig, Trajectory, retime

PRESETS = {"ur5e": TimingConfig.ur5e(), "design_note": TimingConfig.design_note()}
DT_S = 1e-3  # sampling period of every limit check (s)
LIMIT_TOL = 0.01  # samples may exceed a limit by at most 1 %


def random_path(seed: int) -> np.ndarray:
    """A random-ish UR5e path (N, 6) (rad) with 5-10 waypoints, steps of up to 0.9 rad per joint."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 11))
    start = rng.uniform(-1.5, 1.5, 6)
    return start + np.vstack([np.zeros(6), np.cumsum(rng.uniform(-0.9, 0.9, (n - 1, 6)), axis=0)])


def sample_grid(traj: Trajectory, dt: float = DT_S) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sample at ``dt`` from 0 to the duration, the end included; returns (ts, q, qd, qdd)."""
    ts = np.append(np.arange(0.0, traj.duration_s, dt), traj.duration_s)
    return (ts, *traj.sample_many(ts))


def distance_to_polyline(q: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Euclidean joint-space distance (M,) of each configuration q (M, 6) to the polyline poly (K, 6)."""
    a, d = poly[:-1], np.diff(poly, axis=0)
    f = np.clip(np.einsum("mkj,kj->mk", q[:, None, :] - a, d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    return np.linalg.norm(q[:, None, :] - (a + f[..., None] * d), axis=-1).min(axis=1)


def single_joint_min_time(dist: float, vmax: float, amax: float) -> float:
    """Analytic minimum rest-to-rest time (s) of a double integrator under |v| <= vmax, |a| <= amax."""
    if dist >= vmax**2 / amax:  # trapezoid: reaches vmax
        return dist / vmax + vmax / amax
    return 2.0 * math.sqrt(dist / amax)  # bang-bang triangle


# --------------------------------------------------------------------------- #
# limits, boundary conditions, geometry
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize("preset", sorted(PRESETS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_path_respects_limits_and_boundaries(preset: str, seed: int, record_property) -> None:
    cfg = PRESETS[preset]
    path = random_path(seed)
    traj = retime(path, cfg)
    assert 0.1 < traj.duration_s < 60.0
    _, q, qd, qdd = sample_grid(traj)
    v_ratio = np.max(np.abs(qd) / np.array(cfg.velocity_limits_rad_s))
    a_ratio = np.max(np.abs(qdd) / np.array(cfg.acceleration_limits_rad_s2))
    record_property("worst_velocity_ratio", float(v_ratio))
    record_property("worst_acceleration_ratio", float(a_ratio))
    assert v_ratio <= 1.0 + LIMIT_TOL
    assert a_ratio <= 1.0 + LIMIT_TOL
    # time-optimal: some joint saturates a limit most of the way, so the peak ratio is close to 1
    assert max(v_ratio, a_ratio) > 0.98
    np.testing.assert_allclose(q[0], path[0], atol=1e-6)
    np.testing.assert_allclose(q[-1], path[-1], atol=1e-6)
    np.testing.assert_allclose(qd[[0, -1]], 0.0, atol=1e-6)
    assert traj.retime_time_s > 0.0
    assert traj.peak_velocity_ratio <= 1.0 + LIMIT_TOL and traj.peak_acceleration_ratio <= 1.0 + LIMIT_TOL


def test_at_rest_outside_and_scalar_sample_matches_sample_many() -> None:
    path = random_path(3)
    traj = retime(path)
    for t, q_expected in [(-1.0, path[0]), (traj.duration_s + 1.0, path[-1])]:
        q, qd, qdd = traj.sample(t)
        assert q.shape == qd.shape == qdd.shape == (6,)
        np.testing.assert_allclose(q, q_expected, atol=1e-9)
        np.testing.assert_array_equal(qd, 0.0)
        np.testing.assert_array_equal(qdd, 0.0)
    ts = np.linspace(0.0, traj.duration_s, 7)
    qs, qds, qdds = traj.sample_many(ts)
    assert qs.shape == (7, 6)
    for k, t in enumerate(ts):
        q, qd, qdd = traj.sample(float(t))
        np.testing.assert_allclose(q, qs[k], atol=1e-12)
        np.testing.assert_allclose(qd, qds[k], atol=1e-12)
        np.testing.assert_allclose(qdd, qdds[k], atol=1e-12)
    np.testing.assert_array_equal(traj.waypoints, path)
    with pytest.raises(ValueError, match="finite"):
        traj.sample_many(np.array([0.0, np.nan]))


def test_velocity_is_derivative_of_position() -> None:
    traj = retime(random_path(4))
    ts, q, qd, _ = sample_grid(traj, dt=1e-4)
    fd = np.diff(q, axis=0) / np.diff(ts)[:, None]
    mid = 0.5 * (qd[:-1] + qd[1:])
    assert np.max(np.abs(fd - mid)[:-1]) < 2e-3  # rad/s; the last step may be shorter than dt


def test_trajectory_passes_through_waypoints_and_hugs_polyline(record_property) -> None:
    path = random_path(5)
    traj = retime(path)
    _, q, _, _ = sample_grid(traj, dt=2e-4)
    dev = distance_to_polyline(q, path)
    record_property("max_deviation_rad", float(dev.max()))
    record_property("reported_max_deviation_rad", traj.max_deviation_rad)
    # the reported figure (same-arc-length distance, sampled) bounds the true distance to the polyline
    assert dev.max() <= traj.max_deviation_rad + 1e-3
    assert traj.max_deviation_rad < 0.05  # rad, with the default max_segment_rad = 0.1
    # every waypoint is a spline knot, so the trajectory passes through it (up to the 0.2 ms sampling)
    for w in path:
        assert np.min(np.linalg.norm(q - w, axis=1)) < 2e-3


def test_sparse_knots_overshoot_more_than_default() -> None:
    path = random_path(5)
    sparse = retime(path, TimingConfig(max_segment_rad=100.0))
    dense = retime(path)
    assert sparse.max_deviation_rad > 3.0 * dense.max_deviation_rad
    assert len(dense.knots) > len(sparse.knots) == len(path)


# --------------------------------------------------------------------------- #
# near-duplicate waypoints
# --------------------------------------------------------------------------- #


def test_near_duplicate_waypoints_give_the_deduplicated_duration() -> None:
    path = random_path(6)
    reference = retime(path).duration_s
    noisy = np.vstack([path[:2], path[1] + 1e-9, path[1], path[2:4], path[3], path[4:], path[-1] + 1e-9])
    noisy[-1] = path[-1]
    noisy = np.vstack([noisy[:1], noisy[:1], noisy])  # repeated start too
    traj = retime(noisy)
    assert math.isfinite(traj.duration_s)
    assert traj.duration_s == pytest.approx(reference, rel=0.01)
    _, q, qd, _ = sample_grid(traj)
    np.testing.assert_allclose(q[-1], path[-1], atol=1e-6)
    np.testing.assert_allclose(qd[[0, -1]], 0.0, atol=1e-6)


def test_endpoint_near_duplicate_keeps_exact_endpoint() -> None:
    path = random_path(7)
    shifted = np.vstack([path, path[-1] + 1e-7])
    traj = retime(shifted)
    np.testing.assert_allclose(traj.sample(traj.duration_s)[0], shifted[-1], atol=1e-9)


@pytest.mark.parametrize("offset", [0.0, 1e-9])
def test_motionless_path_gives_zero_duration_at_rest(offset: float) -> None:
    q0 = np.array([0.1, -1.2, 1.5, -0.3, 1.57, 0.0])
    traj = retime(np.vstack([q0, q0 + offset, q0]))
    assert traj.duration_s == 0.0
    for t in (0.0, 1.0):
        q, qd, qdd = traj.sample(t)
        np.testing.assert_allclose(q, q0, atol=1e-8)
        np.testing.assert_array_equal(qd, 0.0)
        np.testing.assert_array_equal(qdd, 0.0)


def test_closed_loop_path_is_retimed() -> None:
    path = random_path(8)
    loop = np.vstack([path, path[0]])
    traj = retime(loop)
    assert traj.duration_s > 0.5
    np.testing.assert_allclose(traj.sample(traj.duration_s)[0], path[0], atol=1e-6)


# --------------------------------------------------------------------------- #
# time-optimality against analytic minimum times
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize(
    ("preset", "joint", "dist"),
    [("ur5e", 0, 0.3), ("ur5e", 1, 2.5), ("ur5e", 4, -1.0), ("design_note", 5, 3.0),
     ("design_note", 2, 0.05)],
)
def test_single_joint_move_is_time_optimal(preset: str, joint: int, dist: float) -> None:
    cfg = PRESETS[preset]
    start = np.array([0.0, -1.57, 1.2, -1.0, -1.57, 0.5])
    goal = start.copy()
    goal[joint] += dist
    traj = retime(np.vstack([start, goal]), cfg)
    t_min = single_joint_min_time(
        abs(dist), cfg.velocity_limits_rad_s[joint], cfg.acceleration_limits_rad_s2[joint])
    assert t_min * (1 - 1e-6) <= traj.duration_s <= 1.05 * t_min
    assert traj.duration_s <= 1.01 * t_min  # in practice only the 0.5 % limit margin is lost
    _, q, _, _ = sample_grid(traj)
    others = np.delete(np.arange(6), joint)
    assert np.max(np.abs(q[:, others] - start[others])) < 1e-9  # a straight line stays straight


def test_two_point_multi_joint_move_matches_straight_line_optimum() -> None:
    cfg = TimingConfig.ur5e()
    start = np.array([0.0, -1.57, 1.2, -1.0, -1.57, 0.5])
    delta = np.array([1.2, -0.4, 0.8, 2.0, -0.5, 1.0])
    traj = retime(np.vstack([start, start + delta]), cfg)
    length = float(np.linalg.norm(delta))
    unit = np.abs(delta) / length
    v_path = float(np.min(np.array(cfg.velocity_limits_rad_s) / unit))
    a_path = float(np.min(np.array(cfg.acceleration_limits_rad_s2) / unit))
    t_line = single_joint_min_time(length, v_path, a_path)
    lower = max(single_joint_min_time(abs(d), v, a) for d, v, a in
                zip(delta, cfg.velocity_limits_rad_s, cfg.acceleration_limits_rad_s2, strict=True))
    assert traj.duration_s >= lower
    assert t_line * (1 - 1e-6) <= traj.duration_s <= 1.01 * t_line


# --------------------------------------------------------------------------- #
# the is_segment_valid hook
# --------------------------------------------------------------------------- #


def test_hook_rejecting_overshoot_is_fixed_by_densification() -> None:
    # few, far-apart waypoints with sharp corners: the spline cuts the corners
    path = np.array([
        [0.0, -1.5, 1.5, -1.5, -1.5, 0.0],
        [1.2, -0.8, 0.6, -0.5, -1.0, 1.0],
        [0.2, -1.6, 1.8, -1.8, -0.2, 0.2],
        [1.5, -0.6, 0.5, -0.3, -1.6, 1.4],
    ])
    baseline = retime(path)
    base_dev = float(distance_to_polyline(sample_grid(baseline)[1], path).max())
    max_dev = 0.3 * base_dev  # tighter than the default knots achieve: needs >= 2 halvings
    calls: list[np.ndarray] = []

    def is_segment_valid(qs: np.ndarray) -> bool:
        calls.append(qs)
        return bool(distance_to_polyline(qs, path).max() <= max_dev)

    traj = retime(path, is_segment_valid=is_segment_valid)
    assert len(calls) >= 2 and traj.densify_rounds == len(calls) - 1
    assert all(c.ndim == 2 and c.shape[1] == 6 for c in calls)
    steps = np.linalg.norm(np.diff(calls[-1], axis=0), axis=1)
    assert steps.max() < 0.02  # configurations ~0.01 rad apart
    _, q, qd, qdd = sample_grid(traj)
    assert distance_to_polyline(q, path).max() <= max_dev + 1e-3
    assert traj.max_deviation_rad < baseline.max_deviation_rad
    assert traj.duration_s >= baseline.duration_s  # tighter corners cost time
    cfg = TimingConfig()
    assert np.max(np.abs(qdd) / np.array(cfg.acceleration_limits_rad_s2)) <= 1.0 + LIMIT_TOL
    assert np.max(np.abs(qd) / np.array(cfg.velocity_limits_rad_s)) <= 1.0 + LIMIT_TOL


def test_hook_always_rejecting_raises_timing_failed() -> None:
    calls = []

    def never(qs: np.ndarray) -> bool:
        calls.append(len(qs))
        return False

    cfg = TimingConfig(max_densify_rounds=2)
    with pytest.raises(TimingFailed, match="is_segment_valid"):
        retime(random_path(9), cfg, is_segment_valid=never)
    assert len(calls) == 3


def test_solver_failure_raises_timing_failed(monkeypatch: pytest.MonkeyPatch) -> None:
    import toppra.algorithm

    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_trajectory", lambda self, *a, **k: None)
    with pytest.raises(TimingFailed, match="TOPP-RA"):
        retime(random_path(10))


# --------------------------------------------------------------------------- #
# configuration and input validation
# --------------------------------------------------------------------------- #


def test_presets() -> None:
    assert TimingConfig.ur5e() == TimingConfig()
    assert TimingConfig.ur5e().velocity_limits_rad_s == (math.pi,) * 6
    assert TimingConfig.ur5e().acceleration_limits_rad_s2 == (8.0, 8.0, 8.0, 16.0, 16.0, 16.0)
    dn = TimingConfig.design_note()
    assert dn.velocity_limits_rad_s == (3.14, 3.14, 3.14, 6.28, 6.28, 6.28)
    assert dn.acceleration_limits_rad_s2 == TimingConfig().acceleration_limits_rad_s2
    with pytest.raises(dataclasses.FrozenInstanceError):
        dn.limit_margin = 0.1  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"velocity_limits_rad_s": (3.0, 3.0, -1.0, 3.0, 3.0, 3.0)}, "timing.velocity_limits_rad_s[2]"),
        ({"velocity_limits_rad_s": (3.0,) * 5}, "timing.velocity_limits_rad_s"),
        ({"acceleration_limits_rad_s2": (8.0, math.nan, 8.0, 16.0, 16.0, 16.0)},
         "timing.acceleration_limits_rad_s2[1]"),
        ({"acceleration_limits_rad_s2": (8.0,) * 6 + (1.0,)}, "timing.acceleration_limits_rad_s2"),
        ({"velocity_limits_rad_s": (0.0,) * 6}, "timing.velocity_limits_rad_s[0]"),
        ({"limit_margin": -0.1}, "timing.limit_margin"),
        ({"grid_step_rad": 0.0}, "timing.grid_step_rad"),
        ({"max_densify_rounds": 1.5}, "timing.max_densify_rounds"),
    ],
)
def test_bad_config_raises_config_error_naming_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        TimingConfig(**kwargs)
    assert info.value.field == field
    assert field in str(info.value)


@pytest.mark.parametrize(
    ("path", "match"),
    [
        (np.zeros(6), r"path\.shape"),
        (np.zeros((4, 5)), r"path\.shape .*\(N, 6\)"),
        (np.zeros((1, 6)), r"N >= 2"),
        (np.array([[0.0] * 6, [0.1, 0.2, math.nan, 0.0, 0.0, 0.0]]), r"path\[1\].*finite"),
        ("not a path", r"path"),
    ],
)
def test_bad_path_raises_clear_error(path: object, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as info:
        retime(path)  # type: ignore[arg-type]
    assert isinstance(info.value, PickPlaceError) and isinstance(info.value, ValueError)


# --------------------------------------------------------------------------- #
# several parts timed as one motion (retime_parts), offsets blended in while it runs
# --------------------------------------------------------------------------- #


def _corner_parts(speed: float = math.inf, reserve: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A planned part (a straight joint segment) that meets a 'straight move' (20 closely spaced waypoints along a
    gently curved joint path) at a corner of about 60 degrees in joint space."""
    planned = np.array([[0.0, -1.2, 1.0, -1.4, -1.5, 0.0], [0.6, -1.0, 1.2, -1.6, -1.5, 0.1]])
    s = np.linspace(0.0, 1.0, 21)[:, None]
    straight = planned[-1] + s * np.array([0.0, -0.25, 0.45, -0.2, 0.0, 0.0]) + s**2 * np.array([0, 0, 0.02, 0, 0, 0])
    return planned, straight


def test_parts_are_timed_as_one_motion_that_does_not_stop_between_them() -> None:
    """The arm passes the junction moving, within the limits at every 1 ms sample; it is on the junction's waypoint
    when ``part_times_s`` says; the straight part's spline passes through each of its waypoints."""
    from pickplace.motion.timing import PathPart, retime_parts

    cfg = TimingConfig.ur5e()
    planned, straight = _corner_parts()
    traj = retime_parts([PathPart(planned), PathPart(straight, straight=True)], cfg)
    t0, t_join, t_end = traj.part_times_s
    assert t0 == 0.0 and 0.0 < t_join < t_end == traj.duration_s
    q_join, qd_join, _ = traj.sample(t_join)
    np.testing.assert_allclose(q_join, planned[-1], atol=1e-4)
    assert float(np.linalg.norm(qd_join)) > 0.2  # rad/s: moving on, not stopped
    _, q, qd, qdd = sample_grid(traj)
    assert np.max(np.abs(qd) / np.array(cfg.velocity_limits_rad_s)) <= 1.0 + LIMIT_TOL
    assert np.max(np.abs(qdd) / np.array(cfg.acceleration_limits_rad_s2)) <= 1.0 + LIMIT_TOL
    assert np.linalg.norm(q[-1] - straight[-1]) < 1e-6 and np.abs(qd[-1]).max() < 1e-6
    # every waypoint of the straight move is on the trajectory (the spline interpolates them)
    dense = traj.sample_many(np.linspace(t_join, t_end, 4001))[0]
    assert max(float(np.min(np.linalg.norm(dense - w, axis=1))) for w in straight) < 2e-4
    # stopping at the junction instead takes longer
    apart = retime(planned, cfg).duration_s + retime(straight, cfg).duration_s
    assert traj.duration_s < apart - 0.05


def test_a_part_keeps_its_speed_limit_and_its_reserve() -> None:
    """A speed limit along a part bounds its speed there (here the 'tcp' is the joint vector itself: rate |q'|);
    a part with a reserve is timed within that much less of the acceleration limits."""
    from pickplace.motion.timing import PathPart, retime_parts

    cfg = TimingConfig.ur5e()
    planned, straight = _corner_parts()

    def rate(qs: np.ndarray, dqs: np.ndarray) -> np.ndarray:
        return np.linalg.norm(dqs, axis=1)

    traj = retime_parts([PathPart(planned), PathPart(straight, straight=True, tcp_speed_m_s=0.3, reserve=0.2)],
                        cfg, rate)
    ts = np.arange(traj.part_times_s[1] + 0.02, traj.duration_s, DT_S)
    _, qd, qdd = traj.sample_many(ts)
    assert np.linalg.norm(qd, axis=1).max() <= 0.3 * (1.0 + LIMIT_TOL)
    assert np.max(np.abs(qdd) / np.array(cfg.acceleration_limits_rad_s2)) <= 0.8 * (1.0 + LIMIT_TOL)
    free = retime_parts([PathPart(planned), PathPart(straight, straight=True)], cfg)
    assert traj.duration_s > free.duration_s


def test_an_offset_moves_the_end_smoothly_within_the_room_it_has() -> None:
    """``with_offset`` bends the rest of a trajectory to a new end without a jump; ``offset_headroom`` is the share
    of the offset that keeps every sample within the limits (the part was timed with a reserve)."""
    from pickplace.motion.timing import PathPart, retime_parts

    cfg = TimingConfig.ur5e()
    planned, straight = _corner_parts()
    traj = retime_parts([PathPart(planned), PathPart(straight, straight=True, reserve=0.05)], cfg)
    t0 = traj.part_times_s[1]
    vlim, alim = np.array(cfg.velocity_limits_rad_s), np.array(cfg.acceleration_limits_rad_s2)
    small = np.full(6, 2e-3)
    assert traj.offset_headroom(t0, small, vlim, alim, DT_S) == pytest.approx(1.0)
    bent = traj.with_offset(t0, small)
    np.testing.assert_allclose(bent.end, traj.end + small, atol=1e-12)
    for t in (0.5 * t0, t0):  # nothing changes before it starts, and it starts at rest
        for a, b in zip(bent.sample(t), traj.sample(t), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-12)
    _, _, _, qdd = sample_grid(bent)
    assert np.max(np.abs(qdd) / alim) <= 1.0 + LIMIT_TOL
    big = np.full(6, 0.2)
    share = traj.offset_headroom(t0, big, vlim, alim, DT_S)
    assert 0.0 < share < 1.0
    _, _, _, qdd = sample_grid(traj.with_offset(t0, share * big))
    assert np.max(np.abs(qdd) / alim) <= 1.0 + 1e-3  # checked on its own 1 ms grid, sampled on another here
    slow = bent.slowed(2.0)
    assert slow.part_times_s == pytest.approx(tuple(2.0 * t for t in bent.part_times_s))
    np.testing.assert_allclose(slow.end, bent.end, atol=1e-12)


def test_parts_that_do_not_meet_or_lack_what_they_need_are_refused() -> None:
    from pickplace.motion.timing import PathPart, retime_parts

    planned, straight = _corner_parts()
    with pytest.raises(ConfigError, match=r"parts\[1\]\.waypoints\[0\]"):
        retime_parts([PathPart(planned), PathPart(straight + 0.01, straight=True)])
    with pytest.raises(ConfigError, match="tcp_rate"):
        retime_parts([PathPart(planned), PathPart(straight, straight=True, tcp_speed_m_s=0.5)])
    with pytest.raises(ConfigError, match=r"part\.reserve"):
        PathPart(straight, reserve=0.9)
    with pytest.raises(TimingFailed):  # a check that never passes
        retime_parts([PathPart(planned, is_valid=lambda q: False), PathPart(straight, straight=True)])
