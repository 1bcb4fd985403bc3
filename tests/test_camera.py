"""The depth camera (pickplace.perception.camera): rendered depth, the sensor's noise, back-projection."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from pickplace.errors import ConfigError
from pickplace.perception.camera import CameraConfig, DepthCamera, ImageCrop, point_cloud, sensor_depth
from pickplace.robot.model import Robot


@pytest.fixture(scope="module")
def exact(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """The default scene seen by the default camera: exact depth (H, W) and the object's position."""
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    camera = DepthCamera(robot)
    try:
        depth = camera.render_depth(d)
    finally:
        camera.close()
    return depth, d.xpos[robot.handles.object_body].copy()


def test_back_projection_lands_on_the_table_and_the_cube(robot: Robot, exact) -> None:
    """Exact depth back-projected: the table top at its height, the 40 mm cube's top face 40 mm above it and
    centred on the cube (pinhole model, image orientation and camera pose all agree with the simulator)."""
    depth, cube = exact
    cfg = CameraConfig()
    assert depth.shape == (cfg.height_px, cfg.width_px)
    pts = point_cloud(depth, cfg)
    table = (np.abs(pts[:, 0] - 0.60) < 0.05) & (np.abs(pts[:, 1] + 0.30) < 0.05)
    assert table.sum() > 500
    np.testing.assert_allclose(pts[table, 2], robot.scene.table_height_m, rtol=0, atol=1e-4)
    top_z = robot.scene.table_height_m + 0.040
    top = (np.abs(pts[:, 2] - top_z) < 5e-4) & (np.linalg.norm(pts[:, :2] - cube[:2], axis=1) < 0.05)
    assert top.sum() > 200
    np.testing.assert_allclose(pts[top, :2].mean(axis=0), cube[:2], rtol=0, atol=2e-3)
    assert np.all(np.abs(pts[top, :2] - cube[:2]) <= 0.020 + 1e-3)  # inside the 40 mm face


def test_sensor_noise_grows_with_distance_and_is_quantized(exact) -> None:
    depth, _ = exact
    cfg = CameraConfig()
    # the stereo model: 2.4 mm at 0.8 m for the D435 at 848 x 480 (f = 433 px, 50 mm, 0.08 px)
    assert cfg.focal_px == pytest.approx(240.0 / np.tan(np.radians(29.0)), rel=1e-12)
    assert float(cfg.depth_sigma_m(0.8)) == pytest.approx(0.64 * 0.08 / (cfg.focal_px * 0.05), rel=1e-12)
    assert float(cfg.depth_sigma_m(1.6)) == pytest.approx(4 * float(cfg.depth_sigma_m(0.8)), rel=1e-12)
    noisy = sensor_depth(depth, cfg, np.random.default_rng(0))
    valid = noisy > 0
    assert valid.mean() > 0.95
    units = noisy[valid] / cfg.depth_unit_m
    np.testing.assert_allclose(units, np.round(units), rtol=0, atol=1e-6)  # whole millimetres
    # residuals against the exact depth, normalised by the model (quantization adds unit^2 / 12): unit variance
    expected = np.sqrt(cfg.depth_sigma_m(depth[valid]) ** 2 + cfg.depth_unit_m**2 / 12)
    normalised = (noisy[valid] - depth[valid]) / expected
    assert abs(float(np.std(normalised)) - 1.0) < 0.05
    assert abs(float(np.mean(normalised))) < 0.01
    # the same seed gives the same image; another seed another one
    np.testing.assert_array_equal(noisy, sensor_depth(depth, cfg, np.random.default_rng(0)))
    assert not np.array_equal(noisy, sensor_depth(depth, cfg, np.random.default_rng(1)))


def test_pixels_at_depth_edges_and_out_of_range_are_missing(exact) -> None:
    depth, _ = exact
    cfg = CameraConfig()
    noisy = sensor_depth(depth, cfg, np.random.default_rng(0))
    jump_right = np.abs(np.diff(depth, axis=1)) > cfg.edge_jump_m  # an edge between column c and c + 1
    rows, cols = np.nonzero(jump_right)
    assert rows.size > 50  # the cube's and the table's outlines
    assert np.all(noisy[rows, cols] == 0) and np.all(noisy[rows, cols + 1] == 0)
    smooth = np.ones(depth.shape, dtype=bool)  # pixels with no edge within 2 px: all reported
    for axis in (0, 1):
        step = np.abs(np.diff(depth, axis=axis)) > cfg.edge_jump_m
        for k in range(-2, 3):
            smooth &= ~np.roll(np.pad(step, [(0, 1), (0, 0)] if axis == 0 else [(0, 0), (0, 1)]), k, axis=axis)
    smooth &= (depth > cfg.min_range_m) & (depth < cfg.max_range_m)
    assert smooth.sum() > 0.9 * depth.size
    assert np.all(noisy[smooth] > 0)
    near = CameraConfig(min_range_m=1.0)
    assert np.all(sensor_depth(depth, near, np.random.default_rng(0))[depth < 1.0] == 0)


def test_camera_config_is_validated() -> None:
    with pytest.raises(ConfigError, match=r"camera\.width_px"):
        CameraConfig(width_px=4)
    with pytest.raises(ConfigError, match=r"camera\.look_at_m .* must differ"):
        CameraConfig(position_m=(0.5, 0.0, 1.0), look_at_m=(0.5, 0.0, 1.0))
    with pytest.raises(ConfigError, match=r"straight below"):
        CameraConfig(position_m=(0.5, 0.0, 1.0), look_at_m=(0.5, 0.0, 0.3))
    with pytest.raises(ConfigError, match=r"camera\.max_range_m"):
        CameraConfig(min_range_m=2.0, max_range_m=1.0)
    with pytest.raises(ConfigError, match=r"depth_m = \(10, 10\) is invalid"):
        point_cloud(np.ones((10, 10)), CameraConfig())


def test_calibration_error_is_drawn_per_trial_with_its_sigmas() -> None:
    cfg = CameraConfig()
    rng = np.random.default_rng(5)
    drawn = [cfg.drawn(rng) for _ in range(400)]
    dp = np.array([np.subtract(c.position_m, cfg.position_m) for c in drawn])
    assert abs(float(np.std(dp)) - cfg.calibration_position_sigma_m) < 0.15 * cfg.calibration_position_sigma_m
    axis0 = np.subtract(cfg.look_at_m, cfg.position_m)
    angles = [np.arccos(np.clip(np.dot(axis0, np.subtract(c.look_at_m, c.position_m)) / np.dot(axis0, axis0),
                                -1, 1)) for c in drawn]
    # the optical axis turns by the two rotation components across it: RMS sqrt(2) sigma
    assert abs(float(np.sqrt(np.mean(np.square(angles)))) - np.sqrt(2) * cfg.calibration_angle_sigma_rad) < (
        0.15 * cfg.calibration_angle_sigma_rad)
    exact = CameraConfig(calibration_position_sigma_m=0.0, calibration_angle_sigma_rad=0.0).drawn(rng)
    np.testing.assert_allclose(exact.position_m, cfg.position_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(exact.look_at_m, cfg.look_at_m, rtol=0, atol=1e-12)


def test_render_from_another_pose_is_that_cameras_image(robot: Robot) -> None:
    """One renderer serves the calibrated and the real pose: seen_from gives what a camera built there sees."""
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    moved = CameraConfig().drawn(np.random.default_rng(2))
    one, other = DepthCamera(robot), DepthCamera(robot, moved)
    try:
        np.testing.assert_array_equal(one.render_depth(d, seen_from=moved), other.render_depth(d))
        assert not np.array_equal(one.render_depth(d), other.render_depth(d))
        with pytest.raises(ConfigError, match="seen_from"):
            one.render_depth(d, seen_from=CameraConfig(width_px=424))
    finally:
        one.close()
        other.close()


def test_one_render_gives_the_depth_and_the_self_filter(robot: Robot) -> None:
    """render_view: the depth of render_depth and the pixels of render_mask from one render; at the robot's own
    pixels that depth is also the one without the object (what the hand's registration compares). The depth
    read together with the colours may differ in the last bit of the float32 depth buffer (0.5 um at 1.6 m)."""
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    camera = DepthCamera(robot)
    own = frozenset(robot.handles.robot_bodies)
    try:
        depth, mask = camera.render_view(d, own)
        np.testing.assert_array_equal(mask, camera.render_mask(d, own))
        np.testing.assert_allclose(depth, camera.render_depth(d), rtol=0, atol=1e-6)
        assert mask.sum() > 1000  # the arm is in view
        np.testing.assert_allclose(depth[mask], camera.render_depth(d, hide_object=True)[mask], rtol=0, atol=1e-6)
        # the object in front of nothing the robot knows: its pixels are not the robot's
        assert not np.array_equal(depth, camera.render_depth(d, hide_object=True))
    finally:
        camera.close()


def _between_neighbours(full: np.ndarray, crop: ImageCrop, values: np.ndarray) -> np.ndarray:
    """For each pixel of ``crop``, whether ``values`` there lies between the least and the greatest value of the
    full image at the pixel and its 8 neighbours (to float32 rounding): what the scene moved by a fraction of a
    pixel gives there."""
    padded = np.pad(full.astype(float), 1, mode="edge")
    lo, hi = np.full(values.shape, np.inf), np.full(values.shape, -np.inf)
    for dv in (0, 1, 2):
        for du in (0, 1, 2):
            other = padded[crop.v0 + dv:crop.v0 + dv + crop.height, crop.u0 + du:crop.u0 + du + crop.width]
            lo, hi = np.minimum(lo, other), np.maximum(hi, other)
    tol = 1e-6 * np.maximum(1.0, np.abs(values))
    return (values >= lo - tol) & (values <= hi + tol)


@pytest.mark.parametrize("pose", range(3))
def test_a_crop_renders_the_full_images_pixels(robot: Robot, pose: int) -> None:
    """A crop's render is the crop of the full render, pixel for pixel (the same rays, not a rescale): depth to
    float32 rounding and the same self-filter, from the calibrated and from a drawn pose, for several arm
    configurations and crops (the image's corners, odd sizes). The rasterizer rounds the projected vertices to its
    sub-pixel grid, and the crop's projection may round them the other way: a pixel whose centre lies on a
    silhouette's edge may show the other side, a steep surface's depth may differ by its slope times that
    rounding (microns). Those are rare, and each is what a neighbouring pixel of the full image shows or between."""
    rng = np.random.default_rng(pose)
    d = robot.make_data()
    h = robot.handles
    d.qpos[h.arm_qpos] = robot.home_q + rng.uniform(-0.3, 0.3, len(h.arm_qpos))
    mujoco.mj_forward(robot.mj, d)
    cfg = CameraConfig()
    real = cfg.drawn(rng)
    camera = DepthCamera(robot, cfg)
    own = frozenset(robot.handles.robot_bodies)
    crops = [ImageCrop(0, 0, 200, 200), ImageCrop(848 - 131, 480 - 77, 131, 77), ImageCrop(300, 150, 257, 190),
             ImageCrop(int(rng.integers(0, 600)), int(rng.integers(0, 300)), 173, 141), ImageCrop(5, 7, 1, 1)]
    try:
        full_real = camera.render_depth(d, seen_from=real)
        full_depth, full_mask = camera.render_view(d, own)
        full_known = camera.render_mask(d, own)
        assert full_mask.sum() > 1000  # the arm is in view
        for crop in crops:
            view_depth, view_mask = camera.render_view(d, own, crop=crop)
            got = {"real": (camera.render_depth(d, seen_from=real, crop=crop), full_real),
                   "view": (view_depth, full_depth),
                   "mask": (camera.render_mask(d, own, crop=crop), full_known),
                   "view mask": (view_mask, full_mask)}
            for name, (image, full) in got.items():
                assert image.shape == (crop.height, crop.width), name
                part = full[crop.slices]
                same = (image == part) if image.dtype == bool else np.abs(image - part) <= 1e-6 * np.abs(part)
                assert (~same).sum() <= max(2, 0.002 * same.size), (name, crop, int((~same).sum()))
                assert np.all(_between_neighbours(full, crop, image)[~same]), (name, crop)
    finally:
        camera.close()


def test_a_crops_point_cloud_is_the_full_images_at_those_pixels(exact) -> None:
    depth, _ = exact
    cfg = CameraConfig()
    crop = ImageCrop(123, 201, 190, 97)
    pixels = np.zeros(depth.shape, dtype=bool)
    pixels[crop.slices] = True
    pixels[::3] = False  # and a mask
    np.testing.assert_allclose(point_cloud(depth[crop.slices], cfg, pixels[crop.slices], crop=crop),
                               point_cloud(depth, cfg, pixels), rtol=0, atol=1e-12)
    with pytest.raises(ConfigError, match=r"depth_m = \(97, 190\) is invalid"):
        point_cloud(depth[crop.slices], cfg)
    with pytest.raises(ConfigError, match=r"crop"):
        point_cloud(np.ones((10, 10)), cfg, crop=ImageCrop(840, 0, 10, 10))


def test_a_crop_around_image_coordinates_is_widened_and_clipped() -> None:
    cfg = CameraConfig()
    assert ImageCrop.around(10.2, 20.7, 30.0, 30.5, cfg) == ImageCrop(10, 30, 11, 1)
    assert ImageCrop.around(10.2, 20.7, 30.0, 30.5, cfg, margin_px=16) == ImageCrop(0, 14, 37, 33)
    assert ImageCrop.around(-50.0, 900.0, 470.0, 600.0, cfg, margin_px=4) == ImageCrop(0, 466, 848, 14)
    assert ImageCrop.around(900.0, 950.0, 10.0, 20.0, cfg) == ImageCrop(847, 10, 1, 11)  # outside: one pixel
    assert ImageCrop(0, 0, 10, 10).union(ImageCrop(20, 5, 3, 30)) == ImageCrop(0, 0, 23, 35)
    assert ImageCrop(3, 4, 5, 6).slices == (slice(4, 10), slice(3, 8))


def test_each_pixel_is_the_depth_along_its_own_ray(robot: Robot, exact) -> None:
    """A pixel's depth is that of the first surface on the ray through its centre (MuJoCo's own ray cast against
    the geoms the camera sees), everywhere but at silhouettes: the image is one sample per pixel, not a blend of
    neighbouring rays. To 0.1 mm on flat faces (the table, the cube, boxes); to 1.5 mm on the capsules and
    cylinders, which OpenGL draws as polygons and the ray cast intersects exactly."""
    depth, _ = exact
    cfg = CameraConfig()
    camera = DepthCamera(robot)
    d = mujoco.MjData(camera._m)
    d.qpos[:] = robot.make_data().qpos
    mujoco.mj_forward(camera._m, d)
    groups = np.asarray(camera._seen.geomgroup, dtype=np.uint8)
    camera.close()
    rng = np.random.default_rng(0)
    H, W = depth.shape
    v, u = rng.integers(1, H - 1, 3000), rng.integers(1, W - 1, 3000)
    around = np.stack([depth[v + dv, u + du] for dv, du in ((0, 1), (0, -1), (1, 0), (-1, 0))])
    inside = np.abs(around - depth[v, u]).max(axis=0) < 0.005  # not at a silhouette
    assert inside.sum() > 2500
    R, f, geom = cfg.R_world_camera, cfg.focal_px, np.zeros(1, dtype=np.int32)
    flat_types = {int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_BOX)}
    flat, curved = [], []
    for i in np.flatnonzero(inside):
        ray = R @ np.array([(u[i] + 0.5 - 0.5 * W) / f, (v[i] + 0.5 - 0.5 * H) / f, 1.0])  # unit depth
        hit = mujoco.mj_ray(camera._m, d, np.asarray(cfg.position_m, dtype=float), ray, groups, 1, -1, geom)
        assert hit > 0, f"pixel ({u[i]}, {v[i]}) shows a surface the ray cast does not hit"
        (flat if int(camera._m.geom_type[geom[0]]) in flat_types else curved).append(abs(hit - depth[v[i], u[i]]))
    assert len(flat) > 2000
    assert max(flat) < 1e-4
    assert max(curved, default=0.0) < 1.5e-3


def test_cameras_share_their_threads_opengl_context(robot: Robot, exact) -> None:
    """Cameras made in one thread render on one OpenGL context (each with its own MuJoCo render context): closing
    one leaves the others' images as they were; a camera in another thread gets that thread's own context and
    renders the same image."""
    import threading

    from pickplace.perception.render import shared_gl_context

    depth, _ = exact
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    first, second = DepthCamera(robot), DepthCamera(robot, CameraConfig(width_px=424, height_px=240))
    try:
        assert first._view.gl is second._view.gl is shared_gl_context()[0]
        small = second.render_depth(d)
        first.close()
        np.testing.assert_array_equal(second.render_depth(d), small)
        with pytest.raises(RuntimeError, match="after close"):
            first.render_depth(d)
    finally:
        second.close()
    seen: dict[str, object] = {}

    def elsewhere() -> None:
        camera = DepthCamera(robot)
        try:
            seen["context"], seen["depth"] = camera._view.gl, camera.render_depth(d)
        finally:
            camera.close()

    thread = threading.Thread(target=elsewhere)
    thread.start()
    thread.join()
    assert seen["context"] is not shared_gl_context()[0]
    np.testing.assert_array_equal(seen["depth"], depth)


def test_an_offscreen_scene_draws_what_a_mujoco_renderer_draws(robot: Robot) -> None:
    """An OffscreenScene on the shared context gives a mujoco.Renderer's lit image and depth, to the bit, for a
    camera of the model; a camera the model does not have is named in the error."""
    from pickplace.envs.common import CAMERA
    from pickplace.perception.render import OffscreenScene, RenderError, make_renderer

    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    renderer, _ = make_renderer(robot.mj, 160, 120)
    try:
        renderer.update_scene(d, camera=CAMERA)
        rgb = renderer.render().copy()
        renderer.enable_depth_rendering()
        renderer.update_scene(d, camera=CAMERA)
        depth = renderer.render().copy()
    finally:
        renderer.close()
    view = OffscreenScene(robot.mj, 160, 120)
    try:
        np.testing.assert_array_equal(view.rgb(d, CAMERA), rgb)
        np.testing.assert_array_equal(view.depth(d, CAMERA), depth)
        with pytest.raises(RenderError, match="no camera named 'nope'"):
            view.rgb(d, "nope")
    finally:
        view.close()
    with pytest.raises(RuntimeError, match="after close"):
        view.rgb(d, CAMERA)
