"""The robot's view of the table: one fixed depth camera, used the way a robot can use it.

Where the camera really is differs from where the robot believes it is by a calibration error drawn once per
episode (:meth:`~pickplace.perception.camera.CameraConfig.drawn`): every image is rendered from the real pose,
with the sensor's noise (:func:`~pickplace.perception.camera.sensor_depth`), and back-projected with the
believed one. The robot leaves out what it knows is there: its own links at their configuration and the
obstacles of its map, rendered from where it believes the camera is and widened by :data:`MASK_MARGIN_PX`
pixels for the calibration error. Then:

* :meth:`TableCamera.locate`: the resting object's pose anywhere on the table, or near a point: the table top
  as seen, the object's points above it (:func:`~pickplace.perception.pose.segment`) and the model fit
  (:func:`~pickplace.perception.pose.fit_resting_pose`). Too few points is
  :class:`~pickplace.perception.pose.ObjectNotSeen`.
* :meth:`TableCamera.recheck`: one quick fit from a pose known to be close: where the resting object is now
  (has it moved? has it come to rest?). With ``from_hand``, :meth:`TableCamera.locate` measures a resting
  object against the hand next to it, as below (the check after the release).
* :meth:`TableCamera.in_hand`: the held object's position relative to the hand. In the same image the
  gripper's points are matched to where the robot's model of itself puts them (the image shift and depth
  offset that map one onto the other, :func:`register_offset`): that is the calibration error's displacement
  of the points there, and the object's points, corrected by it, are fitted
  (:func:`~pickplace.perception.pose.fit_held_pose`). The place needs where the object sits in the hand; the
  camera's calibration error cancels out of that to first order (what is left is its rotation error times the
  few centimetres between the gripper and the object).

A look near a known place (:meth:`TableCamera.recheck`, :meth:`TableCamera.locate` with ``near``,
:meth:`TableCamera.in_hand`) renders and processes only the part of the image it uses
(:class:`~pickplace.perception.camera.ImageCrop`): the rectangle of pixels it back-projects around the object
and, measured against the hand, the hand's pixels, widened by :data:`CROP_MARGIN_PX` so that every pixel it
uses is as in the full frame (the self-filter's widening, its shift by the calibration offset and the search of
:func:`register_offset` reach less far than that); only the sensor's noise draws differ. A look over the whole
table takes the full frame.

The only simulator state read here is what a sensor reads: the rendered images. The robot's own configuration
(for its self-filter and its model of itself) is the robot's knowledge, not the object's.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import mujoco
import numpy as np
import pinocchio as pin
from scipy import ndimage

from pickplace.perception.camera import CameraConfig, DepthCamera, ImageCrop, point_cloud, sensor_depth
from pickplace.perception.pose import (
    ObjectNotSeen,
    PoseEstimate,
    SurfaceModel,
    fit_held_pose,
    fit_resting_pose,
    observed_table_height,
    segment,
)
from pickplace.robot.model import INTRUDER, Robot

log = logging.getLogger(__name__)

#: Pixels by which the robot's self-filter is widened (its links are rendered from the calibrated camera pose,
#: which is off by the calibration error: ~0.3 deg, 4 px at 848 x 480).
MASK_MARGIN_PX = 4
#: Band around the table top's nominal height within which points are the table seen (m; observed_table_height).
TABLE_BAND_M = 0.02
#: Radius around the tcp within which the gripper's points measure the calibration offset (m).
HAND_RADIUS_M = 0.15
#: Search radius beyond the object's bounding sphere around where it should be (m).
SEARCH_MARGIN_M = 0.03
#: Largest image shift :func:`register_offset` searches when a look measures against the hand (px).
MAX_SHIFT_PX = 10
#: Pixels around what a look near a known place uses that it renders too (px): more than the farthest a pixel
#: it uses depends on: the self-filter's widening (:data:`MASK_MARGIN_PX`; after its shift by the calibration
#: offset, up to :data:`MAX_SHIFT_PX` and 2 px of widening), :func:`register_offset`'s search (up to
#: :data:`MAX_SHIFT_PX` and a pixel of interpolation), the sensor's depth edges (its ``edge_px``).
CROP_MARGIN_PX = 16


#: :func:`register_offset` evaluates every whole-pixel shift on every :data:`SHORTLIST_EVERY`-th pixel of the
#: region, then the :data:`SHORTLIST` shifts that estimate puts lowest on every pixel.
SHORTLIST = 24
SHORTLIST_EVERY = 8
#: :func:`register_offset`'s stages: (step (px), span (steps either side)); each stage's grid is centred on the best
#: shift so far. Whole pixels over the search range, then halves, fifths and tenths: every tenth of a pixel within
#: half a pixel of the best half pixel is reachable, as on an 11 x 11 grid of tenths, for 43 evaluations instead of
#: 130.
STAGES = ((1.0, None), (0.5, 1), (0.2, 2), (0.1, 1))


def _masked_median(values: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Each row's median over its entries where ``ok``: the value ``np.median(values[i][ok[i]])`` gives, for
    all rows (k, n) at once (every row needs at least one ``ok`` entry).

    A row's missing entries are filled half with -inf and half with +inf (one -inf more where their number is
    odd), so that the middle of the filled row is the middle of its valid entries; one ``np.median`` along the
    rows then does the work of ``k`` calls.
    """
    bad = ~ok
    nbad = bad.sum(axis=1)
    low = bad & (np.cumsum(bad, axis=1) <= (nbad // 2)[:, None])
    filled = np.where(ok, values, np.where(low, -np.inf, np.inf))
    odd = nbad % 2 == 1
    if not np.any(odd):
        return np.median(filled, axis=1)
    out = np.empty(len(values))
    if not np.all(odd):
        out[~odd] = np.median(filled[~odd], axis=1)
    extra = np.full((int(odd.sum()), 1), -np.inf)
    out[odd] = np.median(np.concatenate([filled[odd], extra], axis=1), axis=1)
    return out


def register_offset(measured: np.ndarray, model: np.ndarray, region: np.ndarray, config: CameraConfig,
                    max_shift_px: int = MAX_SHIFT_PX) -> tuple[np.ndarray, np.ndarray]:
    """How far the scene the sensor sees is displaced from the robot's model of it, around ``region``.

    Over the model's pixels in ``region`` (the robot's own, near the hand), finds the image shift (du, dv) (px)
    and depth offset dz (m) that map the model's depth image onto the measured one: the shift minimising the
    median absolute residual (dz the median residual), searched over whole pixels, then refined to a tenth of
    a pixel on the bilinearly interpolated measured image. The silhouette's edges against the
    background fix the shift; its surfaces fix the depth. Locally, that is a displacement of the points by
    ``R_world_camera @ (du z / f, dv z / f, dz)`` (z the region's median depth, f the focal length).

    The search runs in :data:`STAGES`: every whole pixel of the range, then 3 x 3 halves, 5 x 5 fifths and 3 x 3
    tenths of a pixel, each around the best so far; the costs of a stage's shifts are computed together
    (:func:`_masked_median`). The whole pixels are ranked first by the cost over every :data:`SHORTLIST_EVERY`-th
    pixel of the region, and the :data:`SHORTLIST` best of that estimate are evaluated on all of them.

    Measured on the 134 looks against the hand of realistic episodes 0-9 (their images recorded), against the
    displacement that each episode's true calibration error gives the model's points: the error is 0.85 mm median,
    0.96 mm mean, 1.83 mm p95, the same as the exhaustive search's (every whole pixel exactly, then 3 x 3 halves and
    11 x 11 tenths: 0.85, 0.97 and 1.83 mm), in 15 ms a look against its 72 ms (and 41 ms for this search with every
    4th pixel's estimate and all 11 x 11 tenths). The estimate's whole pixel was the exhaustive search's in all 134
    (also on every 16th pixel); the final shift was in 129 (to 1e-9 px; the others within 0.8 px). The
    cost of the shifts near the best is flat and can have two minima a pixel or two apart (a descent from a coarser
    grid of whole pixels found the other one), so the whole pixels are all estimated; the tenths differ from the
    exhaustive search's where two of them cost nearly the same (``tests/test_profile.py`` holds both to the true
    displacement).

    The three images may be the same crop of the camera's images (an image shift is the same in a crop);
    beyond the images' edges the measured image counts as missing.

    Args:
        measured: The sensor's depth image (H, W) (m; 0 where missing).
        model: The robot's model of the scene rendered where it believes the camera is (H, W) (m).
        region: Pixels to match (H, W) (bool): the model's own pixels near the hand.
        config: The camera as calibrated.
        max_shift_px: Largest shift searched (px).

    Returns:
        ``(offset, shift)``: the displacement (3,) (m, world) and the image shift (du, dv) (px).

    Raises:
        ObjectNotSeen: fewer than 30 pixels in the region.
    """
    v, u = np.nonzero(region)
    if len(v) < 30:
        raise ObjectNotSeen(f"the camera sees {len(v)} pixels of the gripper (at least 30 needed to measure the "
                            "object against it)")
    h, w = measured.shape
    z_model = model[v, u]
    # the measured image in a frame of missing pixels wider than any shift: no index leaves it
    pad = max_shift_px + 2
    framed = np.zeros((h + 2 * pad, w + 2 * pad))
    framed[pad:pad + h, pad:pad + w] = measured
    flat, row = framed.ravel(), w + 2 * pad

    def costs(shifts: np.ndarray, every: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The median absolute residual (m) and the median residual dz (m) at each shift (k, 2) (du, dv) (px);
        inf where fewer than half of the region's pixels are valid. Over every ``every``-th pixel of the region
        only, if ``every`` > 1 (an estimate)."""
        du, dv = shifts[:, :1], shifts[:, 1:]
        us, vs, zs = (u, v, z_model) if every == 1 else (u[::every], v[::every], z_model[::every])
        if np.all(shifts == np.round(shifts)):
            z = flat[(vs + pad) * row + us + pad + (dv * row + du).astype(int)]
        else:
            z = ndimage.map_coordinates(framed, [vs + pad + dv, us + pad + du], order=1)
            # between the image's last pixel and the frame: outside, as beyond it
            z[(us + du < 0) | (us + du > w - 1) | (vs + dv < 0) | (vs + dv > h - 1)] = 0.0
        ok = z > 0.0
        r = z - zs
        cost, dz = np.full(len(shifts), np.inf), np.zeros(len(shifts))
        enough = ok.sum(axis=1) >= len(zs) // 2
        if np.any(enough):
            r, ok = r[enough], ok[enough]
            dz[enough] = _masked_median(r, ok)
            cost[enough] = _masked_median(np.abs(r - dz[enough][:, None]), ok)
        return cost, dz

    def grid(centre: np.ndarray, step: float, span: int) -> np.ndarray:
        k = step * np.arange(-span, span + 1)
        dv, du = np.meshgrid(centre[1] + k, centre[0] + k, indexing="ij")
        return np.column_stack([du.ravel(), dv.ravel()])

    # every whole pixel of the range, then half and tenth pixels around the best
    best = (np.inf, 0.0, np.zeros(2))
    for step, span in STAGES:
        shifts = grid(best[2], step, max_shift_px if span is None else span)
        if step == 1.0 and len(shifts) > SHORTLIST:  # the whole pixels: a shortlist by an estimate, then exactly
            estimate, _ = costs(shifts, SHORTLIST_EVERY)
            shifts = shifts[np.sort(np.argsort(estimate, kind="stable")[:SHORTLIST])]
        cs, dzs = costs(shifts)
        i = int(np.argmin(cs))
        if cs[i] < best[0]:
            best = (float(cs[i]), float(dzs[i]), shifts[i])
    _, dz, (du, dv) = best
    z = float(np.median(z_model))
    f = config.focal_px
    return config.R_world_camera @ np.array([du * z / f, dv * z / f, dz]), np.array([du, dv])


def _image_bounds(config: CameraConfig, p_camera: np.ndarray) -> tuple[float, float, float, float] | None:
    """The image coordinates (px) ``u_lo, u_hi, v_lo, v_hi`` that points ``p_camera`` (3, N) (m, the camera's
    frame) span, or None if one of them is not beyond the camera's nearest range."""
    if np.any(p_camera[2] <= config.min_range_m):
        return None
    u, v = config.image_coordinates(p_camera)
    return float(u.min()), float(u.max()), float(v.min()), float(v.max())


class TableCamera:
    """The robot's depth camera over the table (see the module's docstring).

    Args:
        robot: The models (the scene, the object the robot looks for).
        config: The camera as calibrated (where the robot believes it is; its noise model).
        rng: Seeded generator: the calibration error (drawn here, once) and the sensor's noise.

    Attributes:
        config: The calibrated camera.
        real: Where the camera really is.
        images: Images taken so far.
        wall_s: Wall time spent on images and fits (s).
    """

    def __init__(self, robot: Robot, config: CameraConfig, rng: np.random.Generator) -> None:
        self.robot, self.config, self.rng = robot, config, rng
        self.real = config
        self.draw_calibration()
        self.camera = DepthCamera(robot, config)
        m, h, scene = robot.mj, robot.handles, robot.scene
        unknown = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name) for name in ("table", INTRUDER)}
        unknown |= {0, h.object_body}
        self.known = frozenset(b for b in range(m.nbody) if b not in unknown)  # its links, its map's obstacles
        self.obj = scene.object
        self.model = SurfaceModel(self.obj)
        centre, half = np.asarray(scene.table_center_xy_m), np.asarray(scene.table_size_xy_m) / 2
        self.table_box = (centre - half, centre + half)
        self.clearance_m = 4 * float(config.depth_sigma_m(1.0))
        geo = self.obj.geometry()
        self.tallest_m = 1.5 * float(np.max(geo.extent_m))
        lo, hi = geo.vertices.min(axis=0), geo.vertices.max(axis=0)
        self._centre_local = (lo + hi) / 2
        self._radius_m = float(np.linalg.norm(hi - lo)) / 2 + SEARCH_MARGIN_M
        self._reach_m = float(np.max(np.linalg.norm(geo.vertices, axis=1)))  # its farthest point from its origin
        self._table_crop = self._table_view()
        self.images = 0
        self.wall_s = 0.0

    def draw_calibration(self) -> None:
        """Draw where the camera really is again (a new calibration error, from the generator)."""
        self.real = self.config.drawn(self.rng)

    def close(self) -> None:
        """Release the OpenGL context."""
        self.camera.close()

    def _scene(self, d: mujoco.MjData, own: bool = False,
               crop: ImageCrop | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The exact depth image of the scene now, seen from where the camera really is, the pixels of what
        the robot knows is there, and (``own``) the robot's model of the scene: its depth rendered where it
        believes the camera is, from the same render as those pixels (renders: the frames of one look share
        them; each has its own noise, :meth:`_frame`). Of the pixels of ``crop`` only, if one is given."""
        exact = self.camera.render_depth(d, seen_from=self.real, crop=crop)
        if own:
            model, known = self.camera.render_view(d, self.known, crop=crop)
            return exact, known, model
        return exact, self.camera.render_mask(d, self.known, crop=crop), None

    def _frame(self, exact: np.ndarray) -> np.ndarray:
        """One depth frame as the sensor reports it (its noise drawn now)."""
        self.images += 1
        return sensor_depth(exact, self.config, self.rng)

    def _window(self, T_world_object: pin.SE3) -> tuple[int, int, int, int] | None:
        """The image's rectangle around the object's bounding sphere at this pose (plus the table around it),
        so that a look near a known place back-projects only those pixels: columns ``u0:u1`` and rows
        ``v0:v1`` (px), or None when it holds no pixel."""
        c = self.config
        centre = T_world_object.act(self._centre_local)
        p = c.R_world_camera.T @ (centre - np.asarray(c.position_m))
        z = float(p[2])
        if z <= c.min_range_m:
            return None
        u, v = c.image_coordinates(p)
        r = 2 * self._radius_m * c.focal_px / z + MASK_MARGIN_PX
        u0, u1 = max(0, int(u - r)), min(c.width_px, max(0, int(u + r) + 1))
        v0, v1 = max(0, int(v - r)), min(c.height_px, max(0, int(v + r) + 1))
        return (u0, u1, v0, v1) if u0 < u1 and v0 < v1 else None

    def _table_view(self) -> ImageCrop | None:
        """The part of the image that can show a point a look over the whole table uses, or None if the table is
        not wholly in front of the camera.

        Such a look keeps only points over the table (its ``table_box``) from :data:`TABLE_BAND_M` below the table
        top up to the object's height (:attr:`tallest_m`) and that band again above it (:func:`observed_table_height`
        and :func:`segment`, whose table is the one seen, within the band of the nominal one). That box projects
        inside the bounding rectangle of its corners' projections; a pixel outside it back-projects, at any depth,
        to a point outside the box. Widened by two pixels. (A look measured against the hand moves its points by
        the calibration offset first: it uses the whole image.)
        """
        c = self.config
        (x0, y0), (x1, y1) = self.table_box
        top = self.robot.scene.table_height_m
        corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1)
                            for z in (top - TABLE_BAND_M, top + TABLE_BAND_M + self.tallest_m)])
        bounds = _image_bounds(c, c.R_world_camera.T @ (corners - np.asarray(c.position_m)).T)
        return None if bounds is None else ImageCrop.around(*bounds, c, 2)

    def _hand_bounds(self, d: mujoco.MjData) -> tuple[float, float, float, float] | None:
        """Where the pixels of the robot's own points within :data:`HAND_RADIUS_M` of the tcp can be in the image
        rendered where it believes the camera is (:meth:`_own_hand`): the image coordinates (px) ``u_lo, u_hi,
        v_lo, v_hi`` of the corners of the cube around that sphere; None if part of it is not in front of the
        camera."""
        c = self.config
        tcp = d.site_xpos[self.robot.handles.tcp_site]
        corners = (c.R_world_camera.T @ (tcp - np.asarray(c.position_m)))[:, None] + HAND_RADIUS_M * np.array(
            [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]).T
        return _image_bounds(c, corners)

    def _look(self, d: mujoco.MjData, near: pin.SE3 | None,
              from_hand: bool) -> tuple[ImageCrop | None, np.ndarray | None]:
        """The part of the image a look renders (None: the full frame) and the pixels of it that it back-projects
        (bool, the crop's shape; None: all): near a pose, its :meth:`_window` and (``from_hand``) where the hand's
        pixels can be (:meth:`_hand_bounds`), each widened by :data:`CROP_MARGIN_PX`."""
        if near is None:
            return None, None
        c = self.config
        rect = self._window(near)
        crop = None
        if rect is not None:
            u0, u1, v0, v1 = rect
            crop = ImageCrop.around(u0, u1 - 1, v0, v1 - 1, c, CROP_MARGIN_PX)
            if from_hand:
                bounds = self._hand_bounds(d)
                crop = None if bounds is None else crop.union(ImageCrop.around(*bounds, c, CROP_MARGIN_PX))
        frame = crop if crop is not None else ImageCrop.full(c)
        window = np.zeros((frame.height, frame.width), dtype=bool)
        if rect is not None:
            u0, u1, v0, v1 = rect
            window[v0 - frame.v0:v1 - frame.v0, u0 - frame.u0:u1 - frame.u0] = True
        return crop, window

    def object_sphere(self, T_world_object: pin.SE3, held_at: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """Where the object may be (centre (3,) (m), radius (m)), widened by :data:`SEARCH_MARGIN_M`, whatever
        its believed yaw's error: resting, around its believed origin out to its farthest point (a turn about
        the origin stays inside); held at the point ``held_at`` (3,) (the tcp; the pads hold the object there),
        out to twice that (a grasp whose belief is turned, say half a turn off, still holds the object around
        the pads)."""
        if held_at is not None:
            return np.asarray(held_at, dtype=float).copy(), 2 * self._reach_m + SEARCH_MARGIN_M
        return T_world_object.translation.copy(), self._reach_m + SEARCH_MARGIN_M

    def _near(self, points: np.ndarray, T_world_object: pin.SE3) -> np.ndarray:
        centre = T_world_object.act(self._centre_local)
        return points[np.linalg.norm(points - centre, axis=1) < self._radius_m]

    def _own_hand(self, d: mujoco.MjData, known: np.ndarray, own: np.ndarray,
                  crop: ImageCrop | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The robot's model of the scene rendered where it believes the camera is (H, W) (m) (:meth:`_scene`:
        at the pixels of its own links, their depth), and its own pixels near the tcp (H, W) (bool): what
        :meth:`_hand_offset` matches (images of ``crop`` if given)."""
        tcp = d.site_xpos[self.robot.handles.tcp_site]
        own_px = known & (own > 0.0)
        hand = np.zeros(known.shape, dtype=bool)  # only those pixels are back-projected
        hand[own_px] = np.linalg.norm(point_cloud(own, self.config, own_px, crop=crop) - tcp,
                                      axis=1) < HAND_RADIUS_M
        return own, hand

    def _hand_offset(self, depth: np.ndarray, known: np.ndarray, own: np.ndarray,
                     hand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The calibration error's displacement of the points around the hand and the self-filter where the
        sensor sees the robot (:func:`register_offset` of the robot's model of itself near the tcp,
        :meth:`_own_hand`, on this frame)."""
        offset, shift = register_offset(depth, own, hand, self.config)
        moved = ndimage.shift(known, (shift[1], shift[0]), order=0, mode="constant", cval=False)
        return offset, ndimage.binary_dilation(moved, iterations=2)

    def locate(self, d: mujoco.MjData, near: pin.SE3 | None = None, start: pin.SE3 | None = None,
               from_hand: bool = False, views: int = 1) -> PoseEstimate:
        """The resting object's pose.

        Args:
            d: The simulation (rendered; the robot's configuration for its self-filter).
            near: Look only around this pose (where the object should be); default: the whole table.
            start: Fit from this pose only (:meth:`recheck`); default: from several yaws.
            from_hand: Measure the object against the hand next to it (the calibration error cancels, as in
                :meth:`in_hand`): where the hand is close, e.g. just after the release.
            views: Images taken (of the same scene: consecutive frames), their points fitted together: the
                sensor's noise averages out (not the calibration error, which is the same in every frame).

        Raises:
            ObjectNotSeen: too few points of the object (or of the table, or of the hand).
        """
        t0 = time.perf_counter()
        try:
            crop, window = self._look(d, near, from_hand)
            exact, known, model = self._scene(d, own=from_hand, crop=crop)
            if from_hand:
                assert model is not None
                own, hand = self._own_hand(d, known, model, crop)
            else:
                offset, mask = np.zeros(3), ndimage.binary_dilation(known, iterations=MASK_MARGIN_PX)
            # a look over the whole image back-projects only what can show the table (the noise is drawn on all)
            table_only = self._table_crop if crop is None and not from_hand else None
            clouds = []
            for _ in range(views):
                depth = self._frame(exact)
                if from_hand:
                    offset, mask = self._hand_offset(depth, known, own, hand)
                pixels = ~mask if window is None else ~mask & window
                if table_only is not None:
                    rows, cols = table_only.slices
                    cloud = point_cloud(depth[rows, cols], self.config, pixels[rows, cols], crop=table_only)
                else:
                    cloud = point_cloud(depth, self.config, pixels, crop=crop)
                clouds.append(cloud - offset)
            cloud = np.concatenate(clouds)
            table = observed_table_height(cloud, self.robot.scene.table_height_m, self.table_box, TABLE_BAND_M)
            if near is not None:
                cloud = self._near(cloud, near)
            points = segment(cloud, table, self.table_box, self.clearance_m, self.tallest_m)
            est = fit_resting_pose(points, self.obj, table, self.rng, start=start, model=self.model)
            # it rests on the table of the robot's map: its height is that table's (the table as seen gave the
            # fit its heights; the calibration error shifts them by a few mm)
            T = est.T_world_object
            z = self.robot.scene.table_height_m - self.model.z_min_m
            return dataclasses.replace(est, T_world_object=pin.SE3(T.rotation, np.array([*T.translation[:2], z])))
        finally:
            self.wall_s += time.perf_counter() - t0

    def recheck(self, d: mujoco.MjData, believed: pin.SE3, from_hand: bool = False) -> PoseEstimate:
        """Where the resting object is now, looking near where it is believed to be and fitting from there
        (``from_hand``: measured against the hand next to it, :meth:`locate`)."""
        return self.locate(d, near=believed, start=believed, from_hand=from_hand)

    def in_hand(self, d: mujoco.MjData, guess: pin.SE3, free_axes: np.ndarray | None = None) -> PoseEstimate:
        """The held object's pose, its position measured against the gripper in the same image.

        Args:
            d: The simulation (rendered; the robot's configuration for its model of itself).
            guess: Where the grasp model puts the object (its orientation is kept).
            free_axes: The directions (3, k) (world, orthonormal) along which the position is measured; along
                the others it stays the grasp model's (:func:`~pickplace.perception.pose.fit_held_pose`).
                Default: all three.

        Raises:
            ObjectNotSeen: too few points of the object or of the gripper.
        """
        t0 = time.perf_counter()
        try:
            crop, window = self._look(d, guess, from_hand=True)
            assert window is not None
            exact, known, model = self._scene(d, own=True, crop=crop)
            assert model is not None
            depth = self._frame(exact)
            offset, mask = self._hand_offset(depth, known, *self._own_hand(d, known, model, crop))
            points = self._near(point_cloud(depth, self.config, ~mask & window, crop=crop) - offset, guess)
            points = points[points[:, 2] > self.robot.scene.table_height_m + self.clearance_m]
            est = fit_held_pose(points, self.obj, guess, self.rng, model=self.model, free_axes=free_axes)
            log.debug("in hand: calibration offset at the gripper (%.1f, %.1f, %.1f) mm; object %.1f mm from the "
                      "grasp model", *(offset * 1e3), np.linalg.norm(est.T_world_object.translation
                                                                     - guess.translation) * 1e3)
            return est
        finally:
            self.wall_s += time.perf_counter() - t0


__all__ = ["CROP_MARGIN_PX", "HAND_RADIUS_M", "MASK_MARGIN_PX", "MAX_SHIFT_PX", "TableCamera", "register_offset"]
