"""Grasp-aware motion: what a grip can carry (pickplace.grasping.grip) and episodes that respect it.

The capacity is ``2 mu F`` along the pads' faces; an object whose weight needs more (with the safety factor)
is rejected before the arm moves, and motions that carry it are slowed down until it holds.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from pickplace.errors import CannotHold
from pickplace.grasping.grip import G, GripCapacity, com_accelerations, grip_capacity, slowdown_for_grip
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot.gripper import squeeze_per_pad_n
from pickplace.robot.model import Robot
from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.world.objects import library_object


def test_squeeze_is_the_actuator_limit_shared_by_the_pads(robot: Robot) -> None:
    """40 N on the finger pair, 20 N per pad, for anything wider than 20 mm; less for thin objects (the servo's
    kp x the travel left before its fully closed target)."""
    assert squeeze_per_pad_n(robot, 0.040) == pytest.approx(20.0, abs=1e-9)
    assert squeeze_per_pad_n(robot, 0.070) == pytest.approx(20.0, abs=1e-9)
    assert squeeze_per_pad_n(robot, 0.010) == pytest.approx(5000.0 * (0.005 - 0.002) / 2, abs=1e-6)
    assert squeeze_per_pad_n(robot, 0.003) == 0.0  # narrower than the closed gripper


def test_capacity_of_the_default_grip(robot: Robot) -> None:
    cap = grip_capacity(robot, library_object("cube"), pin.SE3.Identity(), 0.040, 1.25)
    assert cap.pad_force_n == pytest.approx(20.0, abs=1e-9)
    assert cap.friction_force_n == pytest.approx(40.0, abs=1e-9)
    assert cap.needed_at_rest_n == pytest.approx(0.150 * G * 1.25, abs=1e-12)
    assert cap.acceleration_budget_m_s2 == pytest.approx(40.0 / (0.150 * 1.25), rel=1e-12)
    cap.require_holdable("cube")
    heavy = GripCapacity(3.0, 0.4, 20.0, 1.25, (0.0, 0.0, 0.0))
    with pytest.raises(CannotHold, match=r"needs 36\.8 N of friction .* the pads give 16\.0 N") as info:
        heavy.require_holdable("box")
    assert info.value.needed_n == pytest.approx(3.0 * G * 1.25) and info.value.available_n == pytest.approx(16.0)


def test_slowdown_is_the_time_scaling_that_holds() -> None:
    """A horizontal acceleration a holds after slowing down k times when sqrt((a / k^2)^2 + g^2) <= budget."""
    cap = GripCapacity(1.0, 0.6, 20.0, 1.0, (0.0, 0.0, 0.0))  # budget 24 m/s^2
    accels = np.array([[0.0, 0.0, 0.0], [30.0, 0.0, 0.0], [-10.0, 5.0, 0.0]])
    k = slowdown_for_grip(accels, cap)
    assert k**2 == pytest.approx(30.0 / math.sqrt(24.0**2 - G**2), rel=1e-8)
    assert slowdown_for_grip(accels / 100.0, cap) == 1.0
    with pytest.raises(CannotHold):
        slowdown_for_grip(accels, GripCapacity(1.0, 0.2, 20.0, 1.0, (0.0, 0.0, 0.0)))  # 8 N < m g


def test_slowed_trajectory_scales_velocity_and_acceleration(robot: Robot) -> None:
    traj = retime(np.array([robot.home_q, robot.home_q + 0.4]), TimingConfig.ur5e())
    slow = traj.slowed(2.0)
    assert slow.duration_s == pytest.approx(2 * traj.duration_s, rel=1e-12)
    t = np.linspace(0.0, traj.duration_s, 37)
    q, qd, qdd = traj.sample_many(t)
    q2, qd2, qdd2 = slow.sample_many(2 * t)
    np.testing.assert_allclose(q2, q, atol=1e-12)
    np.testing.assert_allclose(qd2, qd / 2, atol=1e-12)
    np.testing.assert_allclose(qdd2, qdd / 4, atol=1e-9)
    a1 = com_accelerations(robot, traj, np.zeros(3), 0.0)
    a2 = com_accelerations(robot, slow, np.zeros(3), 0.0)
    assert np.max(np.linalg.norm(a2, axis=1)) == pytest.approx(np.max(np.linalg.norm(a1, axis=1)) / 4, rel=0.05)


def test_a_heavy_box_at_low_friction_is_carried_gently_without_slip() -> None:
    """1.5 kg at mu 0.5: the weight needs 14.7 N of the pads' 20 N. Lift, transport and set-down are slowed to
    what the grip holds with the safety factor, and the box arrives."""
    r = run_episode(EpisodeConfig().with_object(mass_kg=1.5, friction=0.5).with_scene(obstacle=True))
    print(f"\n1.5 kg at mu 0.5: {r.success}, slip {r.slip_max_m * 1e3:.2f} mm, slowdown {r.slowdown_for_grip}, "
          f"cycle {r.cycle_time_s:.2f} s")
    assert r.success, r.failure_reason
    assert r.slip_max_m < 3e-3 and r.retries == 0
    assert r.slowdown_for_grip["transport"] > 1.5  # the wall's detour is too fast for this grip otherwise
    assert r.slowdown_for_grip["approach"] == 1.0 and r.slowdown_for_grip["return"] == 1.0  # nothing held


def test_a_box_the_pads_cannot_hold_is_rejected_before_moving() -> None:
    r = run_episode(EpisodeConfig().with_object(mass_kg=3.0, friction=0.4))
    assert (r.failure_phase, r.failure_kind) == ("IDLE", "CannotHold")
    assert "needs 36.8 N of friction" in r.failure_reason and "the pads give 16.0 N" in r.failure_reason
    assert r.cycle_time_s == 0.0


def test_an_off_centre_object_needs_torque_and_a_heavy_one_is_rejected(robot: Robot) -> None:
    """The L-bracket gripped across its length at the upright leg: its centre of mass lies 13.6 mm off the
    closing axis (the legs' centroids weighted by volume, computed here by hand). At 119 g the weight's torque
    is far within the pads' torsional friction; at 1.65 kg it is not (at friction 0.6 the force alone would
    hold), and the episode refuses it in IDLE."""
    bracket = library_object("l_bracket")
    flat, upright = bracket.parts
    com_x = (flat.volume_m3 * flat.pos_m[0] + upright.volume_m3 * upright.pos_m[0]) / (flat.volume_m3
                                                                                         + upright.volume_m3)
    # top-down, closing along the bracket's length (its y), the tcp in the upright leg's mid-plane
    T_object_tcp = pin.SE3(np.diag([1.0, -1.0, -1.0]), np.array([upright.pos_m[0], 0.0, 0.025]))
    cap = grip_capacity(robot, bracket, T_object_tcp.inverse(), 0.040, 1.25, up_tcp=T_object_tcp.rotation[2])
    assert cap.lever_m == pytest.approx(abs(com_x - upright.pos_m[0]), abs=1e-9)
    assert cap.lever_m == pytest.approx(0.0136, abs=2e-4)
    assert cap.torsion_m == pytest.approx(0.005, abs=1e-12)  # the pads' (and the object's) torsional friction
    assert cap.torque_capacity_nm == pytest.approx(2 * 0.005 * 20.0, abs=1e-9)
    assert cap.holds_at_rest
    heavy = dataclasses.replace(cap, mass_kg=1.65)
    assert heavy.needed_at_rest_n < heavy.friction_force_n  # the force alone would hold ...
    assert not heavy.holds_at_rest  # ... the torque does not
    with pytest.raises(CannotHold, match=r"turns it about the grip axis with 0\.27\d N m .* resist 0\.200 N m"):
        heavy.require_holdable("l_bracket")
    # an acceleration budget that also respects the torque
    assert cap.acceleration_budget_m_s2 == pytest.approx(
        min(cap.friction_force_n, cap.torque_capacity_nm / cap.lever_m) / (cap.mass_kg * 1.25), rel=1e-12)
    config = EpisodeConfig().with_object(**{**dataclasses.asdict(bracket), "mass_kg": 1.65, "friction": 0.6,
                                            "parts": bracket.parts})
    result = run_episode(config)
    assert not result.success and result.failure_phase == "IDLE" and result.failure_kind == "CannotHold"
    assert "turns it about the grip axis" in result.failure_reason
    assert result.cycle_time_s == 0.0
