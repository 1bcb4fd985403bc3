"""The realistic profile: the robot knows the object only through its sensors (pickplace.task.profile,
pickplace.task.observe.SensorObserver, pickplace.perception.view).

Every episode here runs the real thing: MuJoCo physics, the depth camera rendered offscreen (EGL), the pose
fits. The truth is read only to measure the episode.
"""

from __future__ import annotations

import dataclasses
import sys

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from scipy import ndimage

from pickplace.errors import ConfigError
from pickplace.grasping import configurations
from pickplace.motion.collision import CollisionChecker
from pickplace.motion.control import ControlConfig
from pickplace.motion.loop import LoopConfig
from pickplace.perception import view
from pickplace.perception.camera import CameraConfig, DepthCamera, point_cloud, sensor_depth
from pickplace.perception.view import TableCamera, _masked_median, register_offset
from pickplace.robot import gripper
from pickplace.robot.gripper import GripperConfig
from pickplace.robot.ik import IKConfig, solve_ik
from pickplace.robot.model import Robot, build
from pickplace.robot.model_error import ModelErrorConfig
from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.task.observe import SensorObserver, SimulatorObserver
from pickplace.task.profile import ProfileConfig
from pickplace.world.config import SceneConfig

REALISTIC = EpisodeConfig().with_profile("realistic")
#: The skill's methods that measure the episode against the truth (the record), and nothing else.
MEASUREMENTS = {"_measure_place", "_after_done", "_note_estimate"}


def test_profile_config_from_toml_tables_and_errors_name_the_field() -> None:
    c = EpisodeConfig.from_dict({"profile": {"name": "realistic", "camera": {"subpixel_px": 0.15},
                                             "sensing": {"watch_period_s": 0.05}}})
    assert c.profile.realistic and c.profile.camera.subpixel_px == 0.15 and c.profile.sensing.watch_period_s == 0.05
    assert EpisodeConfig.from_dict(c.to_dict()) == c  # round trip
    assert not EpisodeConfig().profile.realistic  # ideal by default
    with pytest.raises(ConfigError, match=r"profile\.name.*ideal, realistic"):
        EpisodeConfig.from_dict({"profile": {"name": "perfect"}})
    with pytest.raises(ConfigError, match=r"profile\.lidar"):
        EpisodeConfig.from_dict({"profile": {"lidar": {}}})
    with pytest.raises(ConfigError, match=r"sensing\.watch_period_s"):
        EpisodeConfig.from_dict({"profile": {"sensing": {"watch_period_s": 0.0}}})


def test_the_realistic_profile_is_the_whole_robot_and_brings_its_gains() -> None:
    """Realistic: the camera and the sensors, the 500 Hz loop with latency, model error and friction, the
    slower gripper, and the gains that hold such a loop; back to ideal restores all of it."""
    r = REALISTIC
    assert r.profile.realistic and r.profile.loop == LoopConfig.realistic()
    assert r.profile.model_error == ModelErrorConfig.realistic() and r.profile.gripper == GripperConfig.realistic()
    assert r.control == ControlConfig.realistic()
    assert EpisodeConfig(profile=ProfileConfig.named("realistic")).control == ControlConfig.realistic()
    assert r.with_profile("ideal") == EpisodeConfig()
    tuned = dataclasses.replace(r, control=dataclasses.replace(r.control, max_tcp_error_m=0.03))
    assert tuned.with_profile("ideal").control.max_tcp_error_m == 0.03  # a user's gains are kept
    toml = EpisodeConfig.from_dict({"profile": {"name": "realistic"}, "control": {"max_tcp_error_m": 0.03}})
    assert toml.control == dataclasses.replace(ControlConfig.realistic(), max_tcp_error_m=0.03)


def test_register_offset_recovers_a_known_image_shift_and_depth_offset() -> None:
    """A depth image shifted by a fraction of a pixel and moved 3 mm further: found within 0.2 px and 1 mm."""
    robot = build()
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    camera = DepthCamera(robot)
    try:
        model = camera.render_depth(d, hide_object=True)
        own = camera.render_mask(d, frozenset(robot.handles.robot_bodies))
    finally:
        camera.close()
    du, dv, dz = 2.3, -1.6, 0.003
    measured = ndimage.shift(model, (dv, du), order=1, mode="nearest") + dz
    offset, shift = register_offset(measured, model, own, camera.config)
    assert np.allclose(shift, [du, dv], atol=0.2)
    along_axis = float(offset @ camera.config.R_world_camera[:, 2])
    assert abs(along_axis - dz) < 0.001


def _exhaustive_offset(measured: np.ndarray, model: np.ndarray, region: np.ndarray, max_shift_px: int = 10,
                       stages: tuple[tuple[float, int], ...] = ((0.5, 1), (0.1, 5))) -> tuple[float, float, float]:
    """The reference search: every whole-pixel shift of the range, then (by default) 3 x 3 half and 11 x 11 tenth
    pixels, one shift at a time (``np.median`` of each): (du, dv, dz)."""
    v, u = np.nonzero(region)
    h, w = measured.shape
    z_model = model[v, u]

    def cost(du: float, dv: float) -> tuple[float, float]:
        uu, vv = u + du, v + dv
        inside = (uu >= 0) & (uu <= w - 1) & (vv >= 0) & (vv <= h - 1)
        if float(du).is_integer() and float(dv).is_integer():
            z = measured[np.clip(vv, 0, h - 1).astype(int), np.clip(uu, 0, w - 1).astype(int)]
        else:
            z = ndimage.map_coordinates(measured, [np.clip(vv, 0, h - 1), np.clip(uu, 0, w - 1)], order=1)
        ok = inside & (z > 0.0)
        if ok.sum() < len(v) // 2:
            return np.inf, 0.0
        r = (z - z_model)[ok]
        dz = float(np.median(r))
        return float(np.median(np.abs(r - dz))), dz

    best = (np.inf, 0.0, 0.0, 0.0)
    for step, span in ((1.0, max_shift_px), *stages):
        u0, v0 = best[1], best[2]
        for dv in v0 + step * np.arange(-span, span + 1):
            for du in u0 + step * np.arange(-span, span + 1):
                c, dz = cost(float(du), float(dv))
                if c < best[0]:
                    best = (c, float(du), float(dv), dz)
    return best[1], best[2], best[3]


def _true_displacement(model: np.ndarray, region: np.ndarray, config: CameraConfig, real: CameraConfig) -> np.ndarray:
    """The displacement (3,) (m, world) that the calibration error gives the model's points of ``region``: where
    the camera really is it sees each of them at a pixel and depth that the calibrated camera reads as another
    point; the median of those moves (what :func:`register_offset` measures)."""
    P = point_cloud(model, config, region)
    p = (P - np.asarray(real.position_m)) @ real.R_world_camera
    u, v = real.image_coordinates(p.T)
    z, f = p[:, 2], config.focal_px
    seen = np.column_stack([(u - 0.5 * config.width_px) * z / f, (v - 0.5 * config.height_px) * z / f, z])
    return np.median(np.asarray(config.position_m) + seen @ config.R_world_camera.T - P, axis=0)


def test_register_offset_is_as_accurate_as_an_exhaustive_search(monkeypatch: pytest.MonkeyPatch) -> None:
    """On the sensor's noisy image of the robot's own pixels shifted by its calibration error, for twelve
    calibration errors: the whole pixel shortlisted by an estimate on every 8th pixel is that of evaluating every
    whole pixel of the range exactly (to 1e-9 px); the final displacement, after the halves, fifths and tenths
    (:data:`~pickplace.perception.view.STAGES`), is within 0.1 mm as close to the calibration error's true
    displacement as the exhaustive search's (every whole pixel, then 3 x 3 halves and 11 x 11 tenths, one at a
    time), and within 1.5 mm of it."""
    robot = build()
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    config = CameraConfig()
    camera = DepthCamera(robot, config)
    rng = np.random.default_rng(5)
    f = config.focal_px
    try:
        model = camera.render_depth(d, hide_object=True)
        own = camera.render_mask(d, frozenset(robot.handles.robot_bodies))
        tcp = d.site_xpos[robot.handles.tcp_site]
        errors = []
        for _ in range(12):
            real = config.drawn(rng)
            measured = sensor_depth(camera.render_depth(d, seen_from=real), config, rng)
            region = own & (model > 0.0)
            region[region] = np.linalg.norm(point_cloud(model, config, region) - tcp, axis=1) < 0.3
            with monkeypatch.context() as whole_only:
                whole_only.setattr(view, "STAGES", ((1.0, None),))
                _, whole = register_offset(measured, model, region, config)
            np.testing.assert_allclose(whole, _exhaustive_offset(measured, model, region, stages=())[:2], rtol=0,
                                       atol=1e-9)
            du, dv, dz = _exhaustive_offset(measured, model, region)
            z = float(np.median(model[region]))
            reference = config.R_world_camera @ np.array([du * z / f, dv * z / f, dz])
            offset, _ = register_offset(measured, model, region, config)
            true = _true_displacement(model, region, config, real)
            errors.append((float(np.linalg.norm(offset - true)), float(np.linalg.norm(reference - true))))
        ours, exhaustive = np.array(errors).T
        assert np.all(ours <= exhaustive + 1e-4), errors
        assert np.all(ours < 1.5e-3), errors
    finally:
        camera.close()


def test_masked_median_is_each_rows_median_of_its_valid_entries() -> None:
    """Rows with even and odd numbers of valid and missing entries: the same value as ``np.median`` row by
    row (exactly: the same order statistics, the same mean of the middle two)."""
    rng = np.random.default_rng(0)
    values = rng.normal(size=(40, 101))
    ok = rng.random((40, 101)) < rng.uniform(0.3, 1.0, (40, 1))
    ok[:, 0] = True
    ok[0] = True  # a row without missing entries
    ok[1, :2] = False  # an even number missing
    expected = np.array([np.median(values[i][ok[i]]) for i in range(len(values))])
    assert np.array_equal(_masked_median(values, ok), expected)


def _hand_over_goal(robot: Robot, d: mujoco.MjData, scene: SceneConfig, yaw: float) -> pin.SE3:
    """Put the arm (by IK) with a top-down tcp at ``yaw`` (rad) holding the scene's object 0.12 m over its goal;
    return the tcp's pose (forward kinematics done)."""
    h = robot.handles
    R = np.diag([1.0, -1.0, -1.0]) @ pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    T_tcp = pin.SE3(R, np.array([*scene.goal_pos_m[:2],
                                 scene.goal_pos_m[2] + 0.12 + scene.object.geometry().extent_m[2] / 2]))
    d.qpos[h.arm_qpos] = solve_ik(robot, T_tcp, robot.home_q, "hold", IKConfig()).q
    mujoco.mj_forward(robot.mj, d)
    return pin.SE3(d.site_xmat[h.tcp_site].reshape(3, 3).copy(), d.site_xpos[h.tcp_site].copy())


def test_the_held_object_is_measured_against_the_hand_through_the_calibration_error() -> None:
    """A cube held 0.12 m over the goal, off the grasp model by up to 8 mm along the pads: with the camera's
    calibration error (2 mm and 0.2 degrees per axis, which displaces the points there by several mm), the
    estimate relative to the hand is within 2.5 mm of the truth every time and 1.5 mm in the median."""
    scene = SceneConfig()
    robot = build(scene)
    d = robot.make_data()
    h = robot.handles
    geo = scene.object.geometry()
    lo, hi = geo.vertices.min(axis=0), geo.vertices.max(axis=0)
    centre = (lo + hi) / 2
    R_tcp_object = np.diag([1.0, -1.0, -1.0])  # upright under a top-down tcp
    errors = []
    for trial in range(5):
        rng = np.random.default_rng(trial)
        camera = TableCamera(robot, CameraConfig(), rng)
        try:
            yaw = rng.uniform(-1.0, 1.0)
            tcp = _hand_over_goal(robot, d, scene, yaw)
            off = rng.uniform(-0.008, 0.008)
            model = tcp * pin.SE3(R_tcp_object, -R_tcp_object @ centre)
            truth = tcp * pin.SE3(R_tcp_object, np.array([off, 0.0, 0.0]) - R_tcp_object @ centre)
            a = h.object_qpos
            d.qpos[a:a + 3] = truth.translation
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, truth.rotation.ravel())
            d.qpos[a + 3:a + 7] = quat
            mujoco.mj_forward(robot.mj, d)
            est = camera.in_hand(d, model)
            errors.append(float(np.linalg.norm(est.T_world_object.translation - truth.translation)))
        finally:
            camera.close()
    assert max(errors) < 0.0025, errors
    assert float(np.median(errors)) < 0.0015, errors


def _poison(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulator's object state and contact forces: readable only by the skill's measurements."""

    def guard(name: str, original: object) -> object:
        def read(*args: object, **kwargs: object) -> object:
            caller = sys._getframe(1).f_code.co_name
            if caller not in MEASUREMENTS:
                raise AssertionError(f"{caller} read the simulator's {name} in the realistic profile")
            return original(*args, **kwargs)  # type: ignore[operator]
        return read

    for name in ("object_pose", "object_position", "object_velocity", "observe", "moved_m", "load_sample",
                 "pad_forces", "pad_contacts", "slip_m", "start_holding"):
        monkeypatch.setattr(SimulatorObserver, name, guard(name, getattr(SimulatorObserver, name)))
    for name in ("pad_forces", "pad_load", "pad_contacts"):
        monkeypatch.setattr(gripper, name, guard(name, getattr(gripper, name)))
    # the planners' collision world: never the simulation itself (the object's pose and anything that appeared
    # would come with it), only the robot's believed world
    simulations: list[mujoco.MjData] = []
    sensor_init = SensorObserver.__init__

    def record(self: SensorObserver, robot: object, data: mujoco.MjData, *args: object) -> None:
        simulations.append(data)
        sensor_init(self, robot, data, *args)  # type: ignore[arg-type]

    def world_guard(name: str, original: object, at: int) -> object:
        def read(*args: object, **kwargs: object) -> object:
            world = args[at] if len(args) > at else None
            if any(world is sim for sim in simulations):
                raise AssertionError(f"{name} was given the simulation as the planners' world")
            return original(*args, **kwargs)  # type: ignore[operator]
        return read

    monkeypatch.setattr(SensorObserver, "__init__", record)
    monkeypatch.setattr(CollisionChecker, "set_world", world_guard("set_world", CollisionChecker.set_world, 1))
    monkeypatch.setattr(configurations, "_world_copy", world_guard("_world_copy", configurations._world_copy, 1))


def test_a_realistic_episode_never_reads_the_simulators_object_state(monkeypatch: pytest.MonkeyPatch) -> None:
    """The access test: with every accessor of the object's state and of the contact forces poisoned (they
    raise for anyone but the episode's measurements), and the simulation refused as the planners' collision
    world (grasps and paths are checked in the believed world), a realistic episode runs exactly as without poison,
    and places the cube within the realistic profile's bounds."""
    clean = run_episode(REALISTIC, seed=2)
    # the same episode in the ideal profile reads the truth: its estimates are exact
    ideal = run_episode(REALISTIC.with_profile("ideal"), seed=2)
    assert all(err == 0.0 for _, _, err, _ in ideal.pose_estimates)
    _poison(monkeypatch)
    poisoned = run_episode(REALISTIC, seed=2)
    assert clean.success and poisoned.success, (clean.failure_reason, poisoned.failure_reason)
    assert poisoned.phase_timeline == clean.phase_timeline
    assert poisoned.place_error_xy_m == clean.place_error_xy_m
    assert clean.place_error_xy_m < 0.003
    what = [w for _, w, _, _ in clean.pose_estimates]
    # the pick, the look from the hand above it, the re-aim above the goal, the place check
    assert what == ["resting", "from the hand", "in hand", "resting"]
    assert all(err < 0.015 for _, _, err, _ in clean.pose_estimates)  # a few mm: the camera's, not the truth
    assert all(err < 0.004 for _, w, err, _ in clean.pose_estimates[1:])  # against the hand: calibration cancels
    assert abs(clean.measured_mass_kg / REALISTIC.scene.object.mass_kg - 1.0) < 0.15  # weighed at the wrist


def test_the_object_not_seen_is_a_clear_failure_before_the_arm_moves() -> None:
    """A camera looking away from the table sees neither the table nor the object: IDLE fails and says so."""
    away = dataclasses.replace(REALISTIC, profile=dataclasses.replace(
        REALISTIC.profile, camera=CameraConfig(position_m=(0.8, 0.0, 1.05), look_at_m=(2.0, 0.0, 1.5))))
    r = run_episode(away, seed=0)
    assert not r.success and r.failure_phase == "IDLE"
    assert r.failure_kind == "ObjectNotSeen" and "no point of the table top" in (r.failure_reason or "")
    assert r.cycle_time_s == 0.0  # nothing moved


def test_a_robot_compensates_the_payload_it_weighed() -> None:
    """After the lift the controllers compensate the mass the wrist weighed in the realistic profile (the
    model's is what the robot believed before weighing), the model's (exact) mass in the ideal one."""
    robot = build(REALISTIC.scene)
    d = robot.make_data()
    ideal = REALISTIC.with_profile("ideal").profile.observer(robot, d, np.random.default_rng(0))
    real = REALISTIC.profile.observer(robot, d, np.random.default_rng(0))
    try:
        assert ideal.payload_mass_kg(0.15, 0.4) == 0.15
        assert real.payload_mass_kg(0.15, 0.4) == 0.4
        assert real.payload_mass_kg(0.15, float("nan")) == 0.15  # nothing weighed: the model's
    finally:
        real.close()


@pytest.mark.parametrize("trial", range(2))
def test_a_look_near_a_known_place_sees_in_its_crop_what_the_full_frame_shows(
        monkeypatch: pytest.MonkeyPatch, trial: int) -> None:
    """The looks near a known place render only a crop (the pixels they use, CROP_MARGIN_PX around them): without
    the sensor's noise, the held object's estimate, a resting object's measured against the hand next to it and
    its plain re-check are those of the same looks on the full frame (the self-filter's shift, the registration's
    search and the depth edges stay inside the margin)."""
    scene = SceneConfig()
    robot = build(scene)
    d = robot.make_data()
    h = robot.handles
    geo = scene.object.geometry()
    lo, hi = geo.vertices.min(axis=0), geo.vertices.max(axis=0)
    R_tcp_object = np.diag([1.0, -1.0, -1.0])
    config = dataclasses.replace(CameraConfig(), subpixel_px=0.0)  # exact depth, quantized
    # the same depth images whatever their size: the noise draws must not move the fits' generator on
    monkeypatch.setattr(view, "sensor_depth", lambda z, c, rng: sensor_depth(z, c, np.random.default_rng(0)))
    cropped = TableCamera._look

    def full_frame(self: TableCamera, d: mujoco.MjData, near: pin.SE3 | None,
                   from_hand: bool) -> tuple[None, np.ndarray | None]:
        crop, window = cropped(self, d, near, from_hand)
        if crop is None:
            return None, window
        assert window is not None and (crop.width, crop.height) != (config.width_px, config.height_px)
        full = np.zeros((config.height_px, config.width_px), dtype=bool)
        full[crop.slices] = window
        return None, full

    def put(T: pin.SE3) -> None:
        a = h.object_qpos
        d.qpos[a:a + 3] = T.translation
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, T.rotation.ravel())
        d.qpos[a + 3:a + 7] = quat

    estimates = {}
    for mode in ("crop", "full"):
        monkeypatch.setattr(TableCamera, "_look", cropped if mode == "crop" else full_frame)
        rng = np.random.default_rng(trial)
        camera = TableCamera(robot, config, rng)
        try:
            yaw = rng.uniform(-1.0, 1.0)
            R = np.diag([1.0, -1.0, -1.0]) @ pin.rpy.rpyToMatrix(0.0, 0.0, yaw)  # the top-down hand at yaw
            tcp = _hand_over_goal(robot, d, scene, yaw)  # held 4 mm off the grasp model along the pads:
            guess = tcp * pin.SE3(R_tcp_object, -R_tcp_object @ (lo + hi) / 2)
            put(guess * pin.SE3(np.eye(3), R_tcp_object.T @ np.array([0.004, 0.0, 0.0])))
            mujoco.mj_forward(robot.mj, d)
            held = camera.in_hand(d, guess).T_world_object
            # resting at the goal, the hand 3 cm above it
            rest = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw),
                           np.array([*scene.goal_pos_m[:2], scene.table_height_m - camera.model.z_min_m]))
            put(rest)
            T_tcp = pin.SE3(R, np.array([*scene.goal_pos_m[:2], rest.translation[2] + geo.extent_m[2] + 0.03]))
            d.qpos[h.arm_qpos] = solve_ik(robot, T_tcp, robot.home_q, "hold", IKConfig()).q
            mujoco.mj_forward(robot.mj, d)
            estimates[mode] = (held, camera.recheck(d, rest, from_hand=True).T_world_object,
                               camera.recheck(d, rest).T_world_object)
        finally:
            camera.close()
    for name, a, b in zip(("in hand", "against the hand", "re-check"), *estimates.values(), strict=True):
        assert np.linalg.norm(a.translation - b.translation) < 5e-5, name
        assert np.linalg.norm(pin.log3(a.rotation.T @ b.rotation)) < 1e-3, name
