"""Faults injected on purpose: each is detected in the right phase with the right reason, within a stated time,
and recovered from where it can be.

Every fault is a real change to the simulation (see :mod:`pickplace.task.faults`). Each test runs full episodes
(about 0.5–1 s each): with recovery off (``machine.max_retries = 0``) to check the detection, and with the
default recovery to check what it achieves. Run with ``-s`` to see the detection times.
"""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from pickplace.robot import model
from pickplace.task.episode import EpisodeConfig, EpisodeResult, run_episode
from pickplace.task.faults import FaultConfig, apply_model_faults
from pickplace.task.machine import MachineConfig

TRANSPORT_PUSH = FaultConfig(transport_push_n=(0.0, 0.0, -40.0), transport_push_start_s=0.2, transport_push_s=0.05)
PRE_PICK_PUSH = FaultConfig(pre_pick_push_n=(0.0, -2.5), pre_pick_push_s=0.1)


def _run(faults: FaultConfig, recovery: bool, seed: int = 0, **scene: object) -> EpisodeResult:
    config = dataclasses.replace(EpisodeConfig(), faults=faults,
                                 machine=MachineConfig(max_retries=3 if recovery else 0))
    if scene:
        config = config.with_scene(**scene)
    return run_episode(config, seed, record=True)


def _phase_start(r: EpisodeResult, phase: str) -> float:
    assert r.telemetry is not None
    return next(a for name, a, _ in r.telemetry.phase_spans() if name == phase)


def _kg(text: str, after: str) -> float:
    """The mass (kg) printed in ``text`` right after ``after``."""
    match = re.search(re.escape(after) + r" ([0-9.]+) kg", text)
    assert match, text
    return float(match.group(1))


def _report(label: str, r: EpisodeResult, detection_s: float | None = None) -> None:
    det = f", detected {detection_s * 1e3:.0f} ms after onset" if detection_s is not None else ""
    outcome = "success" if r.success else f"FAILED in {r.failure_phase} ({r.failure_kind}): {r.failure_reason}"
    print(f"\n{label}: {outcome}{det}; retries {r.retries}; t = {r.cycle_time_s:.3f} s")
    for line in r.recoveries:
        print(f"    recovery: {line}")


def test_transport_push_drops_the_cube_detected_and_picked_again() -> None:
    """A 40 N downward push for 50 ms knocks the cube out of the grip while it is carried."""
    r = _run(TRANSPORT_PUSH, recovery=False)
    onset = _phase_start(r, "EXEC_TRANSPORT") + TRANSPORT_PUSH.transport_push_start_s
    _report("transport push, no recovery", r, r.cycle_time_s - onset)
    assert not r.success
    assert (r.failure_phase, r.failure_kind) == ("EXEC_TRANSPORT", "GraspFailed")
    assert "slipped" in r.failure_reason
    assert 0.0 < r.cycle_time_s - onset <= 0.1  # detected within 100 ms of the push

    r = _run(TRANSPORT_PUSH, recovery=True)
    _report("transport push, with recovery", r)
    assert r.success, r.failure_reason
    assert r.retries == 1 and r.recoveries[0].startswith("EXEC_TRANSPORT: GraspFailed")
    assert r.place_error_xy_m <= 1.4e-3 and r.final_place_error_xy_m <= 2e-3


def test_cube_pushed_before_the_pick_detected_and_reobserved() -> None:
    """The cube is pushed away after it was observed: the monitor sees it move, the machine looks again."""
    r = _run(PRE_PICK_PUSH, recovery=False)
    onset = _phase_start(r, "EXEC_APPROACH")
    _report("pre-pick push, no recovery", r, r.cycle_time_s - onset)
    assert (r.failure_phase, r.failure_kind) == ("EXEC_APPROACH", "ObjectMoved")
    assert "moved" in r.failure_reason
    assert r.cycle_time_s - onset <= 0.1

    r = _run(PRE_PICK_PUSH, recovery=True)
    _report("pre-pick push, with recovery", r)
    assert r.success, r.failure_reason
    assert r.retries == 1 and "ObjectMoved" in r.recoveries[0]
    assert r.place_error_xy_m <= 1.4e-3


def check_slippery_pads(run: Callable[..., EpisodeResult], phase_start: Callable[[EpisodeResult, str], float],
                        label: str = "") -> None:
    """Friction 0.02 (the reference design's slipping cube): detected in LIFT within 0.3 s. The regrasp slips the
    same way, so the machine stops retrying: the cause is not transient. ``run(faults, recovery=...)`` runs the
    episode in a profile; ``phase_start`` is when a phase started; ``label`` prefixes the report."""
    faults = FaultConfig(pad_friction_scale=0.02)
    r = run(faults, recovery=False)
    _report(f"{label}pad friction x0.02, no recovery", r, r.cycle_time_s - phase_start(r, "LIFT"))
    assert (r.failure_phase, r.failure_kind) == ("LIFT", "GraspFailed")
    assert "slipped" in r.failure_reason
    assert r.cycle_time_s - phase_start(r, "LIFT") <= 0.3

    r = run(faults, recovery=True)
    _report(f"{label}pad friction x0.02, with recovery", r)
    assert not r.success and r.failure_phase == "LIFT"
    assert r.retries == 1 and "slipped" in r.recoveries[0]
    assert "slipped" in r.failure_reason and "not transient" in r.failure_reason


def test_slippery_pads_detected_in_lift_and_not_retried_forever() -> None:
    check_slippery_pads(_run, _phase_start)


def test_half_friction_and_sensor_noise_are_tolerated() -> None:
    r = _run(FaultConfig(pad_friction_scale=0.5, joint_noise_rad=1e-4), recovery=False)
    _report("pad friction x0.5 and 0.1 mrad joint noise", r)
    assert r.success, r.failure_reason
    assert r.place_error_xy_m <= 1.4e-3 and r.tracking_error_max_rad < 5e-3


def test_pads_that_would_miss_the_cube_are_caught_before_closing() -> None:
    """The tcp is believed 30 mm further out than it is: at the end of the approach the tcp stands 30 mm short of
    its grasp, which the approach's own check sees (measured against the cube as it lies), before closing on air."""
    r = _run(FaultConfig(tcp_offset_error_m=0.03), recovery=False)
    _report("tcp offset +30 mm (pads would miss the cube)", r, r.phase_durations_s["DESCEND"])
    assert (r.failure_phase, r.failure_kind) == ("DESCEND", "PhaseFailed")
    off = re.search(r"the tcp is ([0-9.]+) mm from its grasp on the cube", r.failure_reason)
    assert off and float(off.group(1)) == pytest.approx(30.0, abs=0.5), r.failure_reason
    assert "CLOSE" not in r.phase_durations_s


def test_flipped_tcp_offset_rejected_before_moving() -> None:
    """The reference design's IK failure: a flipped tcp offset sign. The targets would drive the fingers into
    the table, so IK rejects them and the episode fails in IDLE naming the geoms, before anything moves."""
    r = _run(FaultConfig(tcp_offset_error_m=-0.2), recovery=True)
    _report("flipped tcp offset", r)
    assert (r.failure_phase, r.failure_kind) == ("IDLE", "UnreachableTarget")
    assert "table_top" in r.failure_reason and "pad" in r.failure_reason
    assert r.cycle_time_s == 0.0


def test_gripper_turned_on_the_flange_places_the_cube_turned_and_release_says_so() -> None:
    """The tcp is believed turned 0.2 rad about the tool axis: the cube is grasped and set down turned by as much,
    at the right place. Only the yaw check can catch it: the cube rests within 1 mm of B, on the table."""
    r = _run(FaultConfig(tcp_yaw_error_rad=0.2), recovery=True)
    _report("gripper turned 0.2 rad", r)
    assert (r.failure_phase, r.failure_kind) == ("RELEASE", "PhaseFailed")
    assert "yaw" in r.failure_reason
    assert r.place_error_yaw_rad == pytest.approx(0.2, abs=0.05)
    assert r.place_error_xy_m < 1e-3 and abs(r.place_error_z_m) < 1e-3


def test_a_small_gripper_turn_is_within_the_yaw_tolerance_and_measured() -> None:
    r = _run(FaultConfig(tcp_yaw_error_rad=-0.02), recovery=False)
    _report("gripper turned -0.02 rad", r)
    assert r.success, r.failure_reason
    assert r.place_error_yaw_rad == pytest.approx(-0.02, abs=0.005)  # measured, not assumed


def test_cube_bumped_after_the_release_fails_the_place() -> None:
    """A 2 N push for 0.1 s on the placed cube as the arm retracts: it slides away after the release check passed.
    The place counts only if the cube still lies at B 1 s after the release. A 1 N push is below friction
    (μ m g = 1.47 N) and moves nothing."""
    r = _run(FaultConfig(placed_push_n=(2.0, 0.0)), recovery=True)
    _report("cube bumped after the release", r)
    assert (r.failure_phase, r.failure_kind) == ("RELEASE", "PhaseFailed")
    assert "moved after the release" in r.failure_reason
    assert r.place_error_xy_m < 1e-3 < 3e-3 < r.final_place_error_xy_m  # it was placed, then it moved
    r = _run(FaultConfig(placed_push_n=(1.0, 0.0)), recovery=False)
    assert r.success, r.failure_reason
    assert r.final_place_error_xy_m == pytest.approx(r.place_error_xy_m, abs=5e-5)


def test_heavier_cube_is_weighed_and_compensated() -> None:
    """The cube is 5x heavier than believed: the lift sags (13 mm below its reference as the lift runs on into the
    transport, 2 mm short of its height for a Cartesian lift); the pads weigh it and the payload is fixed."""
    faults = FaultConfig(true_mass_scale=5.0)
    r = _run(faults, recovery=False)
    _report("cube 5x heavier, no recovery", r)
    assert (r.failure_phase, r.failure_kind) == ("LIFT", "PhaseFailed")
    assert "lift height" in r.failure_reason
    assert _kg(r.failure_reason, "cube weighed") == pytest.approx(0.75, rel=0.02)

    r = _run(faults, recovery=True)
    _report("cube 5x heavier, with recovery", r)
    assert r.success, r.failure_reason
    assert r.measured_mass_kg == pytest.approx(0.75, rel=0.02)
    assert r.retries == 1 and _kg(r.recoveries[0], "the cube weighs") == pytest.approx(0.75, rel=0.02)
    assert r.place_error_xy_m <= 1.4e-3


def test_cube_too_heavy_for_the_grip_slips_in_lift() -> None:
    r = _run(FaultConfig(true_mass_scale=30.0), recovery=False)  # 4.5 kg: beyond the 3 kg the pads hold
    _report("cube 30x heavier", r)
    assert (r.failure_phase, r.failure_kind) == ("LIFT", "GraspFailed") and "slipped" in r.failure_reason


def test_soft_contacts_detected_as_slip() -> None:
    """Pads 20x softer (the reference design's soft solref): the cube sags and rocks in the grip; the slip
    monitor catches it instead of letting it fall quietly."""
    r = _run(FaultConfig(pad_softness_scale=20.0), recovery=False)
    _report("pad solref x20", r)
    assert not r.success and r.failure_kind == "GraspFailed" and "slipped" in r.failure_reason
    assert r.failure_phase in ("LIFT", "EXEC_TRANSPORT", "DESCEND_PLACE")


def test_obstacle_after_planning_predicted_and_replanned() -> None:
    """A wall appears across the transport path once it is planned. Without recovery the arm runs into it
    (the contact monitor names the geoms); with recovery the collision is predicted ahead, the arm stops and
    the machine replans around it."""
    faults = FaultConfig(intruder=True)
    r = _run(faults, recovery=False)
    _report("obstacle appears, no recovery", r)
    assert (r.failure_phase, r.failure_kind) == ("EXEC_TRANSPORT", "UnexpectedContact")
    assert any("intruder" in pair for pair in r.unexpected_contacts)

    r = _run(faults, recovery=True)
    _report("obstacle appears, with recovery", r)
    assert r.success, r.failure_reason
    assert r.unexpected_contacts == ()  # stopped before touching it
    assert r.retries >= 1 and all("CollisionPredicted" in line for line in r.recoveries)
    assert "intruder" in r.recoveries[0]
    ahead_s = float(r.recoveries[0].split(" s ahead")[0].rsplit(", ", 1)[1])
    assert ahead_s >= 0.1  # predicted at least 100 ms before the contact
    assert r.place_error_xy_m <= 1.4e-3


def test_faulted_episodes_are_deterministic() -> None:
    """Sensor noise and recovery included: the same config and seed give the same result, bit for bit."""
    faults = FaultConfig(joint_noise_rad=2e-4, transport_push_n=(0.0, 0.0, -40.0), transport_push_s=0.05)
    config = dataclasses.replace(EpisodeConfig(), faults=faults)
    a, b = run_episode(config, 5), run_episode(config, 5)
    wall = {"wall_time_s", "real_time_factor", "plan_time_s", "retime_time_s"}
    strip = lambda r: json.dumps({k: v for k, v in r.to_dict().items() if k not in wall}, sort_keys=True)  # noqa: E731
    assert strip(a) == strip(b)
    assert a.retries == 1
    c = run_episode(config, 6)
    assert strip(c) != strip(a)  # the seed matters (noise stream)


def test_fault_config_validation_names_the_field() -> None:
    from pickplace.errors import ConfigError

    for field, value in [("pad_friction_scale", -1.0), ("transport_push_n", (1.0, 2.0)),
                         ("joint_noise_rad", float("nan")), ("intruder", "yes"),
                         ("tcp_yaw_error_rad", 1.0), ("placed_push_n", (1.0, 2.0, 3.0)), ("true_mass_scale", 0.0)]:
        with pytest.raises(ConfigError, match=rf"faults\.{field}"):
            FaultConfig(**{field: value})
    with pytest.raises(ConfigError, match=r"faults\.bogus"):
        EpisodeConfig.from_dict({"faults": {"bogus": 1}})
    # the key of earlier versions still works
    assert EpisodeConfig.from_dict({"faults": {"cube_mass_scale": 2.0}}).faults.true_mass_scale == 2.0


def _pad_contacts(faults: FaultConfig) -> list[mujoco.MjContact]:
    """Every contact between a pad and the object with the object put into the left pad (a real collision)."""
    robot = model.build()
    apply_model_faults(robot, faults)
    m, h = robot.mj, robot.handles
    d = robot.make_data()
    d.qpos[h.arm_qpos] = robot.home_q
    mujoco.mj_forward(m, d)
    d.qpos[h.object_qpos : h.object_qpos + 3] = d.geom_xpos[h.pad_geoms[0]]
    mujoco.mj_forward(m, d)
    pads, obj = set(h.pad_geoms.tolist()), h.object_geom_set
    pairs = [(c, {int(c.geom1), int(c.geom2)}) for c in d.contact[: d.ncon]]
    found = [c for c, pair in pairs if pair & pads and pair & obj]
    assert found, "the object put into the pad touches it"
    return found


def test_pad_faults_scale_the_pad_contacts_own_parameters() -> None:
    """The resolved pad-object contact: nominally the pads' solref and solimp (their solmix weighs 1e6 to the
    object's 1, hence rel 1e-5) with the object's friction; the pad faults make them the pads' outright, scaled
    (friction x 0.5, time constant x 3), and leave the impedance and condim as they were."""
    robot = model.build()
    m, h = robot.mj, robot.handles
    pad, obj = int(h.pad_geoms[0]), int(h.object_geoms[0])
    nominal = _pad_contacts(FaultConfig())
    faulted = _pad_contacts(FaultConfig(pad_friction_scale=0.5, pad_softness_scale=3.0))
    for c in nominal:
        np.testing.assert_allclose(c.solref, m.geom_solref[pad], rtol=1e-5)
        np.testing.assert_allclose(c.solimp, m.geom_solimp[pad], rtol=1e-5)
        np.testing.assert_allclose(c.friction[:3], m.geom_friction[obj, [0, 0, 1]], rtol=1e-12)
    for c, n in zip(faulted, nominal, strict=True):
        np.testing.assert_allclose(c.solref, m.geom_solref[pad] * [3.0, 1.0], rtol=1e-12)
        np.testing.assert_allclose(c.solimp, m.geom_solimp[pad], rtol=1e-12)
        np.testing.assert_allclose(c.friction[:2], 0.5 * n.friction[:2], rtol=1e-12)  # the two sliding directions
        np.testing.assert_allclose(c.friction[2:], n.friction[2:], rtol=1e-12)  # torsional, rolling
        assert c.dim == n.dim


def test_a_lost_grip_is_set_down_before_the_hand_opens() -> None:
    """The push above slides the cube 3 mm down the pads in transit, the grip no longer squeezing it as a settled
    grip does: the recovery lowers it straight down onto the table before the pads let go of it (they used to open
    where the grip failed, dropping it from the transport's height), then picks it again."""
    config = dataclasses.replace(EpisodeConfig(), faults=TRANSPORT_PUSH, machine=MachineConfig(max_retries=3))
    r = run_episode(config, 0, record=True)
    assert r.success, r.failure_reason
    assert r.recoveries and "open, back off" in r.recoveries[0]
    tel = r.telemetry
    assert tel is not None
    recover = tel.phase == tel.phase_names.index("RECOVER")
    touched = np.flatnonzero(recover & (tel.pad_force_n > 0.0).any(axis=1))
    z_rest = config.scene.table_height_m + 0.5 * 0.040  # the 40 mm cube's centre, resting on the table
    z_let_go = tel.object_pos_m[touched[-1], 2]
    print(f"\nthe pads let go of the cube with its centre {(z_let_go - z_rest) * 1e3:.2f} mm above its resting height")
    assert z_let_go - z_rest <= 1e-3
    after = touched[-1] + np.flatnonzero(recover[touched[-1]:])
    assert np.all(tel.object_pos_m[after, 2] - z_rest <= 1e-3)  # not dropped, not thrown up
