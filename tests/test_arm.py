"""Straight tcp moves made on their own (:meth:`pickplace.task.arm.Arm.linear`): joint trajectories through the
line's IK waypoints, timed within the joints' limits with the tcp on the line, checked for collisions before the
arm moves, tracked by the joint controller; the Cartesian controller only where no such trajectory can be built.

The arm starts nearly stretched out (the tcp 0.73 m from the base, 35 mm above the table), where the joints turn
fast along a vertical line: the case in which a lift made by the Cartesian controller let the elbow fold the
other way and the upper arm touched the table.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import UnreachableTarget
from pickplace.motion.control import CartesianRecord, ControlConfig, TrackingRecord
from pickplace.motion.planning import PlannerConfig
from pickplace.motion.timing import TimingConfig
from pickplace.robot.ik import solve_ik
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import Robot, build
from pickplace.task import arm as arm_module
from pickplace.task.arm import LINE_TOLERANCE_M, Arm
from pickplace.task.phases import MachineConfig, Phase, PhaseFailed

FAR_OUT_M = (0.6095, 0.3965)  # where a tennis ball lay whose Cartesian lift put the upper arm on the table
RISE_M = 0.15


@pytest.fixture(scope="module")
def robot() -> Robot:
    return build()


def _arm_at(robot: Robot, xy: tuple[float, float], z: float) -> Arm:
    """An arm at rest with the tcp pointing down at ``(x, y, z)`` (m), the gripper open."""
    down = frame_pose(robot.pin, robot.pin.createData(), robot.pin_q(robot.home_q), robot.pin_tcp_frame).rotation
    q = solve_ik(robot, pin.SE3(down, np.array([*xy, z])), robot.home_q).q
    d = robot.make_data()
    d.qpos[robot.handles.arm_qpos] = q
    mujoco.mj_forward(robot.mj, d)
    arm = Arm(robot, d, MachineConfig(), ControlConfig(), PlannerConfig(), TimingConfig())
    arm.monitor.phase = Phase.LIFT.value
    return arm


def _off_line_m(arm: Arm, qs: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance (m) of the tcp from the line through ``a`` and ``b`` over configurations ``qs``."""
    u = (b - a) / np.linalg.norm(b - a)
    off = np.array([arm.tcp_at(q) - a for q in qs])
    return float(np.max(np.linalg.norm(off - np.outer(off @ u, u), axis=1)))


def test_a_straight_move_far_out_is_a_joint_trajectory_on_its_line(robot: Robot) -> None:
    arm = _arm_at(robot, FAR_OUT_M, robot.scene.table_height_m + 0.035)
    start = arm.tcp_pose()
    target = pin.SE3(start.rotation, start.translation + np.array([0.0, 0.0, RISE_M]))
    traj = arm.line_trajectory(target, arm.free(0.0))
    dt = 1e-3
    qs, qds, qdds = traj.sample_many(np.arange(0.0, traj.duration_s + dt, dt))
    print(f"\nfar-out rise of {RISE_M} m: {traj.duration_s:.3f} s, elbow {qs[0, 2]:.3f} -> {qs[-1, 2]:.3f} rad, "
          f"peak ratios speed {traj.peak_velocity_ratio:.3f} acceleration {traj.peak_acceleration_ratio:.3f}")
    assert _off_line_m(arm, qs, start.translation, target.translation) <= LINE_TOLERANCE_M
    assert np.all(np.abs(qds) <= np.array(arm.timing.velocity_limits_rad_s) + 1e-9)
    assert np.all(np.abs(qdds) <= np.array(arm.timing.acceleration_limits_rad_s2) * (1 + 1e-6))
    assert np.linalg.norm(arm.tcp_at(traj.end) - target.translation) < 1e-4
    assert abs(qs[0, 2]) - abs(qs[-1, 2]) > 0.5  # the elbow straightens: the joints turn fast along the line

    with arm.following(start.translation, target.translation) as line:
        rec = arm.linear(Phase.LIFT, target, checker=arm.free(0.0))
    assert isinstance(rec, TrackingRecord)  # the joint controller tracked it
    report = arm.limits.report()
    print(f"tracked: the tcp {line.max_m * 1e3:.4f} mm off its line at most, {report.violations} steps over a limit "
          f"(peak acceleration {report.acceleration_ratio_max:.3f})")
    assert line.max_m <= 1e-3
    assert report.violations == 0 and report.acceleration_ratio_max <= 1.0
    assert np.linalg.norm(arm.tcp_pose().translation - target.translation) < 1e-3
    assert arm.monitor.t == pytest.approx(traj.duration_s + arm.cfg.settle_s, abs=2e-3)


def test_a_straight_move_into_something_fails_before_the_arm_moves(robot: Robot) -> None:
    arm = _arm_at(robot, (0.5, -0.3), robot.scene.table_height_m + 0.1)
    q0 = arm.q
    below = arm.tcp_pose().translation - np.array([0.0, 0.0, 0.2])  # the fingers through the table top
    with pytest.raises(PhaseFailed) as info:
        arm.linear(Phase.DESCEND, below, checker=arm.free(0.0))
    assert info.value.phase is Phase.DESCEND and "table_top" in info.value.reason
    assert arm.monitor.t == 0.0 and np.array_equal(arm.q, q0)


def test_a_move_already_made_stands_still(robot: Robot) -> None:
    arm = _arm_at(robot, (0.5, -0.3), robot.scene.table_height_m + 0.1)
    q0 = arm.q
    traj = arm.line_trajectory(arm.tcp_pose())
    assert traj.duration_s == 0.0 and np.allclose(traj.end, q0)


def test_where_no_joint_trajectory_can_be_built_the_cartesian_controller_moves(
        robot: Robot, monkeypatch: pytest.MonkeyPatch) -> None:
    """A line whose waypoints do not solve on the arm's branch (stubbed here: no such line is known in the default
    scene's workspace) is made by the Cartesian controller, within the joints' limits as well."""
    arm = _arm_at(robot, (0.5, -0.3), robot.scene.table_height_m + 0.1)

    def unsolvable(*args: object, **kwargs: object) -> None:
        raise UnreachableTarget("straight move", "a joint jumps 0.50 rad in one 10 mm step (near a singularity)")

    monkeypatch.setattr(arm_module, "solve_line", unsolvable)
    target = arm.tcp_pose().translation + np.array([0.0, 0.0, 0.05])
    rec = arm.linear(Phase.RETRACT, target)
    assert isinstance(rec, CartesianRecord) and rec.reached
    assert np.linalg.norm(arm.tcp_pose().translation - target) < 1e-3
    assert arm.limits.report().violations == 0
    assert math.isfinite(rec.final_error_m)
