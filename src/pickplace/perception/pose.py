"""The object's pose from a depth camera's point cloud: segment it from the table, fit its model to it.

:func:`segment` keeps the points above the table top, on the table, and away from everything the robot knows
is there (its own links at their known configuration, the obstacles of its map: ``known`` points). The
largest cluster that is left is the object; fewer than ``min_points`` is :class:`ObjectNotSeen`, a clear
failure rather than a guess.

:func:`fit_resting_pose` fits the object's own surface mesh (box, cylinder, sphere, compound or mesh, one
code path) to those points, for an object resting on its resting face: the unknowns are its position on the
table and its yaw (x, y, yaw); its height is the table's. The model's surface is sampled densely
(``trimesh.sample.sample_surface``, ``SURFACE_SAMPLES`` points with their face normals, in a KD-tree); each
point's residual is its distance to the tangent plane of the nearest sample (point-to-plane, so the sampling
spacing does not bias it on flat faces), or, where it is further from that sample than the samples' spacing
(beyond a face's edge, where the plane says nothing), that distance less the spacing.
``scipy.optimize.least_squares`` minimises them (soft L1 loss, so
that a few stray points do not pull it; for the resting fit with the residuals' analytic Jacobian, the nearest
samples held fixed, :meth:`SurfaceModel.residuals_and_gradients`) from several starting yaws across the object's
symmetry. The result
reports the RMS residual (m) and how many points it used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy import ndimage
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from pickplace.errors import PickPlaceError
from pickplace.grasping.targets import object_yaw
from pickplace.robot.kinematics import rot_z
from pickplace.world.objects import ObjectConfig

#: Fewest points of the object for a fit.
MIN_POINTS = 30
#: Points used in the fit at most (a random subset beyond; the fit's cost grows with them).
MAX_FIT_POINTS = 600
#: Samples of the model's surface for the fit's nearest-point queries.
SURFACE_SAMPLES = 20_000
#: Points the starting yaws are tried on (the best start is then refined on all of them).
START_POINTS = 150
#: Starting yaws tried per symmetry period.
_YAW_STARTS = 12


class ObjectNotSeen(PickPlaceError):
    """The camera sees too little of the object to fit its pose (the numbers say how little)."""


@dataclass(frozen=True)
class PoseEstimate:
    """A fitted pose.

    Attributes:
        T_world_object: The object's pose (its resting frame).
        residual_m: RMS distance of the points used from the fitted surface (m).
        points: Points used.
    """

    T_world_object: pin.SE3
    residual_m: float
    points: int


def over_box(points: np.ndarray, box_xy_m: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Which points (N, 3) (m) lie over the box ``(min (2,), max (2,))`` (m) in x and y, edges included (bool (N,)).
    Column by column: a quarter of the cost of comparing the (N, 2) block row by row, the same answer."""
    (x0, y0), (x1, y1) = box_xy_m
    x, y = points[:, 0], points[:, 1]
    return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)


def observed_table_height(points: np.ndarray, nominal_m: float, table_box_xy_m: tuple[np.ndarray, np.ndarray],
                          band_m: float = 0.02) -> float:
    """The table top's height as the camera sees it (m): the median height of the points over the table within
    ``band_m`` of the nominal height. A calibration error tilts and shifts the whole cloud; heights measured
    from the table as seen, not from its nominal height, keep the object's fit from absorbing that shift.

    Raises:
        ObjectNotSeen: no point of the table is seen (the cloud is not of this scene).
    """
    z = points[:, 2]
    near = np.abs(z - nominal_m) < band_m
    near[near] = over_box(points[near], table_box_xy_m)
    if not np.any(near):
        raise ObjectNotSeen(f"no point of the table top within {band_m * 1e3:.0f} mm of its height "
                            f"{nominal_m:.3f} m")
    return float(np.median(z[near]))


def segment(points: np.ndarray, table_height_m: float, table_box_xy_m: tuple[np.ndarray, np.ndarray],
            clearance_m: float, max_height_m: float = math.inf, min_points: int = MIN_POINTS) -> np.ndarray:
    """The points (N, 3) of the object: above the table top, over the table, in the largest cluster.

    Args:
        points: World points (M, 3) (m), e.g. :func:`~pickplace.perception.camera.point_cloud` with the
            robot's and the map's pixels already left out.
        table_height_m: The table top's height (m).
        table_box_xy_m: The table's corners (min (2,), max (2,)) (m).
        clearance_m: Points less than this above the table top are the table (m): a few times the sensor's
            depth noise there (:meth:`CameraConfig.depth_sigma_m`), or the noise makes table points of it.
        max_height_m: Points higher than this above the table top are not the object (m): the robot knows
            how tall the object is (e.g. its largest extent), and what is higher (a link the self-filter
            missed by a pixel or two) must not be taken for it.
        min_points: Fewest points of an object.

    Raises:
        ObjectNotSeen: fewer than ``min_points`` are left.
    """
    z = points[:, 2] - table_height_m
    keep = (z > clearance_m) & (z < max_height_m)
    keep[keep] = over_box(points[keep], table_box_xy_m)
    above = points[keep]
    if len(above) < min_points:
        raise ObjectNotSeen(f"the camera sees {len(above)} points above the table (at least {min_points} needed)")
    # the largest cluster on a 1 cm grid (8-connected cells), so that a stray blob does not join the object
    cells = np.floor((above[:, :2] - above[:, :2].min(axis=0)) / 0.01).astype(int)
    grid = np.zeros(cells.max(axis=0) + 1, dtype=bool)
    grid[cells[:, 0], cells[:, 1]] = True
    labels, _ = ndimage.label(grid, structure=np.ones((3, 3)))
    ids = labels[cells[:, 0], cells[:, 1]]
    biggest = np.bincount(ids).argmax()
    obj = above[ids == biggest]
    if len(obj) < min_points:
        raise ObjectNotSeen(f"the largest cluster above the table has {len(obj)} points (at least {min_points} "
                            "needed)")
    return obj


class SurfaceModel:
    """An object's surface for fits: dense samples of its mesh with their normals, in a KD-tree.

    Each point's residual is its distance to the tangent plane of the nearest sample (point-to-plane, so the
    sampling spacing does not bias it on flat faces), or, where it is further from that sample than the
    samples' spacing (beyond a face's edge, where the plane says nothing), that distance less the spacing.

    Args:
        obj: The object (its geometry).
    """

    def __init__(self, obj: ObjectConfig) -> None:
        import trimesh

        geo = obj.geometry()
        mesh = trimesh.Trimesh(geo.vertices, geo.faces, process=False)
        self.samples, face = trimesh.sample.sample_surface(mesh, SURFACE_SAMPLES, seed=0)
        self.normals = mesh.face_normals[face]
        self.tree = cKDTree(self.samples)
        self.spacing_m = math.sqrt(mesh.area / SURFACE_SAMPLES)  # mean distance between neighbouring samples (m)
        self.z_min_m = float(geo.z_min_m)

    def residuals(self, local: np.ndarray) -> np.ndarray:
        """Distances (N,) (m) of points (N, 3) given in the object's frame from its surface."""
        return self.residuals_and_gradients(local)[0]

    def residuals_and_gradients(self, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`residuals` (N,) (m) and their gradients (N, 3) with respect to the points (the nearest sample
        held fixed: the plane's normal, signed, or the unit vector from the sample)."""
        dist, k = self.tree.query(local)
        off = local - self.samples[k]
        normal = self.normals[k]
        signed = np.einsum("ij,ij->i", off, normal)
        plane = np.abs(signed)
        edge = dist - self.spacing_m
        beyond = edge > plane  # off the surface's edge, the plane alone would say 0
        grad = np.where(beyond[:, None], off / np.maximum(dist, 1e-12)[:, None], np.sign(signed)[:, None] * normal)
        return np.maximum(plane, edge), grad


def _subset(points: np.ndarray, obj: ObjectConfig, rng: np.random.Generator | None) -> np.ndarray:
    if len(points) < MIN_POINTS:
        raise ObjectNotSeen(f"{len(points)} points of the {obj.name} (at least {MIN_POINTS} needed)")
    rng = rng if rng is not None else np.random.default_rng(0)
    if len(points) > MAX_FIT_POINTS:
        points = points[rng.choice(len(points), MAX_FIT_POINTS, replace=False)]
    return points


def fit_resting_pose(points: np.ndarray, obj: ObjectConfig, table_height_m: float,
                     rng: np.random.Generator | None = None, start: pin.SE3 | None = None,
                     model: SurfaceModel | None = None) -> PoseEstimate:
    """Fit ``obj`` resting on the table to its points (N, 3) (m): position on the table and yaw.

    Args:
        points: The object's points (from :func:`segment`).
        obj: The object (its geometry).
        table_height_m: The table top's height (m).
        rng: Generator for the subset of points (seeded: the same points give the same pose).
        start: Start from this pose only (a pose known to be close, e.g. to check whether the object moved);
            default: from the points' centre at several yaws across the object's symmetry.
        model: The object's :class:`SurfaceModel`, if already built (it is the same for every fit).

    Raises:
        ObjectNotSeen: fewer than ``MIN_POINTS`` points.
    """
    points = _subset(points, obj, rng)
    model = model if model is not None else SurfaceModel(obj)
    z0 = table_height_m - model.z_min_m

    evaluated: dict[str, np.ndarray] = {}

    def residuals(x: np.ndarray) -> np.ndarray:
        local = (points - np.array([x[0], x[1], z0])) @ rot_z(x[2])  # R^T (p - t), row by row
        r, grad = model.residuals_and_gradients(local)
        evaluated.update(x=x.copy(), local=local, grad=grad)
        return r

    def jacobian(x: np.ndarray) -> np.ndarray:
        """d residuals / d (x, y, yaw) (N, 3): the points' gradients through q = R(yaw)^T (p - t)."""
        if "x" not in evaluated or not np.array_equal(evaluated["x"], x):
            residuals(x)
        q, g = evaluated["local"], evaluated["grad"]
        c, s = math.cos(x[2]), math.sin(x[2])
        # dq/dx = -(c, -s, 0), dq/dy = -(s, c, 0), dq/dyaw = (q_y, -q_x, 0)
        return np.column_stack([-(g[:, 0] * c - g[:, 1] * s), -(g[:, 0] * s + g[:, 1] * c),
                                g[:, 0] * q[:, 1] - g[:, 1] * q[:, 0]])

    period = obj.yaw_period_rad if obj.yaw_period_rad > 0 else 2 * math.pi
    if start is not None:
        starts = [np.array([start.translation[0], start.translation[1], object_yaw(start.rotation)])]
    else:
        centre = points[:, :2].mean(axis=0)
        starts = [np.array([centre[0], centre[1], k * period / _YAW_STARTS])
                  for k in range(_YAW_STARTS if obj.yaw_period_rad > 0 else 1)]
    best = None
    if len(starts) > 1:  # the starts on a quarter of the points; the best one refined on all of them
        every = points
        points = points[:: max(1, len(points) // START_POINTS)]
        for x0 in starts:
            sol = least_squares(residuals, x0, jac=jacobian, loss="soft_l1", f_scale=0.002,
                                x_scale=[0.01, 0.01, 0.1])
            if best is None or sol.cost < best.cost:
                best = sol
        assert best is not None
        starts, points = [best.x], every
    sol = least_squares(residuals, starts[0], jac=jacobian, loss="soft_l1", f_scale=0.002, x_scale=[0.01, 0.01, 0.1])
    x = sol.x
    r = residuals(x)
    yaw = float(np.mod(x[2], period)) if obj.yaw_period_rad > 0 else 0.0
    return PoseEstimate(pin.SE3(rot_z(yaw), np.array([x[0], x[1], z0])), float(np.sqrt(np.mean(r**2))), len(points))


def fit_held_pose(points: np.ndarray, obj: ObjectConfig, guess: pin.SE3, rng: np.random.Generator | None = None,
                  model: SurfaceModel | None = None, free_axes: np.ndarray | None = None) -> PoseEstimate:
    """Fit the position of ``obj`` held in the hand to its points (N, 3) (m), its orientation the ``guess``'s.

    In the hand the grasp fixes the object's orientation to within the pads' compliance, and the pads, closing
    together, centre it between them; how deep they closed on it is where the hand went to grasp it. Where
    they closed on it along their faces is what the grasp model does not know (the error of the estimate it
    was picked from). So the fit's unknowns are the coordinates of its position along ``free_axes``: for a
    parallel gripper the direction along the pads' faces across the approach. Along the others the grasp
    model is the better measurement (the pads cover the faces that would show the closing axis; the top face
    alone fixes the height poorly where few of its points are seen).

    Args:
        points: The object's points.
        obj: The object (its geometry).
        guess: Where the grasp model puts it (its orientation is kept; its position along the fixed axes).
        rng: Generator for the subset of points.
        model: The object's :class:`SurfaceModel`, if already built.
        free_axes: The directions (3, k) (world, orthonormal columns) along which the position is fitted.
            Default: all three.

    Raises:
        ObjectNotSeen: fewer than ``MIN_POINTS`` points.
    """
    points = _subset(points, obj, rng)
    model = model if model is not None else SurfaceModel(obj)
    R, t0 = guess.rotation, guess.translation.copy()
    free = np.eye(3) if free_axes is None else np.asarray(free_axes, dtype=float).reshape(3, -1)

    def residuals(s: np.ndarray) -> np.ndarray:
        return model.residuals((points - (t0 + free @ s)) @ R)

    sol = least_squares(residuals, np.zeros(free.shape[1]), loss="soft_l1", f_scale=0.002, x_scale=0.01)
    r = residuals(sol.x)
    return PoseEstimate(pin.SE3(R.copy(), t0 + free @ sol.x), float(np.sqrt(np.mean(r**2))), len(points))


__all__ = ["MIN_POINTS", "ObjectNotSeen", "PoseEstimate", "SurfaceModel", "fit_held_pose", "fit_resting_pose",
           "observed_table_height", "segment"]
