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
from pickplace.motion.timing import TimingConfig
from pickplace.robot.ik import solve_line
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import Robot

VLIM = np.array(TimingConfig().velocity_limits_rad_s)
ALIM = np.array(TimingConfig().acceleration_limits_rad_s2)


def _step(robot: Robot, d: mujoco.MjData, qd: np.ndarray, tau: np.ndarray) -> None:
    """Write the state of the next physics step: the arm's joint speeds (6,) (rad/s) and torques (6,) (N m)."""
    h = robot.handles
    d.time += float(robot.mj.opt.timestep)
    d.qvel[h.arm_dof] = qd
    d.ctrl[h.arm_actuators] = tau


def test_the_limit_meter_counts_every_step_over_a_limit_by_kind_and_phase(robot: Robot) -> None:
    d = mujoco.MjData(robot.mj)
    dt = float(robot.mj.opt.timestep)
    meter = LimitMeter(robot, VLIM, ALIM)
    tau_max = np.asarray(robot.torque_limits_nm)
    zero = np.zeros(6)
    meter(d, "A")  # at rest: the first step has no acceleration to measure
    # elbow at half its acceleration limit for one step: within
    qd = np.array([0.0, 0.0, 0.5 * ALIM[2] * dt, 0.0, 0.0, 0.0])
    _step(robot, d, qd, zero)
    meter(d, "A")
    # the same speed again: no acceleration
    _step(robot, d, qd, zero)
    meter(d, "A")
    # wrist_3 jumps to 1.1x its speed limit in one step (far past its acceleration limit), and shoulder_lift's
    # torque is at its limit: one step over all three
    qd2 = qd + np.array([0, 0, 0, 0, 0, 1.1 * VLIM[5]])
    _step(robot, d, qd2, np.array([0.0, tau_max[1], 0.0, 0.0, 0.0, 0.0]))
    meter(d, "B")
    rep = meter.report()
    assert rep.samples == 4 and rep.hold_samples == 0
    assert rep.speed_ratio_max == pytest.approx(1.1)
    assert rep.acceleration_ratio_max == pytest.approx(1.1 * VLIM[5] / dt / ALIM[5])
    assert rep.torque_ratio_max == pytest.approx(1.0)
    assert (rep.speed_violations, rep.acceleration_violations, rep.torque_violations) == (1, 1, 1)
    assert rep.violations == 1 and rep.violations_by_phase == {"B": 1}
    assert rep.worst.startswith("acceleration of wrist_3 in B")
    # the speed held over its limit: a speed violation only, in its phase
    _step(robot, d, qd2, zero)
    meter(d, "C")
    rep = meter.report()
    assert (rep.speed_violations, rep.acceleration_violations, rep.torque_violations) == (2, 1, 1)
    assert rep.violations == 2 and rep.violations_by_phase == {"B": 1, "C": 1}
    # a step while the arm is told to hold still is counted apart
    _step(robot, d, zero, zero)
    meter(d, "CLOSE", moving=False)
    rep = meter.report()
    assert rep.samples == 5 and rep.violations == 2
    assert rep.hold_samples == 1 and rep.hold_violations == 1 and rep.hold_violations_by_phase == {"CLOSE": 1}
    assert "in CLOSE" in rep.hold_worst


def test_the_limit_meter_does_not_difference_across_a_gap_in_time(robot: Robot) -> None:
    """An acceleration is the change of speed over one physics step; two states further apart (another loop ran
    in between, unmeasured) give none."""
    d = mujoco.MjData(robot.mj)
    meter = LimitMeter(robot, VLIM, ALIM)
    meter(d, "A")
    d.time += 5 * float(robot.mj.opt.timestep)
    d.qvel[robot.handles.arm_dof] = 0.5 * VLIM
    meter(d, "A")
    rep = meter.report()
    assert rep.acceleration_ratio_max == 0.0 and rep.violations == 0
    assert rep.speed_ratio_max == pytest.approx(0.5)


def test_the_limit_meter_reduces_batches_as_it_would_step_by_step(robot: Robot) -> None:
    """Steps are buffered and reduced in batches: 1,000 random steps across phases, holds, a gap in time and batch
    boundaries give the same figures as a meter that reduces every step."""

    class EveryStep(LimitMeter):
        BATCH = 1

    rng = np.random.default_rng(3)
    d = mujoco.MjData(robot.mj)
    batched, single = LimitMeter(robot, VLIM, ALIM), EveryStep(robot, VLIM, ALIM)
    tau_max = np.asarray(robot.torque_limits_nm)
    qd = np.zeros(6)
    for k in range(1000):
        qd = qd + rng.normal(0.0, 0.012, 6) * ALIM  # now and then past the acceleration limit
        tau = np.where(rng.random(6) < 0.002, tau_max, rng.uniform(-0.5, 0.5, 6) * tau_max)
        _step(robot, d, np.clip(qd, -1.05 * VLIM, 1.05 * VLIM), tau)
        if k == 600:
            d.time += 0.5  # another loop ran in between, unmeasured
        phase, moving = ("A", True) if k < 300 else ("CLOSE", False) if k < 420 else ("B", True)
        batched(d, phase, moving)
        single(d, phase, moving)
    a, b = batched.report(), single.report()
    assert a.violations > 0 and a.hold_violations > 0
    assert a == b


def test_the_line_meter_measures_the_distance_from_the_line(robot: Robot) -> None:
    d = mujoco.MjData(robot.mj)
    site = robot.handles.tcp_site
    a, b = np.array([0.5, 0.1, 0.4]), np.array([0.5, 0.1, 0.25])
    meter = LineMeter(robot, a, b)
    for p in ([0.5, 0.1, 0.3], [0.5003, 0.0996, 0.35], [0.5, 0.1, 0.1]):  # on it, 0.5 mm off it, on it past b
        d.site_xpos[site] = p
        meter(d)
    assert meter.max_m == pytest.approx(5e-4, rel=1e-9)


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
