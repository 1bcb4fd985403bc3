"""The control loop as the robot runs it (pickplace.motion.loop): rate, latency, zero-order hold, encoders,
velocity filter, and the realistic profile's tracking, on the real MuJoCo scene (no mocks).

Every test prints its measured figures (``pytest -s``) and asserts them with explicit tolerances.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import ConfigError
from pickplace.grasping.configurations import GraspConfigurations
from pickplace.motion import control
from pickplace.motion.control import ControlConfig
from pickplace.motion.loop import ControlLoop, LoopConfig
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot.model import Robot
from pickplace.robot.model_error import ModelErrorConfig, with_model_error

RES = 2.0 * math.pi / 2**18


def _data_at(robot: Robot, q: np.ndarray) -> mujoco.MjData:
    d = robot.make_data()
    d.qpos[robot.handles.arm_qpos] = q
    mujoco.mj_forward(robot.mj, d)
    d.ctrl[robot.handles.arm_actuators] = d.qfrc_bias[robot.handles.arm_dof]  # as if a controller held it
    return d


class _Tape:
    """A hook recording the state after every physics step and the torque that step applied."""

    def __init__(self, robot: Robot, d: mujoco.MjData) -> None:
        self.h = robot.handles
        self.q = [d.qpos[self.h.arm_qpos].copy()]  # q[i]: the state before step i
        self.v = [d.qvel[self.h.arm_dof].copy()]
        self.finger = [float(d.qpos[self.h.finger_qpos[0]])]
        self.u: list[np.ndarray] = []  # u[i]: the torque applied during step i

    def __call__(self, d: mujoco.MjData) -> None:
        self.q.append(d.qpos[self.h.arm_qpos].copy())
        self.v.append(d.qvel[self.h.arm_dof].copy())
        self.finger.append(float(d.qpos[self.h.finger_qpos[0]]))
        self.u.append(d.ctrl[self.h.arm_actuators].copy())


# --------------------------------------------------------------------------- #
# configuration
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"control_period_s": -0.002}, "loop.control_period_s"),
    ({"latency_s": math.nan}, "loop.latency_s"),
    ({"encoder_resolution_rad": "1e-5"}, "loop.encoder_resolution_rad"),
    ({"encoder_noise_std_rad": -1e-6}, "loop.encoder_noise_std_rad"),
    ({"velocity_cutoff_hz": math.inf}, "loop.velocity_cutoff_hz"),
    ({"control_period_s": 0.002, "velocity_cutoff_hz": 300.0}, "loop.velocity_cutoff_hz"),  # past Nyquist
])
def test_loop_config_rejects_bad_values(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        LoopConfig(**kwargs)
    assert info.value.field == field and field in str(info.value)


def test_loop_defaults_and_realistic_profile(robot: Robot) -> None:
    assert LoopConfig().ideal and ControlLoop().ideal
    r = LoopConfig.realistic()
    assert not r.ideal
    assert r.control_period_s == 0.002 and r.latency_s == 0.002  # UR e-Series 500 Hz, one period late
    assert r.encoder_resolution_rad == pytest.approx(RES)
    assert r.steps(0.001) == (2, 2)
    with pytest.raises(ConfigError, match=r"loop\.rng"):
        ControlLoop(r)  # noise needs a seeded generator
    with pytest.raises(ConfigError, match=r"loop\.control_period_s"):
        control.hold(robot, _data_at(robot, robot.home_q), robot.home_q, 0.01, ControlConfig(),
                     loop=ControlLoop(LoopConfig(control_period_s=0.0015)))  # not a whole number of 1 ms steps


# --------------------------------------------------------------------------- #
# rate, latency, hold
# --------------------------------------------------------------------------- #


def test_torque_runs_at_500_hz_one_period_late(robot: Robot) -> None:
    """The applied torque changes only every second physics step, and the torque applied from tick k on is the
    law evaluated on what the encoders read at tick k - 1 (quantized positions, filtered differences)."""
    cfg = LoopConfig(control_period_s=0.002, latency_s=0.002, encoder_resolution_rad=RES, velocity_cutoff_hz=100.0)
    q1 = robot.home_q + np.array([0.05, -0.04, 0.05, 0.05, -0.05, 0.05])
    traj = retime(np.array([robot.home_q, q1]), TimingConfig.ur5e())
    d = _data_at(robot, robot.home_q)
    u0 = d.ctrl[robot.handles.arm_actuators].copy()
    tape = _Tape(robot, d)
    gains = ControlConfig()
    rec = control.track(robot, d, traj, gains, loop=ControlLoop(cfg), hook=tape, settle_s=0.05)
    q_true, v_true, u = np.array(tape.q), np.array(tape.v), np.array(tape.u)
    steps = len(u)
    print(f"\n{steps} physics steps, {len(rec.tau)} control ticks; max error {rec.max_error_rad * 1e3:.3f} mrad")
    assert rec.steps == steps and steps % 2 == 0 and len(rec.tau) == steps // 2
    # zero-order hold: odd steps keep the torque of the even step before them
    np.testing.assert_array_equal(u[1::2], u[0::2])
    # the first period still applies what was in ctrl before the loop started (the latency)
    np.testing.assert_array_equal(u[0], u0)
    # from tick 1 on, the torque applied is the one computed at the previous tick
    for j in range(1, steps // 2):
        np.testing.assert_array_equal(u[2 * j], rec.tau[j - 1])
    # ... and that torque is the law on the encoder readings of the previous tick, recomputed here
    arm = control.arm_model(robot)
    alpha = 1.0 - math.exp(-2.0 * math.pi * 100.0 * 0.002)
    v_est = v_true[0].copy()
    q_prev = None
    dt = 0.001
    qs, _, _ = traj.sample_many(np.arange(-1, steps + 2) * dt)
    q_ref, qd_ref, qdd_ref = control._grid_reference(qs, dt)
    worst = 0.0
    for j in range(steps // 2):
        k = 2 * j
        q_s = np.round(q_true[k] / RES) * RES
        np.testing.assert_array_equal(rec.q[j], q_s)  # the record holds what the encoders read
        if q_prev is not None:
            v_est += alpha * ((q_s - q_prev) / 0.002 - v_est)
        q_prev = q_s
        tau = control.joint_impedance(arm, q_s, v_est, q_ref[k], qd_ref[k], qdd_ref[k], gains.joint_kp,
                                      gains.joint_kd, finger_m=tape.finger[k])
        control.saturate(tau, arm.torque_limits_nm)
        worst = max(worst, float(np.abs(tau - rec.tau[j]).max()))
    print(f"law recomputed on the readings of the previous tick: max difference {worst:.2e} N m")
    assert worst < 1e-9


def test_encoder_readings_are_counts_plus_noise(robot: Robot) -> None:
    std = 0.5 * RES
    loop = ControlLoop(LoopConfig(control_period_s=0.002, latency_s=0.002, encoder_resolution_rad=RES,
                                  encoder_noise_std_rad=std), np.random.default_rng(3))
    d = _data_at(robot, robot.home_q)
    tape = _Tape(robot, d)
    rec = control.hold(robot, d, robot.home_q, 0.4, ControlConfig(), loop=loop, hook=tape)
    q_true = np.array(tape.q)[0: rec.steps + 1: 2]
    noise = rec.q - np.round(q_true / RES) * RES
    print(f"\nreading - count: mean {noise.mean():.2e} rad, std {noise.std():.3e} rad (configured {std:.3e}), "
          f"{noise.size} samples")
    assert abs(noise.mean()) < 0.1 * std
    assert noise.std() == pytest.approx(std, rel=0.1)
    # without noise, every reading is a whole number of counts
    rec0 = control.hold(robot, d, robot.home_q, 0.02, ControlConfig(),
                        loop=ControlLoop(LoopConfig(control_period_s=0.002, encoder_resolution_rad=RES)))
    counts = rec0.q / RES
    assert np.abs(counts - np.round(counts)).max() < 1e-6


def test_encoder_noise_is_one_draw_of_six_per_tick_across_motions(robot: Robot) -> None:
    """The loop draws its encoders' noise in chunks; across two motions of one loop, the noise of each tick is the
    generator's next six normal draws, none skipped or reordered (the chunk ends inside the second motion)."""
    std = 0.5 * RES
    loop = ControlLoop(LoopConfig(control_period_s=0.002, encoder_resolution_rad=RES, encoder_noise_std_rad=std),
                       np.random.default_rng(11))
    d = _data_at(robot, robot.home_q)
    noises = []
    for duration_s in (0.3, 0.4):  # 150 + 200 ticks: past the first chunk of draws
        tape = _Tape(robot, d)
        rec = control.hold(robot, d, robot.home_q, duration_s, ControlConfig(), loop=loop, hook=tape)
        q_true = np.array(tape.q)[0: rec.steps + 1: 2]
        noises.append(rec.q - np.round(q_true / RES) * RES)
    noise = np.vstack(noises)
    expected = np.random.default_rng(11).normal(0.0, std, (len(noise), 6))
    print(f"\n{len(noise)} ticks, largest difference from sequential draws {np.abs(noise - expected).max():.2e} rad")
    assert np.abs(noise - expected).max() < 1e-12  # the same draws (the reading's rounding: ~1e-16 rad)

def test_filtered_velocity_tracks_the_true_velocity(robot: Robot) -> None:
    """A smooth motion (a TOPP-RA trajectory at the UR5e's limits), 500 Hz, 18-bit encoders with noise, 100 Hz
    filter: the estimate the law receives follows MuJoCo's velocity within its expected lag."""
    loop = ControlLoop(LoopConfig.realistic(), np.random.default_rng(4))
    q1 = robot.home_q + np.array([0.6, -0.4, 0.5, 0.5, -0.5, 0.8])
    traj = retime(np.array([robot.home_q, q1]), TimingConfig.ur5e())
    n = round(traj.duration_s / 0.001) // 2 * 2
    qs, _, _ = traj.sample_many(np.arange(-1, n + 2) * 0.001)
    q_ref, qd_ref, qdd_ref = control._grid_reference(qs, 0.001)
    d = _data_at(robot, robot.home_q)
    arm = control.arm_model(robot)
    cfg = ControlConfig()
    seen: list[tuple[np.ndarray, np.ndarray]] = []

    def law(k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray | None:
        if k >= n:
            return None
        seen.append((qd.copy(), d.qvel[robot.handles.arm_dof].copy()))
        return control.joint_impedance(arm, q, d.qvel[robot.handles.arm_dof], q_ref[k], qd_ref[k], qdd_ref[k],
                                       cfg.joint_kp, cfg.joint_kd)  # driven on the true velocity: smooth

    loop.run(robot, d, law, None)
    est, true = (np.array(a) for a in zip(*seen, strict=True))
    err = est - true
    rms_err, rms_v = float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.mean(true**2)))
    peak_v = float(np.abs(true).max())
    print(f"\nvelocity estimate over {len(seen)} ticks: rms error {rms_err:.4f} rad/s, max {np.abs(err).max():.4f} "
          f"rad/s, against rms {rms_v:.3f} and peak {peak_v:.3f} rad/s")
    # the lag (about 2.6 ms: half a period of difference + the filter) times ~8-16 rad/s^2, plus noise
    assert rms_err < 0.03 * peak_v
    assert float(np.abs(err).max()) < 0.06


# --------------------------------------------------------------------------- #
# the realistic profile meets its targets
# --------------------------------------------------------------------------- #


def _profile(robot: Robot, configs: GraspConfigurations, loop: ControlLoop | None,
             gains: ControlConfig) -> tuple[control.TrackingRecord, list[control.CartesianRecord]]:
    traj = retime(np.array([robot.home_q, configs.pregrasp.q]), TimingConfig.ur5e())
    joint = control.track(robot, _data_at(robot, robot.home_q), traj, gains, loop=loop)
    d = _data_at(robot, configs.pregrasp.q)
    z0 = float(d.site_xpos[robot.handles.tcp_site][2])
    control.hold(robot, d, configs.pregrasp.q, 0.1, gains, loop=loop)
    moves = [control.move_vertical(robot, d, z, gains, loop=loop, raise_on_timeout=False) for z in (z0 - 0.15, z0)]
    return joint, moves


def test_realistic_profile_tracks_within_its_targets(robot: Robot, configs: GraspConfigurations) -> None:
    """500 Hz with 2 ms latency, 18-bit encoders with noise, 100 Hz velocity filter, +/- 10 % inertial error and
    unknown friction (3 N m Coulomb on the big joints): a TOPP-RA joint move within 5 mrad and straight 0.15 m
    descent and lift within 2 mm, with the realistic gains; the ideal gains miss both there."""
    plant = with_model_error(robot, ModelErrorConfig.realistic(), np.random.default_rng(11))
    print()
    figures = {}
    for name, bot, loop, gains in (
        ("ideal loop, ideal gains", robot, None, ControlConfig()),
        ("realistic, ideal gains", plant, ControlLoop(LoopConfig.realistic(), np.random.default_rng(5)),
         ControlConfig()),
        ("realistic, realistic gains", plant, ControlLoop(LoopConfig.realistic(), np.random.default_rng(5)),
         ControlConfig.realistic()),
    ):
        joint, moves = _profile(bot, configs, loop, gains)
        tcp = max(m.position_error_max_m for m in moves)
        figures[name] = (joint, moves, tcp)
        print(f"{name}: joint max {joint.max_error_rad * 1e3:.2f} mrad, rms {joint.rms_error_rad * 1e3:.2f} mrad, "
              f"final {joint.final_error_rad * 1e3:.3f} mrad, {joint.saturation_events} saturated; tcp max "
              f"{tcp * 1e3:.2f} mm, final {[round(m.final_error_m * 1e3, 3) for m in moves]} mm, reached "
              f"{[m.reached for m in moves]}, orientation {max(m.orientation_error_max_rad for m in moves):.2e} rad")
    joint, moves, tcp = figures["realistic, realistic gains"]
    assert joint.max_error_rad < 5e-3
    assert joint.saturation_events == 0
    assert tcp < 2e-3
    assert all(m.reached for m in moves)
    assert all(m.saturation_events == 0 for m in moves)
    joint_i, _, tcp_i = figures["realistic, ideal gains"]
    assert joint_i.max_error_rad > 5e-3 and tcp_i > 2e-3  # why the realistic profile has its own gains


# --------------------------------------------------------------------------- #
# inertia-shaped gains (ControlConfig.joint_bandwidth_rad_s, cartesian_bandwidth_rad_s)
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"joint_bandwidth_rad_s": -1.0}, "control.joint_bandwidth_rad_s"),
    ({"cartesian_bandwidth_rad_s": math.nan}, "control.cartesian_bandwidth_rad_s"),
    ({"joint_integral_zero_rad_s": 10.0}, "control.joint_integral_zero_rad_s"),  # needs a bandwidth
    ({"cartesian_integral_zero_rad_s": 10.0}, "control.cartesian_integral_zero_rad_s"),
])
def test_shaped_gains_config_rejects_bad_values(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        ControlConfig(**kwargs)
    assert info.value.field == field


def test_shaped_gains_are_the_stiffness_w2_m_in_both_spaces(robot: Robot, configs: GraspConfigurations) -> None:
    """At rest, with a small pose error: the joint law's feedback is ``w^2 M(q) e_q`` and the Cartesian law's is
    ``J^T w^2 Lambda e_x``; for the UR5e's square Jacobian both are ``w^2 M(q) dq`` (``J^T Lambda J = M``), each
    checked against an independent computation (MuJoCo's inertia, finite joint offsets)."""
    w = 80.0
    arm = control.arm_model(robot)
    q = configs.pregrasp.q.copy()
    zero = np.zeros(6)
    g = control.joint_impedance(arm, q, zero, q, zero, zero, np.ones(6), np.ones(6), bandwidth_rad_s=w)
    dq = np.array([1e-4, -2e-4, 1.5e-4, 3e-4, -2e-4, 1e-4])
    tau = control.joint_impedance(arm, q, zero, q + dq, zero, zero, np.ones(6), np.ones(6), bandwidth_rad_s=w)
    d = robot.make_data()
    d.qpos[robot.handles.arm_qpos] = q
    mujoco.mj_forward(robot.mj, d)
    M_full = np.zeros((robot.mj.nv, robot.mj.nv))
    mujoco.mj_fullM(robot.mj, d, M_full)
    dof = robot.handles.arm_dof
    M = M_full[np.ix_(dof, dof)] + np.diag(robot.mj.opt.timestep * robot.mj.dof_damping[dof])  # implicit damping
    rel = np.abs(tau - g - w**2 * M @ dq).max() / np.abs(w**2 * M @ dq).max()
    print(f"\njoint law: feedback vs w^2 M dq (MuJoCo's M): relative difference {rel:.2e}")
    assert rel < 1e-6
    # Cartesian: the reference pose of the arm at q + dq, the arm at q
    pdata = robot.pin.createData()
    pin.framesForwardKinematics(robot.pin, pdata, robot.pin_q(q + dq))
    T_ref = pdata.oMf[robot.pin_tcp_frame]
    cmd = control.cartesian_impedance(arm, q, zero, T_ref.translation.copy(), np.zeros(3), np.zeros(3),
                                      T_ref.rotation.copy(), np.ones(6), 1.0, q, 0.0, 0.0, bandwidth_rad_s=w)
    rel_c = np.abs(cmd.tau - g - w**2 * M @ dq).max() / np.abs(w**2 * M @ dq).max()
    print(f"Cartesian law: feedback vs w^2 M dq: relative difference {rel_c:.2e} (first order in dq)")
    assert rel_c < 1e-3


def test_realistic_straight_moves_settle_at_once(robot: Robot, configs: GraspConfigurations) -> None:
    """The set-down failure of the realistic profile (seed 1: 'tcp not settled ... 0.225 mm from it'): with fixed
    Cartesian gains (8000 N/m, 200 N m/rad, integral 150000 N/(m s)) the arm's translation modes sit at 15-35 rad/s,
    below the integral's zero, and against the unknown Coulomb friction the tcp hunts about its target for most
    of a second after the profile; with the inertia-shaped gains every straight move settles within its 0.2 mm
    promptly. Three model-error draws, a 0.15 m descent and lift each."""
    fixed = ControlConfig(
        joint_kp_nm_rad=(3200.0, 10400.0, 4000.0, 330.0, 240.0, 190.0),
        joint_kd_nm_s_rad=(86.0, 280.0, 106.0, 8.7, 6.4, 5.0),
        joint_ki_nm_rad_s=(57600.0, 187200.0, 72000.0, 5940.0, 4320.0, 3420.0),
        cartesian_stiffness_n_m=8000.0, cartesian_rot_stiffness_nm_rad=200.0, cartesian_modal_damping=True,
        cartesian_ki_n_m_s=150000.0, cartesian_rot_ki_nm_rad_s=2000.0)
    waits: dict[str, list[float]] = {"fixed": [], "shaped": []}
    tcp_max = 0.0
    for draw in (11, 12, 13):
        plant = with_model_error(robot, ModelErrorConfig.realistic(), np.random.default_rng(draw))
        for name, gains in (("fixed", fixed), ("shaped", ControlConfig.realistic())):
            loop = ControlLoop(LoopConfig.realistic(), np.random.default_rng(5))
            d = _data_at(plant, configs.pregrasp.q)
            z0 = float(d.site_xpos[robot.handles.tcp_site][2])
            control.hold(plant, d, configs.pregrasp.q, 0.1, gains, loop=loop)
            for z in (z0 - 0.15, z0):
                m = control.move_vertical(plant, d, z, gains, loop=loop, raise_on_timeout=False)
                assert m.reached and m.saturation_events == 0
                waits[name].append(m.duration_s - m.profile_duration_s)
                if name == "shaped":
                    tcp_max = max(tcp_max, m.position_error_max_m)
    print(f"\nsettle wait after the profile: fixed gains {np.round(waits['fixed'], 3).tolist()} s, shaped "
          f"{np.round(waits['shaped'], 3).tolist()} s; shaped tcp error max {tcp_max * 1e3:.3f} mm")
    assert max(waits["shaped"]) < 0.3
    assert float(np.mean(waits["shaped"])) < 0.1
    assert min(waits["fixed"]) > 0.5  # why the realistic profile shapes its gains
    assert tcp_max < 1e-3
