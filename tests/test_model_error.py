"""Model error and plant friction (pickplace.robot.model_error) and the gripper drive (pickplace.robot.gripper
.GripperConfig), on the real models (no mocks)."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import ConfigError
from pickplace.motion import control
from pickplace.robot import gripper
from pickplace.robot.model import Robot
from pickplace.robot.model_error import ModelErrorConfig, is_physical, with_model_error


def _second_moments(inertia: pin.Inertia) -> np.ndarray:
    m = np.linalg.eigvalsh(np.asarray(inertia.inertia))
    return np.sort(0.5 * m.sum() - m)


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"mass_error_frac": -0.1}, "model_error.mass_error_frac"),
    ({"com_error_frac": 0.9}, "model_error.com_error_frac"),
    ({"inertia_error_frac": math.nan}, "model_error.inertia_error_frac"),
    ({"coulomb_friction_nm": (1, 1, 1)}, "model_error.coulomb_friction_nm"),
    ({"extra_damping_nm_s_rad": (1, 1, 1, 1, 1, -1)}, "model_error.extra_damping_nm_s_rad[5]"),
])
def test_config_rejects_bad_values(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        ModelErrorConfig(**kwargs)
    assert info.value.field == field and field in str(info.value)


def test_no_error_is_the_same_robot(robot: Robot) -> None:
    assert with_model_error(robot, ModelErrorConfig()) is robot
    with pytest.raises(ConfigError, match=r"model_error\.rng"):
        with_model_error(robot, ModelErrorConfig(mass_error_frac=0.1))


def test_draws_are_reproducible_bounded_and_physical(robot: Robot) -> None:
    cfg = ModelErrorConfig.realistic()
    a = with_model_error(robot, cfg, np.random.default_rng(7))
    b = with_model_error(robot, cfg, np.random.default_rng(7))
    c = with_model_error(robot, cfg, np.random.default_rng(8))
    worst = {"mass": 0.0, "com": 0.0, "moment": 0.0}
    for j in range(1, 7):
        nom, ia, ib = robot.pin.inertias[j], a.pin.inertias[j], b.pin.inertias[j]
        np.testing.assert_array_equal(ia.toDynamicParameters(), ib.toDynamicParameters())  # same seed, same draw
        assert not np.allclose(ia.toDynamicParameters(), c.pin.inertias[j].toDynamicParameters())
        assert is_physical(ia)
        worst["mass"] = max(worst["mass"], abs(ia.mass / nom.mass - 1.0))
        com_n = np.asarray(nom.lever)
        big = np.abs(com_n) > 1e-9
        worst["com"] = max(worst["com"], float(np.abs(np.asarray(ia.lever)[big] / com_n[big] - 1.0).max()))
        m_n = np.sort(np.linalg.eigvalsh(np.asarray(nom.inertia)))
        m_a = np.sort(np.linalg.eigvalsh(np.asarray(ia.inertia)))
        worst["moment"] = max(worst["moment"], float(np.abs(m_a / m_n - 1.0).max()))
    print(f"\nlargest relative errors over the six links: {worst}")
    assert all(0.0 < v <= 0.1 + 1e-9 for v in worst.values())
    # a harder bound, many draws: the upper arm's moments (0.015, 0.334, 0.332 kg m^2) sit near the triangle
    # inequality's edge, yet every draw stays a physical body
    hard = ModelErrorConfig(mass_error_frac=0.3, com_error_frac=0.3, inertia_error_frac=0.3)
    rng = np.random.default_rng(0)
    for _ in range(30):
        r = with_model_error(robot, hard, rng)
        assert all(is_physical(r.pin.inertias[j]) for j in range(1, 7))
        assert all((_second_moments(r.pin.inertias[j]) >= 0.0).all() for j in range(1, 7))


def test_kinematics_and_known_damping_are_unchanged(robot: Robot) -> None:
    r = with_model_error(robot, ModelErrorConfig.realistic(), np.random.default_rng(1))
    q = robot.pin_q(robot.home_q + 0.3, 0.01)
    d0, d1 = robot.pin.createData(), r.pin.createData()
    pin.framesForwardKinematics(robot.pin, d0, q)
    pin.framesForwardKinematics(r.pin, d1, q)
    for f in (robot.pin_tcp_frame, robot.pin_tool0_frame):
        np.testing.assert_array_equal(d0.oMf[f].homogeneous, d1.oMf[f].homogeneous)
    np.testing.assert_array_equal(r.pin.damping, robot.pin.damping)
    np.testing.assert_array_equal(control.arm_model(r).damping, control.arm_model(robot).damping)
    g0 = pin.computeGeneralizedGravity(robot.pin, d0, q)[:6]
    g1 = pin.computeGeneralizedGravity(r.pin, d1, q)[:6]
    print(f"\ngravity torque believed with the error - nominal: {np.round(g1 - g0, 3)} N m")
    assert np.abs(g1 - g0).max() > 0.1  # the belief's dynamics did change


def test_friction_is_in_the_plant_only(robot: Robot) -> None:
    """A wrist torque below the Coulomb friction does not move the perturbed plant, and does move the nominal one;
    the original robot and the controller's model keep the nominal values."""
    cfg = ModelErrorConfig(coulomb_friction_nm=(3.0, 3.0, 2.0, 1.0, 1.0, 1.0),
                           extra_damping_nm_s_rad=(2.0, 2.0, 1.5, 0.5, 0.5, 0.5))
    r = with_model_error(robot, cfg)
    h = robot.handles
    np.testing.assert_array_equal(r.mj.dof_frictionloss[h.arm_dof], cfg.coulomb_friction_nm)
    np.testing.assert_allclose(r.mj.dof_damping[h.arm_dof] - robot.mj.dof_damping[h.arm_dof],
                               cfg.extra_damping_nm_s_rad)
    assert not robot.mj.dof_frictionloss[h.arm_dof].any()
    assert r.pin is robot.pin  # no inertial error asked: the belief is the nominal model

    moved = []
    for bot in (robot, r):
        d = bot.make_data()
        mujoco.mj_forward(bot.mj, d)
        q0 = d.qpos[h.arm_qpos].copy()
        for _ in range(200):
            mujoco.mj_forward(bot.mj, d)
            d.ctrl[h.arm_actuators] = d.qfrc_bias[h.arm_dof]  # gravity compensated exactly
            d.ctrl[h.arm_actuators[5]] += 0.5  # half the wrist's Coulomb friction
            mujoco.mj_step(bot.mj, d)
        moved.append(float(abs(d.qpos[h.arm_qpos[5]] - q0[5])))
    print(f"\nwrist 3 after 0.2 s of 0.5 N m: nominal plant moved {moved[0]:.3e} rad, with friction {moved[1]:.3e} rad")
    assert moved[0] > 0.05
    assert moved[1] < 0.05 * moved[0]  # MuJoCo's friction loss is a soft constraint: it creeps a little


# --------------------------------------------------------------------------- #
# gripper drive
# --------------------------------------------------------------------------- #


def _free_close(robot: Robot) -> tuple[float, float]:
    """The driven finger's speed (m/s) and how far the mirrored one trails it (m), medians mid-stroke, closing on
    nothing (the arm held up by gravity compensation)."""
    d = robot.make_data()
    h = robot.handles
    d.qpos[h.arm_qpos] = robot.home_q
    mujoco.mj_forward(robot.mj, d)
    gripper.command(robot, d, closed=True)
    speeds, lags = [], []
    for _ in range(400):
        d.ctrl[h.arm_actuators] = d.qfrc_bias[h.arm_dof]
        mujoco.mj_step(robot.mj, d)
        if 0.01 < d.qpos[h.finger_qpos[0]] < 0.03:
            speeds.append(float(d.qvel[h.finger_dof[0]]))
            lags.append(float(d.qpos[h.finger_qpos[0]] - d.qpos[h.finger_qpos[1]]))
    return float(np.median(speeds)), float(np.median(lags))


def _free_closing_speed(robot: Robot) -> float:
    return _free_close(robot)[0]


def test_gripper_drive(robot: Robot) -> None:
    assert gripper.with_gripper(robot, gripper.GripperConfig()) is robot  # the ideal default: the model as built
    assert gripper.closing_speed_m_s(robot) == pytest.approx(1.0 / 3.0)
    real = gripper.with_gripper(robot, gripper.GripperConfig.realistic())
    fast, slow = _free_closing_speed(robot), _free_closing_speed(real)
    print(f"\nfree closing speed: as built {fast:.3f} m/s, realistic {slow:.3f} m/s (Robotiq 2F-85: 0.020-0.150)")
    assert fast == pytest.approx(1.0 / 3.0, rel=0.05)
    assert slow == pytest.approx(0.150, rel=0.05)
    assert gripper.squeeze_per_pad_n(real, 0.05) == pytest.approx(20.0)
    strong = gripper.with_gripper(robot, gripper.GripperConfig(closing_speed_m_s=0.1, grip_force_n=100.0))
    assert gripper.squeeze_per_pad_n(strong, 0.05) == pytest.approx(100.0)
    assert _free_closing_speed(strong) == pytest.approx(0.1, rel=0.05)
    assert robot.mj.actuator_forcerange[robot.handles.gripper_actuator, 1] == 40.0  # the original is untouched
    with pytest.raises(ConfigError) as info:
        gripper.GripperConfig(grip_force_n=300.0)
    assert info.value.field == "gripper.grip_force_n" and "235" in str(info.value)
    with pytest.raises(ConfigError, match=r"gripper\.closing_speed_m_s"):
        gripper.GripperConfig(closing_speed_m_s=0.0)


def test_the_fingers_close_together_in_both_drives(robot: Robot) -> None:
    """The servo drives the fingers' mean travel through a tendon (half its force on each): closing on nothing, the
    mirrored finger keeps with the driven one, whatever the coupling's stiffness (the realistic profile's 2F-85
    linkage, 2 ms, or the coupling as built, 5 ms); a finger that trailed the other by a millimetre used to meet the
    object alone."""
    real = gripper.with_gripper(robot, gripper.GripperConfig.realistic())
    soft = gripper.with_gripper(robot, dataclasses.replace(gripper.GripperConfig.realistic(),
                                                           coupling_timeconst_s=gripper.IDEAL_COUPLING_TIMECONST_S))
    eq = mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_EQUALITY, "finger_coupling")
    assert real.mj.eq_solref[eq, 0] == pytest.approx(0.002) and robot.mj.eq_solref[eq, 0] == pytest.approx(0.005)
    lags = {name: _free_close(r)[1] for name, r in (("as built", robot), ("linkage", real), ("soft", soft))}
    print("\nmirrored finger's lag mid-stroke: " + ", ".join(f"{k} {v * 1e6:.3f} um" for k, v in lags.items()))
    for lag in lags.values():
        assert abs(lag) < 1e-6
    with pytest.raises(ConfigError, match=r"gripper\.coupling_timeconst_s.*two physics steps"):
        gripper.with_gripper(robot, gripper.GripperConfig(coupling_timeconst_s=0.0015))
