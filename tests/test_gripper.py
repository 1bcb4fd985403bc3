"""Tests of pickplace.robot.gripper: the measured geometry and the hold test (close, lift, carry, measure slip)."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.grasping.hold import HoldResult, hold_test
from pickplace.robot import model
from pickplace.robot.gripper import GripperGeometry, closing_speed_m_s, command
from pickplace.world.config import SceneConfig

SLIP_M = 0.001


@pytest.fixture(scope="module")
def geometry(robot: model.Robot) -> GripperGeometry:
    return GripperGeometry.measure(robot)


def _pads_in_tcp(robot: model.Robot, q_arm: np.ndarray, finger: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Left and right pad centres in the tcp frame, and the pads' half thickness, at a finger opening."""
    m, h = robot.mj, robot.handles
    d = mujoco.MjData(m)
    d.qpos[h.arm_qpos] = q_arm
    d.qpos[h.finger_qpos] = finger
    mujoco.mj_kinematics(m, d)
    R = d.site_xmat[h.tcp_site].reshape(3, 3)
    p = d.site_xpos[h.tcp_site]
    left, right = (R.T @ (d.geom_xpos[g] - p) for g in h.pad_geoms)
    half = float(m.geom_size[h.pad_geoms[0], 1])
    assert m.geom_size[h.pad_geoms[1], 1] == half
    return left, right, half


def _print(label: str, r: HoldResult) -> None:
    print(f"\nhold test {label}: held={r.held} slip {r.slip_m * 1e3:.4f} mm / {r.slip_rad:.2e} rad, grip force "
          f"{r.grip_force_n:.2f} N per pad (min {r.min_grip_force_n:.2f}), peak acceleration "
          f"{r.peak_acceleration_m_s2:.2f} m/s^2, load {r.load_n:.2f} N")


# --------------------------------------------------------------------------- #
# geometry
# --------------------------------------------------------------------------- #


def test_geometry_fits_the_cube(robot: model.Robot, geometry: GripperGeometry) -> None:
    half = robot.scene.object.size_m[0] / 2
    print(f"\ngripper: open inner face {geometry.open_inner_face_y_m * 1e3:.3f} mm, closed "
          f"{geometry.closed_inner_face_y_m * 1e3:.3f} mm, open width {geometry.open_width_m * 1e3:.3f} mm, "
          f"tcp {geometry.tcp_offset_m * 1e3:.3f} mm from tool0")
    # the closed target lies past contact, so the actuator saturates on the cube
    assert geometry.closed_inner_face_y_m < half
    assert geometry.open_width_m > robot.scene.object.size_m[0] + 0.010
    assert geometry.open_width_m == pytest.approx(2 * geometry.open_inner_face_y_m, abs=1e-12)
    # gripper.xml: 84 mm open, 4 mm closed, 40 mm travel, 20 mm pads, tcp 0.100 m from tool0
    assert geometry.open_width_m == pytest.approx(0.084, abs=1e-9)
    assert geometry.closed_inner_face_y_m == pytest.approx(0.002, abs=1e-9)
    assert geometry.travel_m == pytest.approx(0.040, abs=1e-12)
    assert geometry.pad_half_height_m == pytest.approx(0.010, abs=1e-12)
    assert geometry.tcp_offset_m == pytest.approx(0.100, abs=1e-9)
    # the pads touch the cube at contact_travel_m
    travel = geometry.contact_travel_m(robot.scene.object.size_m[0])
    left, right, t = _pads_in_tcp(robot, robot.home_q, travel)
    assert left[1] - t == pytest.approx(half, abs=1e-9)
    assert right[1] + t == pytest.approx(-half, abs=1e-9)


@pytest.mark.parametrize("finger", [0.0, 0.005, 0.013, 0.022, 0.031, 0.040])
def test_tcp_is_midway_between_the_pads(robot: model.Robot, finger: float) -> None:
    rng = np.random.default_rng(int(finger * 1e3))
    for q in (robot.home_q, rng.uniform(robot.arm_lower, robot.arm_upper)):
        left, right, t = _pads_in_tcp(robot, q, finger)
        left_face, right_face = left[1] - t, right[1] + t
        assert left_face > 0 > right_face
        assert abs(left_face + right_face) <= 1e-9  # symmetric about the tcp
        assert left_face == pytest.approx(0.042 - finger, abs=1e-9)
        np.testing.assert_allclose((left + right) / 2, 0.0, rtol=0, atol=1e-9)  # pad centres about the tcp
        np.testing.assert_allclose(left[[0, 2]], 0.0, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- #
# hold test
# --------------------------------------------------------------------------- #


def test_the_fingers_close_together(robot: model.Robot) -> None:
    """The servo drives both fingers through a tendon that averages them (half its force on each), so closing on
    nothing neither finger trails the other; a servo on one finger, the other following through the coupling, left
    it 1 mm behind at 1/3 m/s, and the leading pad met the object alone and pushed the held arm aside."""
    m, h = robot.mj, robot.handles
    assert m.actuator_trntype[h.gripper_actuator] == mujoco.mjtTrn.mjTRN_TENDON
    d = robot.make_data()
    mujoco.mj_forward(m, d)
    command(robot, d, closed=True)
    lags, speeds = [], []
    for _ in range(200):
        d.ctrl[h.arm_actuators] = d.qfrc_bias[h.arm_dof]  # the arm held up by gravity compensation
        mujoco.mj_step(m, d)
        left, right = d.qpos[h.finger_qpos]
        if 0.005 < left < 0.035:
            lags.append(abs(left - right))
            speeds.append(float(d.qvel[h.finger_dof[0]]))
    print(f"\nfree closing at {np.median(speeds):.3f} m/s: the fingers {max(lags) * 1e6:.3f} um apart at most")
    assert np.median(speeds) == pytest.approx(closing_speed_m_s(robot), rel=0.05)
    assert max(lags) < 1e-6


def test_hold_default_scene(robot: model.Robot) -> None:
    r = hold_test()
    _print("default cube (0.15 kg, mu 1.0, 40 mm)", r)
    m, h = robot.mj, robot.handles
    assert m.actuator_forcelimited[h.gripper_actuator]
    force_limit = float(m.actuator_forcerange[h.gripper_actuator, 1])
    assert force_limit == pytest.approx(40.0, abs=1e-12)
    # the actuator drives the left finger; the right one follows through the joint equality, so its force
    # is shared by the two pads: force_limit / 2 on each
    per_pad = force_limit / 2
    assert r.held
    assert r.slip_m < SLIP_M
    assert r.grip_force_n == pytest.approx(per_pad, rel=0.10)
    assert r.min_grip_force_n == pytest.approx(per_pad, rel=0.10)
    assert r.peak_acceleration_m_s2 >= 3.0
    assert r.mass_kg == pytest.approx(0.150, abs=1e-12)
    assert r.load_n == pytest.approx(0.150 * (9.81 + r.peak_acceleration_m_s2), rel=1e-12)


def test_hold_three_times_heavier_cube() -> None:
    r = hold_test(SceneConfig.from_mapping(dict(cube_mass_kg=0.45)))
    _print("0.45 kg cube", r)
    assert r.held
    assert r.slip_m < SLIP_M
    assert r.peak_acceleration_m_s2 >= 3.0


@pytest.mark.parametrize(
    ("friction", "size"),
    [(0.6, 0.040), (1.0, 0.030), (1.0, 0.050), (0.6, 0.030), (0.6, 0.050)],
)
def test_hold_other_friction_and_sizes(friction: float, size: float) -> None:
    r = hold_test(SceneConfig.from_mapping(dict(cube_friction=friction, cube_size_m=size)))
    _print(f"mu {friction}, {size * 1e3:.0f} mm", r)
    assert r.held
    assert r.slip_m < SLIP_M


def test_hold_fails_when_it_should() -> None:
    """Control case: mu 0.05 and 1.5 kg. Friction can carry at most 0.05 * 2 * 20 N = 2 N < 14.7 N of weight."""
    r = hold_test(SceneConfig.from_mapping(dict(cube_friction=0.05, cube_mass_kg=1.5)))
    _print("control: mu 0.05, 1.5 kg", r)
    assert not r.held
    assert r.slip_m > SLIP_M


def test_the_drive_slows_onto_the_object_squeezes_up_and_eases_off(robot: model.Robot) -> None:
    """Closing on the default cube with the arm held still: the fingers close fast, slow down a millimetre before
    the pads are expected to meet it, so that both meet it slowly (and within a step of each other), then the
    squeeze rises to the servo's 20 N per pad; opening, the squeeze falls over ``SQUEEZE_RAMP_S`` before the pads
    leave it. The held arm is never jolted past a joint's acceleration limit."""
    from pickplace.motion import control
    from pickplace.robot.gripper import SLOW_SPEED_M_S, SQUEEZE_RAMP_S, GripDrive, pad_forces
    from pickplace.robot.ik import solve_ik

    m, h = robot.mj, robot.handles
    size = robot.scene.object.size_m[0]
    down_x = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # pads closing along the world's x
    centre = np.array([*robot.scene.start_xy_m, robot.scene.table_height_m + size / 2])
    q = solve_ik(robot, pin.SE3(down_x, centre), robot.home_q).q
    d = robot.make_data()
    d.qpos[h.arm_qpos] = q
    mujoco.mj_forward(m, d)
    alim = np.array([8.0, 8.0, 8.0, 16.0, 16.0, 16.0])
    log: list[tuple[np.ndarray, np.ndarray, float]] = []  # pad forces, arm velocities, finger speed

    def run(drive: GripDrive, seconds: float) -> None:
        def hook(d: mujoco.MjData) -> None:
            drive(d)
            log.append((pad_forces(robot, d), d.qvel[h.arm_dof].copy(), float(np.mean(d.qvel[h.finger_dof]))))
        control.hold(robot, d, q, seconds, control.ControlConfig(), hook=hook)

    closing = GripDrive(robot, d, True, size)
    run(closing, 0.15)
    forces = np.array([f for f, _, _ in log])
    first = [int(np.argmax(forces[:, side] > 0.0)) for side in (0, 1)]
    speed_at_touch = log[min(first) - 1][2]
    print(f"\npads meet the cube at steps {first}, the fingers at {speed_at_touch * 1e3:.0f} mm/s; squeeze "
          f"{forces[-1].round(2)} N")
    assert closing.done
    assert abs(first[0] - first[1]) <= 1
    assert 0.0 < speed_at_touch <= 1.25 * SLOW_SPEED_M_S
    np.testing.assert_allclose(forces[-1], 20.0, atol=0.5)

    n_closed = len(log)
    opening = GripDrive(robot, d, False)
    run(opening, 0.05)
    after = np.array([f for f, _, _ in log[n_closed:]])
    gone = int(np.argmax(after.max(axis=1) <= 0.0))
    print(f"opening: the pads leave the cube {gone} ms after the command, the squeeze falling by "
          f"{np.max(-np.diff(after, axis=0)):.2f} N per ms at most")
    assert opening.done and gone * float(m.opt.timestep) >= SQUEEZE_RAMP_S - 1e-9
    assert np.max(-np.diff(after[:gone], axis=0)) <= 20.0 * float(m.opt.timestep) / SQUEEZE_RAMP_S * 1.5
    accel = np.abs(np.diff(np.array([v for _, v, _ in log]), axis=0)) / float(m.opt.timestep)
    assert np.all(accel <= alim), f"held arm at {np.max(accel / alim):.2f} of a limit"
