"""Full pick-and-place episodes in MuJoCo: the default scene (in the default suite) and the variation matrix.

Every test runs the real stack (IK, RRT*, TOPP-RA, impedance control, gripper contacts) and asserts the
measured result against the targets: the reference design's figures (place error 1.4 mm RMS, cycle time
8.2 s, tracking < 5 mrad, no torque saturation) and ours (the cube still within 2 mm of B 1 s after release).
Run with ``-s`` to see the figures. The matrix, the default episode's video and ``pickplace run`` in a
subprocess are ``-m slow``; the matrix's cases are distinct episodes (checked).

All figures are of the ideal robot: the cube's pose is read from the simulator, the controller's model is the
simulated arm's own.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from pickplace.errors import ConfigError
from pickplace.eval.campaign.store import toml_dumps
from pickplace.motion.control import ControlConfig
from pickplace.task.episode import EpisodeConfig, EpisodeResult, run_episode
from pickplace.task.machine import Phase

PLACE_ERROR_MAX_M = 1.4e-3  # the reference design's RMS place error, beaten on every episode
LINE_DEVIATION_MAX_M = 1e-3  # the tcp on its straight line in the final approach and the set-down (issue 15)
STABLE_ERROR_MAX_M = 2e-3  # the cube within 2 mm of B 1 s after release
CYCLE_TIME_MAX_S = 8.2  # the reference design's cycle time
TRACKING_MAX_RAD = 5e-3  # the reference design's tracking bound
ORDER = [p.value for p in Phase if p not in (Phase.DONE, Phase.FAILED, Phase.RECOVER)]


def _report(label: str, r: EpisodeResult) -> None:
    print(f"\n{label}: success {r.success}, place error {r.place_error_xy_m * 1e3:.3f} mm "
          f"(1 s later {r.final_place_error_xy_m * 1e3:.3f} mm, z {r.place_error_z_m * 1e3:+.3f} mm, yaw "
          f"{r.place_error_yaw_rad:+.1e} rad), cycle {r.cycle_time_s:.3f} s, tracking max "
          f"{r.tracking_error_max_rad * 1e3:.4f} mrad, saturation {r.torque_saturation_events}, slip "
          f"{r.slip_max_m * 1e3:.2f} mm, lift load {r.lift_load_n:.3f} N, wall {r.wall_time_s:.2f} s, "
          f"real-time factor {r.real_time_factor:.1f}, steps over a limit {r.limit_violations} (peaks speed "
          f"{r.joint_speed_ratio_max:.3f}, acceleration {r.joint_acceleration_ratio_max:.3f}, torque "
          f"{r.torque_ratio_max:.3f}; holding still {r.hold_limit_violations}), off the line "
          f"{r.approach_line_deviation_max_m * 1e3:.3f} / {r.place_line_deviation_max_m * 1e3:.3f} mm")


def _assert_meets_targets(r: EpisodeResult) -> None:
    assert r.success, f"failed in {r.failure_phase}: {r.failure_reason}"
    assert r.failure_phase is None and r.failure_reason is None
    assert r.place_error_xy_m <= PLACE_ERROR_MAX_M
    assert r.final_place_error_xy_m <= STABLE_ERROR_MAX_M
    assert abs(r.place_error_z_m) <= 1e-3  # resting on the table
    assert abs(r.place_error_yaw_rad) <= 0.02
    assert r.cycle_time_s <= CYCLE_TIME_MAX_S
    assert r.tracking_error_max_rad < TRACKING_MAX_RAD
    assert r.torque_saturation_events == 0
    assert r.force_closure and r.grasp_margin > 0
    assert r.unexpected_contacts == ()
    assert r.retries == 0 and r.recoveries == ()  # nothing went wrong that needed a recovery
    assert list(r.phase_durations_s) == ORDER  # every phase ran, in order
    mg = r.config.scene.object.mass_kg * 9.81
    assert r.lift_load_n == pytest.approx(mg, rel=0.05)  # the pads carry the cube's weight at the top
    assert r.ik_position_error_m < 1e-4 and r.ik_orientation_error_rad < 1e-4
    # every 1 ms step of every motion within the UR5e's joint speed, acceleration and torque limits
    assert r.limit_violations == 0, f"{r.limit_violations_by_phase}; worst: {r.limit_worst}"
    assert max(r.joint_speed_ratio_max, r.joint_acceleration_ratio_max, r.torque_ratio_max) <= 1.0
    # and while it holds still (the gripper closing on the object, opening, waits): nothing jolts it past them
    assert r.hold_limit_violations == 0, f"held: {r.hold_limit_worst}"
    assert r.approach_line_deviation_max_m <= LINE_DEVIATION_MAX_M
    assert r.place_line_deviation_max_m <= LINE_DEVIATION_MAX_M


@pytest.fixture(scope="module")
def default_episode() -> EpisodeResult:
    return run_episode(EpisodeConfig(), seed=0, record=True)


@pytest.fixture(scope="module")
def stepwise_episode() -> EpisodeResult:
    """The default scene with the phases' motions one after another: every blend off (the arm stops at the
    pregrasp, at the lift height, above the goal and after backing off), straight moves by the Cartesian loop."""
    control = dataclasses.replace(ControlConfig(), blend_approach=False, blend_lift=False, blend_set_down=False,
                                  blend_retract=False)
    return run_episode(dataclasses.replace(EpisodeConfig(), control=control), seed=0)


def test_default_episode_beats_the_reference(default_episode: EpisodeResult) -> None:
    r = default_episode
    _report("default scene", r)
    _assert_meets_targets(r)
    assert r.cycle_time_s <= 3.3  # issue 15 (simulated time; 3.85 s with a stop at every phase); reference: 8.2 s
    assert sum(r.phase_durations_s.values()) == pytest.approx(r.cycle_time_s, abs=1e-9)
    assert set(r.plan_time_s) == {"approach", "transport", "return"}
    assert all(n >= 2 for n in r.waypoints_shortcut.values())


def test_telemetry_follows_the_cube(default_episode: EpisodeResult) -> None:
    """The recorded samples agree with the result: the cube ends at B, rose during LIFT, pads squeezed."""
    tel = default_episode.telemetry
    assert tel is not None
    goal = default_episode.config.scene.goal_pos_m
    assert np.linalg.norm(tel.object_pos_m[-1, :2] - goal[:2]) <= STABLE_ERROR_MAX_M
    spans = {name: (a, b) for name, a, b in tel.phase_spans()}
    assert set(spans) >= {"EXEC_APPROACH", "LIFT", "EXEC_TRANSPORT", "RELEASE"}
    in_lift = (tel.t_s >= spans["LIFT"][0]) & (tel.t_s < spans["LIFT"][1])
    rise = tel.object_pos_m[in_lift, 2].max() - tel.object_pos_m[in_lift, 2].min()
    assert rise == pytest.approx(0.15, abs=3e-3)
    assert tel.pad_force_n[in_lift].min() >= 2.0  # both pads press throughout the lift
    assert len(tel.frame_qpos) == pytest.approx(tel.t_s[-1] * 30, abs=2)


def test_reported_place_errors_are_the_cubes_measured_position(default_episode: EpisodeResult) -> None:
    """The place errors are recomputed here from the recorded cube positions, independently of the machine: at
    the last step of RELEASE (where the machine checks the place) and at the end of the episode."""
    r, tel = default_episode, default_episode.telemetry
    assert tel is not None
    goal = r.config.scene.goal_pos_m
    checked = tel.object_pos_m[np.flatnonzero(tel.phase == tel.phase_names.index("RELEASE"))[-1]]
    assert r.place_error_xy_m == pytest.approx(float(np.hypot(*(checked[:2] - goal[:2]))), abs=1e-9)
    assert r.place_error_z_m == pytest.approx(float(checked[2] - goal[2]), abs=1e-9)
    final = tel.object_pos_m[-1]
    assert r.final_place_error_xy_m == pytest.approx(float(np.hypot(*(final[:2] - goal[:2]))), abs=1e-9)
    release_start = next(a for n, a, _ in tel.phase_spans() if n == "RELEASE")
    assert tel.t_s[-1] == pytest.approx(release_start + r.config.machine.stable_after_release_s, abs=2e-3)


def test_the_arm_moves_on_through_the_pregrasp_the_lift_and_the_preplace(default_episode: EpisodeResult) -> None:
    """The approach runs into the descent, the lift into the transport into the set-down, the back-off into the way
    home: the tcp passes each junction moving, and each phase still ran its own part (in order, checked by
    ``_assert_meets_targets``). The final approach's straightness is measured here again, independently, from the
    recorded tcp: the largest distance of any step of DESCEND from the line through its first and last."""
    r, tel = default_episode, default_episode.telemetry
    assert tel is not None
    speed = np.linalg.norm(np.diff(tel.tcp_pos_m, axis=0), axis=1) / np.diff(tel.t_s)
    spans = {name: (a, b) for name, a, b in tel.phase_spans()}
    for phase in ("DESCEND", "EXEC_TRANSPORT", "DESCEND_PLACE"):
        k = int(np.searchsorted(tel.t_s, spans[phase][0]))
        assert speed[k] > 0.1, f"the tcp stopped where {phase} starts ({speed[k]:.3f} m/s)"
    assert r.plan_time_s.keys() == {"approach", "transport", "return"}
    descent = tel.tcp_pos_m[(tel.t_s >= spans["DESCEND"][0]) & (tel.t_s <= spans["DESCEND"][1])]
    u = (descent[-1] - descent[0]) / np.linalg.norm(descent[-1] - descent[0])
    off = descent - descent[0]
    assert np.linalg.norm(off - np.outer(off @ u, u), axis=1).max() <= LINE_DEVIATION_MAX_M
    assert np.linalg.norm(descent[-1] - descent[0]) == pytest.approx(0.15, abs=2e-3)  # pregrasp to grasp


def test_the_phases_one_after_another_stop_between_them_and_keep_the_limits(stepwise_episode: EpisodeResult,
                                                                            default_episode: EpisodeResult) -> None:
    """With every blend off (how the realistic profile approaches and sets down), each straight move is a joint
    trajectory of its own through its IK waypoints, at rest at both ends, within the joints' limits (a Cartesian
    move with the tcp's minimum-jerk profile asked the elbow for 1.47 times its limit); the continuous motion saves
    a few tenths of a second more."""
    r = stepwise_episode
    _report("default scene, phases one after another", r)
    _assert_meets_targets(r)
    assert default_episode.cycle_time_s < r.cycle_time_s - 0.5
    assert abs(r.place_error_xy_m - default_episode.place_error_xy_m) < 1e-4


@pytest.mark.parametrize(("label", "scene"), [
    ("heavy and slippery", {"cube_mass_kg": 1.0, "cube_friction": 0.6}),
    ("light and small", {"cube_mass_kg": 0.05, "cube_size_m": 0.03}),
    ("large, grippy, turned far out", {"cube_size_m": 0.05, "cube_friction": 1.5, "cube_yaw_rad": -0.785,
                                       "cube_start_xy_m": (0.55, 0.15)}),
    ("near the base to a turned goal", {"cube_start_xy_m": (0.25, 0.15), "goal_yaw_rad": 0.6}),
], ids=lambda v: v if isinstance(v, str) else "")
def test_varied_scenes_keep_the_limits_and_the_lines(label: str, scene: dict) -> None:
    """Masses, sizes, frictions and poses the arm must cope with differently (the lift's support reserve grows
    with the mass; the lines and the speeds with the pose): every 1 ms step within the limits, the tcp on its lines."""
    r = run_episode(EpisodeConfig().with_scene(**scene), seed=0)
    _report(label, r)
    _assert_meets_targets(r)


@pytest.mark.parametrize(("name", "mass_kg", "friction", "start", "start_yaw", "goal", "goal_yaw"), [
    ("sugar_box", 0.7475, 1.02, (0.3367, 0.2216), 0.0757, (0.3246, -0.203), 2.1793),
    ("sugar_box", 0.9854, 0.77, (0.38, 0.2356), 2.9775, (0.3589, -0.2155), -0.1027),
], ids=["sugar box 0.75 kg", "sugar box 0.99 kg"])
def test_carried_library_objects_stay_squeezed_by_both_pads(name: str, mass_kg: float, friction: float,
                                                            start: tuple[float, float], start_yaw: float,
                                                            goal: tuple[float, float], goal_yaw: float) -> None:
    """Sugar boxes of the object campaign (tall, up to twice the nominal mass) whose transport loads the pads along
    their faces for long: the object creeps towards one pad by tens of micrometres,
    and with the pads' squeeze pressing them only 34 um into it the other pad's contact vanished for a step; its
    return jolted the wrist (to 4.6 times wrist 1's acceleration limit). The pads' contact impedance now keeps them
    75 um deep, and both pads squeeze at every step; nothing passes a limit, moving or held."""
    from pickplace.world.objects import library_object

    base = EpisodeConfig()
    obj = dataclasses.replace(library_object(name), mass_kg=mass_kg, friction=friction)
    config = dataclasses.replace(base, scene=dataclasses.replace(base.scene, object=obj, start_xy_m=start,
                                                                 start_yaw_rad=start_yaw, goal_xy_m=goal,
                                                                 goal_yaw_rad=goal_yaw))
    r = run_episode(config, seed=0)
    _report(f"{name}, {mass_kg} kg", r)
    _assert_meets_targets(r)


def test_a_stretched_out_arm_still_moves_on_through_its_straight_moves() -> None:
    """A tall box far out (a 0.4 kg sugar box at (0.557, 0.30) m): at its pregrasp the arm is nearly stretched out
    (elbow 0.13 rad), the joints turn fast along the descent, and a spline through its 1 cm waypoints strays more than
    0.5 mm off the line; the straight moves are re-solved every 2.5 mm and the motion is still one, within the limits
    at every step, the tcp on its lines."""
    from pickplace.world.objects import library_object

    base = EpisodeConfig()
    box = dataclasses.replace(library_object("sugar_box"), mass_kg=0.4)
    config = dataclasses.replace(base, scene=dataclasses.replace(base.scene, object=box, start_xy_m=(0.557, 0.30),
                                                                 start_yaw_rad=2.0))
    r = run_episode(config, seed=0, record=True)
    _report("sugar box far out", r)
    _assert_meets_targets(r)
    tel = r.telemetry
    assert tel is not None
    speed = np.linalg.norm(np.diff(tel.tcp_pos_m, axis=0), axis=1) / np.diff(tel.t_s)
    spans = {name: (a, b) for name, a, b in tel.phase_spans()}
    for phase in ("DESCEND", "EXEC_TRANSPORT", "DESCEND_PLACE"):  # moving (the joints' speeds bound the tcp's)
        k = int(np.searchsorted(tel.t_s, spans[phase][0]))
        assert speed[k] > 0.03, f"the tcp stopped where {phase} starts ({speed[k]:.3f} m/s)"


def test_a_lift_that_cannot_run_into_the_transport_is_a_joint_trajectory_of_its_own() -> None:
    """A tennis ball far out, at (0.6095, 0.3965) m: near the stretched-out pose the spline of the lift timed with
    the transport strays from the lift's line even through waypoints 2.5 mm apart, so the ball is lifted on its
    own. That lift is a joint trajectory through its IK waypoints, checked against the table; a Cartesian lift
    there let the elbow fold the other way (87 times its acceleration limit) and the upper arm touched the table."""
    from pickplace.world.objects import library_object

    base = EpisodeConfig()
    config = dataclasses.replace(base, scene=dataclasses.replace(
        base.scene, object=library_object("tennis_ball"), start_xy_m=(0.6095, 0.3965), goal_xy_m=(0.53, -0.25)))
    r = run_episode(config, seed=0)
    _report("tennis ball far out", r)
    _assert_meets_targets(r)
    assert r.tracking_by_phase["LIFT"].cartesian_steps == 0 and r.tracking_by_phase["LIFT"].joint_steps > 0


def test_tracking_errors_cover_every_phase_that_tracks(default_episode: EpisodeResult,
                                                       stepwise_episode: EpisodeResult) -> None:
    """Joint loops (trajectories, holds) are measured in the phase they ran in; the episode's figures are the
    maxima over all phases. Moving on between the phases or one after another, every motion is a joint loop: the
    straight moves made on their own are joint trajectories through their IK waypoints too, not Cartesian moves."""
    r = default_episode
    by_phase = r.tracking_by_phase
    assert {p for p, t in by_phase.items() if t.cartesian_steps > 0} == set()
    assert {p for p, t in by_phase.items() if t.joint_steps > 0} >= {
        "EXEC_APPROACH", "DESCEND", "CLOSE", "LIFT", "EXEC_TRANSPORT", "DESCEND_PLACE", "RELEASE", "RETRACT"}
    assert math.isnan(r.tcp_tracking_error_max_m)
    r = stepwise_episode
    by_phase = r.tracking_by_phase
    assert {p for p, t in by_phase.items() if t.cartesian_steps > 0} == set()
    joint = {p for p, t in by_phase.items() if t.joint_steps > 0}
    assert joint >= {"EXEC_APPROACH", "DESCEND", "CLOSE", "LIFT", "EXEC_TRANSPORT", "DESCEND_PLACE", "RELEASE",
                     "RETRACT"}
    assert r.tracking_error_max_rad == max(by_phase[p].joint_error_max_rad for p in joint)
    assert math.isnan(r.tcp_tracking_error_max_m) and math.isnan(r.tcp_orientation_error_max_rad)
    steps = sum(t.joint_steps + t.cartesian_steps for t in by_phase.values())
    assert steps == pytest.approx(r.cycle_time_s / 1e-3 + 1000 * r.config.machine.stable_after_release_s, abs=1100)
    json_phase = r.to_dict()["tracking_by_phase"]["LIFT"]
    assert json_phase["joint_error_max_rad"] > 0 and json_phase["tcp_position_error_max_m"] is None


@pytest.mark.slow
def test_default_episode_renders_a_video_and_plots(default_episode: EpisodeResult, tmp_path) -> None:
    """The product's video and plots, offscreen on a CPU-only machine (EGL / Mesa)."""
    iio = pytest.importorskip("imageio.v3", reason="needs the video extra: pip install 'pickplace[video]'")
    from pickplace.eval import report
    from pickplace.robot import model

    tel = default_episode.telemetry
    assert tel is not None
    path = report.render_video(model.build(default_episode.config.scene), tel, tmp_path / "episode.mp4",
                               width=160, height=120, shadows=False)
    frames = iio.imread(path, plugin="FFMPEG")
    assert frames.shape[1:] == (120, 160, 3)
    assert abs(len(frames) - len(tel.frame_qpos)) <= 1
    assert 20 < frames.mean() < 235 and np.abs(frames[0].astype(int) - frames[len(frames) // 2]).mean() > 1
    pngs = report.save_plots(tel, tmp_path / "plots")
    assert {p.name for p in pngs} == {"joint_tracking.png", "tcp_height.png", "grip_force.png",
                                      "phase_timeline.png"}
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def test_same_seed_same_episode() -> None:
    """Bit-identical results for the same config and seed (wall times aside), on the scene that plans."""
    config = EpisodeConfig().with_scene(obstacle=True)
    a, b = run_episode(config, seed=3), run_episode(config, seed=3)
    _report("obstacle scene, seed 3", a)
    _assert_meets_targets(a)
    wall = {"wall_time_s", "real_time_factor", "plan_time_s", "retime_time_s"}
    da = {k: v for k, v in a.to_dict().items() if k not in wall}
    db = {k: v for k, v in b.to_dict().items() if k not in wall}
    assert json.dumps(da, sort_keys=True) == json.dumps(db, sort_keys=True)


def test_saturated_motors_are_counted_in_the_result() -> None:
    """Trajectories timed at 300 rad/s² and 10 rad/s (the UR5e: 8–16 rad/s², π rad/s) ask for more torque than
    the motors have: the episode reports the clipped steps (whatever becomes of it)."""
    from pickplace.motion.timing import TimingConfig

    fast = dataclasses.replace(TimingConfig.ur5e(), acceleration_limits_rad_s2=(300.0,) * 6,
                               velocity_limits_rad_s=(10.0,) * 6)
    r = run_episode(dataclasses.replace(EpisodeConfig(), timing=fast))
    _report("timed at 300 rad/s²", r)
    assert r.torque_saturation_events >= 10


def test_goal_out_of_reach_fails_before_the_arm_moves() -> None:
    r = run_episode(EpisodeConfig().with_scene(goal_xy_m=(1.5, 0.0)), record=True)
    assert not r.success
    assert r.failure_phase == "IDLE" and r.failure_kind == "UnreachableTarget"
    assert "(1.500, 0.000" in r.failure_reason  # the unreachable target's position
    assert r.cycle_time_s == 0.0  # no simulation step was taken
    assert r.telemetry is not None and r.telemetry.t_s.size == 0


def test_goal_inside_the_obstacle_names_the_geoms() -> None:
    scene = dict(obstacle=True, obstacle_offset_xy_m=(0.0, -0.2))  # the wall's centre on the goal
    r = run_episode(EpisodeConfig().with_scene(**scene))
    assert not r.success and r.failure_phase == "IDLE"
    assert "cube <-> obstacle" in r.failure_reason
    assert r.cycle_time_s == 0.0


def test_reachable_goal_off_the_table_is_a_config_error() -> None:
    config = EpisodeConfig().with_scene(goal_xy_m=(0.15, -0.45))
    with pytest.raises(ConfigError, match=r"scene\.goal_xy_m .* the cube must lie on the table"):
        run_episode(config)


def test_bad_seed_and_config_rejected() -> None:
    with pytest.raises(ConfigError, match="seed"):
        run_episode(EpisodeConfig(), seed=-1)
    with pytest.raises(ConfigError, match=r"planner\.bogus"):
        EpisodeConfig.from_dict({"planner": {"bogus": 1}})
    with pytest.raises(ConfigError, match="unknown table"):
        EpisodeConfig.from_dict({"scenery": {}})


def test_config_round_trips_through_toml(tmp_path) -> None:
    config = EpisodeConfig().with_scene(cube_mass_kg=0.3, obstacle=True)
    config = dataclasses.replace(config, planner=dataclasses.replace(config.planner, time_budget_s=0.5))
    path = tmp_path / "episode.toml"
    path.write_text(toml_dumps(config.to_dict()))
    assert EpisodeConfig.from_toml(path) == config
    realistic = config.with_profile("realistic")  # its sub-tables ([profile.camera], [profile.loop], ...) too
    path.write_text(toml_dumps(realistic.to_dict()))
    assert EpisodeConfig.from_toml(path) == realistic


@pytest.mark.slow
def test_cli_run_json_and_unreachable_goal() -> None:
    """``pickplace run`` as a user runs it: JSON on success; one line, no traceback, exit 1 on a bad goal."""
    ok = subprocess.run([sys.executable, "-m", "pickplace", "run", "--json", "--cube-mass", "0.2"],
                        capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stderr
    data = json.loads(ok.stdout)
    assert data["success"] is True and data["config"]["object"]["mass_kg"] == 0.2
    bad = subprocess.run([sys.executable, "-m", "pickplace", "run", "--goal", "1.5", "0"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 1
    assert "Traceback" not in bad.stderr and bad.stdout == ""
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and "UnreachableTarget" in lines[0] and "1.500" in lines[0]


# --------------------------------------------------------------------------- #
# the variation matrix (-m slow)
# --------------------------------------------------------------------------- #

#: Each case changes something the robot must cope with. In the default scene every segment is a direct path, so
#: the planner's seed changes nothing there; it matters only where RRT* runs (the obstacle scene).
MATRIX: list[tuple[str, int, dict]] = (
    [("A and B swapped", 0, {"cube_start_xy_m": (0.35, -0.20), "goal_xy_m": (0.35, 0.20)}),
     ("far reach", 0, {"cube_start_xy_m": (0.58, 0.25), "goal_xy_m": (0.58, -0.25)}),
     ("near the base", 0, {"cube_start_xy_m": (0.25, 0.25), "goal_xy_m": (0.25, -0.25)}),
     ("short hop", 0, {"cube_start_xy_m": (0.45, 0.05), "goal_xy_m": (0.45, -0.05)}),
     ("put back where it was, turned", 0, {"goal_xy_m": (0.35, 0.20), "goal_yaw_rad": 0.3}),
     ("heavy and slippery", 0, {"cube_mass_kg": 1.0, "cube_friction": 0.6}),
     ("light and small", 0, {"cube_mass_kg": 0.02, "cube_size_m": 0.02}),
     ("large", 0, {"cube_mass_kg": 0.4, "cube_size_m": 0.065}),
     ("turned at A and at B", 0, {"cube_yaw_rad": 0.6, "goal_yaw_rad": -0.7}),
     ("obstacle, A and B swapped", 0, {"obstacle": True, "cube_start_xy_m": (0.35, -0.20),
                                       "goal_xy_m": (0.35, 0.20)})]
    + [(f"obstacle seed {s}", s, {"obstacle": True}) for s in range(5)]  # RRT* finds other paths
    + [(f"start {dx:+.2f},{dy:+.2f} yaw {yaw:+.3f}", 0,
        {"cube_start_xy_m": (0.35 + dx, 0.20 + dy), "cube_yaw_rad": yaw})
       for dx, dy in ((-0.05, -0.05), (0.05, 0.05), (0.05, -0.05), (-0.05, 0.05)) for yaw in (-0.785, 0.4)]
    + [(f"goal {dx:+.2f},{dy:+.2f}", 0, {"goal_xy_m": (0.35 + dx, -0.20 + dy)})
       for dx, dy in ((-0.05, -0.05), (0.05, 0.05), (0.05, -0.05), (-0.05, 0.05))]
    + [(f"mass {m}", 0, {"cube_mass_kg": m}) for m in (0.05, 0.5)]
    + [(f"size {s}", 0, {"cube_size_m": s}) for s in (0.03, 0.05)]
    + [(f"friction {mu}", 0, {"cube_friction": mu}) for mu in (0.6, 1.5)]
    + [("goal yaw 0.6", 0, {"goal_yaw_rad": 0.6})]
    + [("worst corner", 1, {"cube_size_m": 0.03, "cube_mass_kg": 0.5, "cube_friction": 0.6, "obstacle": True,
                            "cube_yaw_rad": -0.785, "goal_yaw_rad": 0.5})]
)
#: What each case of the matrix run so far did, to check that no two cases are the same episode.
_SEEN: dict[str, tuple] = {}


def _signature(r: EpisodeResult) -> tuple:
    """What an episode did, to the resolution that tells two cases apart (a cube turned by 90 degrees, say, is
    the same case: it looks the same)."""
    return (round(r.cycle_time_s, 3), round(r.place_error_xy_m, 5), round(r.tracking_error_max_rad, 6),
            round(r.lift_load_n, 3), round(r.grasp_margin, 3),
            tuple((k, round(v, 3)) for k, v in sorted(r.trajectory_duration_s.items())))


@pytest.mark.slow
@pytest.mark.parametrize(("label", "seed", "scene"), MATRIX, ids=[m[0] for m in MATRIX])
def test_matrix(label: str, seed: int, scene: dict) -> None:
    r = run_episode(EpisodeConfig().with_scene(**scene), seed)
    _report(label, r)
    _assert_meets_targets(r)
    same = [other for other, sig in _SEEN.items() if sig == _signature(r)]
    assert not same, f"'{label}' ran the same episode as {same}: it is not a case of its own"
    _SEEN[label] = _signature(r)
