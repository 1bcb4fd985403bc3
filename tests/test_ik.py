"""Tests of pickplace.robot.ik and the four grasp configurations (pickplace.grasping: configurations, targets)."""

from __future__ import annotations

import math
import re

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import ConfigError, UnreachableTarget
from pickplace.grasping.configurations import GraspConfigurations, solve_grasp_configurations
from pickplace.grasping.targets import top_down
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.robot import model
from pickplace.robot.ik import IKConfig, IKStatus, solve_ik
from pickplace.robot.kinematics import frame_pose, rot_z, wrap_to_pi
from pickplace.world.config import SceneConfig

TOL = 1e-4


def _rotation_angle(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.linalg.norm(pin.log3(R_a.T @ R_b)))


def _pin_tcp(robot: model.Robot, q: np.ndarray, finger: float = 0.0) -> pin.SE3:
    return frame_pose(robot.pin, robot.pin.createData(), robot.pin_q(q, finger), robot.pin_tcp_frame)


def _mj_tcp(robot: model.Robot, q: np.ndarray, finger: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    d.qpos[h.arm_qpos] = q
    d.qpos[h.finger_qpos] = finger
    mujoco.mj_kinematics(m, d)
    return d.site_xpos[h.tcp_site].copy(), d.site_xmat[h.tcp_site].reshape(3, 3).copy()


def _check_solved(robot: model.Robot, configs: GraspConfigurations, *, scene_label: str = "") -> None:
    """Every target converged, FK (Pinocchio and MuJoCo) lands on it, within limits, collision free."""
    free = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    carry = configs.carrying_checker(robot, margin_m=0.0)
    targets = dict(configs.targets.named())
    for r in configs.results():
        T = targets[r.name]
        assert r.success, (scene_label, r.name, r.status)
        assert r.status is IKStatus.CONVERGED
        assert r.position_error_m < TOL, (scene_label, r.name)
        assert r.orientation_error_rad < TOL, (scene_label, r.name)
        T_pin = _pin_tcp(robot, r.q)
        p_mj, R_mj = _mj_tcp(robot, r.q, configs.held_finger_m)
        errs = (
            float(np.linalg.norm(T_pin.translation - T.translation)),
            _rotation_angle(T_pin.rotation, T.rotation),
            float(np.linalg.norm(p_mj - T.translation)),
            _rotation_angle(R_mj, T.rotation),
        )
        print(f"{scene_label}{r.name:9s} reported {r.position_error_m:.2e} m {r.orientation_error_rad:.2e} rad;"
              f" FK pin {errs[0]:.2e} m {errs[1]:.2e} rad, mujoco {errs[2]:.2e} m {errs[3]:.2e} rad,"
              f" {r.iterations} it")
        assert max(errs) < TOL, (scene_label, r.name, errs)
        # the reported residual is the measured one
        assert r.position_error_m == pytest.approx(errs[0], abs=1e-12)
        assert r.orientation_error_rad == pytest.approx(errs[1], abs=1e-12)
        assert np.all(r.q >= robot.arm_lower)
        assert np.all(r.q <= robot.arm_upper)
        assert free.colliding_pairs(r.q) == [], (scene_label, r.name)
        if r.name == "preplace":
            assert carry.colliding_pairs(r.q) == [], (scene_label, r.name)


def test_targets_are_solved(robot: model.Robot, configs: GraspConfigurations) -> None:
    print()
    _check_solved(robot, configs)
    assert [r.name for r in configs.results()] == ["pregrasp", "grasp", "lift", "preplace", "place", "retreat"]
    # a top-down grasp lifts back along its approach, on the same IK branch: to the pregrasp's configuration
    # (both converge to 1e-4 of the same pose, so they agree to well within a milliradian)
    np.testing.assert_allclose(configs.lift.q, configs.pregrasp.q, rtol=0, atol=1e-3)
    assert configs.targets.retreat_rise_m == 0.0  # nothing near the goal: back off 6 cm up and go
    assert configs.targets.retreat_back_m == pytest.approx(0.06, abs=1e-12)
    assert configs.grasps_tried == 1


def test_targets_geometry(robot: model.Robot, configs: GraspConfigurations) -> None:
    """Top-down tcp: over the cube at the grasp, over the goal at the place, 0.15 m above both for the pre-poses."""
    tg, scene = configs.targets, robot.scene
    for _, T in tg.named():
        np.testing.assert_allclose(T.rotation[:, 2], [0.0, 0.0, -1.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(tg.grasp.translation[:2], scene.start_xy_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tg.place.translation[:2], scene.goal_xy_m, rtol=0, atol=1e-12)
    assert tg.pregrasp.translation[2] - tg.grasp.translation[2] == pytest.approx(0.150, abs=1e-12)
    assert tg.preplace.translation[2] - tg.place.translation[2] == pytest.approx(0.150, abs=1e-12)
    np.testing.assert_allclose(tg.lift.translation, tg.pregrasp.translation, rtol=0, atol=1e-12)
    # for the default 40 mm cube the tcp is at its centre, the finger tips 5 mm above the table
    np.testing.assert_allclose(tg.T_object_tcp.translation, 0.0, rtol=0, atol=1e-12)
    assert tg.grasp.translation[2] == pytest.approx(scene.rest_z_m, abs=1e-12)
    assert tg.width_m == pytest.approx(0.040, abs=1e-12)


def test_round_trip_from_home(robot: model.Robot) -> None:
    rng = np.random.default_rng(42)
    worst_p = worst_r = 0.0
    for _ in range(20):
        q_true = robot.home_q + rng.uniform(-0.5, 0.5, 6)
        T = _pin_tcp(robot, q_true)
        r = solve_ik(robot, T, robot.home_q, name="round trip")
        T_sol = _pin_tcp(robot, r.q)
        p_err = float(np.linalg.norm(T_sol.translation - T.translation))
        r_err = _rotation_angle(T_sol.rotation, T.rotation)
        worst_p, worst_r = max(worst_p, p_err), max(worst_r, r_err)
        assert r.success
        assert p_err < TOL
        assert r_err < TOL
        assert np.all(r.q >= robot.arm_lower)
        assert np.all(r.q <= robot.arm_upper)
    print(f"\nround trip: worst {worst_p:.2e} m, {worst_r:.2e} rad")


def test_unreachable_target_raises(robot: model.Robot) -> None:
    T = pin.SE3(top_down(0.0), np.array([1.5, 0.0, 0.4]))
    with pytest.raises(UnreachableTarget) as info:
        solve_ik(robot, T, robot.home_q, name="far away")
    err = info.value
    msg = str(err)
    print(f"\n{msg}")
    assert err.target == "far away"
    assert "'far away'" in msg
    assert "(1.500, 0.000, 0.400)" in msg
    # the residual is real (the UR5e reaches 0.85 m from the shoulder, plus the tool) and in the message
    assert err.position_error_m > 0.3
    assert math.isfinite(err.orientation_error_rad)
    assert f"residual {err.position_error_m * 1e3:.3g} mm" in msg
    assert f"{err.orientation_error_rad:.3g} rad" in msg


@pytest.mark.parametrize("yaw", [-0.7, -0.3, 0.3, 0.7])
def test_cube_yaw_is_followed(yaw: float) -> None:
    robot = model.build(SceneConfig.from_mapping(dict(cube_yaw_rad=yaw)))
    configs = solve_grasp_configurations(robot)
    R = configs.targets.grasp.rotation
    closing = R[:, 1]
    assert abs(closing[2]) <= 1e-12  # horizontal
    cube_R = rot_z(yaw)
    # angle between the closing axis and the cube's x axis, modulo pi/2: 0 means across two faces
    angle = math.atan2(np.cross(cube_R[:, 0], closing)[2], float(cube_R[:, 0] @ closing))
    off = abs(float(wrap_to_pi(4 * angle))) / 4
    grasp_yaw = math.atan2(R[1, 0], R[0, 0])
    print(f"\nyaw {yaw:+.1f}: grasp yaw {grasp_yaw:+.4f} rad, off-face {off:.1e} rad")
    assert off < 1e-9
    # the compiled cube has that yaw too
    q = robot.mj.body_quat[robot.handles.object_body]
    assert 2 * math.atan2(q[3], q[0]) == pytest.approx(yaw, abs=1e-12)
    # the wrist turns by less than 45 degrees from its home twist to do it
    T_home = _pin_tcp(robot, robot.home_q)
    twist_home = math.atan2(T_home.rotation[1, 0], T_home.rotation[0, 0]) - math.atan2(
        T_home.translation[1], T_home.translation[0])
    cube_xy = robot.scene.start_xy_m
    twist = grasp_yaw - math.atan2(cube_xy[1], cube_xy[0])
    assert abs(float(wrap_to_pi(twist - twist_home))) <= math.pi / 4 + 1e-12
    _check_solved(robot, configs, scene_label=f"yaw {yaw:+.1f} ")


def test_obstacle_scene_is_solved() -> None:
    robot = model.build(SceneConfig(obstacle=True))
    configs = solve_grasp_configurations(robot)
    print()
    _check_solved(robot, configs, scene_label="obstacle ")


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"step": 0.0}, "ik.step"),
        ({"step": 1.5}, "ik.step"),
        ({"tolerance": -1e-4}, "ik.tolerance"),
        ({"tolerance": math.nan}, "ik.tolerance"),
        ({"damping_sq": -1.0}, "ik.damping_sq"),
        ({"max_iterations": 0}, "ik.max_iterations"),
        ({"max_iterations": 10.5}, "ik.max_iterations"),
        ({"restarts": -1}, "ik.restarts"),
        ({"seed": -1}, "ik.seed"),
    ],
)
def test_ik_config_validation(kwargs: dict, field: str) -> None:
    value = next(iter(kwargs.values()))
    with pytest.raises(ConfigError, match="^" + re.escape(f"{field} = ")) as info:
        IKConfig(**kwargs)
    assert info.value.field == field
    assert repr(value) in str(info.value)
