"""Choosing a grasp in the world: synthesized candidates ranked, tried in order, and the one that works executed.

Next to a wall the top-down grasps collide (the gripper's coupling and the wall); a tilted grasp from the other
side reaches the object, and the lift raises it above the wall before the transport is planned.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pickplace.errors import UnreachableTarget
from pickplace.grasping.configurations import candidate_grasps, solve_grasp_configurations, start_pose
from pickplace.grasping.synthesis import ApproachKind
from pickplace.grasping.targets import raised
from pickplace.robot.ik import solve_ik
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
