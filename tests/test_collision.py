"""Tests of pickplace.motion.collision: configuration validity on MuJoCo's collision detection."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import CollisionError, ConfigError
from pickplace.grasping.configurations import GraspConfigurations
from pickplace.grasping.targets import top_down
from pickplace.motion import collision
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.robot import model
from pickplace.robot.ik import solve_ik

#: Depth of the finger tips below the tcp (m): pads and finger boxes end 10 mm past the tcp (gripper.xml).
TIP_BELOW_TCP_M = 0.010


def _tcp_at(robot: model.Robot, xyz: tuple[float, float, float], q0: np.ndarray | None = None) -> np.ndarray:
    """Arm configuration putting the tcp, pointing down, at ``xyz`` (IK without any collision check)."""
    r = solve_ik(robot, pin.SE3(top_down(0.0), np.array(xyz)), robot.home_q if q0 is None else q0, "probe")
    assert r.success
    return r.q


def _clearance_to(robot: model.Robot, q: np.ndarray, geom_name: str) -> float:
    """Smallest signed distance (m) from any colliding robot geom to a geom, measured by mj_geomDistance."""
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.qpos[h.arm_qpos] = q
    mujoco.mj_kinematics(m, d)
    target = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, geom_name)
    fromto = np.zeros(6)
    robot_geoms = [g for g in range(m.ngeom)
                   if m.geom_bodyid[g] in h.robot_bodies and (m.geom_contype[g] or m.geom_conaffinity[g])]
    return min(mujoco.mj_geomDistance(m, d, g, target, 0.5, fromto) for g in robot_geoms)


def test_home_is_valid(robot: model.Robot) -> None:
    for policy in (CollisionPolicy(), CollisionPolicy(margin_m=0.0), CollisionPolicy(margin_m=0.05)):
        checker = CollisionChecker(robot, policy)
        assert checker.is_valid(robot.home_q), policy
        assert checker.colliding_pairs(robot.home_q) == []
        checker.require_valid(robot.home_q, "home")  # does not raise


def test_tcp_in_the_table_is_invalid(robot: model.Robot) -> None:
    z = robot.scene.table_height_m - 0.05
    q = _tcp_at(robot, (0.45, 0.0, z))
    checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    pairs = checker.colliding_pairs(q)
    print(f"\ntcp 5 cm into the table: {pairs}, clearance {_clearance_to(robot, q, 'table_top') * 1e3:.1f} mm")
    assert not checker.is_valid(q)
    assert pairs
    assert all("table_top" in pair for pair in pairs)
    assert ("left_pad", "table_top") in pairs
    assert ("right_pad", "table_top") in pairs
    with pytest.raises(CollisionError, match=r"tcp in table is in collision: .*left_pad <-> table_top") as info:
        checker.require_valid(q, "tcp in table")
    assert info.value.pairs == pairs


def test_is_valid_and_are_valid_agree(robot: model.Robot) -> None:
    checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    rng = np.random.default_rng(2024)
    qs = robot.home_q + rng.normal(0.0, 1.0, (200, 6))
    batch = checker.are_valid(qs)
    single = np.array([checker.is_valid(q) for q in qs])
    pairs_empty = np.array([checker.colliding_pairs(q) == [] for q in qs])
    print(f"\n{batch.sum()} of {len(qs)} random configurations valid")
    assert batch.dtype == bool
    assert batch.shape == (200,)
    np.testing.assert_array_equal(batch, single)
    np.testing.assert_array_equal(batch, pairs_empty)
    assert 0 < batch.sum() < len(qs)  # both outcomes are exercised
    # a single configuration as a batch
    assert checker.are_valid(qs[0]).tolist() == [single[0]]


def test_margin(robot: model.Robot) -> None:
    gap = 0.004
    z = robot.scene.table_height_m + TIP_BELOW_TCP_M + gap
    q = _tcp_at(robot, (0.45, 0.0, z))
    clearance = _clearance_to(robot, q, "table_top")
    print(f"\nfinger tips {clearance * 1e3:.3f} mm above the table")
    assert 0.0 < clearance < 0.005
    assert clearance == pytest.approx(gap, abs=2e-4)  # the IK tolerance is 1e-4
    tight = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    wide = CollisionChecker(robot, CollisionPolicy(margin_m=0.01))
    assert tight.is_valid(q)
    assert not wide.is_valid(q)
    assert all("table_top" in pair for pair in wide.colliding_pairs(q))
    # the margin is edited on a private copy: the simulation's model is untouched
    assert np.all(robot.mj.geom_margin == 0.0)


def test_held_cube_pushed_into_the_table(robot: model.Robot, configs: GraspConfigurations) -> None:
    rel = configs.targets.T_tcp_object
    policy = CollisionPolicy(margin_m=0.0, object_held=True, allow_object_table=False, finger_m=configs.held_finger_m)
    checker = CollisionChecker(robot, policy, T_tcp_object=rel)
    # at the place target the cube hangs 1 mm above the table: valid
    assert checker.colliding_pairs(configs.place.q) == []
    # lowered by 5 mm, the cube goes 4 mm into the table (the finger tips stay 6 mm above it)
    place = configs.targets.place
    lowered = pin.SE3(place.rotation, place.translation - np.array([0.0, 0.0, 0.005]))
    q = solve_ik(robot, lowered, configs.place.q, "lowered place").q
    pairs = checker.colliding_pairs(q)
    print(f"\nheld cube 4 mm into the table: {pairs}")
    assert not checker.is_valid(q)
    assert pairs == [("cube", "table_top")]
    with pytest.raises(CollisionError, match=r"lowered place is in collision: cube <-> table_top"):
        checker.require_valid(q, "lowered place")
    # the same contact is allowed while setting the cube down
    placing = CollisionChecker(robot, CollisionPolicy(margin_m=0.0, object_held=True, allow_object_table=True,
                                                      finger_m=configs.held_finger_m), T_tcp_object=rel)
    assert placing.is_valid(q)


def test_the_carried_object_keeps_the_margin_not_twice_it(robot: model.Robot, configs: GraspConfigurations) -> None:
    """The held cube over the table (its contact with the table not allowed), a 10 mm margin: 15 mm above the table
    is valid, 5 mm is not; with a 4 mm table margin, 5 mm is valid. Each counted pair of geoms has one margin,
    whatever rule MuJoCo combines two geoms' margins by (MuJoCo 4 adds them: a margin on the object as well as on
    the table kept it 20 mm away)."""
    rel = configs.targets.T_tcp_object
    place = configs.targets.place
    heights = {}
    for above_m in (0.015, 0.005):  # the cube's bottom above the table (it hangs 1 mm above it at the place target)
        raised = pin.SE3(place.rotation, place.translation + np.array([0.0, 0.0, above_m - 0.001]))
        heights[above_m] = solve_ik(robot, raised, configs.place.q, "raised place").q
    for table_margin_m, valid in ((None, {0.015: True, 0.005: False}), (0.004, {0.015: True, 0.005: True})):
        checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.01, object_held=True, allow_object_table=False,
                                                          table_margin_m=table_margin_m,
                                                          finger_m=configs.held_finger_m), T_tcp_object=rel)
        for above_m, q in heights.items():
            assert checker.is_valid(q) == valid[above_m], (table_margin_m, above_m, checker.colliding_pairs(q))


def test_table_margin_keeps_the_cushion_from_walls_only(robot: model.Robot) -> None:
    """``table_margin_m`` = 0 with a 10 mm margin: finger tips 4 mm above the table pass, the table counts at
    contact only (the robot geoms still keep the margin from everything else)."""
    z = robot.scene.table_height_m + TIP_BELOW_TCP_M + 0.004
    q = _tcp_at(robot, (0.45, 0.0, z))
    assert not CollisionChecker(robot, CollisionPolicy(margin_m=0.01)).is_valid(q)
    assert CollisionChecker(robot, CollisionPolicy(margin_m=0.01, table_margin_m=0.0)).is_valid(q)
    with pytest.raises(ConfigError, match=r"^collision\.table_margin_m = -0\.001 is invalid"):
        CollisionPolicy(table_margin_m=-0.001)


def test_one_checker_re_aimed_with_set_held_agrees_with_new_ones(robot: model.Robot,
                                                                   configs: GraspConfigurations) -> None:
    """A checker whose held object is moved with ``set_held`` answers as one built with that pose and opening."""
    policy = CollisionPolicy(margin_m=0.005, object_held=True, allow_object_table=False)
    reused = CollisionChecker(robot, policy)
    rng = np.random.default_rng(3)
    qs = np.vstack([configs.place.q, configs.preplace.q, configs.place.q + rng.normal(0.0, 0.05, (20, 6))])
    for dz, finger in ((0.0, configs.held_finger_m), (-0.02, 0.0), (0.03, 0.01)):
        rel = configs.targets.T_tcp_object * pin.SE3(np.eye(3), np.array([0.0, 0.0, dz]))
        reused.set_held(rel, finger)
        fresh = CollisionChecker(robot, CollisionPolicy(margin_m=0.005, object_held=True, allow_object_table=False,
                                                        finger_m=finger), T_tcp_object=rel)
        np.testing.assert_array_equal(reused.are_valid(qs), fresh.are_valid(qs))
        for q in qs[:4]:
            assert reused.colliding_pairs(q) == fresh.colliding_pairs(q)


def test_checkers_in_the_same_state_share_a_model_and_re_aiming_one_leaves_the_others_alone(
        robot: model.Robot, configs: GraspConfigurations) -> None:
    """Checkers of one scene, policy and held pose share one model; a checker re-aimed (set_held, or set_world
    bringing a parked body within reach) takes another, and the one it shared with answers as before, as does a
    checker built from scratch (every cache emptied)."""
    policy = CollisionPolicy(margin_m=0.01, object_held=True, finger_m=configs.held_finger_m)
    rel = configs.targets.T_tcp_object
    a, b = CollisionChecker(robot, policy, T_tcp_object=rel), CollisionChecker(robot, policy, T_tcp_object=rel)
    assert a._m is b._m
    qs = robot.home_q + np.random.default_rng(13).normal(0.0, 0.8, (300, 6))
    before = b.are_valid(qs)
    assert 0 < before.sum() < len(qs)
    a.set_held(rel * pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.05])))
    d = robot.make_data()
    d.mocap_pos[robot.mj.body(model.INTRUDER).mocapid[0]] = [0.45, 0.0, 0.5]
    a.set_world(d)
    assert a._m is not b._m and a.far_bodies == b.far_bodies - 1
    assert not np.array_equal(a.are_valid(qs), before)
    np.testing.assert_array_equal(b.are_valid(qs), before)
    collision._model_family.cache_clear()
    collision._checker_model.cache_clear()
    fresh = CollisionChecker(robot, policy, T_tcp_object=rel)
    assert fresh._m is not b._m
    np.testing.assert_array_equal(fresh.are_valid(qs), before)


def test_checkers_sharing_one_data_answer_as_checkers_on_their_own_when_used_in_turn(
        robot: model.Robot, configs: GraspConfigurations) -> None:
    """The checkers of a scene share one MjData, each loading its own state (world, fingers) when another used it
    last: used in turn, configuration by configuration, they answer as checkers that each have data of their own."""
    d = robot.make_data()
    d.mocap_pos[robot.mj.body(model.INTRUDER).mocapid[0]] = [0.45, 0.0, 0.5]
    rel = configs.targets.T_tcp_object
    makers = [lambda: CollisionChecker(robot, CollisionPolicy(margin_m=0.01), world=d),
              lambda: CollisionChecker(robot, CollisionPolicy(margin_m=0.01)),
              lambda: CollisionChecker(robot, CollisionPolicy(margin_m=0.01, object_held=True,
                                                              finger_m=configs.held_finger_m), T_tcp_object=rel),
              lambda: CollisionChecker(robot, CollisionPolicy(margin_m=0.0, object_held=True, finger_m=0.0),
                                       T_tcp_object=rel * pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.03])))]
    alone = []
    for make in makers:
        collision._shared_data.cache_clear()  # (each of these gets data of its own)
        alone.append(make())
    collision._shared_data.cache_clear()
    shared = [make() for make in makers]
    assert len({id(c._d) for c in shared}) == 1 and len({id(c._d) for c in alone}) == len(alone)
    qs = robot.home_q + np.random.default_rng(17).normal(0.0, 0.8, (200, 6))
    for q in qs:
        for a, b in zip(alone, shared, strict=True):
            assert a.is_valid(q) == b.is_valid(q)
    ref = [a.are_valid(qs) for a in alone]
    assert len({r.tobytes() for r in ref}) == len(ref)  # (the four differ: the test can tell them apart)
    for k in range(3):
        for a, b in zip(ref, shared, strict=True):
            np.testing.assert_array_equal(b.are_valid(qs[k::3]), a[k::3])
    shared[0].set_world(robot.make_data())  # the intruder parked again: as the second one
    np.testing.assert_array_equal(shared[0].are_valid(qs), ref[1])
    np.testing.assert_array_equal(shared[1].are_valid(qs), ref[1])


def test_policy_validation() -> None:
    with pytest.raises(ConfigError, match=r"^collision\.margin_m = -0\.01 is invalid"):
        CollisionPolicy(margin_m=-0.01)
    with pytest.raises(ConfigError, match=r"^collision\.finger_m = 0\.05 is invalid"):
        CollisionPolicy(finger_m=0.05)


def test_far_bodies_are_switched_off_without_changing_an_answer(robot: model.Robot,
                                                                 configs: GraspConfigurations) -> None:
    """The intruder and the 64 seen-obstacle columns, parked far away, are out of the broad phase; moved next to
    the arm (set_world) they count again. A checker that keeps every body answers the same throughout."""
    rng = np.random.default_rng(7)
    qs = robot.home_q + rng.normal(0.0, 0.8, (300, 6))
    rel = configs.targets.T_tcp_object
    for policy in (CollisionPolicy(margin_m=0.01),
                   CollisionPolicy(margin_m=0.01, object_held=True, finger_m=configs.held_finger_m)):
        culled = CollisionChecker(robot, policy, T_tcp_object=rel)
        full = CollisionChecker(robot, policy, T_tcp_object=rel, cull_far=False)
        assert culled.far_bodies == 1 + len(model.SEEN_OBSTACLE_NAMES) and full.far_bodies == 0
        np.testing.assert_array_equal(culled.are_valid(qs), full.are_valid(qs))
        # the intruder and one column moved in front of the arm: switched on again
        d = robot.make_data()
        d.mocap_pos[robot.mj.body(model.INTRUDER).mocapid[0]] = [0.45, 0.0, 0.5]
        d.mocap_pos[robot.mj.body(model.SEEN_OBSTACLE_NAMES[3]).mocapid[0]] = [0.35, 0.25, 0.4]
        for checker in (culled, full):
            checker.set_world(d)
        assert culled.far_bodies == len(model.SEEN_OBSTACLE_NAMES) - 1
        blocked = _tcp_at(robot, (0.45, 0.0, 0.5))
        assert "intruder" in {name for pair in culled.colliding_pairs(blocked) for name in pair}
        np.testing.assert_array_equal(culled.are_valid(qs), full.are_valid(qs))
        # parked again: off again
        for checker in (culled, full):
            checker.set_world(robot.make_data())
        assert culled.far_bodies == 1 + len(model.SEEN_OBSTACLE_NAMES)
        assert culled.is_valid(blocked) == full.is_valid(blocked)


def test_reach_bounds_every_robot_geom_in_every_configuration(robot: model.Robot,
                                                              configs: GraspConfigurations) -> None:
    """reach_m is a bound along the kinematic chain: every colliding robot geom (and the carried object), its
    bounding sphere and margin included, stays within it from the base, whatever the joint angles."""
    policy = CollisionPolicy(margin_m=0.01, object_held=True, finger_m=configs.held_finger_m)
    checker = CollisionChecker(robot, policy, T_tcp_object=configs.targets.T_tcp_object)
    reach = checker.reach_m()
    m = checker._m
    d = mujoco.MjData(m)
    robot_geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in robot.handles.robot_bodies | {
        mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "held_object")} and checker._contype[g]]
    arm = m.jnt_qposadr[[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in model.ARM_JOINTS]]
    rng = np.random.default_rng(11)
    farthest = 0.0
    for q in rng.uniform(-np.pi, np.pi, (500, 6)):
        d.qpos[arm] = q
        mujoco.mj_kinematics(m, d)
        far = np.linalg.norm(d.geom_xpos[robot_geoms], axis=1) + m.geom_rbound[robot_geoms] + m.geom_margin[
            robot_geoms]
        farthest = max(farthest, float(far.max()))
    print(f"\nreach bound {reach:.3f} m, farthest geom seen {farthest:.3f} m")
    assert farthest <= reach
    assert reach < 2.0  # and not absurdly loose: the parked obstacles (7 m away) are beyond it


def test_first_invalid_stops_at_the_first_collision_and_counts_its_checks(robot: model.Robot) -> None:
    checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    rng = np.random.default_rng(5)
    qs = robot.home_q + rng.normal(0.0, 1.0, (60, 6))
    valid = checker.are_valid(qs)
    assert not valid.all() and valid[0]
    checker.checks = 0
    first = checker.first_invalid(qs)
    assert first == int(np.flatnonzero(~valid)[0])
    assert checker.checks == first + 1
    assert checker.all_valid(qs[:first]) and not checker.all_valid(qs)
    checker.checks = 0
    assert checker.first_invalid(qs[valid]) == -1 and checker.checks == int(valid.sum())
    assert checker.first_invalid(robot.home_q) == -1  # a single configuration
