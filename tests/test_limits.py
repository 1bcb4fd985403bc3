"""The executed motion against the joint limits (:mod:`pickplace.motion.limits`) and the straight moves' duration
within them (:func:`pickplace.motion.control.line_duration_s`).

The meters are checked on states written by hand (each joint's speed, its change over one step, the torque
applied); the duration of a straight move against an independent computation: the joint path of the line solved
by IK every 2 mm, splined, run on the minimum-jerk profile of that duration and differentiated numerically.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from scipy.interpolate import CubicSpline

from pickplace.grasping.configurations import GraspConfigurations
from pickplace.motion import control
from pickplace.motion.control import ControlConfig, line_duration_s, min_jerk
from pickplace.motion.limits import LimitMeter, LineMeter
from pickplace.motion.loop import Measured
from pickplace.motion.timing import TimingConfig
from pickplace.robot.ik import solve_line
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import ARM_STATE_WIDTH, Robot

VLIM = np.array(TimingConfig().velocity_limits_rad_s)
ALIM = np.array(TimingConfig().acceleration_limits_rad_s2)


def _rows(qd: np.ndarray, tau: np.ndarray, tcp: np.ndarray | None = None) -> np.ndarray:
    """Rows of a control loop's tape of the arm's state (robot.model.ARM_STATE_FIELDS) from the joints' speeds
    (k, 6) (rad/s), the torques applied (k, 6) (N m) and the tcp (k, 3) (m; zeros if None); positions zero."""
    qd, tau = np.atleast_2d(qd), np.atleast_2d(tau)
    rows = np.zeros((len(qd), ARM_STATE_WIDTH))
    rows[:, 6:12], rows[:, 12:18] = qd, tau
    if tcp is not None:
        rows[:, 18:21] = tcp
    return rows


def test_the_limit_meter_counts_every_step_over_a_limit_by_kind_and_phase(robot: Robot) -> None:
    dt = float(robot.mj.opt.timestep)
    meter = LimitMeter(robot, VLIM, ALIM)
    tau_max = np.asarray(robot.torque_limits_nm)
    zero = np.zeros(6)
    # at rest (the first step has no acceleration to measure); the elbow at half its acceleration limit for one
    # step: within; the same speed again: no acceleration
    qd = np.array([0.0, 0.0, 0.5 * ALIM[2] * dt, 0.0, 0.0, 0.0])
    meter.add(_rows([zero, qd, qd], [zero, zero, zero]), 0.0, "A")
    # wrist_3 jumps to 1.1x its speed limit in one step (far past its acceleration limit), and shoulder_lift's
    # torque is at its limit: one step over all three
    qd2 = qd + np.array([0, 0, 0, 0, 0, 1.1 * VLIM[5]])
    meter.add(_rows(qd2, [0.0, tau_max[1], 0.0, 0.0, 0.0, 0.0]), 3 * dt, "B")
    rep = meter.report()
    assert rep.samples == 4 and rep.hold_samples == 0
    assert rep.speed_ratio_max == pytest.approx(1.1)
    assert rep.acceleration_ratio_max == pytest.approx(1.1 * VLIM[5] / dt / ALIM[5])
    assert rep.torque_ratio_max == pytest.approx(1.0)
    assert (rep.speed_violations, rep.acceleration_violations, rep.torque_violations) == (1, 1, 1)
    assert rep.violations == 1 and rep.violations_by_phase == {"B": 1}
    assert rep.worst.startswith("acceleration of wrist_3 in B")
    assert "t = 0.003 s" in rep.worst
    # the speed held over its limit: a speed violation only, in its phase
    meter.add(_rows(qd2, zero), 4 * dt, "C")
    rep = meter.report()
    assert (rep.speed_violations, rep.acceleration_violations, rep.torque_violations) == (2, 1, 1)
    assert rep.violations == 2 and rep.violations_by_phase == {"B": 1, "C": 1}
    # a step while the arm is told to hold still is counted apart
    meter.add(_rows(zero, zero), 5 * dt, "CLOSE", moving=False)
    rep = meter.report()
    assert rep.samples == 5 and rep.violations == 2
    assert rep.hold_samples == 1 and rep.hold_violations == 1 and rep.hold_violations_by_phase == {"CLOSE": 1}
    assert "in CLOSE" in rep.hold_worst


def test_the_limit_meter_does_not_difference_across_a_gap_in_time(robot: Robot) -> None:
    """An acceleration is the change of speed over one physics step; two states further apart (another loop ran
    in between, unmeasured) give none."""
    dt = float(robot.mj.opt.timestep)
    meter = LimitMeter(robot, VLIM, ALIM)
    meter.add(_rows(np.zeros(6), np.zeros(6)), 0.0, "A")
    meter.add(_rows(0.5 * VLIM, np.zeros(6)), 5 * dt, "A")
    rep = meter.report()
    assert rep.acceleration_ratio_max == 0.0 and rep.violations == 0
    assert rep.speed_ratio_max == pytest.approx(0.5)
    meter.add(_rows(0.6 * VLIM, np.zeros(6)), 6 * dt, "A")  # the next step: differenced with the last one
    assert meter.report().acceleration_ratio_max == pytest.approx(float(np.max(0.1 * VLIM / dt / ALIM)))


def test_the_limit_meter_gives_the_same_figures_whatever_the_blocks(robot: Robot) -> None:
    """The loops hand the meter their tapes in blocks of any size: 1,000 random steps across phases, holds and a gap
    in time, given step by step and in random blocks, give the same figures."""
    rng = np.random.default_rng(3)
    dt = float(robot.mj.opt.timestep)
    tau_max = np.asarray(robot.torque_limits_nm)
    qd = np.zeros(6)
    steps = []
    t = 0.0
    for k in range(1000):
        qd = qd + rng.normal(0.0, 0.012, 6) * ALIM  # now and then past the acceleration limit
        tau = np.where(rng.random(6) < 0.002, tau_max, rng.uniform(-0.5, 0.5, 6) * tau_max)
        if k == 600:
            t += 0.5  # another loop ran in between, unmeasured
        phase, moving = ("A", True) if k < 300 else ("CLOSE", False) if k < 420 else ("B", True)
        steps.append((np.clip(qd, -1.05 * VLIM, 1.05 * VLIM), tau, t, phase, moving))
        t += dt
    single, blocks = LimitMeter(robot, VLIM, ALIM), LimitMeter(robot, VLIM, ALIM)
    for v, tau, t0, phase, moving in steps:
        single.add(_rows(v, tau), t0, phase, moving)
    start = 0
    while start < len(steps):  # blocks of random length that end at a change of phase or a gap at the latest
        end = min(len(steps), start + int(rng.integers(1, 300)))
        for k in range(start + 1, end):
            if steps[k][3:] != steps[start][3:] or abs(steps[k][2] - steps[k - 1][2] - dt) > 1e-9:
                end = k
                break
        v, tau = np.array([x[0] for x in steps[start:end]]), np.array([x[1] for x in steps[start:end]])
        blocks.add(_rows(v, tau), steps[start][2], *steps[start][3:])
        start = end
    a, b = single.report(), blocks.report()
    assert a.violations > 0 and a.hold_violations > 0
    assert a.samples == b.samples == 880 and a.hold_samples == b.hold_samples == 120
    assert (a.violations, a.hold_violations, a.violations_by_phase, a.hold_violations_by_phase) == (
        b.violations, b.hold_violations, b.violations_by_phase, b.hold_violations_by_phase)
    assert (a.speed_violations, a.acceleration_violations, a.torque_violations) == (
        b.speed_violations, b.acceleration_violations, b.torque_violations)
    assert a.worst == b.worst and a.hold_worst == b.hold_worst
    for x, y in ((a.speed_ratio_max, b.speed_ratio_max), (a.acceleration_ratio_max, b.acceleration_ratio_max),
                 (a.torque_ratio_max, b.torque_ratio_max)):
        assert x == pytest.approx(y, rel=1e-12)


def test_the_line_meter_measures_the_distance_from_the_line() -> None:
    a, b = np.array([0.5, 0.1, 0.4]), np.array([0.5, 0.1, 0.25])
    meter = LineMeter(a, b)
    tcp = np.array([[0.5, 0.1, 0.3], [0.5003, 0.0996, 0.35], [0.5, 0.1, 0.1]])  # on it, 0.5 mm off it, on it past b
    meter.add(_rows(np.zeros((3, 6)), np.zeros((3, 6)), tcp)[:1])
    assert meter.max_m == pytest.approx(0.0, abs=1e-12)
    meter.add(_rows(np.zeros((3, 6)), np.zeros((3, 6)), tcp)[1:])
    assert meter.max_m == pytest.approx(5e-4, rel=1e-9)


def test_the_loops_tape_is_the_arm_state_of_every_step(robot: Robot) -> None:
    """A loop hands a Measured hook one row per physics step, in order and without a gap, each the arm's state at the
    start of its step (positions, velocities, torques applied in it, tcp), whatever the block boundaries."""
    d = robot.make_data()
    rows: list[np.ndarray] = []
    starts: list[float] = []
    states: list[np.ndarray] = []

    def tape(block: np.ndarray, t0_s: float) -> None:
        rows.extend(block.copy())
        starts.append(t0_s)

    h = robot.handles

    def step(data: mujoco.MjData) -> None:
        states.append(np.concatenate((data.qvel[h.arm_dof], data.actuator_force[h.arm_actuators])))

    q0 = d.qpos[h.arm_qpos].copy()
    control.hold(robot, d, q0, 1.3, ControlConfig(), hook=Measured(step, tape), comply_along=np.array([0, 0, 1.0]))
    assert len(rows) == len(states) == 1300
    assert starts[0] == 0.0 and len(starts) >= 3  # several blocks (TAPE_CHUNK rows each)
    np.testing.assert_allclose(np.array(rows)[0, :6], q0, rtol=0, atol=1e-12)
    # the velocities of a row are those after the step before it; the torques, the ones applied in its step
    np.testing.assert_allclose(np.array(rows)[1:, 6:12], np.array(states)[:-1, :6], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.array(rows)[:, 12:18], np.array(states)[:, 6:], rtol=0, atol=1e-12)


def test_a_straight_move_is_timed_within_the_joints_limits(robot: Robot, configs: GraspConfigurations) -> None:
    """The default descent (pregrasp to grasp, 15 cm): the minimum-jerk profile :func:`line_duration_s` gives keeps
    every joint within its speed and acceleration limits, and reaches one of them (it is the shortest such);
    the tcp's own limits alone would ask the elbow for more than its limit."""
    q0 = configs.pregrasp.q
    finger = 0.0
    T0 = frame_pose(robot.pin, robot.pin.createData(), robot.pin_q(q0, finger), robot.pin_tcp_frame)
    delta = np.array([0.0, 0.0, -0.15])
    arm = control.arm_model(robot)
    duration = line_duration_s(arm, q0, finger, delta, VLIM, ALIM)
    # independent: the joint path of the line by IK every 2 mm, splined in the line's parameter
    line = solve_line(robot, pin.SE3(T0.rotation, T0.translation + delta), q0, "descent", step_m=0.002)
    assert line.path is not None
    sigma = np.linspace(0.0, 1.0, len(line.path))
    path = CubicSpline(sigma, line.path, axis=0)

    def peak_ratios(duration_s: float) -> tuple[float, float]:
        dt = 1e-3
        s, sd, sdd = min_jerk(np.arange(0.0, duration_s + dt, dt), duration_s)
        qd = path(s, 1) * sd[:, None]
        qdd = path(s, 2) * sd[:, None] ** 2 + path(s, 1) * sdd[:, None]
        return float(np.max(np.abs(qd) / VLIM)), float(np.max(np.abs(qdd) / ALIM))

    v, a = peak_ratios(duration)
    assert max(v, a) <= 1.0 + 0.01  # within the limits (1 % for the two discretizations)
    assert max(v, a) >= 0.97  # and at one of them: the shortest such profile
    tcp_only = ControlConfig().vertical_duration_s(0.15)
    assert duration > tcp_only
    assert max(peak_ratios(tcp_only)) > 1.2  # what the tcp's limits alone would ask (1.47 on this descent)
