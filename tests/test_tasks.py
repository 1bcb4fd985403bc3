"""Tasks with several objects: the scene's [[objects]] and bin, the task planner's choices, and whole tasks run in
simulation (a stack, a swap through a buffer spot, a carried object taken around another, a knocked object)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import ConfigError
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.planning import PlannerConfig, plan, segment_valid
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import build
from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.task.task_episode import run_task
from pickplace.task.tasks import TaskConfig, TaskPlanner, random_task_scene
from pickplace.world.config import BinConfig, SceneConfig, SceneObject
from pickplace.world.objects import ObjectConfig, library_object


def cube(name: str, edge: float = 0.04) -> ObjectConfig:
    return dataclasses.replace(library_object("cube"), name=name, size_m=(edge, edge, edge))


def entry(name: str, xy: tuple[float, float], goal: tuple[float, float] | None = None, **obj: object) -> dict:
    out: dict = {"library": "cube", "name": name, "start_xy_m": list(xy), **obj}
    if goal is not None:
        out["goal_xy_m"] = list(goal)
    return out


def poses_at_start(scene: SceneConfig) -> dict[str, pin.SE3]:
    return {o.name: pin.SE3(rot_z(o.start_yaw_rad), np.array([*o.start_xy_m, scene.table_height_m
                                                              - o.object.geometry().z_min_m]))
            for o in scene.objects}


# --------------------------------------------------------------------------- config
def test_objects_table_round_trips_and_builds_every_body() -> None:
    data = {"objects": [entry("a", (0.35, 0.20), (0.45, -0.10)), entry("b", (0.50, 0.10), (0.35, -0.20)),
                        {"library": "soda_can", "name": "can", "start_xy_m": [0.55, 0.30], "goal_xy_m": [0.55, -0.1]}],
            "task": {"kind": "place"}}
    cfg = EpisodeConfig.from_dict(data)
    assert [o.name for o in cfg.scene.objects] == ["a", "b", "can"]
    assert cfg.scene.others[1].object.kind == "cylinder"
    assert EpisodeConfig.from_dict(cfg.to_dict()) == cfg
    robot = build(cfg.scene)
    d = robot.make_data()
    for o in cfg.scene.objects:  # each object's body rests at its start
        body = "object" if o.name == "a" else o.name
        xy = d.xpos[mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY, body)][:2]
        assert np.allclose(xy, o.start_xy_m, atol=1e-9)


@pytest.mark.parametrize("data, field, words", [
    ({"objects": [entry("a", (0.35, 0.20)), entry("b", (0.37, 0.21))]}, "objects.b.start_xy_m", "overlap the a"),
    ({"objects": [entry("a", (0.35, 0.20)), entry("a", (0.50, 0.10))]}, "objects.a", "unique"),
    ({"objects": [entry("a", (0.45, -0.30))], "bin": {}}, "scene.start_xy_m", "on the bin"),
    ({"objects": [entry("a", (0.35, 0.20)), entry("b", (0.95, 0.10))]}, "objects.b.start_xy_m", "on the table"),
    ({"objects": [entry("a", (0.35, 0.20))], "task": {"kind": "clear"}}, "bin", "needs a bin"),
    ({"objects": [entry("a", (0.35, 0.20)), entry("b", (0.5, 0.1))], "task": {"kind": "place"}},
     "objects.b.goal_xy_m", "goal per object"),
    ({"objects": [entry("a", (0.45, -0.19))], "task": {"kind": "stack"}}, "task.stack_xy_m", "where the tower"),
    ({"objects": [entry("a", (0.35, 0.20))], "task": {"kind": "sort"}}, "task.kind", "place, stack, clear"),
    ({"objects": [entry("a", (0.35, 0.20))], "scene": {"start_xy_m": [0.3, 0.1]}}, "scene.start_xy_m", "own entry"),
    ({"objects": [{"library": "cube", "start_xy_m": [0.3, 0.1]}]}, "objects[0].name", "needs a name"),
    ({"objects": [entry("a", (0.35, 0.20))], "bin": {"wall_height_m": 0.5}}, "bin.wall_height_m", "<= 0.15"),
])
def test_bad_task_scenes_name_the_field(data: dict, field: str, words: str) -> None:
    with pytest.raises(ConfigError) as err:
        EpisodeConfig.from_dict(data)
    assert err.value.field == field
    assert words in str(err.value)


def test_single_runs_refuse_a_task_and_tasks_refuse_the_realistic_profile() -> None:
    cfg = EpisodeConfig.from_dict({"objects": [entry("a", (0.35, 0.20)), entry("b", (0.5, 0.1))],
                                   "task": {"kind": "stack"}})
    with pytest.raises(ConfigError, match="run_task"):
        run_episode(cfg)
    with pytest.raises(ConfigError, match="ideal profile"):
        run_task(cfg.with_profile("realistic"))


# --------------------------------------------------------------------------- planner
def test_swap_goes_through_a_free_buffer_spot() -> None:
    scene = SceneConfig(object=cube("a"), start_xy_m=(0.35, 0.20), goal_xy_m=(0.50, 0.00),
                        others=(SceneObject(cube("b"), (0.50, 0.00), 0.0, (0.35, 0.20)),))
    planner = TaskPlanner(scene, TaskConfig(kind="place"), 0.003, 0.05)
    poses = poses_at_start(scene)
    first = planner.next_pick(poses)
    assert first is not None and first.goal.label == "buffer"
    spot = np.array(first.goal.xy_m)
    for o in scene.objects:  # the spot is clear of every object where it is and of every goal
        for xy in (o.start_xy_m, o.goal_xy_m):
            assert np.linalg.norm(spot - np.asarray(xy)) > 0.04 + 0.02
    # parked there, the other's goal is free: it goes next, to its goal
    poses[first.name] = pin.SE3(np.eye(3), np.array([*spot, poses[first.name].translation[2]]))
    second = planner.next_pick(poses)
    assert second is not None and second.name != first.name and second.goal.label == "goal"


def test_an_occupied_goal_is_freed_first_and_listed_order_does_not() -> None:
    # a's goal is where b stands; b's goal is free: b goes first (planned), a first (listed)
    scene = SceneConfig(object=cube("a"), start_xy_m=(0.35, 0.20), goal_xy_m=(0.50, 0.00),
                        others=(SceneObject(cube("b"), (0.50, 0.00), 0.0, (0.40, -0.25)),))
    poses = poses_at_start(scene)
    planned = TaskPlanner(scene, TaskConfig(kind="place"), 0.003, 0.05).next_pick(poses)
    listed = TaskPlanner(scene, TaskConfig(kind="place", order="listed"), 0.003, 0.05).next_pick(poses)
    assert planned is not None and planned.name == "b"
    assert listed is not None and listed.name == "a"


def test_stack_order_is_widest_base_first_and_levels_go_on_the_observed_top() -> None:
    scene = SceneConfig(object=cube("small", 0.03), start_xy_m=(0.35, 0.20),
                        others=(SceneObject(cube("big", 0.06), (0.50, 0.10)),
                                SceneObject(cube("mid", 0.045), (0.55, 0.30))))
    planner = TaskPlanner(scene, TaskConfig(kind="stack"), 0.003, 0.05)
    assert planner.preference == ["big", "mid", "small"]
    poses = poses_at_start(scene)
    first = planner.next_pick(poses)
    assert first is not None and first.name == "big" and first.goal.support == ""
    # the big cube placed on the tower's spot, 1 mm off and turned: the next level goes on its observed top
    T = pin.SE3(rot_z(0.3), np.array([0.451, -0.20, scene.table_height_m + 0.03]))
    poses["big"] = T
    planner.placed(first, poses)
    second = planner.next_pick(poses)
    assert second is not None and second.name == "mid" and second.goal.support == "big"
    assert second.goal.xy_m == pytest.approx((0.451, -0.20), abs=1e-9)
    assert second.goal.surface_z_m == pytest.approx(scene.table_height_m + 0.06, abs=1e-9)
    assert second.goal.yaw_rad == pytest.approx(0.3, abs=1e-9)


def test_bin_spots_fill_the_bin_without_overlap() -> None:
    rng = np.random.default_rng(3)
    scene = random_task_scene("clear", 5, rng)
    planner = TaskPlanner(scene, TaskConfig(kind="clear"), 0.003, 0.05)
    poses = poses_at_start(scene)
    assert scene.bin is not None
    lo, hi = scene.bin.inner_box_xy_m
    floor = scene.bin.floor_z_m(scene.table_height_m)
    placed = 0
    for o in scene.objects:  # put each where the planner says, as if placed exactly
        spot = planner.bin_spot(o.name, poses)
        if spot is None:
            break
        z = floor - o.object.geometry().z_min_m
        poses[o.name] = pin.SE3(rot_z(spot.yaw_rad), np.array([*spot.xy_m, z]))
        assert planner.in_bin(o.name, poses[o.name])
        assert np.all(np.asarray(spot.xy_m) > lo) and np.all(np.asarray(spot.xy_m) < hi)
        placed += 1
    assert placed >= 3  # the default bin takes at least three of five random library objects by geometry alone


# --------------------------------------------------------------------------- whole tasks
def test_stack_of_three_cubes_stands_level_on_level() -> None:
    cfg = EpisodeConfig.from_dict({"objects": [entry("a", (0.35, 0.20), start_yaw_rad=0.5),
                                               entry("b", (0.50, 0.10), start_yaw_rad=-0.3),
                                               entry("c", (0.55, 0.30))], "task": {"kind": "stack"}})
    r = run_task(cfg, seed=0)
    assert r.success, r.failure_reason
    assert [name for name, _ in r.order] == ["a", "b", "c"]  # equal bases: the listed order
    assert [label for _, label in r.order] == ["level 1", "level 2", "level 3"]
    for o in r.objects[1:]:  # every level within 2 mm and 2 degrees of the one below, resting on it
        assert o.ok and o.xy_error_m <= 0.002 and abs(o.yaw_error_rad) <= math.radians(2.0)
        assert abs(o.z_error_m) <= 0.001
    assert r.total_time_s == pytest.approx(sum(r.time_per_object_s.values()), abs=1e-6)
    assert r.total_time_s == pytest.approx(sum(span for _, span in r.pick_spans_s), abs=1e-6)
    for p, (_, span) in zip(r.picks, r.pick_spans_s, strict=True):  # a pick's cycle, then the settling
        assert p.cycle_time_s <= span
    assert not r.knocked


def test_swap_is_solved_with_a_buffer_spot() -> None:
    cfg = EpisodeConfig.from_dict({"objects": [entry("a", (0.35, 0.20), (0.50, 0.00)),
                                               entry("b", (0.50, 0.00), (0.35, 0.20))], "task": {"kind": "place"}})
    r = run_task(cfg, seed=0)
    assert r.success, r.failure_reason
    assert [label for _, label in r.order] == ["buffer", "goal", "goal"]
    assert r.order[0][0] == r.order[2][0]
    for o in r.objects:
        assert o.xy_error_m <= 0.003
    # the listed order, without a buffer, cannot start: each goal is taken by the other
    listed = run_task(dataclasses.replace(cfg, task=dataclasses.replace(cfg.task, order="listed")), seed=0)
    assert not listed.success and listed.failure_kind == "TaskStuck"
    assert len(listed.skipped) == 2 and not listed.picks


def test_a_carried_object_is_taken_around_another_on_the_direct_path() -> None:
    """A pillar (a tall box, another object of the scene) stands between the cube's start and goal: the straight
    transport would carry the cube into it, the planner goes around it, and the task succeeds without touching it."""
    pillar = ObjectConfig(name="pillar", kind="box", size_m=(0.06, 0.06, 0.22), mass_kg=0.5)
    cfg = EpisodeConfig.from_dict({"objects": [entry("a", (0.45, 0.22), (0.45, -0.22))], "task": {"kind": "place"}})
    scene = dataclasses.replace(cfg.scene, others=(SceneObject(pillar, (0.45, 0.0), 0.0, (0.45, 0.0)),))
    cfg = dataclasses.replace(cfg, scene=scene)
    # the direct path at the transport's height is blocked by the pillar for the carried cube
    robot = build(scene)
    from pickplace.grasping.configurations import solve_grasp_configurations
    from pickplace.task.task_episode import _view

    focused = robot.focus(_view(scene, "a"), "a")
    configs = solve_grasp_configurations(focused, clearance_m=0.01)
    checker = CollisionChecker(focused, CollisionPolicy(margin_m=0.01, object_held=True, allow_object_table=False,
                                                        finger_m=configs.held_finger_m),
                               T_tcp_object=configs.targets.T_tcp_object)
    assert not segment_valid(checker, configs.lift.q, configs.preplace.q, 0.01)
    pairs = set()
    for s in np.linspace(0.0, 1.0, 41):
        pairs |= set(checker.colliding_pairs(configs.lift.q + s * (configs.preplace.q - configs.lift.q)))
    assert any("pillar" in p for p in pairs), pairs
    path = plan(checker, configs.lift.q, configs.preplace.q, robot.arm_lower, robot.arm_upper,
                PlannerConfig(seed=0))
    assert len(path.path) > 2
    # and the whole task goes around it
    r = run_task(cfg, seed=0)
    assert r.success, r.failure_reason
    assert not r.knocked and not r.picks[0].unexpected_contacts
    assert r.picks[0].waypoints_shortcut["transport"] > 2


@pytest.mark.parametrize("repair", [False, True])
def test_a_knocked_placed_object_is_detected_and_named(repair: bool) -> None:
    """While the second cube is handled, the first one (already at its goal) is shoved 2 cm: the task names it,
    and either fails (repairs off) or places it again."""
    cfg = EpisodeConfig.from_dict({"objects": [entry("a", (0.35, 0.20), (0.35, -0.20)),
                                               entry("b", (0.55, 0.25), (0.55, -0.15))],
                                   "task": {"kind": "place", "repair": repair}})
    robot = build(cfg.scene)
    body = mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY, "object")  # the first object, a
    state = {"t0": None}

    def shove(d: mujoco.MjData, pick: int, t: float) -> None:
        if pick != 1:
            return
        if state["t0"] is None:
            state["t0"] = t
        on = 0.5 <= t - state["t0"] < 0.53  # 30 ms of 4 N along +x, well into the second pick
        d.xfrc_applied[body, :3] = (4.0, 0.0, 0.0) if on else (0.0, 0.0, 0.0)

    r = run_task(cfg, seed=0, step_hook=shove)
    assert [k.name for k in r.knocked] == ["a"]
    k = r.knocked[0]
    assert k.by == "b" and k.was_done and k.shift_m > 0.005 and k.repaired == repair
    if repair:
        assert r.success, r.failure_reason
        assert [name for name, _ in r.order] == ["a", "b", "a"]
    else:
        assert not r.success and r.failure_kind == "ObjectKnocked" and "the a was knocked" in r.failure_reason


# --------------------------------------------------------------------------- campaigns
def test_task_campaign_trials_are_drawn_whole_and_reproducibly() -> None:
    from pickplace.eval.campaign import CampaignConfig, RandomizationSpec, make_trial

    base = EpisodeConfig(scene=SceneConfig(bin=BinConfig()), task=TaskConfig(kind="clear"))
    spec = RandomizationSpec(task_objects=(2, 5))
    campaign = CampaignConfig(base, spec, trials=20, seed=3)
    trials = [make_trial(campaign, i) for i in range(20)]
    counts = {len(t.config.scene.objects) for t in trials}
    assert counts <= {2, 3, 4, 5} and len(counts) >= 3  # the count varies within the range
    assert len({t.config.scene for t in trials}) == 20
    for t in trials:
        assert t.config.task == base.task and t.config.scene.bin is not None
        assert t.params["task_objects"] == len(t.config.scene.objects)
        assert make_trial(campaign, t.index).config == t.config  # a trial depends on the seed and its index only
    assert RandomizationSpec.from_dict(spec.to_dict()) == spec
    with pytest.raises(ConfigError) as err:
        RandomizationSpec(task_objects=(3, 2))
    assert err.value.field == "randomization.task_objects"


@pytest.mark.slow
def test_a_task_campaign_runs_and_summarizes_by_object(tmp_path: Path) -> None:
    from pickplace.eval.campaign import CampaignConfig, RandomizationSpec, run_campaign

    base = EpisodeConfig(task=TaskConfig(kind="stack"))
    campaign = CampaignConfig(base, RandomizationSpec(objects=("cube",), task_objects=(2, 2)), trials=2, workers=2)
    run = run_campaign(campaign, tmp_path)
    s = run.summary
    assert s.trials == 2 and s.successes == 2
    assert 4.0 < s.task_time_mean_s < 20.0 and s.task_time_per_object_mean_s == pytest.approx(s.task_time_mean_s / 2)
    assert s.place_error_xy_rms_m < 0.003  # over the four picks
    assert not s.failures_by_object


def test_a_carried_object_turned_over_is_carried_slower() -> None:
    """The arm going from one IK branch to another turns the hand over on the way (the tcp's approach axis ~90
    degrees from straight down): such a transport is run TURN_OVER_SLOWDOWN times slower; one that only turns
    about the base keeps the hand down."""
    from pickplace.motion.timing import TimingConfig, retime
    from pickplace.task.arm import TURN_OVER_RAD, hand_turn_rad

    robot = build(SceneConfig())
    lift = np.array([3.477, -1.241, 0.893, -1.224, -1.571, 0.413])  # a ball lifted far out on +y
    flipped = np.array([5.871, -2.105, -0.585, -2.022, 1.571, 0.713])  # above a spot far out on -y, turned over
    turned = lift + np.array([-1.0, 0.0, 0.0, 0.0, 0.0, -1.0])  # the same arm shape turned about the base
    timing = TimingConfig.ur5e()
    assert hand_turn_rad(robot, retime(np.vstack([lift, flipped]), timing)) > TURN_OVER_RAD
    assert hand_turn_rad(robot, retime(np.vstack([lift, turned]), timing)) < math.radians(1.0)


def test_objects_out_of_reach_are_refused_before_anything_moves() -> None:
    """A goal in the table's far corner is out of the arm's reach: run_task refuses the task naming the object's
    goal before anything runs. A goal the arm reaches only by turning the carried object over is valid, but out of
    the upright workspace the random task scenes are drawn from."""
    from pickplace.task.tasks import check_reachable

    far = SceneConfig(object=cube("a"), start_xy_m=(0.35, 0.20), goal_xy_m=(0.79, 0.48),
                      others=(SceneObject(cube("b"), (0.45, 0.05), 0.0, (0.40, -0.15)),))
    with pytest.raises(ConfigError) as exc:
        run_task(EpisodeConfig(scene=far, task=TaskConfig(kind="place")))
    assert exc.value.field == "objects.a.goal_xy_m" and "out of the arm's reach for the a" in str(exc.value)
    turning = SceneConfig(object=cube("c"), start_xy_m=(0.613, 0.351), start_yaw_rad=-0.27,
                          goal_xy_m=(0.608, -0.352), goal_yaw_rad=-0.36)
    check_reachable(turning, "place", 0.01)  # turning it over on the way
    with pytest.raises(ConfigError, match="carried upright"):
        check_reachable(turning, "place", 0.01, upright=True)
