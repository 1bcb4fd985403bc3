"""Joint and Cartesian impedance control on the real MuJoCo scene and Pinocchio model (no mocks).

Every test prints its measured figures (``pytest -s``) and asserts them with explicit tolerances.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import ConfigError, ControlError, GraspFailed
from pickplace.grasping.configurations import GraspConfigurations
from pickplace.motion import control
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.motion.control import ControlConfig, Payload
from pickplace.motion.loop import ERROR_CHECK_STEPS, ServoGains
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot import gripper
from pickplace.robot.model import Robot

#: A stretched pose behind the robot, away from the table: about 61 N m of gravity on the shoulder.
STRETCHED_Q = np.array([-0.4, -0.5, 0.2, -1.2, 1.5708, 0.0])


def _data_at(robot: Robot, q: np.ndarray) -> mujoco.MjData:
    """Fresh data (gripper open, cube at its start) with the arm at rest at ``q``."""
    d = robot.make_data()
    d.qpos[robot.handles.arm_qpos] = q
    mujoco.mj_forward(robot.mj, d)
    return d


def _tcp(robot: Robot, d: mujoco.MjData) -> np.ndarray:
    """Tcp position (3,) (m) of the current state, by MuJoCo's own kinematics."""
    mujoco.mj_kinematics(robot.mj, d)
    return d.site_xpos[robot.handles.tcp_site].copy()


# --------------------------------------------------------------------------- #
# configuration
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"joint_kp_nm_rad": (-1.0, 200, 200, 100, 100, 100)}, "control.joint_kp_nm_rad[0]"),
    ({"joint_kp_nm_rad": (200, 200, math.nan, 100, 100, 100)}, "control.joint_kp_nm_rad[2]"),
    ({"joint_kp_nm_rad": (200, 200, 200)}, "control.joint_kp_nm_rad"),
    ({"joint_damping_ratio": 0.0}, "control.joint_damping_ratio"),
    ({"feedforward": 1}, "control.feedforward"),
    ({"comply_while_closing": "yes"}, "control.comply_while_closing"),
    ({"cartesian_stiffness_n_m": -5.0}, "control.cartesian_stiffness_n_m"),
    ({"cartesian_rot_stiffness_nm_rad": math.inf}, "control.cartesian_rot_stiffness_nm_rad"),
    ({"posture_kp_nm_rad": math.nan}, "control.posture_kp_nm_rad"),
    ({"vertical_speed_m_s": 0.0}, "control.vertical_speed_m_s"),
    ({"height_tolerance_m": -1e-3}, "control.height_tolerance_m"),
    ({"settle_timeout_s": "1"}, "control.settle_timeout_s"),
])
def test_config_rejects_bad_values(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        ControlConfig(**kwargs)
    assert info.value.field == field
    assert field in str(info.value)


def test_config_defaults_and_gains() -> None:
    cfg = ControlConfig()
    np.testing.assert_allclose(cfg.joint_kd, 2.0 * np.sqrt([200, 200, 200, 100, 100, 100]))
    assert cfg.feedforward is True
    # minimum-jerk peak speed 1.875 d / T: 0.15 m at 0.6 m/s peak takes 0.46875 s; the peak acceleration
    # 10/sqrt(3) d / T^2 then is 3.94 m/s^2, inside the 4 m/s^2 limit
    assert cfg.vertical_duration_s(0.15) == pytest.approx(1.875 * 0.15 / 0.6)
    assert 10 / np.sqrt(3) * 0.15 / cfg.vertical_duration_s(0.15) ** 2 <= cfg.vertical_accel_m_s2
    assert cfg.vertical_duration_s(0.0) == cfg.vertical_min_duration_s
    with pytest.raises(ConfigError, match=r"payload\.mass_kg"):
        Payload(mass_kg=-0.1)


# --------------------------------------------------------------------------- #
# control laws
# --------------------------------------------------------------------------- #


def test_laws_at_rest_are_mujocos_gravity(robot: Robot) -> None:
    """On the reference and at rest, both laws output exactly the gravity torque MuJoCo applies."""
    d = _data_at(robot, STRETCHED_Q)
    g_mj = d.qfrc_bias[robot.handles.arm_dof]
    arm = control.arm_model(robot)
    cfg = ControlConfig()
    z = np.zeros(6)
    tau_j = control.joint_impedance(arm, STRETCHED_Q, z, STRETCHED_Q, z, z, cfg.joint_kp, cfg.joint_kd)
    tau_g = control.joint_impedance(arm, STRETCHED_Q, z, STRETCHED_Q, z, z, cfg.joint_kp, cfg.joint_kd,
                                    feedforward=False)
    p = d.site_xpos[robot.handles.tcp_site].copy()
    R = d.site_xmat[robot.handles.tcp_site].reshape(3, 3).copy()
    cmd = control.cartesian_impedance(arm, STRETCHED_Q, z, p, np.zeros(3), np.zeros(3), R, cfg.cartesian_stiffness,
                                      1.0, STRETCHED_Q, cfg.posture_kp_nm_rad, cfg.posture_kd)
    worst = max(np.abs(t - g_mj).max() for t in (tau_j, tau_g, cmd.tau))
    print(f"\nlaws at rest vs MuJoCo qfrc_bias: max |diff| {worst:.2e} N m (gravity up to {np.abs(g_mj).max():.1f})")
    assert worst < 1e-6
    assert np.abs(cmd.error).max() < 1e-9


def _operational_space_reference(arm: control.ArmModel, q: np.ndarray, qd: np.ndarray, p_ref: np.ndarray,
                                 v_ref: np.ndarray, a_ref: np.ndarray, R_ref: np.ndarray, K: np.ndarray, zeta: float,
                                 q_post: np.ndarray, kp_post: float, kd_post: float, finger_m: float,
                                 bandwidth: float, integral: np.ndarray) -> np.ndarray:
    """The Cartesian law written out as its docstring states it, with Pinocchio's M^-1 and an explicit Lambda and
    null-space projector (the form the law had before it went through J^-1)."""
    model, data = arm.model.copy(), arm.model.createData()
    qp = np.concatenate([q, [finger_m, finger_m]])
    vp = np.concatenate([qd, [0.0, 0.0]])
    pin.computeAllTerms(model, data, qp, vp)
    J = pin.getFrameJacobian(model, data, arm.tcp_frame, pin.LOCAL_WORLD_ALIGNED)[:, :6]
    jdot_qd = pin.getFrameClassicalAcceleration(model, data, arm.tcp_frame, pin.LOCAL_WORLD_ALIGNED).vector
    T = pin.updateFramePlacement(model, data, arm.tcp_frame)
    Minv = pin.computeMinverse(model, data, qp)[:6, :6]
    Lam = np.linalg.inv(J @ Minv @ J.T)
    e = np.concatenate([p_ref - T.translation, pin.log3(R_ref @ T.rotation.T)])
    edot = np.concatenate([v_ref, np.zeros(3)]) - J @ qd
    acc = np.concatenate([a_ref, np.zeros(3)]) - jdot_qd
    tau0 = kp_post * (q_post - q) - kd_post * qd
    if bandwidth > 0.0:
        F = Lam @ (acc + bandwidth**2 * e + 2.0 * zeta * bandwidth * edot) + integral
    else:
        F = Lam @ acc + K * e + 2.0 * zeta * np.sqrt(K * np.diag(Lam)) * edot + integral
    N_T = np.eye(6) - J.T @ Lam @ J @ Minv
    return J.T @ F + N_T @ tau0 + data.nle[:6] + arm.damping * qd


def test_cartesian_law_is_the_operational_space_law(robot: Robot) -> None:
    """Through J^-1 (Lambda = J^-T M J^-1, an empty null space) the law gives the operational-space torques of its
    docstring, computed with M^-1 and the projector, to rounding: at 200 random states and references, holding a
    payload, with the fixed gains and the bandwidth-shaped ones with integral action."""
    arm = control.arm_model(robot, Payload(0.3, (0.0, 0.0, 0.02), (1e-4, 1e-4, 1e-4)))
    rng = np.random.default_rng(7)
    K = ControlConfig().cartesian_stiffness
    worst = 0.0
    for _ in range(200):
        q = robot.home_q + rng.normal(0.0, 0.5, 6)
        qd = rng.normal(0.0, 1.0, 6)
        p_ref, v_ref, a_ref = rng.normal(0.4, 0.1, 3), rng.normal(0.0, 0.1, 3), rng.normal(0.0, 1.0, 3)
        R_ref = pin.exp3(rng.normal(0.0, 0.3, 3))
        finger = float(rng.uniform(0.0, 0.04))
        for bandwidth in (0.0, 80.0):
            integral = rng.normal(0.0, 1.0, 6)
            cmd = control.cartesian_impedance(arm, q, qd, p_ref, v_ref, a_ref, R_ref, K, 1.0, q + 0.05, 10.0, 6.0,
                                              finger_m=finger, integral=integral, bandwidth_rad_s=bandwidth)
            ref = _operational_space_reference(arm, q, qd, p_ref, v_ref, a_ref, R_ref, K, 1.0, q + 0.05, 10.0, 6.0,
                                               finger, bandwidth, integral)
            worst = max(worst, float(np.abs(cmd.tau - ref).max() / np.abs(ref).max()))
    print(f"\nCartesian law vs the operational-space form: worst relative difference {worst:.2e}")
    assert worst < 1e-8


def test_payload_adds_its_weight_through_the_tcp_jacobian(robot: Robot) -> None:
    """A 1 kg payload at the tcp adds J_v^T (0, 0, m g) to the gravity torque."""
    q = STRETCHED_Q
    z = np.zeros(6)
    kp = kd = np.zeros(6)
    bare = control.joint_impedance(control.arm_model(robot), q, z, q, z, z, kp, kd, feedforward=False)
    loaded = control.joint_impedance(control.arm_model(robot, Payload(1.0)), q, z, q, z, z, kp, kd,
                                     feedforward=False)
    pdata = robot.pin.createData()
    J = pin.computeFrameJacobian(robot.pin, pdata, robot.pin_q(q), robot.pin_tcp_frame, pin.LOCAL_WORLD_ALIGNED)
    expected = J[:3, :6].T @ np.array([0.0, 0.0, 9.81])
    print(f"\npayload gravity torque: {np.round(loaded - bare, 4)} N m, expected {np.round(expected, 4)}")
    np.testing.assert_allclose(loaded - bare, expected, atol=1e-9)


def test_min_jerk_profile() -> None:
    t = np.linspace(-0.1, 1.1, 1201)
    s, sd, sdd = control.min_jerk(t, 1.0)
    assert s[0] == 0.0 and s[-1] == 1.0 and sd[0] == 0.0 and sd[-1] == 0.0
    assert sd.max() == pytest.approx(1.875, rel=1e-4)
    np.testing.assert_allclose(np.gradient(s, t)[110:1090], sd[110:1090], atol=1e-4)
    np.testing.assert_allclose(np.gradient(sd, t)[110:1090], sdd[110:1090], atol=1e-3)


# --------------------------------------------------------------------------- #
# joint loops
# --------------------------------------------------------------------------- #


def test_gravity_compensation_holds_four_poses(robot: Robot, configs: GraspConfigurations) -> None:
    """Joint impedance without feedforward holds the arm still for 2 s at four collision-free poses."""
    checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    cfg = ControlConfig(feedforward=False)
    poses = {"home": robot.home_q, "pregrasp": configs.pregrasp.q, "preplace": configs.preplace.q,
             "stretched": STRETCHED_Q}
    print()
    for name, q in poses.items():
        assert checker.is_valid(q), name
        d = _data_at(robot, q)
        rec = control.hold(robot, d, q, 2.0, cfg)
        print(f"hold {name:9s} 2 s: drift max {rec.max_error_rad:.2e} rad, final {rec.final_error_rad:.2e} rad, "
              f"|tau| max {np.abs(rec.tau).max():.1f} N m, {rec.saturation_events} saturated steps")
        assert rec.steps == 2000 and rec.duration_s == pytest.approx(2.0)
        assert rec.max_error_rad < 1e-4
        assert rec.saturation_events == 0


def test_tracks_home_to_pregrasp(robot: Robot, configs: GraspConfigurations) -> None:
    """A TOPP-RA trajectory (at the UR5e's limits) is tracked within 2 mrad, without saturating."""
    traj = retime(np.array([robot.home_q, configs.pregrasp.q]), TimingConfig.ur5e())
    d = _data_at(robot, robot.home_q)
    rec = control.track(robot, d, traj, ControlConfig())
    no_ff = control.track(robot, _data_at(robot, robot.home_q), traj, ControlConfig(feedforward=False))
    print(f"\ntrack home->pregrasp ({traj.duration_s:.3f} s + 0.1 s settle): max {rec.max_error_rad * 1e3:.2e} mrad, "
          f"rms {rec.rms_error_rad * 1e3:.2e} mrad, final {rec.final_error_rad * 1e3:.2e} mrad, "
          f"{rec.saturation_events} saturated steps; without feedforward max {no_ff.max_error_rad * 1e3:.2f} mrad")
    assert rec.max_error_rad < 2e-3
    assert rec.final_error_rad < 1e-4
    assert rec.saturation_events == 0
    assert rec.steps == math.ceil(traj.duration_s / 1e-3 - 1e-9) + 100
    assert rec.q.shape == rec.q_ref.shape == (rec.steps + 1, 6) and rec.tau.shape == (rec.steps, 6)
    np.testing.assert_allclose(rec.q_ref[-1], configs.pregrasp.q, atol=1e-12)
    assert no_ff.max_error_rad > 10 * rec.max_error_rad  # feedforward is what makes it accurate


def test_cube_in_hand_lift_and_carry(robot: Robot, configs: GraspConfigurations) -> None:
    """Close on the cube, lift it 0.15 m with Cartesian impedance and carry it to preplace with the payload."""
    payload = Payload.held(robot.scene.object, configs.targets.T_tcp_object)
    cfg = ControlConfig()
    grasp_z = configs.targets.grasp.translation[2]

    def grasp_and_lift() -> tuple[mujoco.MjData, control.CartesianRecord]:
        d = _data_at(robot, configs.grasp.q)
        gripper.command(robot, d, closed=True)
        control.hold(robot, d, configs.grasp.q, 0.5, cfg)  # the table carries the cube while it closes
        assert gripper.in_contact(robot, d, min_force_n=10.0)
        lift = control.move_vertical(robot, d, grasp_z + 0.15, cfg, payload=payload)
        return d, lift

    d, lift = grasp_and_lift()
    print(f"\nlift 0.15 m with the cube: final height error {lift.final_height_error_m * 1e3:.2e} mm, lateral drift "
          f"{lift.lateral_drift_max_m * 1e3:.3f} mm, orientation {lift.orientation_error_max_rad:.2e} rad, "
          f"{lift.duration_s:.3f} s, {lift.saturation_events} saturated steps")
    assert lift.reached
    assert abs(lift.final_height_error_m) < 5e-4
    assert lift.lateral_drift_max_m < 5e-4
    assert lift.orientation_error_max_rad < 1e-3
    assert lift.saturation_events == 0

    q_lifted = d.qpos[robot.handles.arm_qpos].copy()
    carry = retime(np.array([q_lifted, configs.preplace.q]), TimingConfig.ur5e(),
                   configs.carrying_checker(robot, margin_m=0.0).all_valid)
    rec = control.track(robot, d, carry, cfg, payload=payload)
    cube_in_tcp = d.xpos[robot.handles.object_body] - _tcp(robot, d)
    d2, _ = grasp_and_lift()
    without = control.track(robot, d2, carry, cfg)
    print(f"carry to preplace ({carry.duration_s:.3f} s): max error {rec.max_error_rad * 1e3:.3f} mrad with payload "
          f"compensation, {without.max_error_rad * 1e3:.3f} mrad without; {rec.saturation_events} saturated steps; "
          f"cube {np.linalg.norm(cube_in_tcp) * 1e3:.2f} mm from the tcp")
    assert rec.max_error_rad < 2e-3
    assert rec.saturation_events == 0
    assert without.max_error_rad > 2 * rec.max_error_rad
    assert gripper.in_contact(robot, d, min_force_n=10.0)
    assert np.linalg.norm(cube_in_tcp) < 2e-3


# --------------------------------------------------------------------------- #
# Cartesian loop
# --------------------------------------------------------------------------- #


def test_cartesian_descent_and_lift(robot: Robot, configs: GraspConfigurations) -> None:
    """Down 0.15 m from pregrasp (around the resting cube, gripper open) and back up."""
    d = _data_at(robot, configs.pregrasp.q)
    start = _tcp(robot, d)
    cfg = ControlConfig()
    print()
    for name, z in (("descent", start[2] - 0.15), ("lift", start[2])):
        rec = control.move_vertical(robot, d, z, cfg)
        tcp = _tcp(robot, d)
        print(f"{name}: {rec.duration_s:.3f} s (profile {rec.profile_duration_s:.3f} s), final height error "
              f"{rec.final_height_error_m * 1e3:.2e} mm (MuJoCo site {(tcp[2] - z) * 1e3:.2e} mm), lateral drift "
              f"{rec.lateral_drift_max_m * 1e3:.2e} mm, orientation {rec.orientation_error_max_rad:.2e} rad, "
              f"max |z - z_ref| {np.abs(rec.z - rec.z_ref).max() * 1e3:.2e} mm, {rec.saturation_events} saturated")
        assert rec.reached
        assert abs(rec.final_height_error_m) < 5e-4 and abs(tcp[2] - z) < 5e-4
        assert rec.lateral_drift_max_m < 5e-4 and np.linalg.norm(tcp[:2] - start[:2]) < 5e-4
        assert rec.orientation_error_max_rad < 1e-3
        assert rec.saturation_events == 0
        assert rec.z.shape == rec.z_ref.shape == rec.t.shape == (rec.steps + 1,)


# --------------------------------------------------------------------------- #
# failures
# --------------------------------------------------------------------------- #


def test_hook_exception_aborts_the_loop(robot: Robot) -> None:
    d = _data_at(robot, robot.home_q)
    d.ctrl[robot.handles.gripper_actuator] = 0.0123  # a value no loop would write
    calls = []

    def hook(data: mujoco.MjData) -> None:
        calls.append(data.time)
        if len(calls) == 5:
            raise GraspFailed("slip detected")

    with pytest.raises(GraspFailed, match="slip"):
        control.hold(robot, d, robot.home_q, 1.0, ControlConfig(), hook=hook)
    assert len(calls) == 5 and d.time == pytest.approx(0.005)
    assert d.ctrl[robot.handles.gripper_actuator] == 0.0123  # the loops never touch the gripper


def test_timeouts_and_tracking_bounds_raise(robot: Robot, configs: GraspConfigurations) -> None:
    # a height tolerance no real motion meets: times out 50 ms after the profile
    impossible = ControlConfig(height_tolerance_m=1e-12, settle_timeout_s=0.05)
    d = _data_at(robot, configs.pregrasp.q)
    z = configs.targets.pregrasp.translation[2] - 0.01
    with pytest.raises(ControlError, match="not settled") as info:
        control.move_vertical(robot, d, z, impossible)
    assert info.value.phase == "move_linear" and not info.value.record.reached
    rec = control.move_vertical(robot, _data_at(robot, configs.pregrasp.q), z, impossible, raise_on_timeout=False)
    assert not rec.reached and rec.duration_s == pytest.approx(rec.profile_duration_s + 0.05, abs=2e-3)

    # pushing the tcp into the table: the tcp error grows past its bound
    d = _data_at(robot, configs.pregrasp.q)
    with pytest.raises(ControlError, match="tcp error"):
        control.move_vertical(robot, d, robot.scene.table_height_m - 0.05, ControlConfig())

    # a start far from the trajectory exceeds the joint error bound at once
    traj = retime(np.array([robot.home_q, configs.pregrasp.q]), TimingConfig.ur5e())
    with pytest.raises(ControlError, match="joint error") as info:
        control.track(robot, _data_at(robot, STRETCHED_Q), traj, ControlConfig())
    assert info.value.record.steps == 0


# --------------------------------------------------------------------------- #
# torque limits
# --------------------------------------------------------------------------- #


def _actuator_torque(robot: Robot, d: mujoco.MjData) -> np.ndarray:
    return d.actuator_force[robot.handles.arm_actuators].copy()


def test_joint_torques_beyond_the_limits_are_clipped_and_counted(robot: Robot) -> None:
    """A stiff hold 0.08 rad away asks for ~8000 N m: every torque sent is within the UR5e's limits, and the
    clipped steps are counted."""
    limits = np.asarray(robot.torque_limits_nm)
    d = _data_at(robot, robot.home_q)
    stiff = ControlConfig(joint_kp_nm_rad=(1e5,) * 6)
    applied = []
    rec = control.hold(robot, d, robot.home_q + 0.08, 0.05, stiff, hook=lambda d: applied.append(
        _actuator_torque(robot, d)))
    print(f"\nstiff hold: {rec.saturation_events}/{rec.steps} steps clipped, |tau| max "
          f"{np.abs(rec.tau).max():.1f} N m (limits {limits.tolist()})")
    assert rec.saturation_events >= rec.steps // 2  # the error stays large for most of 50 ms
    assert np.all(np.abs(rec.tau) <= limits + 1e-9)
    assert np.max(np.abs(rec.tau) / limits) == pytest.approx(1.0, abs=1e-9)  # it did reach a limit
    assert np.all(np.abs(np.array(applied)) <= limits + 1e-9)


def test_cartesian_torques_beyond_the_limits_are_clipped_and_counted(robot: Robot,
                                                                     configs: GraspConfigurations) -> None:
    """A 5 cm vertical move in 30 ms (peak 320 m/s²) needs far more than the motors give: clipped and counted."""
    limits = np.asarray(robot.torque_limits_nm)
    d = _data_at(robot, configs.pregrasp.q)
    z = configs.targets.pregrasp.translation[2] + 0.05
    rec = control.move_vertical(robot, d, z, ControlConfig(max_tcp_error_m=1.0), duration_s=0.03,
                                raise_on_timeout=False)
    print(f"\nfast vertical move: {rec.saturation_events}/{rec.steps} steps clipped, |tau| max "
          f"{np.abs(rec.tau).max():.1f} N m, tcp error max {rec.position_error_max_m * 1e3:.1f} mm")
    assert rec.saturation_events >= 10
    assert np.all(np.abs(rec.tau) <= limits + 1e-9)
    assert rec.position_error_max_m > 1e-3  # the arm could not follow


def test_cartesian_tracking_error_is_the_distance_to_the_reference(robot: Robot,
                                                                   configs: GraspConfigurations) -> None:
    """The record's tcp error is measured: recomputed here from its own samples of z and the fixed x, y."""
    d = _data_at(robot, configs.pregrasp.q)
    start = _tcp(robot, d)
    rec = control.move_vertical(robot, d, start[2] - 0.15, ControlConfig())
    z_err = np.abs(rec.z - rec.z_ref)
    assert rec.position_error_max_m >= z_err.max() - 1e-12  # the distance is at least the height error
    assert rec.position_error_max_m <= math.hypot(z_err.max(), rec.lateral_drift_max_m) + 1e-12
    assert 0 < rec.position_error_rms_m <= rec.position_error_max_m < 5e-4


def test_stop_brings_a_fast_arm_to_rest_along_its_motion(robot: Robot) -> None:
    """An arm moving at close to the UR5e's top joint speed: the stop decelerates along the motion within the
    limits and ends at rest; holding where it stands instead overshoots by far more."""
    v0 = np.array([2.5, -2.0, 3.0, -3.0, 3.0, 3.0])
    decel = np.array(TimingConfig.ur5e().acceleration_limits_rad_s2)

    def moving() -> mujoco.MjData:
        d = _data_at(robot, STRETCHED_Q)
        d.qvel[robot.handles.arm_dof] = v0
        return d

    d = moving()
    rec = control.stop(robot, d, decel, ControlConfig(), settle_s=0.2)
    T = float(np.max(np.abs(v0) / decel))
    speed = float(np.abs(d.qvel[robot.handles.arm_dof]).max())
    travelled = d.qpos[robot.handles.arm_qpos] - STRETCHED_Q
    held = control.hold(robot, moving(), STRETCHED_Q, 0.2, ControlConfig(max_joint_error_rad=1.0))
    print(f"\nstop from {np.abs(v0).max():.1f} rad/s: {T:.3f} s, max error {rec.max_error_rad * 1e3:.2f} mrad, final "
          f"speed {speed:.1e} rad/s; a plain hold: max error {held.max_error_rad * 1e3:.1f} mrad")
    assert rec.duration_s == pytest.approx(T + 0.2, abs=2e-3)
    assert speed < 1e-3
    np.testing.assert_allclose(travelled, v0 * T / 2, atol=5e-3)  # along the motion, as far as the profile says
    assert rec.max_error_rad < 0.01
    assert held.max_error_rad > 5 * rec.max_error_rad
    with pytest.raises(ConfigError, match=r"stop\.decel_rad_s2"):
        control.stop(robot, moving(), (8.0, 8.0, 0.0, 16.0, 16.0, 16.0), ControlConfig())


def test_a_hold_that_complies_along_an_axis_yields_there_and_stays_stiff_across(robot: Robot,
                                                                               configs: GraspConfigurations) -> None:
    """A 20 N push on the hand along the pads' closing axis at the grasp pose for 0.3 s, realistic gains: held
    stiffly (integral action), the tcp ends where it was (within 0.2 mm); complying along the push, it moves
    with it (centimetres at the damping's pace), while across the push it stays within 0.5 mm (the
    reference's first-order step, J^-1 at each tick's pose) and its orientation within 1 mrad."""
    q = configs.grasp.q
    hand = mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY, "gripper_base")
    tcp = robot.handles.tcp_site
    results = {}
    for name, comply in (("stiff", None), ("comply", True)):
        d = _data_at(robot, q)
        mujoco.mj_forward(robot.mj, d)
        axis = d.site_xmat[tcp].reshape(3, 3)[:, 1].copy()  # the pads' closing axis
        p0, R0 = d.site_xpos[tcp].copy(), d.site_xmat[tcp].reshape(3, 3).copy()
        d.xfrc_applied[hand, :3] = 20.0 * axis
        rec = control.hold(robot, d, q, 0.3, ControlConfig.realistic(), comply_along=axis if comply else None)
        dp = d.site_xpos[tcp] - p0
        turn = float(np.linalg.norm(pin.log3(R0.T @ d.site_xmat[tcp].reshape(3, 3))))
        results[name] = (float(dp @ axis), float(np.linalg.norm(dp - (dp @ axis) * axis)), turn, rec.max_error_rad)
        print(f"{name}: along {dp @ axis * 1e3:.3f} mm, across {results[name][1] * 1e3:.3f} mm, turn "
              f"{turn * 1e3:.2f} mrad, joint error max {rec.max_error_rad * 1e3:.2f} mrad")
    along_stiff, across_stiff, turn_stiff, _ = results["stiff"]
    along, across, turn, _ = results["comply"]
    assert abs(along_stiff) < 2e-4 and across_stiff < 2e-4 and turn_stiff < 1e-3
    assert along > 5e-3  # it yields
    assert across < 5e-4 and turn < 1e-3  # and only along the axis


def test_comply_along_must_be_a_direction(robot: Robot) -> None:
    d = _data_at(robot, robot.home_q)
    with pytest.raises(ConfigError, match=r"hold\.comply_along"):
        control.hold(robot, d, robot.home_q, 0.01, ControlConfig(), comply_along=np.zeros(3))


# --------------------------------------------------------------------------- #
# joint servos (the ideal loop's joint trajectories and holds)
# --------------------------------------------------------------------------- #


def test_joint_servos_apply_joint_impedance_with_the_references_feedforward(robot: Robot) -> None:
    """With the servos' gain set and each step's control the setpoint from ``servo_setpoints`` less ``kd / kp`` times
    the velocities (what the loop sends), MuJoCo's actuators apply ``kp (q_ref - q) + kd (qd_ref - qd) +
    tau_ff(q_ref, qd_ref, qdd_ref)``, computed here independently with Pinocchio's RNEA on the controller's model,
    clipped to the torque limits."""
    rng = np.random.default_rng(7)
    h = robot.handles
    config = ControlConfig()
    kp, kd = config.joint_kp, config.joint_kd
    arm = control.arm_model(robot)
    limits = np.asarray(robot.torque_limits_nm)
    for _ in range(20):
        q = robot.home_q + rng.uniform(-0.3, 0.3, 6)
        qd = rng.uniform(-1.0, 1.0, 6)
        q_ref = q + rng.uniform(-0.01, 0.01, 6)
        qd_ref, qdd_ref = rng.uniform(-1.0, 1.0, 6), rng.uniform(-5.0, 5.0, 6)
        u = control.servo_setpoints(arm, q_ref[None], qd_ref[None], qdd_ref[None], kp, kd)[0]
        d = _data_at(robot, q)
        d.qvel[h.arm_dof] = qd
        with ServoGains(robot.mj, h.arm_actuators, kp):
            d.ctrl[h.arm_actuators] = u - kd / kp * qd
            mujoco.mj_forward(robot.mj, d)
        v, a = np.zeros(8), np.zeros(8)
        v[:6], a[:6] = qd_ref, qdd_ref
        ff = pin.rnea(arm.model, arm.model.createData(), robot.pin_q(q_ref), v, a)[:6] + arm.damping * qd_ref
        expected = np.clip(kp * (q_ref - q) + kd * (qd_ref - qd) + ff, -limits, limits)
        np.testing.assert_allclose(d.actuator_force[h.arm_actuators], expected, rtol=1e-9, atol=1e-9)
    # out of the block, they are torque motors again
    np.testing.assert_array_equal(robot.mj.actuator_gainprm[h.arm_actuators, 0], 1.0)
    np.testing.assert_array_equal(robot.mj.actuator_biasprm[h.arm_actuators, :3], 0.0)


def test_an_arm_on_its_reference_stays_on_it(robot: Robot, configs: GraspConfigurations) -> None:
    """The feedforward makes the servos exact: an arm that starts on a TOPP-RA trajectory at the UR5e's limits stays
    within a micro-radian of it (its model is the plant's, the feedforward taken on the reference)."""
    traj = retime(np.array([robot.home_q, configs.pregrasp.q]), TimingConfig.ur5e())
    rec = control.track(robot, _data_at(robot, robot.home_q), traj, ControlConfig())
    print(f"\njoint servos home->pregrasp: max {rec.max_error_rad:.2e} rad, rms {rec.rms_error_rad:.2e} rad")
    assert rec.max_error_rad < 1e-6
    assert rec.saturation_events == 0


def test_servo_gains_are_restored_when_a_hook_raises(robot: Robot) -> None:
    h = robot.handles
    traj = retime(np.array([robot.home_q, robot.home_q + 0.2]), TimingConfig.ur5e())
    seen: list[float] = []

    def hook(d: mujoco.MjData) -> None:
        seen.append(float(robot.mj.actuator_gainprm[h.arm_actuators[0], 0]))
        if len(seen) == 50:
            raise GraspFailed("stop here")

    with pytest.raises(GraspFailed):
        control.track(robot, _data_at(robot, robot.home_q), traj, ControlConfig(), hook=hook)
    assert seen[0] == pytest.approx(ControlConfig().joint_kp[0])  # the servo ran
    np.testing.assert_array_equal(robot.mj.actuator_gainprm[h.arm_actuators, 0], 1.0)
    np.testing.assert_array_equal(robot.mj.actuator_biasprm[h.arm_actuators, :3], 0.0)


def test_the_servos_joint_error_check_names_the_first_state_past_the_bound(robot: Robot) -> None:
    """The joint servos' loop checks every step's joint error, on the tape every few steps: a state knocked 0.3 rad
    off its reference (0.1 rad allowed) aborts the loop, reported at its own step, within ERROR_CHECK_STEPS steps."""
    d = _data_at(robot, robot.home_q)
    a = robot.handles.arm_qpos[0]

    def knock(data: mujoco.MjData) -> None:
        if round(data.time / 1e-3) == 50:
            data.qpos[a] += 0.3

    with pytest.raises(ControlError, match=r"joint error 0\.3\d* rad exceeds 0\.1 rad at t = 0\.050 s") as info:
        control.hold(robot, d, robot.home_q, 1.0, ControlConfig(), hook=knock)
    rec = info.value.record
    assert rec.steps == 50 and rec.q.shape == (51, 6)
    assert rec.q[-1, 0] == pytest.approx(robot.home_q[0] + 0.3, abs=1e-3)
    assert 50 < round(d.time / 1e-3) <= 50 + ERROR_CHECK_STEPS


def test_a_hold_of_no_step_takes_none(robot: Robot) -> None:
    d = _data_at(robot, robot.home_q)
    rec = control.hold(robot, d, robot.home_q, 0.0, ControlConfig())
    assert rec.steps == 0 and d.time == 0.0 and rec.q.shape == (1, 6) and rec.tau.shape == (0, 6)
    arm = control.arm_model(robot)
    assert control.servo_setpoints(arm, np.empty((0, 6)), np.empty((0, 6)), np.empty((0, 6)), np.ones(6),
                                   np.ones(6)).shape == (0, 6)
