"""Tests of pickplace.robot.model: the compiled scene, the UR5e against UR's DH table, Pinocchio against MuJoCo.

The DH chain below is written here from ../shared/UR5E.md, independently of the MJCF, so the MJCF's
kinematics and centres of mass are checked against UR's published numbers, not against themselves.
"""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.robot import model
from pickplace.robot.kinematics import frame_jacobian
from pickplace.world.config import SceneConfig
from pickplace.world.objects import library_object

# --------------------------------------------------------------------------- #
# UR5e published data (UR5E.md), typed in independently of the MJCF
# --------------------------------------------------------------------------- #

UR_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
UR_LINKS = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link")
DH_A = (0.0, -0.425, -0.3922, 0.0, 0.0, 0.0)
DH_D = (0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996)
DH_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
LINK_MASSES_KG = (3.761, 8.058, 2.846, 1.37, 1.3, 0.365)
#: centres of mass in DH frame i (m)
LINK_COMS_DH = (
    (0.0, -0.02561, 0.00193),
    (0.2125, 0.0, 0.11336),
    (0.15, 0.0, 0.0265),
    (0.0, -0.0018, 0.01634),
    (0.0, 0.0018, 0.01634),
    (0.0, 0.0, -0.001159),
)
#: principal inertias (kg m^2), ROS description
LINK_INERTIAS = (
    (0.0070021, 0.0064809, 0.0065729),
    (0.0150589, 0.3338809, 0.3324721),
    (0.0039963, 0.0787925, 0.0784851),
    (0.0016549, 0.0013596, 0.0012628),
    (0.0013562, 0.0012783, 0.0009661),
    (0.0001869, 0.0001891, 0.0002576),
)
TORQUE_LIMITS = (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)
ACTUATOR_JOINT = {
    "shoulder_pan": "shoulder_pan_joint",
    "shoulder_lift": "shoulder_lift_joint",
    "elbow": "elbow_joint",
    "wrist_1": "wrist_1_joint",
    "wrist_2": "wrist_2_joint",
    "wrist_3": "wrist_3_joint",
}

N_RANDOM = 120


def _rz(t: float) -> np.ndarray:
    T = np.eye(4)
    c, s = math.cos(t), math.sin(t)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _rx(t: float) -> np.ndarray:
    T = np.eye(4)
    c, s = math.cos(t), math.sin(t)
    T[1:3, 1:3] = [[c, -s], [s, c]]
    return T


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def dh_frames(q: np.ndarray) -> list[np.ndarray]:
    """Standard DH: T_0i = prod_k Rz(theta_k) Tz(d_k) Tx(a_k) Rx(alpha_k), i = 1..6 (base at the origin)."""
    T = np.eye(4)
    out = []
    for theta, a, d, alpha in zip(q, DH_A, DH_D, DH_ALPHA, strict=True):
        T = T @ _rz(theta) @ _trans(0.0, 0.0, d) @ _trans(a, 0.0, 0.0) @ _rx(alpha)
        out.append(T)
    return out


def rotation_angle(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Geodesic angle between two rotations (rad), accurate near zero (atan2 form, not arccos)."""
    R = R_a.T @ R_b
    s = 0.5 * np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    c = 0.5 * (np.trace(R) - 1.0)
    return float(math.atan2(s, c))


# --------------------------------------------------------------------------- #
# fixtures and helpers
# --------------------------------------------------------------------------- #


def _id(m: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(m, kind, name)
    assert i >= 0, f"no {kind.name} named {name!r}"
    return i


def _random_arm(rng: np.random.Generator, robot: model.Robot, n: int) -> np.ndarray:
    return rng.uniform(robot.arm_lower, robot.arm_upper, size=(n, 6))


def _set_mj(robot: model.Robot, d: mujoco.MjData, q_arm: np.ndarray, finger: float = 0.0) -> None:
    h = robot.handles
    d.qpos[h.arm_qpos] = q_arm
    d.qpos[h.finger_qpos] = finger


# --------------------------------------------------------------------------- #
# the compiled scene
# --------------------------------------------------------------------------- #


def test_scene_compiles_with_named_elements(robot: model.Robot) -> None:
    m = robot.mj
    J, B, S = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_SITE
    arm_bodies = robot.handles.robot_bodies - robot.handles.gripper_bodies
    arm_joint_names = [m.joint(j).name for j in range(m.njnt) if m.jnt_bodyid[j] in arm_bodies]
    assert arm_joint_names == list(UR_JOINTS)
    for j in UR_JOINTS:
        assert m.jnt_type[_id(m, J, j)] == mujoco.mjtJoint.mjJNT_HINGE
    for name in ("base", "tool0", "object"):
        _id(m, B, name)
    _id(m, S, "tcp")
    assert m.nkey >= 1
    assert m.key(0).name == "home"
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home") == 0
    np.testing.assert_array_equal(m.key_qpos[0][robot.handles.arm_qpos], robot.home_q)


def test_arm_actuators_are_torque_motors_with_ur_torque_limits(robot: model.Robot) -> None:
    m = robot.mj
    for (act, joint), limit in zip(ACTUATOR_JOINT.items(), TORQUE_LIMITS, strict=True):
        a = _id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, act)
        # as built, a torque motor: direct joint transmission, no dynamics, unit fixed gain, a zero affine bias (the
        # joint servos set it, motion.loop.ServoGains), the force clamped to the torque limit
        assert m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
        assert m.joint(int(m.actuator_trnid[a, 0])).name == joint
        assert m.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE
        assert m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
        assert m.actuator_gainprm[a, 0] == 1.0
        assert m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
        np.testing.assert_array_equal(m.actuator_biasprm[a, :3], 0.0)
        assert m.actuator_gear[a, 0] == 1.0
        assert not m.actuator_ctrllimited[a]
        assert m.actuator_forcelimited[a]
        np.testing.assert_allclose(m.actuator_forcerange[a], [-limit, limit], rtol=0, atol=1e-12)
    np.testing.assert_allclose(robot.torque_limits_nm, TORQUE_LIMITS, rtol=0, atol=1e-12)
    np.testing.assert_allclose(model.TORQUE_LIMITS_NM, TORQUE_LIMITS, rtol=0, atol=1e-12)


def test_a_torque_motor_applies_its_control_clamped_to_the_limit(robot: model.Robot) -> None:
    m, h = robot.mj, robot.handles
    d = robot.make_data()
    d.ctrl[h.arm_actuators] = [10.0, -200.0, 149.0, 30.0, -5.0, 0.5]
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(d.actuator_force[h.arm_actuators], [10.0, -150.0, 149.0, 28.0, -5.0, 0.5],
                               rtol=0, atol=1e-12)


def test_the_arm_state_sensors_read_the_joints_the_actuators_and_the_tcp(robot: model.Robot) -> None:
    m, h = robot.mj, robot.handles
    d = robot.make_data()
    rng = np.random.default_rng(0)
    d.qpos[h.arm_qpos] += rng.uniform(-0.2, 0.2, 6)
    d.qvel[h.arm_dof] = rng.uniform(-1.0, 1.0, 6)
    d.ctrl[h.arm_actuators] = rng.uniform(-20.0, 20.0, 6)
    mujoco.mj_forward(m, d)
    a = h.arm_state_sensor
    block = d.sensordata[a : a + model.ARM_STATE_WIDTH]
    np.testing.assert_allclose(block[0:6], d.qpos[h.arm_qpos], rtol=0, atol=1e-12)
    np.testing.assert_allclose(block[6:12], d.qvel[h.arm_dof], rtol=0, atol=1e-12)
    np.testing.assert_allclose(block[12:18], d.actuator_force[h.arm_actuators], rtol=0, atol=1e-12)
    np.testing.assert_allclose(block[18:21], d.site_xpos[h.tcp_site], rtol=0, atol=1e-12)


def test_the_contact_count_sensors_count_the_contacts_they_name() -> None:
    robot = model.build()
    m, h = robot.mj, robot.handles
    d = robot.make_data()
    d.ctrl[h.arm_actuators] = 0.0  # the arm falls onto the table, beside the cube
    gripper = h.gripper_bodies
    seen = 0
    for _ in range(400):
        mujoco.mj_step(m, d)
        robot_n = object_n = hand_n = 0
        for g1, g2 in d.contact.geom[: d.ncon]:
            b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
            robot_n += b1 in h.robot_bodies or b2 in h.robot_bodies
            object_n += h.object_body in (b1, b2)
            hand_n += (b1 in gripper and b2 == h.object_body) or (b2 in gripper and b1 == h.object_body)
        np.testing.assert_array_equal(d.sensordata[h.contact_count_sensors], [robot_n, object_n, hand_n])
        seen = max(seen, robot_n)
    assert seen > 0  # the arm did reach the table


def test_cube_table_and_timestep(robot: model.Robot) -> None:
    m = robot.mj
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    cube_body = _id(m, mujoco.mjtObj.mjOBJ_BODY, "object")
    object_geoms = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "cube")  # the object's geom is named after it
    assert m.geom_type[object_geoms] == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(m.geom_size[object_geoms], [0.020] * 3, rtol=0, atol=1e-12)  # 40 mm edge
    assert m.body_mass[cube_body] == pytest.approx(0.150, abs=1e-12)
    np.testing.assert_allclose(m.body_pos[cube_body], [0.35, 0.20, 0.335], rtol=0, atol=1e-12)
    np.testing.assert_allclose(d.xpos[cube_body], [0.35, 0.20, 0.335], rtol=0, atol=1e-12)
    # the keyframe puts the cube at its start too
    cq = robot.handles.object_qpos
    np.testing.assert_allclose(m.key_qpos[0][cq:cq + 7], [0.35, 0.20, 0.335, 1, 0, 0, 0], rtol=0, atol=1e-12)

    top = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "table_top")
    assert m.geom_type[top] == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(d.geom_xmat[top].reshape(3, 3), np.eye(3), rtol=0, atol=1e-12)
    top_face_z = d.geom_xpos[top][2] + m.geom_size[top][2]
    assert top_face_z == pytest.approx(0.315, abs=1e-12)
    # the cube rests exactly on it
    assert d.xpos[cube_body][2] - m.geom_size[object_geoms][2] == pytest.approx(top_face_z, abs=1e-12)
    assert m.opt.timestep == pytest.approx(0.001, abs=1e-15)


def test_link_masses_and_inertias_are_urs(robot: model.Robot) -> None:
    m = robot.mj
    for link, mass, inertia in zip(UR_LINKS, LINK_MASSES_KG, LINK_INERTIAS, strict=True):
        b = _id(m, mujoco.mjtObj.mjOBJ_BODY, link)
        assert m.body_mass[b] == pytest.approx(mass, abs=1e-12), link
        np.testing.assert_allclose(np.sort(m.body_inertia[b]), np.sort(inertia), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- #
# UR's DH chain
# --------------------------------------------------------------------------- #


def test_dh_chain_matches_mujoco_tool0(robot: model.Robot) -> None:
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    rng = np.random.default_rng(20240601)
    qs = np.vstack([np.zeros(6), robot.home_q, _random_arm(rng, robot, N_RANDOM)])
    pos_err = rot_err = 0.0
    for q in qs:
        _set_mj(robot, d, q)
        mujoco.mj_kinematics(m, d)
        T = dh_frames(q)[-1]
        pos_err = max(pos_err, float(np.linalg.norm(d.xpos[h.tool0_body] - T[:3, 3])))
        rot_err = max(rot_err, rotation_angle(d.xmat[h.tool0_body].reshape(3, 3), T[:3, :3]))
    print(f"\nDH vs MuJoCo tool0 over {len(qs)} configurations: {pos_err:.2e} m, {rot_err:.2e} rad")
    assert pos_err <= 1e-9
    assert rot_err <= 1e-9


def test_dh_zero_pose_flange_is_urs() -> None:
    """A sanity check of the test's own DH chain: at zero, the flange is at (a2 + a3, -(d4 + d6), d1 - d5)."""
    T = dh_frames(np.zeros(6))[-1]
    np.testing.assert_allclose(T[:3, 3], [-0.8172, -0.2329, 0.0628], rtol=0, atol=1e-12)


def test_centres_of_mass_match_dh(robot: model.Robot) -> None:
    m = robot.mj
    d = mujoco.MjData(m)
    bodies = [_id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in UR_LINKS]
    rng = np.random.default_rng(7)
    qs = np.vstack([np.zeros(6), robot.home_q, _random_arm(rng, robot, N_RANDOM)])
    err = 0.0
    for q in qs:
        _set_mj(robot, d, q)
        mujoco.mj_kinematics(m, d)
        for T, com, b in zip(dh_frames(q), LINK_COMS_DH, bodies, strict=True):
            expected = T[:3, :3] @ np.array(com) + T[:3, 3]
            err = max(err, float(np.linalg.norm(d.xipos[b] - expected)))
    print(f"\nCoM: DH vs MuJoCo xipos over {len(qs)} configurations: {err:.2e} m")
    assert err <= 1e-9


# --------------------------------------------------------------------------- #
# Pinocchio against MuJoCo
# --------------------------------------------------------------------------- #


def test_pinocchio_joints(robot: model.Robot) -> None:
    assert list(robot.pin.names)[1:] == [*UR_JOINTS, "left_finger_joint", "right_finger_joint"]
    assert robot.pin.nq == 8
    assert robot.pin.nv == 8


def test_pinocchio_frames_match_mujoco(robot: model.Robot) -> None:
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    pdata = robot.pin.createData()
    left = _id(m, mujoco.mjtObj.mjOBJ_BODY, "left_finger")
    right = _id(m, mujoco.mjtObj.mjOBJ_BODY, "right_finger")
    pin_left = robot.pin.getFrameId("left_finger", pin.FrameType.BODY)
    pin_right = robot.pin.getFrameId("right_finger", pin.FrameType.BODY)
    rng = np.random.default_rng(11)
    qs = _random_arm(rng, robot, N_RANDOM)
    fingers = rng.uniform(0.0, 0.040, N_RANDOM)
    fingers[:3] = (0.0, 0.020, 0.040)
    pairs = {
        "tool0": (robot.pin_tool0_frame, lambda: (d.xpos[h.tool0_body], d.xmat[h.tool0_body])),
        "tcp": (robot.pin_tcp_frame, lambda: (d.site_xpos[h.tcp_site], d.site_xmat[h.tcp_site])),
        "left_finger": (pin_left, lambda: (d.xpos[left], d.xmat[left])),
        "right_finger": (pin_right, lambda: (d.xpos[right], d.xmat[right])),
    }
    errs = {name: [0.0, 0.0] for name in pairs}
    for q, f in zip(qs, fingers, strict=True):
        _set_mj(robot, d, q, f)
        mujoco.mj_kinematics(m, d)
        pin.framesForwardKinematics(robot.pin, pdata, robot.pin_q(q, f))
        for name, (fid, mj_pose) in pairs.items():
            p, R = mj_pose()
            T = pdata.oMf[fid]
            errs[name][0] = max(errs[name][0], float(np.linalg.norm(T.translation - p)))
            errs[name][1] = max(errs[name][1], float(np.linalg.norm(pin.log3(T.rotation.T @ R.reshape(3, 3)))))
    print("\nPinocchio vs MuJoCo (max m, rad): "
          + ", ".join(f"{k} {v[0]:.2e} {v[1]:.2e}" for k, v in errs.items()))
    for name, (p_err, r_err) in errs.items():
        assert p_err <= 1e-9, name
        assert r_err <= 1e-9, name


def _pin_and_mj_bias(robot: model.Robot, d: mujoco.MjData, pdata: pin.Data, q: np.ndarray, f: np.ndarray,
                     v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Pinocchio rnea(q, v, 0), MuJoCo qfrc_bias) on the 6 arm + 2 finger dofs."""
    h = robot.handles
    d.qpos[h.arm_qpos] = q
    d.qpos[h.finger_qpos] = f
    d.qvel[:] = 0.0
    d.qvel[h.arm_dof] = v[:6]
    d.qvel[h.finger_dof] = v[6:]
    mujoco.mj_forward(robot.mj, d)
    mj = d.qfrc_bias[np.concatenate([h.arm_dof, h.finger_dof])]
    qp = np.concatenate([q, f])
    if np.any(v):
        tau = pin.rnea(robot.pin, pdata, qp, v, np.zeros(robot.pin.nv))
    else:
        tau = pin.computeGeneralizedGravity(robot.pin, pdata, qp)
    return tau.copy(), mj.copy()


def test_gravity_matches_mujoco_bias_at_rest(robot: model.Robot) -> None:
    d = mujoco.MjData(robot.mj)
    pdata = robot.pin.createData()
    rng = np.random.default_rng(3)
    err = scale = 0.0
    for q in _random_arm(rng, robot, 50):
        f = np.full(2, rng.uniform(0.0, 0.040))
        tau, mj = _pin_and_mj_bias(robot, d, pdata, q, f, np.zeros(8))
        err = max(err, float(np.abs(tau - mj).max()))
        scale = max(scale, float(np.abs(mj).max()))
    print(f"\ngravity: |Pinocchio - MuJoCo qfrc_bias| max {err:.2e} N m (largest torque {scale:.1f} N m)")
    assert scale > 10.0  # the comparison is not of zeros
    assert err <= 1e-6


def test_coriolis_matches_mujoco_bias_in_motion(robot: model.Robot) -> None:
    d = mujoco.MjData(robot.mj)
    pdata = robot.pin.createData()
    rng = np.random.default_rng(4)
    err = 0.0
    for q in _random_arm(rng, robot, 50):
        f = np.full(2, rng.uniform(0.0, 0.040))
        v = np.concatenate([rng.uniform(-np.pi, np.pi, 6), np.full(2, rng.uniform(-0.1, 0.1))])
        tau, mj = _pin_and_mj_bias(robot, d, pdata, q, f, v)
        err = max(err, float(np.abs(tau - mj).max()))
    print(f"\nrnea(q, v, 0) vs MuJoCo qfrc_bias: max {err:.2e} N m")
    assert err <= 1e-6


def test_mass_matrix_matches_mujoco(robot: model.Robot) -> None:
    """CRBA (with the joints' armature) equals MuJoCo's joint-space inertia on the arm and finger dofs."""
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    pdata = robot.pin.createData()
    dofs = np.concatenate([h.arm_dof, h.finger_dof])
    np.testing.assert_allclose(robot.pin.armature, m.dof_armature[dofs], rtol=0, atol=1e-15)
    rng = np.random.default_rng(6)
    M = np.zeros((m.nv, m.nv))
    err = 0.0
    for q in _random_arm(rng, robot, 30):
        f = float(rng.uniform(0.0, 0.040))
        _set_mj(robot, d, q, f)
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        Mp = pin.crba(robot.pin, pdata, robot.pin_q(q, f))
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        err = max(err, float(np.abs(Mp - M[np.ix_(dofs, dofs)]).max()))
    print(f"\nmass matrix: |Pinocchio crba - MuJoCo| max {err:.2e} kg m^2")
    assert err <= 1e-9


def test_pinocchio_link_inertias_are_the_compiled_ones(robot: model.Robot) -> None:
    """Every Pinocchio link inertia (about its CoM, in the joint frame) equals MuJoCo's compiled one."""
    m = robot.mj
    worst = ("", 0.0)
    # wrist 3 is left out: Pinocchio lumps the welded gripper into it
    for link, joint in zip(UR_LINKS[:5], UR_JOINTS[:5], strict=True):
        b = _id(m, mujoco.mjtObj.mjOBJ_BODY, link)
        w, x, y, z = m.body_iquat[b]
        R = pin.Quaternion(w, x, y, z).matrix()
        I_mj = R @ np.diag(m.body_inertia[b]) @ R.T
        I_pin = robot.pin.inertias[robot.pin.getJointId(joint)]
        assert I_pin.mass == pytest.approx(m.body_mass[b], abs=1e-12)
        np.testing.assert_allclose(I_pin.lever, m.body_ipos[b], rtol=0, atol=1e-12)
        e = float(np.abs(I_pin.inertia - I_mj).max())
        if e > worst[1]:
            worst = (link, e)
    print(f"\nlink inertias: largest |Pinocchio - MuJoCo| {worst[1]:.2e} kg m^2 ({worst[0]})")
    assert worst[1] <= 1e-12, worst


# --------------------------------------------------------------------------- #
# Jacobians
# --------------------------------------------------------------------------- #


def _mj_tcp(robot: model.Robot, d: mujoco.MjData, q: np.ndarray, f: float) -> tuple[np.ndarray, np.ndarray]:
    _set_mj(robot, d, q, f)
    mujoco.mj_kinematics(robot.mj, d)
    s = robot.handles.tcp_site
    return d.site_xpos[s].copy(), d.site_xmat[s].reshape(3, 3).copy()


def test_tcp_jacobian_matches_mujoco_and_finite_differences(robot: model.Robot) -> None:
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    pdata = robot.pin.createData()
    rng = np.random.default_rng(5)
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    eps = 1e-6
    err_mj = err_fd = 0.0
    for q in _random_arm(rng, robot, 30):
        f = float(rng.uniform(0.0, 0.040))
        J = frame_jacobian(robot.pin, pdata, robot.pin_q(q, f), robot.pin_tcp_frame)
        assert J.shape == (6, 6)
        _set_mj(robot, d, q, f)
        mujoco.mj_forward(m, d)
        mujoco.mj_jacSite(m, d, jacp, jacr, h.tcp_site)
        J_mj = np.vstack([jacp[:, h.arm_dof], jacr[:, h.arm_dof]])
        err_mj = max(err_mj, float(np.abs(J - J_mj).max()))
        # central differences of the tcp pose (MuJoCo's site), world-aligned
        J_fd = np.empty((6, 6))
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = eps
            p_plus, R_plus = _mj_tcp(robot, d, q + dq, f)
            p_minus, R_minus = _mj_tcp(robot, d, q - dq, f)
            J_fd[:3, i] = (p_plus - p_minus) / (2 * eps)
            J_fd[3:, i] = pin.log3(R_plus @ R_minus.T) / (2 * eps)
        err_fd = max(err_fd, float(np.abs(J - J_fd).max()))
    print(f"\ntcp Jacobian: vs mj_jacSite {err_mj:.2e}, vs central differences {err_fd:.2e}")
    assert err_mj <= 1e-9
    assert err_fd <= 1e-6


# --------------------------------------------------------------------------- #
# the scene varies from SceneConfig
# --------------------------------------------------------------------------- #


def test_scene_config_reaches_the_compiled_model() -> None:
    scene = SceneConfig.from_mapping(dict(cube_size_m=0.03, cube_mass_kg=0.3, cube_friction=0.7,
                                          cube_start_xy_m=(0.4, 0.1), cube_yaw_rad=0.3))
    m = model.build(scene).mj
    b = _id(m, mujoco.mjtObj.mjOBJ_BODY, "object")
    g = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "cube")
    np.testing.assert_allclose(m.geom_size[g], [0.015] * 3, rtol=0, atol=1e-12)
    assert m.body_mass[b] == pytest.approx(0.3, abs=1e-12)
    assert m.geom_friction[g][0] == pytest.approx(0.7, abs=1e-12)
    np.testing.assert_allclose(m.body_pos[b], [0.4, 0.1, 0.315 + 0.015], rtol=0, atol=1e-12)
    w, x, y, z = m.body_quat[b]
    assert abs(x) <= 1e-12
    assert abs(y) <= 1e-12
    assert 2 * math.atan2(z, w) == pytest.approx(0.3, abs=1e-12)
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "obstacle") == -1


def test_obstacle_is_added_on_the_table() -> None:
    scene = SceneConfig(obstacle=True)
    m = model.build(scene).mj
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    g = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "obstacle")
    # it stands on the table top, obstacle_height_m tall
    bottom = d.geom_xpos[g][2] - m.geom_size[g][2]
    assert bottom == pytest.approx(scene.table_height_m, abs=1e-12)
    assert 2 * m.geom_size[g][2] == pytest.approx(scene.obstacle_height_m, abs=1e-12)
    np.testing.assert_allclose(d.geom_xpos[g][:2], model.obstacle_xy(scene), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- #
# no MuJoCo warnings
# --------------------------------------------------------------------------- #


def test_scene_steps_without_warnings(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        robot = model.build()
        m, h = robot.mj, robot.handles
        d = robot.make_data()
        d.ctrl[:] = 0.0
        for _ in range(200):
            mujoco.mj_step1(m, d)
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[h.arm_dof] = d.qfrc_bias[h.arm_dof]  # gravity compensation (qvel ~ 0)
            mujoco.mj_step2(m, d)
    drift = float(np.abs(d.qpos[h.arm_qpos] - robot.home_q).max())
    print(f"\n200 steps at home with gravity compensation: arm drift {drift:.2e} rad")
    assert [int(w.number) for w in d.warning] == [0] * len(d.warning)
    mujoco_warnings = [w for w in caught if "mujoco" in str(w.message).lower() or "mujoco" in w.filename]
    assert mujoco_warnings == []
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert list(tmp_path.iterdir()) == []
    assert drift < 1e-3


@pytest.mark.parametrize("xy, yaw", [((0.446, 0.323), 0.69), ((0.432, 0.368), 0.0), ((0.58, -0.22), 0.37)])
def test_a_lying_can_at_rest_stays_at_rest(xy: tuple[float, float], yaw: float) -> None:
    """At these poses the convex collision's default tolerance (1e-6 m) found the can's contact with the table off
    centre and the can rolled away at ~1 mm/s; scene.xml's ccd_tolerance keeps it still (the arm held still)."""
    import dataclasses

    from pickplace.world.objects import library_object

    scene = dataclasses.replace(SceneConfig(), object=library_object("soda_can_lying"), start_xy_m=xy,
                                start_yaw_rad=yaw)
    robot = model.build(scene)
    d = robot.make_data()
    h = robot.handles
    q0 = d.qpos[h.arm_qpos].copy()
    p0 = d.xpos[h.object_body].copy()
    for _ in range(1000):
        mujoco.mj_step(robot.mj, d)
        d.qpos[h.arm_qpos], d.qvel[h.arm_dof] = q0, 0.0
    assert np.linalg.norm(d.xpos[h.object_body] - p0) < 5e-5
    assert np.linalg.norm(d.qvel[h.object_dof:h.object_dof + 3]) < 1e-5


@pytest.mark.parametrize("name", ["mug", "l_bracket"])
def test_the_object_sensors_read_its_origin_not_its_centre_of_mass(name: str) -> None:
    """Objects whose centre of mass is off their origin: the sensors read the body's frame, as the checks expect."""
    robot = model.build(SceneConfig(object=library_object(name)))
    m, h = robot.mj, robot.handles
    d = robot.make_data()
    d.qpos[h.arm_qpos] += 0.1
    mujoco.mj_forward(m, d)
    assert np.linalg.norm(d.xipos[h.object_body] - d.xpos[h.object_body]) > 5e-3  # the case that matters
    a, b = h.object_position_sensor, h.object_in_tcp_sensor
    np.testing.assert_allclose(d.sensordata[a : a + 3], d.xpos[h.object_body], rtol=0, atol=1e-12)
    R = d.site_xmat[h.tcp_site].reshape(3, 3)
    expected = R.T @ (d.xpos[h.object_body] - d.site_xpos[h.tcp_site])
    np.testing.assert_allclose(d.sensordata[b : b + 3], expected, rtol=0, atol=1e-12)
