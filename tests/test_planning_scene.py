"""Planning and time scaling on the real scene: MuJoCo collision checker, UR5e limits, the obstacle wall; fixed boxes
in the scene and the harder planning problems built from them."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import ConfigError, InsideObstacle, PlanningFailed
from pickplace.eval.bench import planning as bench
from pickplace.eval.bench import planning_problems as problems
from pickplace.grasping.configurations import solve_grasp_configurations
from pickplace.grasping.targets import top_down
from pickplace.motion import planning
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot import model
from pickplace.robot.ik import solve_ik
from pickplace.robot.kinematics import frame_pose
from pickplace.task.episode import EpisodeConfig
from pickplace.world.config import BoxConfig, SceneConfig


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


# --------------------------------------------------------------------------- #
# fixed boxes in the scene, and the harder problems built from them
# --------------------------------------------------------------------------- #


def test_boxes_are_validated_and_named_in_errors():
    box = BoxConfig("shelf_board", (0.6, 0.0, 0.5), (0.2, 0.6, 0.02), yaw_rad=0.3)
    assert box.z_range_m == pytest.approx((0.49, 0.51))
    with pytest.raises(ConfigError, match=r"scene\.boxes\.name"):
        BoxConfig("Shelf", (0.6, 0.0, 0.5), (0.2, 0.6, 0.02))
    with pytest.raises(ConfigError, match=r"scene\.boxes\.b\.size_m\[2\]"):
        BoxConfig("b", (0.6, 0.0, 0.5), (0.2, 0.6, 0.0))
    with pytest.raises(ConfigError, match=r"scene\.boxes\.b\.center_m"):
        BoxConfig("b", (0.6, float("nan"), 0.5), (0.2, 0.6, 0.1))
    with pytest.raises(ConfigError, match=r"scene\.boxes\.b.*unique"):
        SceneConfig(boxes=(BoxConfig("b", (0.6, 0.0, 0.5), (0.1, 0.1, 0.1)),) * 2)
    # the object may not start inside a box that reaches down to it; a box above it is fine
    on_object = BoxConfig("b", (0.35, 0.20, 0.33), (0.1, 0.1, 0.05))
    with pytest.raises(InsideObstacle, match=r"inside the box 'b'"):
        SceneConfig(boxes=(on_object,))
    SceneConfig(boxes=(BoxConfig("b", (0.35, 0.20, 0.60), (0.1, 0.1, 0.05)),))


def test_boxes_round_trip_through_toml_tables_and_build_into_the_model():
    scene = SceneConfig(boxes=(BoxConfig("board", (0.6, 0.0, 0.55), (0.2, 0.5, 0.02), 0.1),
                               BoxConfig("post", (0.6, 0.3, 0.45), (0.02, 0.02, 0.2))))
    data = scene.to_dict()
    assert data["boxes"][0] == {"name": "board", "center_m": [0.6, 0.0, 0.55], "size_m": [0.2, 0.5, 0.02],
                                "yaw_rad": 0.1}
    assert SceneConfig.from_mapping(data) == scene
    assert "boxes" not in SceneConfig().to_dict()  # a scene without boxes writes what it always wrote
    assert EpisodeConfig.from_dict(EpisodeConfig(scene=scene).to_dict()).scene == scene
    robot = model.build(scene)
    g = robot.mj.geom("board")
    np.testing.assert_allclose(g.size, [0.1, 0.25, 0.01])
    np.testing.assert_allclose(robot.mj.body("box_board").pos, [0.6, 0.0, 0.55])
    # the hand pointing down into the board collides with it (a box is an obstacle, margin included)
    q = solve_ik(robot, pin.SE3(top_down(0.0), np.array([0.6, 0.0, 0.55])), robot.home_q, "into the board").q
    pairs = CollisionChecker(robot, CollisionPolicy(margin_m=0.01)).colliding_pairs(q)
    assert pairs and all("board" in pair for pair in pairs)


@pytest.fixture(scope="module")
def harder():
    return {seg.scene: seg for seg in bench.problem_segments()}


def test_the_harder_problems_have_valid_ends_on_their_targets_and_no_straight_path(harder):
    assert sorted(harder) == ["bins", "cage", "shelf", "slot"]
    for problem in problems.problems():
        seg = harder[problem.name]
        robot = seg.checker.robot
        assert len(problem.boxes) >= 4 and all(robot.mj.geom(b.name).id >= 0 for b in problem.boxes)
        data = robot.pin.createData()
        for q, target in zip((seg.start, seg.goal), problem.tcp_poses(), strict=True):
            assert seg.checker.is_valid(q) and seg.dense_checker.is_valid(q)
            T = frame_pose(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame)
            assert np.linalg.norm(T.translation - target.translation) < 1e-3
            assert np.linalg.norm(pin.log3(T.rotation.T @ target.rotation)) < 1e-3
            assert np.all(q >= seg.lower) and np.all(q <= seg.upper)
        # harder problems: the straight segment is blocked, so the search has to find a way
        assert not planning.segment_valid(seg.checker, seg.start, seg.goal, 0.01), problem.name


@pytest.mark.parametrize("name", ["shelf", "cage", "bins", "slot"])
def test_the_harder_problems_are_solved_within_a_generous_budget(harder, name):
    """Seeded searches that end by their iteration limit or their first solution, not by the clock (a 60 s budget):
    each problem is solved for three seeds, and the paths are valid when re-checked densely at margin 0."""
    seg = harder[name]
    for seed in range(3):
        cfg = planning.PlannerConfig(seed=seed, time_budget_s=60.0, retries=0)
        res = planning.plan(seg.checker, seg.start, seg.goal, seg.lower, seg.upper, cfg)
        assert res.status is planning.PlanStatus.SOLVED
        np.testing.assert_array_equal(res.path[0], seg.start)
        np.testing.assert_array_equal(res.path[-1], seg.goal)
        assert planning.path_valid(seg.dense_checker, res.path, 0.01)
        assert planning.path_valid(seg.checker, res.path_raw, 0.01)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_box_numbers_are_refused_from_toml(bad):
    for key, value in (("center_m", [0.6, bad, 0.5]), ("size_m", [0.1, 0.1, bad]), ("yaw_rad", bad)):
        table = {"name": "b", "center_m": [0.6, 0.0, 0.5], "size_m": [0.1, 0.1, 0.1], key: value}
        with pytest.raises(ConfigError, match=rf"scene\.boxes\.b\.{key}"):
            EpisodeConfig.from_dict({"scene": {"boxes": [table]}})
    for value in ("shelf", 3.0, {"name": "b"}, ["b"]):
        with pytest.raises(ConfigError, match=r"scene\.boxes"):
            EpisodeConfig.from_dict({"scene": {"boxes": value}})
