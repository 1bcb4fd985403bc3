"""Planning and time scaling on the real scene: MuJoCo collision checker, UR5e limits, the obstacle wall."""

from __future__ import annotations

import numpy as np
import pytest

from pickplace.errors import PlanningFailed
from pickplace.grasping.configurations import solve_grasp_configurations
from pickplace.motion import planning
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot import model
from pickplace.world.config import SceneConfig


@pytest.fixture(scope="module")
def obstacle():
    robot = model.build(SceneConfig(obstacle=True))
    configs = solve_grasp_configurations(robot)

    return robot, configs, configs.carrying_checker(robot, 0.01), configs.carrying_checker(robot, 0.0)


def test_carried_cube_must_go_around_the_wall(obstacle):
    robot, configs, checker, dense = obstacle
    assert not planning.segment_valid(dense, configs.pregrasp.q, configs.preplace.q, 0.01)
    result = planning.plan(checker, configs.pregrasp.q, configs.preplace.q, robot.arm_lower, robot.arm_upper,
                           planning.PlannerConfig(seed=3))
    assert result.status is planning.PlanStatus.SOLVED
    np.testing.assert_array_equal(result.path[0], configs.pregrasp.q)
    np.testing.assert_array_equal(result.path[-1], configs.preplace.q)
    assert planning.path_valid(dense, result.path, 0.01)  # dense re-check at zero margin
    assert result.cost_rad <= result.cost_raw_rad + 1e-12
    print(f"\nobstacle plan: {result.plan_time_s * 1e3:.1f} ms search + {result.shortcut_time_s * 1e3:.1f} ms "
          f"shortcut, cost {result.cost_raw_rad:.3f} -> {result.cost_rad:.3f} rad, {len(result.path)} waypoints")


def test_seeded_plan_is_deterministic(obstacle):
    robot, configs, checker, _ = obstacle
    cfg = planning.PlannerConfig(seed=7)
    a = planning.plan(checker, configs.pregrasp.q, configs.preplace.q, robot.arm_lower, robot.arm_upper, cfg)
    b = planning.plan(checker, configs.pregrasp.q, configs.preplace.q, robot.arm_lower, robot.arm_upper, cfg)
    np.testing.assert_array_equal(a.path, b.path)
    np.testing.assert_array_equal(a.path_raw, b.path_raw)


def test_invalid_goal_names_the_geoms(obstacle):
    robot, configs, checker, _ = obstacle
    into_table = configs.place.q.copy()
    into_table[1] += 0.15  # shoulder lift: pushes the carried cube down into the table
    assert not checker.is_valid(into_table)
    with pytest.raises(PlanningFailed, match="table_top"):
        planning.plan(checker, configs.pregrasp.q, into_table, robot.arm_lower, robot.arm_upper)


@pytest.mark.parametrize("preset", [TimingConfig.ur5e(), TimingConfig.design_note()], ids=["ur5e", "design_note"])
def test_retimed_plan_respects_limits_and_stays_collision_free(obstacle, preset):
    robot, configs, checker, dense = obstacle
    result = planning.plan(checker, configs.pregrasp.q, configs.preplace.q, robot.arm_lower, robot.arm_upper,
                           planning.PlannerConfig(seed=3))
    traj = retime(result.path, preset, is_segment_valid=dense.all_valid)
    t = np.append(np.arange(0.0, traj.duration_s, 0.001), traj.duration_s)  # every 1 ms, and the end
    q, qd, qdd = traj.sample_many(t)
    vmax = np.asarray(preset.velocity_limits_rad_s)
    amax = np.asarray(preset.acceleration_limits_rad_s2)
    assert np.all(np.abs(qd) <= vmax * 1.01)
    assert np.all(np.abs(qdd) <= amax * 1.01)
    np.testing.assert_allclose(q[0], configs.pregrasp.q, atol=1e-9)
    np.testing.assert_allclose(q[-1], configs.preplace.q, atol=1e-6)
    np.testing.assert_allclose(qd[[0, -1]], 0.0, atol=1e-6)
    assert dense.all_valid(q)  # every 1 ms sample of the retimed (spline) path is collision free
    print(f"\n{preset.velocity_limits_rad_s[0]:.2f} rad/s: duration {traj.duration_s:.3f} s, "
          f"peak |qd|/limit {np.max(np.abs(qd) / vmax):.4f}, peak |qdd|/limit {np.max(np.abs(qdd) / amax):.4f}")
