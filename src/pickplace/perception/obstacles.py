"""Obstacles the robot sees but its map does not have: a height map from the depth camera.

The planners check paths against a believed world: the robot's map (its own links, the table, the map's
obstacles), the object where the robot believes it is, and what the camera shows besides. This module gives the
last part. Each image is rendered from where the camera really is, with the sensor's noise, back-projected with
the calibrated pose (as in :mod:`pickplace.perception.view`); the robot's own links and the map's obstacles are
left out by its self-filter, and so is everything within reach of where the object is believed to be. What is
left above the table top (by more than a few times the depth noise) is an unknown obstacle. Its points go into a
2.5-D height map of :data:`~pickplace.robot.model.SEEN_CELL_M` cells: a cell with at least ``min_points`` points
is occupied from the table up to its highest point, and becomes a column of the believed world
(:data:`~pickplace.robot.model.SEEN_OBSTACLE` mocap bodies in the planners' model). A camera above the table
sees tops and the sides facing it; what an obstacle hides below its top counts as occupied, what it hides
behind it (its shadow) does not.

The images are taken at the D435's 256 x 144 depth mode (one of its native modes, up to 90 frames/s; the same
field of view): a 4 cm cell at 0.8 m is about 6 x 6 of its pixels, and its depth noise (1.2 cm at 1 m) is
coarser than the pose fits' 848 x 480 images', so an obstacle must stand about 3.5 cm above the table (four
times the noise at 0.8 m) to be seen.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import pinocchio as pin
from scipy import ndimage

from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.perception.camera import DepthCamera, point_cloud, sensor_depth
from pickplace.perception.pose import over_box
from pickplace.robot import gripper
from pickplace.robot.model import (
    SEEN_CELL_M,
    SEEN_COLUMNS,
    SEEN_HALF_HEIGHT_M,
    SEEN_OBSTACLE_NAMES,
    SEEN_PARKED_POS,
)

if TYPE_CHECKING:
    from pickplace.perception.view import TableCamera

log = logging.getLogger(__name__)

#: Image size of the obstacle images (px): the Intel RealSense D435's 256 x 144 depth mode.
OBSTACLE_IMAGE_PX = (256, 144)
#: Fewest points of an occupied cell: a stray pixel or two at a depth edge is not an obstacle.
MIN_CELL_POINTS = 5
#: Points less than this many times the depth noise (at their depth) above the table top are the table.
CLEARANCE_SIGMAS = 4.0
#: Cells closer than this to the arm or the gripper as they stand are their own points, not an obstacle (m).
OWN_BODY_MARGIN_M = 0.01
#: The self-filter's widening for the calibration error, at the obstacle images' resolution (px).
MASK_MARGIN_PX = 1


def height_map(points: np.ndarray, cell_m: float = SEEN_CELL_M, min_points: int = MIN_CELL_POINTS) -> np.ndarray:
    """The occupied cells of a height map of obstacle points: each cell's centre and its highest point.

    Args:
        points: World points (N, 3) (m) of unknown obstacles (the table's, the robot's and the object's left out).
        cell_m: The cells' side (m), on a grid aligned with the world's x and y axes through the origin.
        min_points: Fewest points of an occupied cell.

    Returns:
        (k, 3) (m): x and y of each occupied cell's centre, and the height of its highest point; highest first.
    """
    if len(points) == 0:
        return np.zeros((0, 3))
    cells = np.floor(points[:, :2] / cell_m).astype(np.int64)
    keys, inverse, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    top = np.full(len(keys), -np.inf)
    np.maximum.at(top, inverse, points[:, 2])
    occupied = counts >= min_points
    columns = np.column_stack([(keys[occupied] + 0.5) * cell_m, top[occupied]])
    return columns[np.argsort(-columns[:, 2], kind="stable")]


class ObstacleCamera:
    """The depth camera's images for unknown obstacles (see the module's docstring).

    Args:
        view: The robot's camera for the pose fits: the same camera (its calibrated and real poses, its noise
            model), the same self-filter and table.
        rng: Seeded generator of the sensor's noise.
    """

    def __init__(self, view: TableCamera, rng: np.random.Generator) -> None:
        w, h = OBSTACLE_IMAGE_PX
        self.view = view
        self.config = dataclasses.replace(view.config, width_px=w, height_px=h)
        self.camera = DepthCamera(view.robot, self.config)
        self.table_height_m = view.robot.scene.table_height_m
        self.rng = rng
        self.images = 0
        self.wall_s = 0.0
        # the arm's own body, for dropping the cells it occupies now (:meth:`columns`)
        robot = view.robot
        self._body = CollisionChecker(robot, CollisionPolicy(margin_m=OWN_BODY_MARGIN_M))
        self._probe = robot.make_data()
        #: The columns' mocap ids in a world state of the robot's model (:meth:`place`).
        self.mocap_ids = robot.mj.body_mocapid[[mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY, n)
                                                for n in SEEN_OBSTACLE_NAMES]]
        self._index = {n: i for i, n in enumerate(SEEN_OBSTACLE_NAMES)}

    def close(self) -> None:
        """Release the OpenGL context."""
        self.camera.close()

    def points(self, d: mujoco.MjData, exclude: list[tuple[np.ndarray, float]]) -> np.ndarray:
        """The points (N, 3) (m) of unknown obstacles in one image of the scene now.

        Args:
            d: The simulation (rendered; the robot's configuration for its self-filter).
            exclude: Spheres (centre (3,) (m), radius (m)) whose points are not obstacles: where the object is
                believed to be, resting or in the hand.
        """
        t0 = time.perf_counter()
        try:
            w, h = OBSTACLE_IMAGE_PX
            real = dataclasses.replace(self.view.real, width_px=w, height_px=h)  # its calibration error
            exact = self.camera.render_depth(d, seen_from=real)
            mask = ndimage.binary_dilation(self.camera.render_mask(d, self.view.known), iterations=MASK_MARGIN_PX)
            depth = sensor_depth(exact, self.config, self.rng)
            self.images += 1
            cloud = point_cloud(depth, self.config, ~mask)
            # above the table by more than CLEARANCE_SIGMAS times the depth noise at the point's own depth
            depth_m = (cloud - np.asarray(self.config.position_m)) @ self.config.R_world_camera[:, 2]
            clearance_m = CLEARANCE_SIGMAS * self.config.depth_sigma_m(depth_m)
            keep = cloud[:, 2] > self.table_height_m + clearance_m
            keep[keep] = over_box(cloud[keep], self.view.table_box)
            for centre, radius in exclude:
                keep &= np.linalg.norm(cloud - centre, axis=1) > radius
            return cloud[keep]
        finally:
            self.wall_s += time.perf_counter() - t0

    def columns(self, d: mujoco.MjData, exclude: list[tuple[np.ndarray, float]]) -> np.ndarray:
        """The occupied cells (k, 3) of the height map of one image now (:func:`height_map`), at most
        :data:`~pickplace.robot.model.SEEN_COLUMNS` (the highest, with a warning if more are occupied), less
        those within :data:`OWN_BODY_MARGIN_M` of the arm and the gripper as they stand now (read from their
        own joints): where the robot is, there is no obstacle, so those points are its own, shifted past the
        self-filter by the calibration error at a depth edge."""
        cols = height_map(self.points(d, exclude))
        if len(cols) > SEEN_COLUMNS:
            log.warning("the camera sees %d cells of unknown obstacles; the believed world holds the highest %d",
                        len(cols), SEEN_COLUMNS)
            cols = cols[:SEEN_COLUMNS]
        if not len(cols):
            return cols
        h = self.view.robot.handles
        self.place(self._probe, cols)
        self._body.set_world(self._probe)
        finger_m = float(np.clip(gripper.finger_travel(self.view.robot, d), 0.0, 0.040))
        self._body.set_held(pin.SE3.Identity(), finger_m=finger_m)  # (the pose: no object is held in this check)
        own = {self._index[name] for pair in self._body.colliding_pairs(d.qpos[h.arm_qpos]) for name in pair
               if name in self._index}
        if own:
            log.debug("%d of %d cells seen are the robot's own body", len(own), len(cols))
            cols = cols[[i for i in range(len(cols)) if i not in own]]
        return cols


    def place(self, d: mujoco.MjData, columns: np.ndarray) -> None:
        """Put the seen-obstacle columns of a (believed) world state ``d`` on the occupied cells ``columns``
        (k, 3) (:meth:`columns`), each column's top at its cell's highest point; park the rest."""
        ids, n = self.mocap_ids, len(columns)
        d.mocap_pos[ids] = SEEN_PARKED_POS
        d.mocap_quat[ids] = (1.0, 0.0, 0.0, 0.0)
        if n:
            d.mocap_pos[ids[:n], :2] = columns[:, :2]
            d.mocap_pos[ids[:n], 2] = columns[:, 2] - SEEN_HALF_HEIGHT_M


__all__ = ["MIN_CELL_POINTS", "OBSTACLE_IMAGE_PX", "ObstacleCamera", "height_map"]
