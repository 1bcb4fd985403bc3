"""Choosing a grasp in the world: synthesized candidates ranked, tried in order, and the one that works executed.

Next to a wall the top-down grasps collide (the gripper's coupling and the wall); a tilted grasp from the other
side reaches the object, and the lift raises it above the wall before the transport is planned.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pickplace.errors import UnreachableTarget
from pickplace.grasping.configurations import candidate_grasps, home_tcp, solve_grasp_configurations, start_pose
from pickplace.grasping.synthesis import ApproachKind
from pickplace.grasping.targets import grasp_targets, raised
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.robot.ik import solve_ik, solve_line
from pickplace.robot.kinematics import frame_pose, rotation_distance
from pickplace.robot.model import Robot, build
from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.world.config import SceneConfig
from pickplace.world.objects import library_object

WALL_CENTRE_XY = np.array([0.42, 0.0])  # the obstacle wall (20 cm along x, 4 cm thick, 25 cm tall)


def beside_the_wall(name: str, gap_m: float, x_m: float) -> SceneConfig:
    """The obstacle scene with the library object ``gap_m`` from the wall's face (on the +y side)."""
    obj = library_object(name)
    base = SceneConfig()
    y = 0.02 + gap_m + float(obj.geometry().bounds_m[1][1])
    mid = (np.array([x_m, y]) + np.asarray(base.goal_xy_m)) / 2
    return dataclasses.replace(base, object=obj, obstacle=True, start_xy_m=(x_m, y),
                               obstacle_offset_xy_m=tuple(float(v) for v in WALL_CENTRE_XY - mid))


def test_default_scene_takes_the_best_ranked_top_down_grasp(robot: Robot) -> None:
    configs = solve_grasp_configurations(robot)
    assert configs.grasps_tried == 1
    assert configs.chosen.approach is ApproachKind.TOP
    assert configs.targets.lift_height_m == pytest.approx(0.15, abs=1e-9)  # nothing near: the usual lift


def test_candidates_are_ranked_and_clear_the_table(robot: Robot) -> None:
    T = start_pose(robot)
    cands = candidate_grasps(robot, T)
    assert len(cands) >= 8
    kinds = {c.approach for c in cands}
    assert {ApproachKind.TOP, ApproachKind.TILTED} <= kinds
    assert cands[0].approach is ApproachKind.TOP


def test_beside_a_wall_the_top_down_grasps_collide_and_a_tilted_one_is_used() -> None:
    robot = build(beside_the_wall("cube", gap_m=0.01, x_m=0.40))
    T = start_pose(robot)
    cands = candidate_grasps(robot, T)
    top = [c for c in cands if c.approach is ApproachKind.TOP]
    assert top
    with pytest.raises(UnreachableTarget, match="obstacle"):
        solve_grasp_configurations(robot, grasps=top, clearance_m=0.02)
    configs = solve_grasp_configurations(robot, clearance_m=0.02)
    assert configs.chosen.approach is not ApproachKind.TOP
    assert configs.grasps_tried > 1
    # the usual 15 cm lift leaves the object beside the 25 cm wall, within the planner's margin of it: the
    # lift is raised until the carried object clears it, so that the transport can be planned from there
    assert configs.targets.lift_height_m > 0.15 + 0.01
    carrying = configs.carrying_checker(robot, margin_m=0.02)
    assert carrying.is_valid(configs.lift.q)
    low = solve_ik(robot, raised(configs.targets.grasp, 0.15), configs.grasp.q, "lift").q
    assert not carrying.is_valid(low)


def test_episode_beside_a_wall_succeeds_with_a_tilted_grasp_and_reports_it() -> None:
    cfg = dataclasses.replace(EpisodeConfig(), scene=beside_the_wall("cube", gap_m=0.01, x_m=0.40))
    result = run_episode(cfg, seed=0)
    assert result.success, result.failure_reason
    assert result.grasp_approach in ("tilted", "side")
    assert 0.2 < result.grasp_tilt_rad <= np.pi / 2 + 1e-9
    assert result.grasps_tried > 1
    assert result.place_error_xy_m <= cfg.machine.place_tolerance_xy_m
    assert result.to_dict()["grasp_approach"] == result.grasp_approach


def test_a_grasp_whose_straight_approach_sweeps_through_the_wall_is_not_taken() -> None:
    """A cube beyond the wall (0.60, 0.16): the best-ranked grasp is top-down, and IK of its pregrasp and its
    grasp, each alone, finds collision-free configurations, but on two IK branches half a turn apart. The arm
    descends continuously from the pregrasp, on the pregrasp's branch, and that branch sweeps the forearm
    through the wall 5 cm down. The chain follows the descent waypoint by waypoint, rejects that grasp and
    takes the next one; its approach, re-checked independently every 2 mm at actual contact, is clear."""
    scene = dataclasses.replace(SceneConfig(), obstacle=True, obstacle_xy_m=(0.42, 0.0), start_xy_m=(0.60, 0.16))
    robot = build(scene)
    T_object = start_pose(robot)
    first = candidate_grasps(robot, T_object)[0]
    targets = grasp_targets(scene, T_object, first.T_object_tcp, first.width_m, home_tcp(robot))
    above = CollisionChecker(robot, CollisionPolicy(margin_m=0.01))
    touching = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    pre = solve_ik(robot, targets.pregrasp, robot.home_q, "pregrasp", is_valid=above.is_valid)
    alone = solve_ik(robot, targets.grasp, pre.q, "grasp", is_valid=touching.is_valid)  # each end alone: fine
    assert float(np.max(np.abs(alone.q - pre.q))) > 1.0  # ... on another branch
    with pytest.raises(UnreachableTarget, match=r"straight move to it is in collision .* forearm_collision <-> "
                                                 r"obstacle"):
        solve_grasp_configurations(robot, clearance_m=0.01, grasps=[first])
    configs = solve_grasp_configurations(robot, clearance_m=0.01)
    assert configs.grasps_tried > 1
    fine = solve_line(robot, configs.targets.grasp, configs.pregrasp.q, "grasp", is_valid=touching.is_valid,
                      step_m=0.002)
    np.testing.assert_allclose(fine.q, configs.grasp.q, rtol=0, atol=2e-3)  # the same branch, the same end


def test_solve_line_follows_the_branch_and_reports_where_it_fails(robot: Robot) -> None:
    """A 15 cm descent from the default pregrasp: every waypoint on the line; a check that refuses the tcp
    below a height fails the move there, naming the distance along it."""
    configs = solve_grasp_configurations(robot)
    start, target = configs.pregrasp.q, configs.targets.grasp
    seen: list[np.ndarray] = []

    def record(q: np.ndarray) -> bool:
        seen.append(q.copy())
        return True

    result = solve_line(robot, target, start, "grasp", is_valid=record)
    assert len(seen) == 15  # one waypoint per centimetre
    data = robot.pin.createData()
    p0, p1 = configs.targets.pregrasp.translation, target.translation
    for k, q in enumerate(seen, start=1):
        T = frame_pose(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame)
        np.testing.assert_allclose(T.translation, p0 + k / 15 * (p1 - p0), rtol=0, atol=2e-4)
        assert rotation_distance(T.rotation, target.rotation) < 2e-4
    assert max(float(np.max(np.abs(b - a))) for a, b in zip([start, *seen[:-1]], seen, strict=True)) < 0.1
    assert result.success and result.position_error_m < 1e-4
    z_floor = float(p1[2]) + 0.05

    def above_floor(q: np.ndarray) -> bool:
        return float(frame_pose(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame).translation[2]) > z_floor

    with pytest.raises(UnreachableTarget, match=r"in collision 0\.110 of 0\.150 m along") as info:
        solve_line(robot, target, start, "grasp", is_valid=above_floor)
    assert info.value.q is not None and not above_floor(info.value.q)


def _into_the_bin(yaw_rad: float) -> Robot:
    """A can lying far out on +y, to be set in the default bin far round the base on -y."""
    from pickplace.world.config import BinConfig

    base, bin_ = SceneConfig(), BinConfig()
    return build(dataclasses.replace(base, object=library_object("soda_can_lying"), start_xy_m=(0.382, 0.378),
                                     start_yaw_rad=-0.41, goal_xy_m=(0.54, -0.37), goal_yaw_rad=yaw_rad, bin=bin_,
                                     goal_z_m=bin_.floor_z_m(base.table_height_m)))


def test_ik_branch_flips_exactly_at_the_singularities(robot: Robot) -> None:
    from pickplace.robot.kinematics import frame_jacobian, ik_branch

    data = robot.pin.createData()
    q = np.array(robot.home_q, dtype=float)

    def branch(q: np.ndarray) -> tuple[int, int, int]:
        return ik_branch(frame_jacobian(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame), q)

    home = branch(q)
    flipped = q.copy()
    flipped[4] = -q[4]  # the wrist through 0: nothing else changes
    assert branch(flipped) == (home[0], home[1], -home[2])
    # the shoulder's sign is that of the wrist's reach in the arm's plane (UR5e DH: a2, a3, d5), the elbow's sin(q3)
    a2, a3, d5 = -0.425, -0.3922, 0.0997
    rng = np.random.default_rng(3)
    for q in rng.uniform(-3.0, 3.0, (50, 6)):
        reach = a2 * np.cos(q[1]) + a3 * np.cos(q[1] + q[2]) + d5 * np.sin(q[1] + q[2] + q[3])
        if min(abs(reach), abs(np.sin(q[2])), abs(np.sin(q[4]))) < 1e-3:
            continue  # too near a singularity to call
        assert branch(q) == (int(np.sign(reach)), int(np.sign(np.sin(q[2]))), int(np.sign(np.sin(q[4]))))
    # at the wrist's singularity the tool axis is horizontal: a wrist flip turns the hand on its side
    for q5 in (0.0, np.pi):
        q_sing = q.copy()
        q_sing[4] = q5
        T = frame_pose(robot.pin, data, robot.pin_q(q_sing), robot.pin_tcp_frame)
        assert abs(T.rotation[2, 2]) < 1e-9


@pytest.mark.parametrize("yaw_rad", [-0.41, 1.16])
def test_a_far_place_is_reached_keeping_the_carried_object_upright(yaw_rad: float) -> None:
    # At yaw 1.16 the first grasp's preplace (the lowest clear one) lies only on the flipped branch: the lift's
    # branch puts the upper arm within the planner's margin of the table. Another grasp keeps the branch.
    from pickplace.grasping.grip import TURN_OVER_RAD, carried_tilt_rad, joint_line
    from pickplace.robot.kinematics import frame_jacobian, ik_branch

    robot = _into_the_bin(yaw_rad)
    configs = solve_grasp_configurations(robot, clearance_m=0.02, turn_over=False)
    data = robot.pin.createData()
    lift, pre = configs.lift.q, configs.preplace.q
    branches = [ik_branch(frame_jacobian(robot.pin, data, robot.pin_q(q), robot.pin_tcp_frame), q)
                for q in (lift, pre)]
    assert branches[0] == branches[1]
    assert carried_tilt_rad(robot, joint_line(lift, pre)) <= TURN_OVER_RAD


def test_a_grasp_that_turns_the_object_over_is_a_last_resort_or_refused() -> None:
    # Among the best-ranked grasps, some reach the place (yaw 1.16) only on another branch than their lift's.
    from pickplace.errors import TurnsOver
    from pickplace.grasping.grip import TURN_OVER_RAD, carried_tilt_rad, joint_line

    robot = _into_the_bin(1.16)
    turning = []
    for grasp in candidate_grasps(robot, start_pose(robot))[:12]:
        try:
            solve_grasp_configurations(robot, clearance_m=0.02, grasps=[grasp], turn_over=False)
        except TurnsOver as exc:
            assert "would tilt" in str(exc)
            turning.append(grasp)
        except UnreachableTarget:
            continue
    assert turning, "no grasp of the first 12 turns the object over: the scene no longer tests this"
    configs = solve_grasp_configurations(robot, clearance_m=0.02, grasps=turning[:1], turn_over=True)
    assert carried_tilt_rad(robot, joint_line(configs.lift.q, configs.preplace.q)) > TURN_OVER_RAD
