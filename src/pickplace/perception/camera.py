"""A fixed depth camera over the table: rendered depth images with a stereo sensor's noise, and point clouds.

The camera renders the simulation offscreen (MuJoCo's depth buffer, :mod:`pickplace.perception.render`) and
turns the exact depth into what a stereo depth sensor reports (:func:`sensor_depth`):

* error growing with the square of the distance: an active stereo camera triangulates with a disparity error
  of ``subpixel_px`` over a ``baseline_m`` baseline, so ``sigma_z = z^2 subpixel / (f baseline)`` (``f``: the
  focal length in pixels). With the defaults (Intel RealSense D435 at 848 x 480) that is 2.4 mm at 0.8 m;
* quantization to the sensor's depth unit (1 mm);
* missing pixels at depth edges, where one of the two stereo views is occluded (``edge_jump_m``), and beyond
  the sensor's range. Missing pixels are 0, as the sensor reports them.

:func:`point_cloud` back-projects the valid pixels through the pinhole model into the world frame.

A look that needs only part of the image renders and processes only that part: an :class:`ImageCrop` of the
full frame, rendered through the same pinhole model (every pixel's ray is the full frame's pixel's; not a
rescale) in a fraction of the time.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import ConfigError
from pickplace.perception.render import OffscreenScene
from pickplace.robot.model import Robot
from pickplace.world.config import check_int, check_range, check_vector

#: The D435's depth field of view is 87 x 58 degrees (Intel RealSense D400 series datasheet, rev. 0.9x, table
#: "Depth field of view"); its recommended depth resolution is 848 x 480 (Intel, "Best known methods for tuning
#: RealSense D4xx depth cameras").
_D435_VFOV_RAD = math.radians(58.0)
#: Geom groups of the camera's private model copy: the object's geoms, and markers a sensor cannot see.
_OBJECT_GROUP, _HIDDEN_GROUP = 4, 5
#: Room in a camera's scene beyond one entry per geom of the model, for what MuJoCo adds to a scene (the camera's
#: options show no frames, contacts or other decorations).
_DECOR_GEOMS = 100


@dataclass(frozen=True)
class CameraConfig:
    """A fixed depth camera (SI units; world frame).

    The defaults are an Intel RealSense D435, a common active-stereo RGB-D camera, 0.8 m above the table:

    * 848 x 480 px depth at 58 degrees vertical field of view (datasheet: 87 x 58 degrees);
    * 50 mm stereo baseline and 0.08 px subpixel disparity RMS (datasheet: "subpixel RMS 0.08 typical"), for
      the depth error model ``sigma_z = z^2 subpixel / (f baseline)``;
    * depth unit 1 mm (the z16 stream's default scale); range 0.195 m (min-Z at 848 x 480) to 3 m;
    * missing pixels within ``edge_px`` of a depth step larger than ``edge_jump_m`` (occlusion in one view);
    * an extrinsic calibration error drawn per trial (:meth:`drawn`): 2 mm per axis and 0.2 degrees per axis
      (RMS), inside the 1-5 mm and 0.1-0.5 degree range that hand-eye calibration methods reach (I. Enebuse et
      al., "A comparative review of hand-eye calibration techniques for vision guided robots", IEEE Access 9,
      2021).

    Attributes:
        position_m: The optical centre (3,) (m).
        look_at_m: The point it looks at (3,) (m): the optical axis goes through it; the image's up is the
            world's up projected on the image plane.
        width_px, height_px: Image size (px).
        vertical_fov_rad: Vertical field of view (rad).
        baseline_m: Stereo baseline (m).
        subpixel_px: Disparity error RMS (px).
        depth_unit_m: Quantization of the reported depth (m).
        min_range_m, max_range_m: Depth range the sensor reports (m); outside it pixels are missing.
        edge_jump_m: A depth step between neighbouring pixels larger than this makes an edge (m).
        edge_px: Pixels on each side of an edge that are missing (px).
        calibration_position_sigma_m: RMS error per axis of the camera's calibrated position (m).
        calibration_angle_sigma_rad: RMS error per axis of its calibrated orientation (rad).
    """

    position_m: tuple[float, float, float] = (0.80, 0.0, 1.05)
    look_at_m: tuple[float, float, float] = (0.45, 0.0, 0.315)
    width_px: int = 848
    height_px: int = 480
    vertical_fov_rad: float = _D435_VFOV_RAD
    baseline_m: float = 0.050
    subpixel_px: float = 0.08
    depth_unit_m: float = 0.001
    min_range_m: float = 0.195
    max_range_m: float = 3.0
    edge_jump_m: float = 0.02
    edge_px: int = 1
    calibration_position_sigma_m: float = 0.002
    calibration_angle_sigma_rad: float = math.radians(0.2)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "position_m", check_vector("camera.position_m", self.position_m, 3, -5.0, 5.0, unit="m"))
        set_(self, "look_at_m", check_vector("camera.look_at_m", self.look_at_m, 3, -5.0, 5.0, unit="m"))
        check_int("camera.width_px", self.width_px, 8, 1280)
        check_int("camera.height_px", self.height_px, 8, 720)
        check_range("camera.vertical_fov_rad", self.vertical_fov_rad, 0.05, 2.5, unit="rad")
        check_range("camera.baseline_m", self.baseline_m, 0.005, 0.5, unit="m")
        check_range("camera.subpixel_px", self.subpixel_px, 0.0, 2.0, unit="px")
        check_range("camera.depth_unit_m", self.depth_unit_m, 0.0, 0.01, unit="m")
        check_range("camera.min_range_m", self.min_range_m, 0.0, 5.0, unit="m")
        check_range("camera.max_range_m", self.max_range_m, self.min_range_m, 20.0, lo_open=True, unit="m")
        check_range("camera.edge_jump_m", self.edge_jump_m, 0.0, 1.0, lo_open=True, unit="m")
        check_int("camera.edge_px", self.edge_px, 0, 10)
        check_range("camera.calibration_position_sigma_m", self.calibration_position_sigma_m, 0.0, 0.05, unit="m")
        check_range("camera.calibration_angle_sigma_rad", self.calibration_angle_sigma_rad, 0.0, 0.1, unit="rad")
        forward = np.subtract(self.look_at_m, self.position_m)
        if np.linalg.norm(forward) < 1e-3:
            raise ConfigError("camera.look_at_m", self.look_at_m, "must differ from camera.position_m")
        if np.linalg.norm(np.cross(forward / np.linalg.norm(forward), [0.0, 0.0, 1.0])) < 1e-3:
            raise ConfigError("camera.look_at_m", self.look_at_m, "must not be straight below or above the camera "
                         "(the image's up would be undefined): tilt it a little")

    @property
    def focal_px(self) -> float:
        """Focal length (px), the same along both image axes (square pixels)."""
        return 0.5 * self.height_px / math.tan(0.5 * self.vertical_fov_rad)

    def image_coordinates(self, p_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pinhole projection :func:`point_cloud` inverts: image coordinates ``u, v`` (px; pixel ``u`` spans
        ``[u, u + 1)``) of points ``p_camera`` (3, ...) in the camera's frame (m, z along the optical axis, > 0)."""
        f = self.focal_px
        return f * p_camera[0] / p_camera[2] + self.width_px / 2, f * p_camera[1] / p_camera[2] + self.height_px / 2

    @property
    def R_world_camera(self) -> np.ndarray:
        """The camera's axes in the world (3, 3): columns right, down, forward (the image's x, y and depth)."""
        forward = np.subtract(self.look_at_m, self.position_m)
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        return np.column_stack([right, down, forward])

    def drawn(self, rng: np.random.Generator) -> CameraConfig:
        """Where the camera really is in one trial: this (calibrated) pose moved by a calibration error drawn
        from ``rng`` (position: ``calibration_position_sigma_m`` per axis; orientation: the optical axis turned
        about the optical centre by a rotation of ``calibration_angle_sigma_rad`` per axis; the image's roll
        stays the one the world's up gives, so a roll error is not modelled). Render with it; back-project with
        this."""
        dp = rng.normal(0.0, self.calibration_position_sigma_m, 3)
        R = pin.exp3(rng.normal(0.0, self.calibration_angle_sigma_rad, 3))
        p = np.asarray(self.position_m) + dp
        look = p + R @ (np.asarray(self.look_at_m) - np.asarray(self.position_m))
        return dataclasses.replace(self, position_m=tuple(float(v) for v in p),
                                   look_at_m=tuple(float(v) for v in look))

    def depth_sigma_m(self, depth_m: np.ndarray | float) -> np.ndarray:
        """The depth error RMS (m) of the stereo model at ``depth_m``: ``z^2 subpixel / (f baseline)``."""
        z = np.asarray(depth_m, dtype=float)
        return z**2 * self.subpixel_px / (self.focal_px * self.baseline_m)


@dataclass(frozen=True)
class ImageCrop:
    """A rectangle of a camera's image (px): columns ``u0`` to ``u0 + width - 1`` and rows ``v0`` to
    ``v0 + height - 1`` (rows counted from the image's top, as in the images' arrays).

    Attributes:
        u0, v0: The first column and row (px).
        width, height: Its size (px), at least 1.
    """

    u0: int
    v0: int
    width: int
    height: int

    @classmethod
    def full(cls, config: CameraConfig) -> ImageCrop:
        """The whole of ``config``'s image."""
        return cls(0, 0, config.width_px, config.height_px)

    @classmethod
    def around(cls, u_lo: float, u_hi: float, v_lo: float, v_hi: float, config: CameraConfig,
               margin_px: int = 0) -> ImageCrop:
        """The pixels whose centres or any part lie within ``[u_lo, u_hi] x [v_lo, v_hi]`` (px, image
        coordinates: pixel ``u`` spans ``[u, u + 1)``), widened by ``margin_px`` on every side and clipped to
        ``config``'s image (at least one pixel)."""
        u0 = min(max(0, math.floor(u_lo) - margin_px), config.width_px - 1)
        v0 = min(max(0, math.floor(v_lo) - margin_px), config.height_px - 1)
        u1 = max(min(config.width_px, math.floor(u_hi) + 1 + margin_px), u0 + 1)
        v1 = max(min(config.height_px, math.floor(v_hi) + 1 + margin_px), v0 + 1)
        return cls(u0, v0, u1 - u0, v1 - v0)

    def union(self, other: ImageCrop) -> ImageCrop:
        """The smallest crop holding both."""
        u0, v0 = min(self.u0, other.u0), min(self.v0, other.v0)
        u1 = max(self.u0 + self.width, other.u0 + other.width)
        v1 = max(self.v0 + self.height, other.v0 + other.height)
        return ImageCrop(u0, v0, u1 - u0, v1 - v0)

    @property
    def slices(self) -> tuple[slice, slice]:
        """The crop's rows and columns of a full image: ``image[crop.slices]`` is the crop."""
        return slice(self.v0, self.v0 + self.height), slice(self.u0, self.u0 + self.width)

    def check(self, config: CameraConfig) -> None:
        """Raise :class:`ConfigError` unless the crop lies inside ``config``'s image."""
        if not (self.width >= 1 and self.height >= 1 and self.u0 >= 0 and self.v0 >= 0
                and self.u0 + self.width <= config.width_px and self.v0 + self.height <= config.height_px):
            raise ConfigError("crop", self, f"must lie inside the {config.width_px} x {config.height_px} px image")


def _free_camera(c: CameraConfig) -> mujoco.MjvCamera:
    """MuJoCo's free camera at ``c``'s pose (optical axis from its position through its look-at point)."""
    forward = np.subtract(c.look_at_m, c.position_m)
    distance = float(np.linalg.norm(forward))
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = c.look_at_m
    cam.distance = distance
    cam.azimuth = math.degrees(math.atan2(forward[1], forward[0]))
    cam.elevation = math.degrees(math.asin(forward[2] / distance))
    return cam


def _finite_planes(m: mujoco.MjModel, c: CameraConfig, margin_m: float = 1.0) -> None:
    """Draw the model's infinite planes (the floor) as finite squares of two by two quads, each large enough to
    hold every point of it within the sensor's range (:attr:`CameraConfig.max_range_m`) of the camera, or of a
    camera up to ``margin_m`` from it (its calibration error); farther, a pixel is missing anyway.

    Planes of the world body only (their pose is the model's). MuJoCo draws an infinite plane as a grid of up to
    200 x 200 quads around the viewer, for its lighting and texture; a depth image needs neither, and on a software
    OpenGL the grid was half the cost of a small image (0.7 of 1.4 ms for 256 x 144 px, Mesa llvmpipe). Only the
    planes' size changes, in the camera's own model; their depths changed by at most 0.5 um (float32 rounding of
    other triangles).
    """
    for g in np.flatnonzero((m.geom_type == mujoco.mjtGeom.mjGEOM_PLANE) & (m.geom_bodyid == 0)):  # (world frame)
        if m.geom_size[g, 0] > 0.0 and m.geom_size[g, 1] > 0.0:
            continue
        # in whole metres: cameras a calibration error apart draw the same quads (the same depths to the bit)
        reach = math.ceil(float(np.linalg.norm(np.subtract(c.position_m, m.geom_pos[g]))) + c.max_range_m + margin_m)
        m.geom_size[g] = (reach, reach, reach)  # (the third: the spacing of its grid lines)


class DepthCamera:
    """Renders depth images of a simulation from a :class:`CameraConfig`.

    Args:
        robot: The models (the scene to render).
        config: The camera.

    Raises:
        RenderError: no OpenGL context, or an image larger than the model's offscreen buffer.
    """

    def __init__(self, robot: Robot, config: CameraConfig | None = None) -> None:
        self.config = config if config is not None else CameraConfig()
        c = self.config
        self._m = copy.deepcopy(robot.mj)  # the field of view is the model's: set on a private copy
        self._m.vis.global_.fovy = math.degrees(c.vertical_fov_rad)
        # One sample per pixel: a depth sensor measures along each pixel's ray and a segmentation has no blended
        # edges, so the viewer's multisampling (the model's 4 samples) buys nothing here and made a full 848 x 480
        # render 2.5 times as costly on a software OpenGL (13.5 against 5.4 ms, Mesa llvmpipe, where the depth and
        # segmentation images came out the same to the bit with either setting). test_camera holds each pixel's
        # depth to the ray cast through its centre.
        self._m.vis.quality.offsamples = 0
        _finite_planes(self._m, c)
        # what a sensor sees: every body's geoms of the visible groups, but not the markers that only exist for
        # the viewer (geoms that collide with nothing and are not the robot's visual meshes); the object's geoms
        # go to their own group, so that the robot's own view of the scene can leave them out (hide_object)
        m = self._m
        marker = (m.geom_contype == 0) & (m.geom_conaffinity == 0) & ~np.isin(m.geom_bodyid,
                                                                              list(robot.handles.robot_bodies))
        m.geom_group[marker] = _HIDDEN_GROUP
        m.geom_group[robot.handles.object_geoms] = _OBJECT_GROUP
        self._seen = mujoco.MjvOption()
        self._seen.geomgroup[:] = 0
        for g in (0, 1, 2, _OBJECT_GROUP):
            self._seen.geomgroup[g] = 1
        self._seen.geomgroup[_HIDDEN_GROUP] = 0
        self._known = mujoco.MjvOption()
        self._known.geomgroup[:] = self._seen.geomgroup
        self._known.geomgroup[_OBJECT_GROUP] = 0
        # MuJoCo's scene and render context, on the thread's shared OpenGL context (a context of its own cost 10-20
        # times as much to make); the camera's options show no frames, contacts or other decorations
        self._view = OffscreenScene(m, c.width_px, c.height_px, decor_geoms=_DECOR_GEOMS)
        self.backend = self._view.backend
        self._cam = _free_camera(c)

    def _render(self, data: mujoco.MjData, camera: mujoco.MjvCamera, option: mujoco.MjvOption, depth: bool = True,
                bodies: frozenset[int] | None = None,
                crop: ImageCrop | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """One render of the scene: its exact depth (H, W) (m) if ``depth``, and which pixels show a geom of one of
        ``bodies`` first (H, W) (bool) if ``bodies`` is given, both read from the same image; of the ``crop`` of
        the image only (h, w) if one is given.

        What ``mujoco.Renderer.render`` does in its depth and its segmentation modes (both render with the
        segmentation flags: the same image), with both buffers read at once: MuJoCo's depth buffer converted to
        metric depth as it converts it (float32 as it returns it), and the segmentation colours (the scene's geom
        index plus one) looked up in a table of the scene's geoms.

        A crop is rendered on its own (:meth:`_narrow`): a viewport of its size and the part of the camera's
        frustum that its pixels see, so that each of its pixels is the full image's pixel there (the same ray;
        its depth the same to float32 rounding, its geom the same) and only its pixels are drawn. The
        rasterizer rounds the projected vertices to its sub-pixel grid and may round the crop's the other way:
        then a pixel whose centre lies on a silhouette's edge shows the other side, or a steep surface's depth
        differs by microns (a handful of pixels in an image).
        """
        c, view = self.config, self._view
        scene = view.update(data, camera, option)
        if crop is not None and (crop.width, crop.height) == (c.width_px, c.height_px):
            crop = None  # the full frame
        if crop is not None:
            crop.check(c)
            self._narrow(scene, crop)
        w, h = (c.width_px, c.height_px) if crop is None else (crop.width, crop.height)
        zbuf = np.empty((h, w), dtype=np.float32) if depth else None
        rgb = np.empty((h, w, 3), dtype=np.uint8) if bodies is not None else None
        view.draw(w, h, segment=True, rgb=rgb, depth=zbuf)
        z = None if zbuf is None else np.flipud(view.metric_depth(zbuf)).astype(float)
        mask = None
        if rgb is not None:
            assert bodies is not None
            lut = np.zeros(scene.ngeom + 1, dtype=bool)  # by segmentation id (0: the background)
            geom_body, geom = self._m.geom_bodyid, int(mujoco.mjtObj.mjOBJ_GEOM)
            for g in scene.geoms[:scene.ngeom]:
                if g.segid >= 0 and g.objtype == geom and 0 <= g.objid < len(geom_body):
                    lut[g.segid + 1] = int(geom_body[g.objid]) in bodies
            if scene.ngeom < 255:  # ids in the red channel only
                seg = rgb[..., 0]
            else:
                c = rgb.astype(np.uint32)
                seg = np.minimum(c[..., 0] + (c[..., 1] << 8) + (c[..., 2] << 16), scene.ngeom)
            mask = np.flipud(lut[seg])
        return z, mask

    def _narrow(self, scene: mujoco.MjvScene, crop: ImageCrop) -> None:
        """Narrow the scene's cameras (updated for the full image) to what the pixels of ``crop`` see.

        ``mjr_render`` projects with ``glFrustum`` from each camera's ``frustum_center``, ``frustum_bottom`` and
        ``frustum_top`` (m, on the near plane), its half-width ``frustum_width``, or when that is 0 the one that
        makes the pixels square in the viewport. A pixel of the full image spans ``(top - bottom) / H`` there; the
        crop's part of the near plane is the span of its columns and rows, and with ``frustum_width`` 0 and a
        viewport of the crop's size, its pixels come out square, the full image's pixels.
        """
        W, H = self.config.width_px, self.config.height_px
        for cam in scene.camera:
            if cam.frustum_width != 0.0:
                raise RuntimeError(f"the scene's camera has frustum_width {cam.frustum_width}: cannot crop it "
                                   "(a free camera's is 0)")
            bottom, top = float(cam.frustum_bottom), float(cam.frustum_top)
            pixel = (top - bottom) / H
            left = float(cam.frustum_center) - 0.5 * W * pixel + crop.u0 * pixel
            low = bottom + (H - crop.v0 - crop.height) * pixel  # OpenGL's rows go up from the image's bottom
            cam.frustum_center = left + 0.5 * crop.width * pixel
            cam.frustum_bottom = low
            cam.frustum_top = low + crop.height * pixel

    def render_depth(self, data: mujoco.MjData, seen_from: CameraConfig | None = None,
                     hide_object: bool = False, crop: ImageCrop | None = None) -> np.ndarray:
        """The exact depth (H, W) (m) along the optical axis of every pixel, from the simulation as it is.

        Args:
            data: The simulation state.
            seen_from: Render from this pose instead of the config's (e.g. where the camera really is,
                :meth:`CameraConfig.drawn`); its image size and field of view must be the config's.
            hide_object: Leave the object out: the scene as the robot's model of it looks without the object
                (its own links, the table), for comparing with what the sensor sees.
            crop: Render only this part of the image: the depth (h, w) of its pixels, those of the full image
                (see :meth:`_render`).
        """
        camera = self._cam
        if seen_from is not None:
            c = self.config
            if ((seen_from.width_px, seen_from.height_px, seen_from.vertical_fov_rad)
                    != (c.width_px, c.height_px, c.vertical_fov_rad)):
                raise ConfigError("seen_from", (seen_from.width_px, seen_from.height_px, seen_from.vertical_fov_rad),
                                  f"must have this camera's image size and field of view ({c.width_px}, "
                                  f"{c.height_px}, {c.vertical_fov_rad})")
            camera = _free_camera(seen_from)
        z, _ = self._render(data, camera, self._known if hide_object else self._seen, crop=crop)
        assert z is not None
        return z

    def render_mask(self, data: mujoco.MjData, bodies: frozenset[int], crop: ImageCrop | None = None) -> np.ndarray:
        """Which pixels (H, W) show a geom of one of ``bodies`` first (bool): a self-filter, for the parts of the
        scene the robot knows (its own links at their known configuration, the obstacles of its map). With
        ``crop``: its pixels only (h, w), the full image's there (see :meth:`_render`)."""
        _, mask = self._render(data, self._cam, self._seen, depth=False, bodies=bodies, crop=crop)
        assert mask is not None
        return mask

    def render_view(self, data: mujoco.MjData, bodies: frozenset[int],
                    crop: ImageCrop | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`render_depth` (the scene as seen, from the config's pose) and :meth:`render_mask` from one
        render: the depth (H, W) (m) and the pixels of ``bodies`` (H, W) (bool) (with ``crop``: of its pixels,
        (h, w)). Where a pixel shows one of ``bodies`` first, its depth is that body's, the depth
        ``hide_object`` gives there too. (Read together with the colours, a depth may differ from
        :meth:`render_depth`'s in the float32 depth buffer's last bit: 0.5 um at 1.6 m.)"""
        z, mask = self._render(data, self._cam, self._seen, bodies=bodies, crop=crop)
        assert z is not None and mask is not None
        return z, mask

    def close(self) -> None:
        """Release MuJoCo's render context (its buffers on the shared OpenGL context)."""
        self._view.close()


def sensor_depth(depth_m: np.ndarray, config: CameraConfig, rng: np.random.Generator) -> np.ndarray:
    """What the sensor reports for an exact depth image (H, W) (m): noise growing with distance, quantized,
    0 where a pixel is missing (beyond the range, or at a depth edge).

    Args:
        depth_m: Exact depth (H, W) (m), e.g. :meth:`DepthCamera.render_depth`.
        config: The camera (its noise model).
        rng: Seeded generator of the noise.
    """
    z = np.asarray(depth_m, dtype=float)
    noisy = z + rng.normal(0.0, 1.0, z.shape) * config.depth_sigma_m(z)
    if config.depth_unit_m > 0.0:
        noisy = np.round(noisy / config.depth_unit_m) * config.depth_unit_m
    missing = (z < config.min_range_m) | (z > config.max_range_m)
    if config.edge_px > 0:
        jump = np.zeros(z.shape, dtype=bool)
        dx = np.abs(np.diff(z, axis=1)) > config.edge_jump_m
        dy = np.abs(np.diff(z, axis=0)) > config.edge_jump_m
        jump[:, 1:] |= dx
        jump[:, :-1] |= dx
        jump[1:, :] |= dy
        jump[:-1, :] |= dy
        for _ in range(config.edge_px - 1):  # widen the band
            grown = jump.copy()
            grown[1:, :] |= jump[:-1, :]
            grown[:-1, :] |= jump[1:, :]
            grown[:, 1:] |= jump[:, :-1]
            grown[:, :-1] |= jump[:, 1:]
            jump = grown
        missing |= jump
    return np.where(missing, 0.0, noisy)


def point_cloud(depth_m: np.ndarray, config: CameraConfig, pixels: np.ndarray | None = None,
                crop: ImageCrop | None = None) -> np.ndarray:
    """Back-project the valid (non-zero) pixels of a depth image (H, W) (m) into world points (N, 3) (m).

    Args:
        depth_m: Depth along the optical axis (m); 0 marks a missing pixel.
        config: The camera (its pose and intrinsics).
        pixels: Optional boolean mask (H, W) of the pixels to use (e.g. a segmentation).
        crop: The part of the image that ``depth_m`` (and ``pixels``) are (h, w); default: the whole image.
    """
    z = np.asarray(depth_m, dtype=float)
    h, w = z.shape
    if crop is None:
        crop = ImageCrop.full(config)
    else:
        crop.check(config)
    if (h, w) != (crop.height, crop.width):
        raise ConfigError("depth_m", z.shape, f"must be ({crop.height}, {crop.width}), the camera's image"
                          + ("" if (crop.width, crop.height) == (config.width_px, config.height_px) else "'s crop"))
    valid = z > 0.0 if pixels is None else (z > 0.0) & pixels
    v, u = np.nonzero(valid)
    d = z[v, u]
    f = config.focal_px
    x = (u + (crop.u0 + 0.5 - 0.5 * config.width_px)) * d / f
    y = (v + (crop.v0 + 0.5 - 0.5 * config.height_px)) * d / f
    return np.asarray(config.position_m) + np.column_stack([x, y, d]) @ config.R_world_camera.T


__all__ = ["CameraConfig", "DepthCamera", "ImageCrop", "point_cloud", "sensor_depth"]
