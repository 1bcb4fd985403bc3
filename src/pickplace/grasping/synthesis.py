"""Grasp candidates from an object's own geometry, in its resting frame, and their ranking.

A candidate is a pose of the tcp in the object's resting frame, ``T_object_tcp``, where the two pads are
centred on two antipodal surface points: tcp y is the closing axis (pointing from the second contact to the
first; the first contact is on the left, +y, pad), tcp z the approach direction (from the gripper into the
object), tcp x along the pads' width. Candidates do not depend on where the object stands: the caller applies
the world's filters (:func:`world_candidates` for the table; then IK, collisions with the arm and obstacles)
and tries them in the order of :func:`rank`.

How the pairs are found (:func:`synthesize`):

* **box** (and each box of a compound): the three pairs of opposite faces; the pads' centre on a grid over the
  face (``spacing_m``, 4 mm inside its edges) plus, for each approach, the lowest point of the face at which
  the gripper clears the resting plane by ``TABLE_GAP_M`` (so that a low object keeps a table-feasible grasp);
* **cylinder**: across the diameter, in ``AXIS_STEPS`` directions around the axis, at heights along the axis
  on the same grid; across the length (end caps) when that fits the stroke, the pads on a grid over the cap;
* **sphere**: diameters at elevations ``SPHERE_ELEVATIONS_RAD`` and every 30 degrees of azimuth;
* **compound**: each part's pairs, every filter checked against the whole object (so a part's face covered by,
  or a pad blocked by, another part is rejected);
* **mesh**: ``samples`` points sampled on the surface (trimesh, seeded), a ray cast from each along its inward
  normal; every point where the ray leaves the material within the stroke is the opposite contact if its
  normal is antipodal within the friction cone (rays are also cast tilted by half the cone and along the
  object's axes, and each pair is refined by closing the jaws along the bisector of its normals); plus the pairs
  along a 1.5 mm grid of lines parallel to each axis of the object. This finds wall pinches of hollow shapes (one
  pad inside a cup) and pinches across a handle. One pair is kept per cell of half ``spacing_m`` and 10 degrees
  of axis (the one whose normals lie closest to its axis).

Each pair is tried with approach directions perpendicular to its closing axis: the most downward one turned
about the closing axis by ``APPROACH_TILTS_RAD`` (top-down, tilted by 30 and 60 degrees, horizontal), or eight
horizontal ones when the closing axis is vertical. Each grasp is also returned turned by 180 degrees about its
approach (the same pads swapped): a different tcp pose with the same contacts.

Filters (all geometric, in the object's frame; thresholds are the module constants):

1. **Stroke**: ``MIN_GRIP_WIDTH_M <= width <= MAX_GRIP_WIDTH_M`` (``min_width_m``, ``max_width_m``): at most
   the open width less 5 mm per side, so that the open pads pass the object with room for pose error; at least
   10 mm, so that the closing fingers still have 3 mm of servo error per side to squeeze with (15 N; the
   squeeze is ``5000 N/m x (width / 2 - 2 mm)`` up to 40 N, see ``gripper.xml``).
2. **Force closure**: the two pads as soft-finger contacts (the object's ``friction`` and
   ``torsional_friction_m``) in force closure, Ferrari–Canny margin ``> CLOSURE_TOL`` about the centre of mass,
   torques divided by half the object's largest extent (:func:`~pickplace.grasping.closure.analyze_grasp`).
   The contacts are exactly antipodal for primitives; a mesh's pairs must have both normals within the
   friction cone of their line, and within 20 degrees of it (what a flat pad can touch).
3. **Pad support**, rays cast along the closing axis from the open pad onto the object, on a 7 x 7 grid over
   each pad's face and on 8 probes around its centre:

   * the pad's centre touches the planned contact: the surface there within ``CONTACT_TOL_M`` (0.25 mm) of it
     (nothing in front of it on the closing line);
   * the contact is not on an edge: the surface continues ``EDGE_MARGIN_M`` (3 mm) around it in every
     direction, within ``EDGE_DROP_M`` (2 mm) of the contact plane, so that a few mm of pose error keep the pad
     on the same surface and the normal is defined (on a box: the pad centre at least 3 mm inside the face; a
     rounded edge of radius >= ~2.3 mm, like a mug handle's section, still counts as surface);
   * the pad reaches the contact: nothing under the pad stands more than ``MAX_PROTRUSION_M`` (3 mm) proud of
     the contact plane (a concave wall may curve round the pad by that much: a cup's inner wall of 35 mm
     radius stands 2.1 mm proud at the pad's edges);
   * the pad touches along a line or an area, not at a point: the patch where it touches (the grid points
     within ``SUPPORT_GAP_M`` (1 mm, about the pads' soft-contact depth) of the point that touches first) is at
     least ``MIN_PATCH_SPAN_M`` (10 mm) long in some direction. A point contact resists no torque about its
     normal and rolls under any torque about the grip axis; a sphere under ~40 mm across (a 10 mm-radius ball:
     a 9 mm patch) fails, a tennis ball (16 mm), a box face and a handle's rounded bar (a line along it) pass;
   * the patch's centroid lies in the middle half of the pad (the squeeze goes through the pad's middle, not
     about one of its edges: rejects a pad touching with one edge a flat face tilted by more than ~5 degrees,
     or a bump off its centre).
4. **Clear approach and closing**: the gripper's collision boxes (``GripperGeometry``: pads, fingers, palm and
   coupling), inflated by ``clearance_m``, swept open from the pregrasp (``approach_distance_m`` back along the
   approach) to the grasp, and each pad and finger swept while closing until the pad touches (stopping
   ``CLOSING_STOP_M`` short), must not overlap the object: exact box-triangle separating-axis tests against the
   surface mesh (a primitive's tessellation lies within 0.1 mm inside its true surface), plus a containment
   test of the open pads' faces (the boxes are connected, so with no triangle crossing any of them none lies
   wholly inside the object).

Not checked here: the table or any other object (:func:`world_candidates` checks the table), reachability (IK),
the arm beyond the gripper, and dynamics (whether the squeeze holds the weight and the accelerations; the
closed gripper squeezes with at most 20 N per pad and less below ~20 mm of width).
"""

from __future__ import annotations

import enum
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickplace.errors import ConfigError
from pickplace.grasping.closure import CLOSURE_TOL, analyze_grasp
from pickplace.grasping.targets import CLEARANCE_M, TABLE_GAP_M
from pickplace.robot.gripper import GripperGeometry
from pickplace.world.contact import Contact
from pickplace.world.objects import MAX_GRIP_WIDTH_M, MIN_GRIP_WIDTH_M, Geometry, ObjectConfig, Part

log = logging.getLogger(__name__)

#: A tcp z within this angle of straight down (in the resting frame) is a top-down approach (rad).
TOP_MAX_TILT_RAD = math.radians(10.0)
#: A tcp z within this angle of the horizontal is a side approach (rad).
SIDE_MAX_ELEVATION_RAD = math.radians(10.0)
#: Approach directions tried per closing axis: turns about it from the most downward direction (rad).
APPROACH_TILTS_RAD = tuple(math.radians(a) for a in (0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0))
#: Horizontal approach directions tried when the closing axis is vertical (evenly spaced).
HORIZONTAL_STEPS = 8
#: Closing directions tried around a cylinder's axis over half a turn (the other half are the flipped grasps).
AXIS_STEPS = 6
#: Elevations of the closing axis tried on a sphere (rad); azimuths every 30 degrees.
SPHERE_ELEVATIONS_RAD = tuple(math.radians(a) for a in (0.0, 30.0, 60.0, 90.0))
#: The surface at the pad's centre must be this close to the planned contact (m).
CONTACT_TOL_M = 0.00025
#: The surface must continue this far around the contact in every direction (m): not on an edge ...
EDGE_MARGIN_M = 0.003
#: ... within this of the contact plane (m) (a rounded edge of radius >= ~2.3 mm still counts as a surface).
EDGE_DROP_M = 0.002
#: A pad touches where the surface is within this of the point it touches first (m): its soft-contact depth.
SUPPORT_GAP_M = 0.001
#: Nothing under a pad may stand more than this proud of the contact plane (m).
MAX_PROTRUSION_M = 0.003
#: The patch a pad touches must be at least this long in some direction (m): a line or an area, not a point.
MIN_PATCH_SPAN_M = 0.010
#: The closing pad is checked up to this short of the surface (m): it ends touching it.
CLOSING_STOP_M = 0.0005
#: Default clearance of the gripper's boxes from the object on the way in and while closing (m).
SWEEP_CLEARANCE_M = 0.002
#: Pad centres are generated this much further inside a face than ``EDGE_MARGIN_M`` (m), off the probes' edge.
_GRID_INSET_M = 0.001
#: Points per side of the grid over each pad's face.
_PAD_GRID = 7
#: Sampled pairs are kept one per cell of half ``spacing_m`` and per this angle of their axis (rad).
_PAIR_DEDUP_RAD = math.radians(10.0)
#: A sampled contact whose normal is further than this from the closing axis cannot be what a flat pad
#: touches first unless the surface is sharply curved there (cos of 20 degrees); the support test decides.
_COS_FLAT_PAD = math.cos(math.radians(20.0))
#: Spacing of the grid of lines swept through a mesh along each of its axes (m).
_LINE_SPACING_M = 0.0015
#: Refinement of sampled pairs (:func:`_refine_pairs`): iterations, how far outside a contact its pad starts
#: (m), and how far a contact may move before the refinement is dropped (m).
_REFINE_STEPS, _REFINE_REACH_M, _REFINE_MAX_MOVE_M = 3, 0.004, 0.006
_WIDTH_TOL_M = 1e-9


class ApproachKind(enum.StrEnum):
    """Where the gripper comes from, in the object's resting frame."""

    TOP = "top"  # tcp z within TOP_MAX_TILT_RAD of straight down
    TILTED = "tilted"  # between
    SIDE = "side"  # tcp z within SIDE_MAX_ELEVATION_RAD of horizontal


#: Preference order of the approach kinds (the cost's approach term, per step).
_APPROACH_RANK = {ApproachKind.TOP: 0, ApproachKind.TILTED: 1, ApproachKind.SIDE: 2}


class FeatureKind(enum.StrEnum):
    """What the two pads squeeze."""

    BOX_FACES = "box_faces"  # two opposite faces of a box
    CYLINDER_SIDE = "cylinder_side"  # across a cylinder's diameter
    CYLINDER_CAPS = "cylinder_caps"  # a cylinder's two end caps
    SPHERE = "sphere"  # across a sphere's diameter
    SAMPLED = "sampled"  # an antipodal pair sampled on a mesh


@dataclass(frozen=True, eq=False)
class GraspCandidate:
    """One grasp, in the object's resting frame.

    Attributes:
        T_object_tcp: The tcp at the grasp: pads centred on the contacts, y the closing axis (from the second
            contact to the first), z the approach (into the object), x along the pads' width.
        width_m: Distance between the two contacts along the closing axis (m).
        contacts_m: The contact points (2, 3) (m): the first under the left (+y) pad, the second under the right.
        normals: Unit contact normals (2, 3) pointing into the object.
        approach: Top-down, tilted or side approach (in the resting frame).
        tilt_rad: Angle between the approach (tcp z) and straight down (rad): 0 top-down, pi/2 horizontal.
        margin: Ferrari–Canny margin of the two soft-finger pad contacts about the centre of mass (units of the
            normal force; torques divided by ``scale_m``).
        com_offset_m: Distance from the centre of mass to the grip axis (the line through the contacts) (m).
        scale_m: The object's characteristic length (m): half its largest extent; the torque scale of ``margin``.
        support: Fraction of the pads' faces that touch the object (the lesser of the two pads), 0-1.
        feature: What the pads squeeze.
        part: Index of the primitive in ``ObjectConfig.primitives()`` the contacts are on (-1 for a mesh).
        touch_m: How far in front of its planned contact each pad (the left's, then the right's) first meets the
            object as it closes (m): 0 on a flat face or a convex one, up to ``MAX_PROTRUSION_M`` where the surface
            stands proud around the contact (a rounded handle's bar met on its flank, a concave wall curving round
            the pad).
    """

    T_object_tcp: pin.SE3
    width_m: float
    contacts_m: np.ndarray
    normals: np.ndarray
    approach: ApproachKind
    tilt_rad: float
    margin: float
    com_offset_m: float
    scale_m: float
    support: float
    feature: FeatureKind
    part: int
    touch_m: tuple[float, float] = (0.0, 0.0)

    @property
    def touch_lag_m(self) -> float:
        """How much sooner one pad meets the object than the other as the gripper closes them alike (m): the first
        then pushes the object alone until the second arrives."""
        return abs(self.touch_m[0] - self.touch_m[1])

    def __post_init__(self) -> None:
        for name in ("contacts_m", "normals"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.shape != (2, 3):
                raise ConfigError(f"grasp.{name}", arr.shape, "must have shape (2, 3)")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def approach_direction(self) -> np.ndarray:
        """Unit approach direction (3,) in the object's frame (the tcp z axis)."""
        return np.array(self.T_object_tcp.rotation[:, 2])

    def pregrasp(self, distance_m: float = CLEARANCE_M) -> pin.SE3:
        """The tcp backed off ``distance_m`` (m) from the grasp along -approach, in the object's frame."""
        R = self.T_object_tcp.rotation
        return pin.SE3(R.copy(), self.T_object_tcp.translation - distance_m * R[:, 2])

    def T_world_tcp(self, T_world_object: pin.SE3) -> pin.SE3:
        """The tcp at the grasp in the world, for the object at ``T_world_object``."""
        return T_world_object * self.T_object_tcp

    def contacts(self, mu: float, torsional_friction_m: float = 0.0) -> tuple[Contact, Contact]:
        """The two contacts as :class:`~pickplace.world.contact.Contact` records (object frame)."""
        return (Contact(self.contacts_m[0], self.normals[0], mu, torsional_friction_m),
                Contact(self.contacts_m[1], self.normals[1], mu, torsional_friction_m))


# --------------------------------------------------------------------------- #
# the gripper as boxes in the tcp frame
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class _Hand:
    """The gripper's collision boxes in the tcp frame, from :class:`GripperGeometry` (m).

    ``pad`` and ``finger``: (lo (3,), hi (3,)) of the left (+y) pad and finger, fully open; the right ones are
    their mirror images in y. ``palm``: (P, 2, 3) boxes that do not move with the fingers.
    """

    pad: np.ndarray
    finger: np.ndarray
    palm: np.ndarray
    open_face_m: float

    @classmethod
    def of(cls, g: GripperGeometry) -> _Hand:
        def lohi(box: Sequence[float]) -> np.ndarray:
            b = np.asarray(box, dtype=float)
            return np.array([b[:3] - b[3:], b[:3] + b[3:]])

        palm = np.array([lohi(b) for b in g.palm_boxes_m]).reshape(-1, 2, 3)
        return cls(lohi(g.pad_box_m), lohi(g.finger_box_m), palm, float(g.open_inner_face_y_m))

    @property
    def pad_centre(self) -> np.ndarray:
        """Centre of the pad's face in the tcp frame's x and z, (2,) (m)."""
        c = self.pad.mean(axis=0)
        return np.array([c[0], c[2]])

    @property
    def pad_half(self) -> np.ndarray:
        """Half the pad's width (x) and height (z), (2,) (m)."""
        h = (self.pad[1] - self.pad[0]) / 2
        return np.array([h[0], h[2]])

    @property
    def flip_symmetric(self) -> bool:
        """Whether the gripper looks the same turned by 180 degrees about its z axis (x-symmetric boxes)."""
        boxes = [self.pad, self.finger, *self.palm]
        return all(abs(b[0, 0] + b[1, 0]) < 1e-6 for b in boxes) and all(abs(b[0, 1] + b[1, 1]) < 1e-6
                                                                         for b in self.palm)

    def boxes(self, width_m: np.ndarray, touch_m: np.ndarray, approach_m: float, clearance_m: float,
              stop_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The swept boxes of K grasps in their tcp frames: ``(lo, hi)``, each (K, B, 3) (m).

        Per side: the pad and the finger coming in open, swept from ``approach_m`` back along the approach to the
        grasp; the pad and the finger closing, swept from open until the pad's face is ``stop_m`` short of where
        it first touches (``touch_m`` (K, 2), how far proud of the contact plane, left then right); then the palm
        boxes swept along the approach. All are inflated by ``clearance_m`` except the closing pad's face and
        sides (the surface it closes on may curve round it, as a cup's inner wall does). In the order the box
        tests use (the likeliest to hit first): pads closing, pads coming in, fingers closing, fingers coming
        in, palm boxes.
        """
        w = np.asarray(width_m, dtype=float)
        k = len(w)
        back = np.array([0.0, 0.0, approach_m])
        infl = np.full(3, clearance_m)
        named: dict[str, tuple[np.ndarray, np.ndarray]] = {}

        def put(name: str, lo: np.ndarray, hi: np.ndarray, sign: float) -> None:
            lo, hi = np.broadcast_to(lo, (k, 3)).copy(), np.broadcast_to(hi, (k, 3)).copy()
            if sign < 0:  # the right side: the mirror image in y
                lo[:, 1], hi[:, 1] = -hi[:, 1], -lo[:, 1]
            named[name] = (lo, hi)

        (pad_lo, pad_hi), (fin_lo, fin_hi) = self.pad, self.finger
        for side, sign in ((0, 1.0), (1, -1.0)):
            stop = w / 2 + touch_m[:, side] + stop_m  # where the pad's face stops, from the tcp along +y (m)
            travel = np.maximum(self.open_face_m - stop, 0.0)[:, None] * np.array([0.0, 1.0, 0.0])
            closing_pad_lo = np.broadcast_to(pad_lo, (k, 3)).copy()
            closing_pad_lo[:, 1] = stop
            put(f"pad_closing_{side}", closing_pad_lo, pad_hi + np.array([0.0, clearance_m, 0.0]), sign)
            put(f"pad_coming_{side}", pad_lo - back - infl, pad_hi + infl, sign)
            put(f"finger_closing_{side}", fin_lo - travel - infl, fin_hi + infl, sign)
            put(f"finger_coming_{side}", fin_lo - back - infl, fin_hi + infl, sign)
        order = [f"{part}_{side}" for part in ("pad_closing", "pad_coming", "finger_closing", "finger_coming")
                 for side in (0, 1)]
        for i, (lo, hi) in enumerate(self.palm):
            put(f"palm_{i}", lo - back - infl, hi + infl, 1.0)
            order.append(f"palm_{i}")
        return (np.stack([named[n][0] for n in order], axis=1), np.stack([named[n][1] for n in order], axis=1))


def _corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Corners (..., 8, 3) of boxes (..., 3)."""
    sel = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=bool)
    return np.where(sel, hi[..., None, :], lo[..., None, :])


# --------------------------------------------------------------------------- #
# geometry kernels (numpy; trimesh's own ray and proximity queries need rtree)
# --------------------------------------------------------------------------- #


def _ray_triangle(o: np.ndarray, d: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Möller–Trumbore: distance along each ray (n,) to its paired triangle, ``inf`` if it misses (n, 3 each)."""
    e1, e2 = b - a, c - a
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    ok = np.abs(det) > 1e-18
    inv = 1.0 / np.where(ok, det, 1.0)
    tv = o - a
    u = np.einsum("ij,ij->i", tv, pv) * inv
    qv = np.cross(tv, e1)
    v = np.einsum("ij,ij->i", d, qv) * inv
    t = np.einsum("ij,ij->i", e2, qv) * inv
    eps = 1e-9
    ok &= (u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps)
    return np.where(ok, t, np.inf)


def _winding(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Generalized winding number (M,) of points (M, 3) about a closed triangle surface (F, 3, 3)."""
    out = np.zeros(len(points))
    step = max(1, 2_000_000 // max(1, len(tri)))
    for s in range(0, len(points), step):
        P = points[s:s + step, None, None, :]
        A, B, C = (tri[None, :, i, :] - P[:, :, 0, :] for i in range(3))
        la, lb, lc = (np.linalg.norm(X, axis=-1) for X in (A, B, C))
        det = np.einsum("mfi,mfi->mf", A, np.cross(B, C))
        den = (la * lb * lc + np.einsum("mfi,mfi->mf", A, B) * lc + np.einsum("mfi,mfi->mf", B, C) * la
               + np.einsum("mfi,mfi->mf", C, A) * lb)
        out[s:s + step] = 2.0 * np.arctan2(det, den).sum(axis=1) / (4.0 * math.pi)
    return out


def _separated(tri: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Whether each triangle (n, 3, 3), relative to its box's centre, is separated from the box of half extents
    (n, 3) along the triangle's normal or an edge-cross axis (the box's own axes are tested by the caller)."""
    v0, v1, v2 = tri[:, 0], tri[:, 1], tri[:, 2]
    sep = np.zeros(len(tri), dtype=bool)
    eye = np.eye(3)
    for edge in (v1 - v0, v2 - v1, v0 - v2):
        for i in range(3):
            axis = np.cross(eye[i], edge)
            p = np.stack([np.einsum("ij,ij->i", v, axis) for v in (v0, v1, v2)], axis=1)
            r = np.einsum("ij,ij->i", half, np.abs(axis))
            sep |= (p.min(axis=1) > r) | (p.max(axis=1) < -r)
    n = np.cross(v1 - v0, v2 - v0)
    sep |= np.abs(np.einsum("ij,ij->i", n, v0)) > np.einsum("ij,ij->i", half, np.abs(n))
    return sep


class _Surface:
    """The object's surface for the checks: triangle-box overlap, first hits of rays, containment."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        self.vertices = np.asarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.tri = self.vertices[self.faces]
        self.tri_lo, self.tri_hi = self.tri.min(axis=1), self.tri.max(axis=1)
        self.bounds = np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)])
        try:  # the extremes of a projection over the vertices are those over their convex hull's
            from scipy.spatial import ConvexHull, QhullError

            self.hull = self.vertices[ConvexHull(self.vertices).vertices]
        except (QhullError, ValueError):
            self.hull = self.vertices

    def boxes_hit(self, R: np.ndarray, p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Whether any box of each grasp overlaps any triangle (K,): boxes (K, B, 3) in the tcp frames (R, p).

        Box by box (a grasp found blocked is not tested further): the boxes' bounds in the object's frame against
        the triangles' bounds, then the exact separating-axis test on the pairs left.
        """
        k_all = len(p)
        out = np.zeros(k_all, dtype=bool)
        F = len(self.faces)
        for b in range(lo.shape[1]):
            active = np.flatnonzero(~out)
            if len(active) == 0:
                break
            centre_l, half = (lo[active, b] + hi[active, b]) / 2, (hi[active, b] - lo[active, b]) / 2
            Ra = R[active]
            centre = p[active] + np.einsum("kij,kj->ki", Ra, centre_l)
            # boxes wholly beyond one of their own faces from every vertex are clear of the object
            near = np.ones(len(active), dtype=bool)
            for s in range(0, len(active), 256):
                v = np.matmul(self.hull[None] - centre[s:s + 256, None], Ra[s:s + 256])  # (k, V, 3)
                h = half[s:s + 256, None]
                near[s:s + 256] = ~np.any(np.all(v > h, axis=1) | np.all(v < -h, axis=1), axis=1)
            active, centre, half, Ra = active[near], centre[near], half[near], Ra[near]
            reach = np.einsum("kij,kj->ki", np.abs(Ra), half)
            step = max(1, 4_000_000 // max(1, 3 * F))
            for s in range(0, len(active), step):
                c, r = centre[s:s + step], reach[s:s + step]
                kk, ff = np.nonzero((self.tri_lo[None, :, 0] <= (c + r)[:, None, 0])
                                    & (self.tri_hi[None, :, 0] >= (c - r)[:, None, 0]))
                for ax in (1, 2):
                    ok = (self.tri_lo[ff, ax] <= (c + r)[kk, ax]) & (self.tri_hi[ff, ax] >= (c - r)[kk, ax])
                    kk, ff = kk[ok], ff[ok]
                if len(kk) == 0:
                    continue
                kk = kk + s
                tri = np.matmul(self.tri[ff] - centre[kk][:, None], Ra[kk])  # in the box's frame, about its centre
                h = half[kk]
                meet = ~np.any((tri.min(axis=1) > h) | (tri.max(axis=1) < -h), axis=1)  # the box's own axes
                kk, tri, h = kk[meet], tri[meet], h[meet]
                hit = ~_separated(tri, h)
                out[active[np.unique(kk[hit])]] = True
        return out

    def pad_hits(self, origins: np.ndarray, axes: np.ndarray, centre: np.ndarray, half: np.ndarray) -> np.ndarray:
        """Distance (P, G) along each of G parallel rays per pad to the first surface they meet (inf if none).

        Args:
            origins: Ray origins (P, G, 3).
            axes: Per pad (P, 3, 3), columns: two unit vectors across the rays, then the rays' unit direction.
            centre: Per pad (P, 3), the centre of a box along ``axes`` of half extents ``half`` (3,) that holds
                the part of the rays that matters: a mesh looks only at the triangles that meet it, so a hit
                outside it may be missed.
        """
        raise NotImplementedError

    def inside(self, points: np.ndarray) -> np.ndarray:
        """Whether each point (M, 3) lies inside the object."""
        raise NotImplementedError


class _Primitives(_Surface):
    """A union of primitives: exact rays and containment, the tessellated surface for the box tests."""

    def __init__(self, parts: Sequence[Part], geo: Geometry) -> None:
        super().__init__(geo.vertices, geo.faces)
        self.parts = tuple(parts)

    @staticmethod
    def _slab(o: np.ndarray, d: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (-half - o) / d, (half - o) / d
        flat = np.abs(d) < 1e-15
        inside = np.abs(o) <= half
        lo = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        hi = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        return lo.max(axis=1), hi.min(axis=1)

    @staticmethod
    def _quadratic(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        disc = b * b - 4 * a * c
        ok = (a > 1e-15) & (disc >= 0)
        root = np.sqrt(np.where(ok, disc, 0.0))
        aa = np.where(ok, a, 1.0)
        lo = np.where(ok, (-b - root) / (2 * aa), np.inf)
        hi = np.where(ok, (-b + root) / (2 * aa), -np.inf)
        parallel = a <= 1e-15  # the ray runs along the axis (cylinder): inside the radius or never
        lo = np.where(parallel, np.where(c <= 0, -np.inf, np.inf), lo)
        hi = np.where(parallel, np.where(c <= 0, np.inf, -np.inf), hi)
        return lo, hi

    def _interval(self, part: Part, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R = part.rotation
        ol, dl = (o - np.asarray(part.pos_m)) @ R, d @ R
        s = part.size_m
        if part.kind == "box":
            return self._slab(ol, dl, np.asarray(s) / 2)
        if part.kind == "cylinder":
            r, hz = s[0], s[1] / 2
            a = dl[:, 0] ** 2 + dl[:, 1] ** 2
            b = 2 * (ol[:, 0] * dl[:, 0] + ol[:, 1] * dl[:, 1])
            c = ol[:, 0] ** 2 + ol[:, 1] ** 2 - r * r
            rlo, rhi = self._quadratic(a, b, c)
            zlo, zhi = self._slab(ol[:, 2:], dl[:, 2:], np.array([hz]))
            return np.maximum(rlo, zlo), np.minimum(rhi, zhi)
        r = s[0]
        return self._quadratic(np.einsum("ij,ij->i", dl, dl), 2 * np.einsum("ij,ij->i", ol, dl),
                               np.einsum("ij,ij->i", ol, ol) - r * r)

    def pad_hits(self, origins: np.ndarray, axes: np.ndarray, centre: np.ndarray, half: np.ndarray) -> np.ndarray:
        P, G = origins.shape[:2]
        o = origins.reshape(-1, 3)
        d = np.repeat(axes[:, :, 2], G, axis=0)
        t = np.full(len(o), np.inf)
        for part in self.parts:
            lo, hi = self._interval(part, o, d)
            hit = (lo <= hi) & (hi >= 0)
            t = np.where(hit, np.minimum(t, np.maximum(lo, 0.0)), t)
        return t.reshape(P, G)

    def inside(self, points: np.ndarray) -> np.ndarray:
        out = np.zeros(len(points), dtype=bool)
        for part in self.parts:
            q = (points - np.asarray(part.pos_m)) @ part.rotation
            s = part.size_m
            if part.kind == "box":
                out |= np.all(np.abs(q) <= np.asarray(s) / 2, axis=1)
            elif part.kind == "cylinder":
                out |= (q[:, 0] ** 2 + q[:, 1] ** 2 <= s[0] ** 2) & (np.abs(q[:, 2]) <= s[1] / 2)
            else:
                out |= np.einsum("ij,ij->i", q, q) <= s[0] ** 2
        return out


class _Mesh(_Surface):
    """A closed triangle mesh: rays against the triangles near them, winding-number containment."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        super().__init__(vertices, faces)
        e1, e2 = self.tri[:, 1] - self.tri[:, 0], self.tri[:, 2] - self.tri[:, 0]
        n = np.cross(e1, e2)
        volume = float(np.einsum("ij,ij->i", self.tri[:, 0], n).sum()) / 6.0
        if volume < 0:  # wound inside out: turn the normals outward
            n = -n
        self.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)  # outward

    def pad_hits(self, origins: np.ndarray, axes: np.ndarray, centre: np.ndarray, half: np.ndarray) -> np.ndarray:
        P, G = origins.shape[:2]
        t = np.full((P, G), np.inf)
        reach = np.abs(axes) @ half  # (P, 3): the boxes' half extents along the object's axes
        for start in range(0, P, 64):
            sl = slice(start, start + 64)
            c, r = centre[sl], reach[sl]
            near = np.all((self.tri_lo[None] <= (c + r)[:, None]) & (self.tri_hi[None] >= (c - r)[:, None]), axis=2)
            pp, ff = np.nonzero(near)
            # the triangles in each pad's own frame: keep those that meet its box
            local = np.matmul(self.tri[ff] - c[pp][:, None], axes[sl][pp])
            keep = np.all((local.min(axis=1) <= half) & (local.max(axis=1) >= -half), axis=1)
            pp, ff, local = pp[keep], ff[keep], local[keep]
            if len(pp) == 0:
                continue
            # each ray against the triangles whose bounds across the rays hold it
            ray_uv = np.matmul(origins[sl] - c[:, None], axes[sl][:, :, :2])  # (p, G, 2)
            lo, hi = local[:, :, :2].min(axis=1)[:, None] - 1e-9, local[:, :, :2].max(axis=1)[:, None] + 1e-9
            uv = ray_uv[pp]
            nn, gg = np.nonzero(np.all((uv >= lo) & (uv <= hi), axis=2))
            if len(nn) == 0:
                continue
            pk, f = pp[nn] + start, ff[nn]
            tt = _ray_triangle(origins[pk, gg], axes[pk, :, 2], self.tri[f, 0], self.tri[f, 1], self.tri[f, 2])
            np.minimum.at(t.reshape(-1), pk * G + gg, np.where(tt >= -1e-9, np.maximum(tt, 0.0), np.inf))
        return t

    def inside(self, points: np.ndarray) -> np.ndarray:
        out = np.zeros(len(points), dtype=bool)
        box = np.all((points >= self.bounds[0]) & (points <= self.bounds[1]), axis=1)
        if np.any(box):  # only the points within the bounds need the winding number
            out[box] = _winding(points[box], self.tri) > 0.5
        return out

    def first_entry(self, o: np.ndarray, d: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
        """Where each segment ``o + t d``, ``0 <= t <= length`` (M rays), first enters the material:
        ``(t (M,), triangle (M,))``, ``(inf, -1)`` if it does not."""
        t_best = np.full(len(o), np.inf)
        f_best = np.full(len(o), -1, dtype=np.int64)
        ends = o + length * d
        seg_lo, seg_hi = np.minimum(o, ends), np.maximum(o, ends)
        step = max(1, 2_000_000 // max(1, len(self.tri)))
        for s in range(0, len(o), step):
            lo, hi = seg_lo[s:s + step, None], seg_hi[s:s + step, None]
            near = np.all((self.tri_lo[None] <= hi) & (self.tri_hi[None] >= lo), axis=2)
            rr, ff = np.nonzero(near)
            rr = rr + s
            entering = np.einsum("ij,ij->i", d[rr], self.normals[ff]) < 0
            rr, ff = rr[entering], ff[entering]
            tt = _ray_triangle(o[rr], d[rr], self.tri[ff, 0], self.tri[ff, 1], self.tri[ff, 2])
            ok = (tt >= 0) & (tt <= length)
            rr, ff, tt = rr[ok], ff[ok], tt[ok]
            order = np.lexsort((tt, rr))
            rr, ff, tt = rr[order], ff[order], tt[order]
            first = np.ones(len(rr), dtype=bool)
            first[1:] = rr[1:] != rr[:-1]
            t_best[rr[first]], f_best[rr[first]] = tt[first], ff[first]
        return t_best, f_best

    def line_pairs(self, spacing: float, width: tuple[float, float], cos_max: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Antipodal pairs along a grid of lines (``spacing`` apart) parallel to each axis of the mesh's frame.

        Along a line, a pair is a point where it enters the material and a later one where it leaves, ``width``
        (min, max) apart, both normals within ``acos(cos_max)`` of the line. Returns ``(c1, c2, n1, n2)`` (N, 3
        each) as the sampled pairs: ``c1`` the exit (under the +y pad, closing along -line), inward normals.
        """
        lo, hi = self.bounds
        out: list[tuple[np.ndarray, ...]] = []
        for axis in range(3):
            a, b = (axis + 1) % 3, (axis + 2) % 3
            e = np.eye(3)[axis]
            cos_n = self.normals @ e
            useful = np.flatnonzero(np.abs(cos_n) >= cos_max)  # faces a pad along this axis could touch
            useful_all = np.flatnonzero(np.abs(cos_n) > 1e-12)  # every face a line along it crosses
            na = int(np.floor((hi[a] - lo[a]) / spacing)) + 1
            nb = int(np.floor((hi[b] - lo[b]) / spacing)) + 1
            # the grid cells each face's bounds cover
            ia0 = np.ceil((self.tri_lo[useful_all, a] - lo[a]) / spacing - 0.5).astype(int).clip(0, na)
            ia1 = np.floor((self.tri_hi[useful_all, a] - lo[a]) / spacing - 0.5).astype(int).clip(-1, na - 1)
            ib0 = np.ceil((self.tri_lo[useful_all, b] - lo[b]) / spacing - 0.5).astype(int).clip(0, nb)
            ib1 = np.floor((self.tri_hi[useful_all, b] - lo[b]) / spacing - 0.5).astype(int).clip(-1, nb - 1)
            ca, cb = np.maximum(ia1 - ia0 + 1, 0), np.maximum(ib1 - ib0 + 1, 0)
            count = ca * cb
            face = np.repeat(useful_all, count)
            k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
            cb_r = np.repeat(np.maximum(cb, 1), count)
            ia = np.repeat(ia0, count) + k // cb_r
            ib = np.repeat(ib0, count) + k % cb_r
            o = np.zeros((len(face), 3))
            o[:, a], o[:, b], o[:, axis] = lo[a] + (ia + 0.5) * spacing, lo[b] + (ib + 0.5) * spacing, lo[axis] - 1e-3
            t = _ray_triangle(o, np.broadcast_to(e, o.shape), self.tri[face, 0], self.tri[face, 1], self.tri[face, 2])
            hit = np.isfinite(t)
            line, t, face, points = (ia * nb + ib)[hit], t[hit], face[hit], o[hit]
            order = np.lexsort((t, line))
            line, t, face, points = line[order], t[order], face[order], points[order] + t[order, None] * e
            keep = np.ones(len(t), dtype=bool)
            keep[1:] = (line[1:] != line[:-1]) | (t[1:] - t[:-1] > 1e-7)  # one crossing per shared edge
            line, t, face, points = line[keep], t[keep], face[keep], points[keep]
            good = np.isin(face, useful)
            entering = cos_n[face] < 0
            first = np.searchsorted(line, np.unique(line))
            for s0, s1 in zip(first, np.append(first[1:], len(line)), strict=True):
                for i in range(s0, s1):
                    if not (entering[i] and good[i]):
                        continue
                    for j in range(i + 1, s1):
                        if t[j] - t[i] > width[1]:
                            break
                        if not entering[j] and good[j] and t[j] - t[i] >= width[0]:
                            out.append((points[j], points[i], -self.normals[face[j]], -self.normals[face[i]]))
        if not out:
            empty = np.zeros((0, 3))
            return empty, empty, empty, empty
        c1, c2, n1, n2 = (np.array(v) for v in zip(*out, strict=True))
        return c1, c2, n1, n2

    def exits(self, o: np.ndarray, d: np.ndarray, t_max: float, *, entries: bool = False
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where each ray (M) leaves the material within ``t_max`` (or enters it, with ``entries``): ``(ray,
        distance, triangle)`` arrays, sorted by ray then distance (one hit where a ray crosses an edge shared by two
        triangles)."""
        ends = o + t_max * d
        seg_lo, seg_hi = np.minimum(o, ends), np.maximum(o, ends)
        out_r, out_t, out_f = [], [], []
        step = max(1, 2_000_000 // max(1, len(self.tri)))
        for s in range(0, len(o), step):
            lo, hi = seg_lo[s:s + step, None], seg_hi[s:s + step, None]
            rr, ff = np.nonzero(np.all((self.tri_lo[None] <= hi) & (self.tri_hi[None] >= lo), axis=2))
            rr = rr + s
            facing = np.einsum("ij,ij->i", d[rr], self.normals[ff])
            leaving = facing < 0 if entries else facing > 0
            rr, ff = rr[leaving], ff[leaving]
            tt = _ray_triangle(o[rr], d[rr], self.tri[ff, 0], self.tri[ff, 1], self.tri[ff, 2])
            ok = (tt > 1e-6) & (tt <= t_max)
            out_r.append(rr[ok])
            out_t.append(tt[ok])
            out_f.append(ff[ok])
        r, t, f = np.concatenate(out_r), np.concatenate(out_t), np.concatenate(out_f)
        order = np.lexsort((t, r))
        r, t, f = r[order], t[order], f[order]
        new = np.ones(len(r), dtype=bool)
        new[1:] = (r[1:] != r[:-1]) | (t[1:] - t[:-1] > 1e-7)
        return r[new], t[new], f[new]


# --------------------------------------------------------------------------- #
# pair generation
# --------------------------------------------------------------------------- #


@dataclass
class _Raw:
    """Grasps before the filters, as arrays (N, ...)."""

    R: list[np.ndarray]
    mid: list[np.ndarray]
    width: list[float]
    c1: list[np.ndarray]
    c2: list[np.ndarray]
    n1: list[np.ndarray]
    n2: list[np.ndarray]
    feature: list[FeatureKind]
    part: list[int]

    @classmethod
    def empty(cls) -> _Raw:
        return cls([], [], [], [], [], [], [], [], [])

    def add(self, R: np.ndarray, mid: np.ndarray, width: float, c1: np.ndarray, c2: np.ndarray, n1: np.ndarray,
            n2: np.ndarray, feature: FeatureKind, part: int) -> None:
        self.R.append(R)
        self.mid.append(mid)
        self.width.append(width)
        self.c1.append(c1)
        self.c2.append(c2)
        self.n1.append(n1)
        self.n2.append(n2)
        self.feature.append(feature)
        self.part.append(part)

    def __len__(self) -> int:
        return len(self.width)


def _frame(closing: np.ndarray, approach: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) with y along ``closing``, z along ``approach`` (perpendicular unit vectors)."""
    return np.column_stack([np.cross(closing, approach), closing, approach])


def _approaches(closing: np.ndarray) -> list[np.ndarray]:
    """Approach directions perpendicular to a unit closing axis (see ``APPROACH_TILTS_RAD``)."""
    down = np.array([0.0, 0.0, -1.0])
    u = down - (down @ closing) * closing
    if np.linalg.norm(u) < 1e-9:  # a vertical closing axis: horizontal approaches
        phis = 2.0 * math.pi * np.arange(HORIZONTAL_STEPS) / HORIZONTAL_STEPS
        return [np.array([math.cos(p), math.sin(p), 0.0]) for p in phis]
    u /= np.linalg.norm(u)
    v = np.cross(closing, u)
    return [math.cos(a) * u + math.sin(a) * v for a in APPROACH_TILTS_RAD]


def _centred(half_range: float, step: float) -> np.ndarray:
    """0, +-step, +-2 step, ... within +-half_range (empty if half_range < 0)."""
    if half_range < -1e-12:
        return np.zeros(0)
    n = math.floor(half_range / step + 1e-9)
    k = np.arange(-n, n + 1, dtype=float)
    return k[np.argsort(np.abs(k) + 0.1 * (k < 0), kind="stable")] * step


def _perp_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (u, v) perpendicular to ``axis``; u horizontal unless the axis is vertical (then along x)."""
    u = np.cross(axis, np.array([0.0, 0.0, 1.0]))
    if np.linalg.norm(u) < 1e-9:
        u = np.array([1.0, 0.0, 0.0]) - axis[0] * axis
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


class _Generator:
    """Generates the grasps of each primitive (see the module docstring)."""

    def __init__(self, hand: _Hand, width_range: tuple[float, float], spacing_m: float, z_rest_m: float) -> None:
        self.hand = hand
        self.w_lo, self.w_hi = width_range
        self.spacing = spacing_m
        self.z_target = z_rest_m + TABLE_GAP_M + 1e-4  # the gripper's lowest point at a table-clear grasp
        self.raw = _Raw.empty()

    def fits(self, width: float) -> bool:
        return self.w_lo - _WIDTH_TOL_M <= width <= self.w_hi + _WIDTH_TOL_M

    def _lowest(self, R: np.ndarray, width: float) -> float:
        """Lowest z of the gripper (no inflation, no approach sweep) relative to the pads' centre point."""
        lo, hi = self.hand.boxes(np.array([width]), np.zeros((1, 2)), 0.0, 0.0, 0.0)
        pc = self.hand.pad_centre
        corners = _corners(lo[0], hi[0]).reshape(-1, 3) - np.array([pc[0], 0.0, pc[1]])
        return float(np.min(corners @ R[2]))

    def _table_clear(self, base: np.ndarray, dirs: Sequence[np.ndarray], R: np.ndarray, width: float
                     ) -> np.ndarray | None:
        """The point nearest ``base``, moving along ``dirs``, where the gripper clears the resting plane."""
        up = sum(((d @ np.array([0.0, 0.0, 1.0])) * d for d in dirs), np.zeros(3))
        up2 = float(up @ up)
        if up2 < 1e-9:
            return None
        need = self.z_target - (base[2] + self._lowest(R, width))
        return base + need * up / up2 if need > 0 else None

    def _add(self, R: np.ndarray, mid: np.ndarray, width: float, feature: FeatureKind, part: int) -> None:
        y = R[:, 1]
        self.raw.add(R, mid, width, mid + width / 2 * y, mid - width / 2 * y, -y, y, feature, part)

    def planar(self, centre: np.ndarray, closing: np.ndarray, width: float, e1: np.ndarray, e2: np.ndarray,
               inside: Callable[[float, float], bool], half1: float, half2: float, feature: FeatureKind,
               part: int) -> None:
        """Two parallel flat faces: the pads' centre on a grid over the face (coordinates along e1, e2)."""
        grid = [(a, b) for a in _centred(half1, self.spacing) for b in _centred(half2, self.spacing) if inside(a, b)]
        for approach in _approaches(closing):
            R = _frame(closing, approach)
            points = [(a, b) for a, b in grid]
            low = self._table_clear(centre, (e1, e2), R, width)
            if low is not None:
                a, b = float((low - centre) @ e1), float((low - centre) @ e2)
                if inside(a, b):
                    points.append((a, b))
            for a, b in points:
                self._add(R, centre + a * e1 + b * e2, width, feature, part)

    def box(self, part: Part, index: int) -> None:
        R, c, h = part.rotation, np.asarray(part.pos_m), np.asarray(part.size_m) / 2
        inset = EDGE_MARGIN_M + _GRID_INSET_M
        for i in range(3):
            if not self.fits(2 * h[i]):
                continue
            j, k = (i + 1) % 3, (i + 2) % 3
            hj, hk = h[j] - inset, h[k] - inset

            def inside(a: float, b: float, hj: float = hj, hk: float = hk) -> bool:
                return abs(a) <= hj + 1e-12 and abs(b) <= hk + 1e-12

            self.planar(c, R[:, i], 2 * h[i], R[:, j], R[:, k], inside, hj, hk, FeatureKind.BOX_FACES, index)

    def cylinder(self, part: Part, index: int) -> None:
        R, c = part.rotation, np.asarray(part.pos_m)
        r, hz = part.size_m[0], part.size_m[1] / 2
        axis = R[:, 2]
        u, v = _perp_basis(axis)
        inset = EDGE_MARGIN_M + _GRID_INSET_M
        if self.fits(2 * r):  # across the diameter, at heights along the axis
            heights = list(_centred(hz - inset, self.spacing))
            for beta in math.pi * np.arange(AXIS_STEPS) / AXIS_STEPS:
                closing = math.cos(beta) * u + math.sin(beta) * v
                for approach in _approaches(closing):
                    Rg = _frame(closing, approach)
                    ts = list(heights)
                    low = self._table_clear(c, (axis,), Rg, 2 * r)
                    if low is not None and abs(float((low - c) @ axis)) <= hz - inset + 1e-12:
                        ts.append(float((low - c) @ axis))
                    for t in ts:
                        self._add(Rg, c + t * axis, 2 * r, FeatureKind.CYLINDER_SIDE, index)
        if self.fits(2 * hz):  # across the length, on the end caps
            rr = r - inset

            def inside(a: float, b: float) -> bool:
                return a * a + b * b <= rr * rr + 1e-12

            self.planar(c, axis, 2 * hz, u, v, inside, rr, rr, FeatureKind.CYLINDER_CAPS, index)

    def sphere(self, part: Part, index: int) -> None:
        c, r = np.asarray(part.pos_m), part.size_m[0]
        if not self.fits(2 * r):
            return
        for elev in SPHERE_ELEVATIONS_RAD:
            if elev > math.pi / 2 - 1e-9:
                azimuths = [0.0]
            else:
                turn = math.pi if elev < 1e-9 else 2 * math.pi  # a horizontal axis: its other half is the flip
                azimuths = list(np.arange(0.0, turn - 1e-9, math.radians(30.0)))
            for az in azimuths:
                closing = np.array([math.cos(elev) * math.cos(az), math.cos(elev) * math.sin(az), math.sin(elev)])
                for approach in _approaches(closing):
                    self._add(_frame(closing, approach), c, 2 * r, FeatureKind.SPHERE, index)

    def sampled(self, mesh: _Mesh, samples: int, seed: int, mu: float) -> None:
        """Antipodal pairs from points sampled on the mesh (see the module docstring)."""
        import trimesh

        tm = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
        points, face_idx = trimesh.sample.sample_surface(tm, samples, seed=seed)
        points = np.asarray(points, dtype=float)
        inward = -mesh.normals[np.asarray(face_idx)]
        # rays along the inward normal; tilted from it by half the friction cone, four ways; and along the
        # object's axes within the cone (a mirror-symmetric shape is usually modelled square to them, and its
        # pinches across a rounded ridge, like a handle's sides, lie exactly along one)
        cone = math.atan(mu)
        cos_cone = math.cos(cone)
        u, v = np.array([_perp_basis(n) for n in inward]).transpose(1, 0, 2)
        dirs = [inward] + [math.cos(cone / 2) * inward + math.sin(cone / 2) * (math.cos(a) * u + math.sin(a) * v)
                           for a in (0.0, math.pi / 2, math.pi, 3 * math.pi / 2)]
        sample = [np.arange(len(points))] * len(dirs)
        for axis in np.vstack([np.eye(3), -np.eye(3)]):
            within = np.flatnonzero(inward @ axis >= cos_cone)
            dirs.append(np.broadcast_to(axis, (len(within), 3)))
            sample.append(within)
        which = np.concatenate(sample)
        starts, d = points[which], np.concatenate(dirs)
        starts_n = inward[which]
        ray, t, f = mesh.exits(starts - 1e-7 * d, d, self.w_hi + 1e-6)
        ok = (t >= self.w_lo - _WIDTH_TOL_M) & (np.einsum("ij,ij->i", d[ray], mesh.normals[f]) >= cos_cone - 1e-12)
        ray, t, f = ray[ok], t[ok], f[ok]
        if len(ray) == 0:
            ray = t = f = np.zeros(0, dtype=np.int64)
        # the first contact is under the +y pad: the closing axis y is -d; inward normals: at p (the sample's
        # face), at q (the face it leaves by)
        c1, c2 = starts[ray], starts[ray] + t[:, None] * d[ray]
        n1, n2 = starts_n[ray], -mesh.normals[f]
        r1, r2, rn1, rn2 = _refine_pairs(mesh, c1, c2, n1, n2)
        # and the pairs along a grid of lines parallel to each of the object's axes: a pinch of a narrow feature
        # (a rounded ridge, like a handle's sides) is found wherever the grid crosses it, not only where a random
        # sample happens to land
        g1, g2, gn1, gn2 = mesh.line_pairs(_LINE_SPACING_M, (self.w_lo - _WIDTH_TOL_M, self.w_hi + _WIDTH_TOL_M),
                                           _COS_FLAT_PAD)
        c1, c2 = np.concatenate([c1, r1, g1]), np.concatenate([c2, r2, g2])
        n1, n2 = np.concatenate([n1, rn1, gn1]), np.concatenate([n2, rn2, gn2])
        axis = c1 - c2
        width = np.linalg.norm(axis, axis=1)
        axis = axis / np.maximum(width, 1e-12)[:, None]
        align = np.minimum(-np.einsum("ij,ij->i", n1, axis), np.einsum("ij,ij->i", n2, axis))
        ok = (width >= self.w_lo - _WIDTH_TOL_M) & (width <= self.w_hi + _WIDTH_TOL_M)
        ok &= align >= max(cos_cone, _COS_FLAT_PAD) - 1e-12
        flip = axis[np.arange(len(axis)), np.argmax(np.abs(axis), axis=1)] < 0  # the same pair from either side
        c1, c2, n1, n2 = np.where(flip[:, None], c2, c1), np.where(flip[:, None], c1, c2), \
            np.where(flip[:, None], n2, n1), np.where(flip[:, None], n1, n2)
        axis = np.where(flip[:, None], -axis, axis)
        # one pair per cell of half the position spacing and per 10 degrees of axis: the best aligned one
        mid = (c1 + c2) / 2
        cell = np.hstack([np.floor(mid / (self.spacing / 2)), np.round(axis / _PAIR_DEDUP_RAD)]).astype(np.int64)
        seen: set[tuple[int, ...]] = set()
        for i in np.flatnonzero(ok)[np.argsort(-align[ok], kind="stable")]:
            key = tuple(cell[i])
            if key in seen:
                continue
            seen.add(key)
            for approach in _approaches(axis[i]):
                self.raw.add(_frame(axis[i], approach), mid[i], float(width[i]), c1[i], c2[i], n1[i], n2[i],
                             FeatureKind.SAMPLED, -1)


def _refine_pairs(mesh: _Mesh, c1: np.ndarray, c2: np.ndarray, n1: np.ndarray, n2: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Close the jaws on each sampled pair (N, 3 each) along the bisector of its two normals: each contact
    becomes the first point of the surface its pad meets coming from outside (``_REFINE_REACH_M`` beyond it).

    Repeated ``_REFINE_STEPS`` times, a pair settles where both normals lie along the closing line (the flat
    pads' contacts: across a round handle, the section's two extreme points). A pair whose contact moves more
    than ``_REFINE_MAX_MOVE_M`` (it jumped to another feature) keeps its sampled contacts.
    """
    a1, a2, m1, m2 = c1.copy(), c2.copy(), n1.copy(), n2.copy()
    alive = np.ones(len(c1), dtype=bool)
    for _ in range(_REFINE_STEPS):
        y = m2 - m1
        y /= np.maximum(np.linalg.norm(y, axis=1, keepdims=True), 1e-12)
        mid = (a1 + a2) / 2
        half = np.abs(np.einsum("ij,ij->i", a1 - a2, y)) / 2
        reach = half + _REFINE_REACH_M
        o1, o2 = mid + reach[:, None] * y, mid - reach[:, None] * y
        t1, f1 = mesh.first_entry(o1, -y, 2 * _REFINE_REACH_M)
        t2, f2 = mesh.first_entry(o2, y, 2 * _REFINE_REACH_M)
        ok = alive & np.isfinite(t1) & np.isfinite(t2)
        alive &= ok
        a1 = np.where(ok[:, None], o1 - np.where(ok, t1, 0.0)[:, None] * y, a1)
        a2 = np.where(ok[:, None], o2 + np.where(ok, t2, 0.0)[:, None] * y, a2)
        m1 = np.where(ok[:, None], -mesh.normals[np.maximum(f1, 0)], m1)
        m2 = np.where(ok[:, None], -mesh.normals[np.maximum(f2, 0)], m2)
    moved = np.maximum(np.linalg.norm(a1 - c1, axis=1), np.linalg.norm(a2 - c2, axis=1)) > _REFINE_MAX_MOVE_M
    keep = alive & ~moved
    # a refined pair's contacts lie on one line along the bisector; an unrefined one keeps its sampled line
    return (np.where(keep[:, None], a1, c1), np.where(keep[:, None], a2, c2), np.where(keep[:, None], m1, n1),
            np.where(keep[:, None], m2, n2))


# --------------------------------------------------------------------------- #
# synthesis
# --------------------------------------------------------------------------- #


def centre_of_mass(geo: Geometry) -> np.ndarray:
    """Centre of mass (3,) at uniform density in the resting frame (m): the primitives' volume-weighted centre,
    or the mesh's (trimesh ``center_mass``)."""
    if geo.primitives:
        vols = np.array([p.volume_m3 for p in geo.primitives])
        centres = np.array([p.pos_m for p in geo.primitives], dtype=float)
        return vols @ centres / vols.sum()
    import trimesh

    mesh = trimesh.Trimesh(vertices=np.asarray(geo.vertices), faces=np.asarray(geo.faces), process=False)
    return np.asarray(mesh.center_mass, dtype=float)


def approach_kind(approach: np.ndarray) -> tuple[ApproachKind, float]:
    """The kind of an approach direction (unit (3,), resting frame) and its tilt from straight down (rad)."""
    a = np.asarray(approach, dtype=float)
    tilt = math.acos(float(np.clip(-a[2], -1.0, 1.0)))
    if tilt <= TOP_MAX_TILT_RAD + 1e-9:
        return ApproachKind.TOP, tilt
    if abs(a[2]) <= math.sin(SIDE_MAX_ELEVATION_RAD) + 1e-9:
        return ApproachKind.SIDE, tilt
    return ApproachKind.TILTED, tilt


def _check_positive(name: str, value: float, *, zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(name, value, "must be a number") from None
    if isinstance(value, bool) or not math.isfinite(v) or v < 0 or (v == 0 and not zero):
        raise ConfigError(name, value, "must be a finite number " + (">= 0" if zero else "> 0") + " (m)")
    return v


def synthesize(
    obj: ObjectConfig,
    gripper: GripperGeometry,
    *,
    samples: int = 300,
    seed: int = 0,
    spacing_m: float = 0.020,
    approach_distance_m: float = CLEARANCE_M,
    clearance_m: float = SWEEP_CLEARANCE_M,
    min_width_m: float = MIN_GRIP_WIDTH_M,
    max_width_m: float = MAX_GRIP_WIDTH_M,
    geometry: Geometry | None = None,
) -> tuple[GraspCandidate, ...]:
    """Grasp candidates of ``obj`` from its geometry, in its resting frame (unranked: see :func:`rank`).

    Args:
        obj: The object (its shape, ``friction`` and ``torsional_friction_m`` are used).
        gripper: The gripper's measured geometry.
        samples: Points sampled on a mesh's surface (primitives are enumerated, not sampled).
        seed: Seed of the mesh sampling: the same seed gives the same candidates.
        spacing_m: Step of the pad positions over a face or along a cylinder (m).
        approach_distance_m: Length of the straight approach checked for collisions, pregrasp to grasp (m).
        clearance_m: Clearance of the gripper's boxes from the object on the way in and while closing (m).
        min_width_m: Narrowest width taken (m). The default, ``MIN_GRIP_WIDTH_M``, leaves the closing fingers
            3 mm of servo error per side, i.e. 15 N of squeeze; narrower widths are squeezed less (5000 N/m times
            the error: 2.5 N at 5 mm). At least the closed gripper's width.
        max_width_m: Widest width taken (m). The default, ``MAX_GRIP_WIDTH_M``, is the open width less 5 mm per
            side; at most that.
        geometry: The object's shape if the caller has it (e.g. a mesh from perception); default
            ``obj.geometry()``. A geometry without primitives is treated as a mesh.

    Returns:
        The candidates that pass every filter of the module docstring, without exact duplicates, in a
        deterministic order (by primitive, pair, approach, position; each followed by its 180-degree flip).

    Raises:
        ConfigError: a bad argument.
    """
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ConfigError("samples", samples, "must be an integer >= 1")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ConfigError("seed", seed, "must be an integer")
    spacing_m = _check_positive("spacing_m", spacing_m)
    approach_distance_m = _check_positive("approach_distance_m", approach_distance_m, zero=True)
    clearance_m = _check_positive("clearance_m", clearance_m, zero=True)
    if not isinstance(obj, ObjectConfig):
        raise ConfigError("obj", obj, "must be an ObjectConfig")
    started = time.perf_counter()
    geo = geometry if geometry is not None else obj.geometry()
    hand = _Hand.of(gripper)
    w_lo = _check_positive("min_width_m", min_width_m)
    w_hi = _check_positive("max_width_m", max_width_m)
    if w_lo < 2 * gripper.closed_inner_face_y_m - 1e-12:
        raise ConfigError("min_width_m", min_width_m, f">= {2 * gripper.closed_inner_face_y_m:g} m, the closed width")
    if w_hi > gripper.open_width_m - 2 * 0.005 + 1e-12 or w_hi < w_lo:
        raise ConfigError("max_width_m", max_width_m,
                          f"between min_width_m and {gripper.open_width_m - 0.010:g} m (the open width less 5 mm per "
                          "side)")
    com = centre_of_mass(geo)
    scale = 0.5 * float(np.max(np.asarray(geo.bounds_m[1]) - np.asarray(geo.bounds_m[0])))
    mu, gamma = obj.friction, obj.torsional_friction_m
    if gamma <= 0.0:
        log.warning("%s: torsional_friction_m is 0: two pad contacts are never in force closure", obj.name)

    gen = _Generator(hand, (w_lo, w_hi), spacing_m, float(geo.z_min_m))
    surface: _Surface
    if geo.primitives:
        surface = _Primitives(geo.primitives, geo)
        for index, part in enumerate(geo.primitives):
            getattr(gen, part.kind)(part, index)
    else:
        mesh = _Mesh(geo.vertices, geo.faces)
        surface = mesh
        gen.sampled(mesh, int(samples), int(seed), mu)
    raw = gen.raw
    n_raw = len(raw)
    if n_raw == 0:
        log.info("%s: no pair of surfaces fits the stroke (%.0f-%.0f mm)", obj.name, w_lo * 1e3, w_hi * 1e3)
        return ()

    R = np.array(raw.R)
    mid = np.array(raw.mid)
    width = np.array(raw.width)
    c1, c2, n1, n2a = np.array(raw.c1), np.array(raw.c2), np.array(raw.n1), np.array(raw.n2)
    if not hand.flip_symmetric:  # evaluate the flipped grasps on their own
        flip = np.diag([-1.0, -1.0, 1.0])
        R = np.concatenate([R, R @ flip])
        mid, width = np.concatenate([mid, mid]), np.concatenate([width, width])
        c1, c2 = np.concatenate([c1, c2]), np.concatenate([c2, c1])
        n1, n2a = np.concatenate([n1, n2a]), np.concatenate([n2a, n1])
        raw.feature, raw.part = raw.feature * 2, raw.part * 2

    keep = np.ones(len(width), dtype=bool)
    pc = hand.pad_centre
    tcp = mid - R @ np.array([pc[0], 0.0, pc[1]])
    # a first, optimistic pass of the box tests (the pads stopping as early as the support test allows), so that
    # only the grasps that may be clear go through the rays of the support test
    idx = np.flatnonzero(keep)
    if len(idx):
        early = np.full((len(idx), 2), MAX_PROTRUSION_M)
        lo, hi = hand.boxes(width[idx], early, approach_distance_m, clearance_m, CLOSING_STOP_M)
        keep[idx] &= ~surface.boxes_hit(R[idx], tcp[idx], lo, hi)
    n_early = int(keep.sum())

    # the pads' support
    touch = np.zeros((len(width), 2))
    support = np.zeros(len(width))
    idx = np.flatnonzero(keep)
    if len(idx):
        ok, tch, sup, failed = _pad_support(surface, hand, R[idx], tcp[idx], width[idx], c1[idx], c2[idx])
        log.debug("%s: pad support rules failed by %s grasps", obj.name, failed)
        keep[idx] &= ok
        touch[idx], support[idx] = tch, sup
    n_support = int(keep.sum())

    # the gripper's boxes on the way in and while closing
    idx = np.flatnonzero(keep)
    if len(idx):
        lo, hi = hand.boxes(width[idx], touch[idx], approach_distance_m, clearance_m, CLOSING_STOP_M)
        hit = surface.boxes_hit(R[idx], tcp[idx], lo, hi)
        open_pads = np.stack([tcp[idx] + R[idx] @ np.array([pc[0], s * hand.open_face_m, pc[1]]) for s in (1, -1)],
                             axis=1)
        buried = surface.inside(open_pads.reshape(-1, 3)).reshape(-1, 2).any(axis=1)
        keep[idx] &= ~hit & ~buried
    n_clear = int(keep.sum())

    # force closure, once per pair of contacts (last: the costliest test per pair, on the fewest)
    margin = np.zeros(len(width))
    cache: dict[tuple[float, ...], float] = {}
    for i in np.flatnonzero(keep):
        key = tuple(np.round(np.concatenate([c1[i], c2[i], n1[i], n2a[i]]), 9))
        if key not in cache:
            contacts = [Contact(c1[i], n1[i], mu, gamma), Contact(c2[i], n2a[i], mu, gamma)]
            res = analyze_grasp(contacts, com, scale)
            cache[key] = res.margin if res.force_closure else 0.0
        margin[i] = cache[key]
    keep &= margin > CLOSURE_TOL
    n_closure = int(keep.sum())

    out: list[GraspCandidate] = []
    seen: set[tuple[int, ...]] = set()
    flip = np.diag([-1.0, -1.0, 1.0])
    for i in np.flatnonzero(keep):
        variants = [(R[i], c1[i], c2[i], n1[i], n2a[i], (float(touch[i, 0]), float(touch[i, 1])))]
        if hand.flip_symmetric:
            variants.append((R[i] @ flip, c2[i], c1[i], n2a[i], n1[i], (float(touch[i, 1]), float(touch[i, 0]))))
        for Rv, a1, a2, m1, m2, tv in variants:
            t = mid[i] - Rv @ np.array([pc[0], 0.0, pc[1]])
            key = (*np.round(t * 1e6).astype(int), *np.round(Rv.ravel() * 1e6).astype(int))
            if key in seen:
                continue
            seen.add(key)
            kind, tilt = approach_kind(Rv[:, 2])
            axis = a1 - a2
            axis /= np.linalg.norm(axis)
            r = com - a2
            out.append(GraspCandidate(
                T_object_tcp=pin.SE3(Rv.copy(), t.copy()), width_m=float(width[i]),
                contacts_m=np.array([a1, a2]), normals=np.array([m1, m2]), approach=kind, tilt_rad=tilt,
                margin=float(margin[i]), com_offset_m=float(np.linalg.norm(r - (r @ axis) * axis)),
                scale_m=scale, support=float(support[i]), feature=raw.feature[i], part=int(raw.part[i]), touch_m=tv))
    log.debug("%s: %d grasps generated, %d not blocked, %d supported, %d clear, %d in force closure -> %d candidates "
              "in %.3f s", obj.name, n_raw, n_early, n_support, n_clear, n_closure, len(out),
              time.perf_counter() - started)
    return tuple(out)


def _pad_grid(hand: _Hand) -> tuple[np.ndarray, int, np.ndarray]:
    """Offsets (G, 2) in the pad's (x, z) from its centre: the grid, then the centre, then the edge probes."""
    hx, hz = hand.pad_half
    gx, gz = np.meshgrid(np.linspace(-hx, hx, _PAD_GRID), np.linspace(-hz, hz, _PAD_GRID), indexing="ij")
    grid = np.column_stack([gx.ravel(), gz.ravel()])
    ang = 2 * math.pi * np.arange(8) / 8
    probes = EDGE_MARGIN_M * np.column_stack([np.cos(ang), np.sin(ang)])
    offsets = np.vstack([grid, [[0.0, 0.0]], probes])
    return offsets, len(grid), grid


def _pad_support(surface: _Surface, hand: _Hand, R: np.ndarray, tcp: np.ndarray, width: np.ndarray,
                 c1: np.ndarray, c2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """The pad-support filter (module docstring, 3) of K grasps.

    Returns:
        ``(ok (K,), touch (K, 2), support (K,), failed)``: whether both pads pass; how far proud of the contact
        plane each pad first touches (m); the lesser fraction of a pad's face that touches; how many grasps
        fail each rule (``centre``, ``edge``, ``protrusion``, ``span``, ``centroid``; a grasp may fail several).
    """
    offsets, n_grid, grid = _pad_grid(hand)
    pc = hand.pad_centre
    k, g = len(width), len(offsets)
    ok = np.ones(k, dtype=bool)
    touch = np.zeros((k, 2))
    frac = np.ones(k)
    hx, hz = hand.pad_half
    fails = {name: np.zeros(k, dtype=bool) for name in ("centre", "edge", "protrusion", "span", "centroid")}
    pair_dist = np.linalg.norm(grid[:, None] - grid[None], axis=2)  # (n_grid, n_grid)
    for side, contact in ((0, c1), (1, c2)):
        s = 1.0 if side == 0 else -1.0
        local = np.zeros((g, 3))
        local[:, 0] = pc[0] + offsets[:, 0]
        local[:, 1] = s * hand.open_face_m
        local[:, 2] = pc[1] + offsets[:, 1]
        origins = tcp[:, None, :] + np.einsum("kij,gj->kgi", R, local)
        axes = np.stack([R[:, :, 0], R[:, :, 2], -s * R[:, :, 1]], axis=2)
        # where the hits that matter lie: the pad's footprint, within a few mm of the contact plane
        band = MAX_PROTRUSION_M + EDGE_DROP_M + SUPPORT_GAP_M
        t = surface.pad_hits(origins, axes, contact,
                             np.array([hx + 1e-4, hz + 1e-4, band]))
        proud = (hand.open_face_m - width / 2)[:, None] - t  # > 0: in front of the contact plane
        centre = proud[:, n_grid]
        probes = proud[:, n_grid + 1:]
        first = np.max(proud[:, :n_grid + 1], axis=1)
        patch = proud[:, :n_grid] >= (first - SUPPORT_GAP_M)[:, None]
        count = patch.sum(axis=1)
        centroid = (patch[:, :, None] * grid[None]).sum(axis=1) / np.maximum(count, 1)[:, None]
        fails["centre"] |= np.abs(centre) > CONTACT_TOL_M
        span = np.max(np.where(patch[:, :, None] & patch[:, None, :], pair_dist[None], 0.0), axis=(1, 2))
        fails["edge"] |= np.any(np.abs(probes) > EDGE_DROP_M, axis=1)
        fails["protrusion"] |= first > MAX_PROTRUSION_M
        fails["span"] |= span < MIN_PATCH_SPAN_M - 1e-9
        fails["centroid"] |= (np.abs(centroid[:, 0]) > hx / 2 + 1e-9) | (np.abs(centroid[:, 1]) > hz / 2 + 1e-9)
        touch[:, side] = np.maximum(first, 0.0)
        frac = np.minimum(frac, count / n_grid)
    for f in fails.values():
        ok &= ~f
    return ok, touch, frac, {name: int(f.sum()) for name, f in fails.items()}


# --------------------------------------------------------------------------- #
# ranking
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class RankWeights:
    """Weights of the ranking cost (lower cost first); every term is dimensionless.

    ``cost = - margin * margin_weight
             + com_offset * (com_offset_m / scale_m)
             + approach * step            (step: 0 top, 1 tilted, 2 side)
             + touch_lag * lag_mm         (how much sooner one pad meets the object than the other, mm)
             + orientation * angle_rad    (angle from the caller's reference tcp orientation, if given)
             + extra * extra_cost         (the caller's per-candidate cost, e.g. joint-space distance in rad)``

    Attributes:
        margin: Per unit of Ferrari–Canny margin (typically 0.05-0.3 for two soft-finger pads).
        com_offset: Per object's characteristic length (half its largest extent) of centre-of-mass offset from
            the grip axis: the weight makes a torque about the grip axis that torsional friction must hold.
        approach: Per step from top-down to tilted to side: a tie-breaker (top-down keeps the arm above the
            object and the fingers out of the table's way).
        touch_lag: Per millimetre by which one pad meets the object before the other (``GraspCandidate.touch_lag_m``):
            the first pushes it alone, with up to the servo's 20 N, and jolts the arm holding still (to 3-4.7 times a
            wrist's acceleration limit, pinching a mug's handle planned on its bar's flank, 2.6 mm in front of the
            other pad's contact). A grasp whose pads meet the object together is taken before one that does not
            (unless its force-closure margin is a millimetre's worth better).
        orientation: Per radian between the candidate's tcp orientation and the caller's reference.
        extra: Per unit of the caller's extra cost.
    """

    margin: float = 1.0
    com_offset: float = 0.1
    approach: float = 0.02
    orientation: float = 0.05
    extra: float = 1.0
    touch_lag: float = 1.0

    def __post_init__(self) -> None:
        for name in ("margin", "com_offset", "approach", "orientation", "extra", "touch_lag"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"rank_weights.{name}", v, "must be a finite number >= 0")


ExtraCost = Sequence[float] | np.ndarray | Callable[[GraspCandidate], float]


def costs(
    candidates: Sequence[GraspCandidate],
    weights: RankWeights | None = None,
    *,
    reference: pin.SE3 | np.ndarray | None = None,
    extra_cost: ExtraCost | None = None,
) -> np.ndarray:
    """The ranking cost (N,) of each candidate (see :class:`RankWeights`; lower is better).

    Args:
        candidates: The candidates.
        weights: The weights (default :class:`RankWeights`).
        reference: A tcp orientation in the object's frame to stay close to (3, 3), or a pose whose rotation is
            used (e.g. the wrist's current tcp orientation expressed in the object's frame).
        extra_cost: Per-candidate extra cost: an array (N,) aligned with ``candidates`` or a function of a
            candidate (e.g. the joint-space distance of its IK solution from the current configuration).

    Raises:
        ConfigError: ``extra_cost`` of the wrong length or not finite, or a bad ``reference``.
    """
    w = weights if weights is not None else RankWeights()
    n = len(candidates)
    margin = np.array([c.margin for c in candidates], dtype=float)
    com = np.array([c.com_offset_m / c.scale_m for c in candidates], dtype=float)
    step = np.array([_APPROACH_RANK[c.approach] for c in candidates], dtype=float)
    lag_mm = np.array([c.touch_lag_m * 1e3 for c in candidates], dtype=float)
    cost = -w.margin * margin + w.com_offset * com + w.approach * step + w.touch_lag * lag_mm
    if reference is not None:
        Rref = np.asarray(reference.rotation if isinstance(reference, pin.SE3) else reference, dtype=float)
        if Rref.shape != (3, 3) or not np.allclose(Rref.T @ Rref, np.eye(3), atol=1e-6):
            raise ConfigError("reference", Rref.shape, "must be a rotation (3, 3) or a pin.SE3")
        angle = np.array([np.linalg.norm(pin.log3(Rref.T @ c.T_object_tcp.rotation)) for c in candidates])
        cost = cost + w.orientation * angle
    if extra_cost is not None:
        if callable(extra_cost):
            extra = np.array([float(extra_cost(c)) for c in candidates], dtype=float)
        else:
            extra = np.asarray(extra_cost, dtype=float).reshape(-1)
        if extra.shape != (n,) or not np.all(np.isfinite(extra)):
            raise ConfigError("extra_cost", extra.shape, f"must give one finite cost per candidate ({n})")
        cost = cost + w.extra * extra
    return cost.reshape(n)


def rank(
    candidates: Sequence[GraspCandidate],
    weights: RankWeights | None = None,
    *,
    reference: pin.SE3 | np.ndarray | None = None,
    extra_cost: ExtraCost | None = None,
) -> tuple[GraspCandidate, ...]:
    """The candidates sorted by :func:`costs`, lowest first (ties keep their order)."""
    c = costs(candidates, weights, reference=reference, extra_cost=extra_cost)
    return tuple(candidates[i] for i in np.argsort(c, kind="stable"))


# --------------------------------------------------------------------------- #
# into the world
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class WorldCandidate:
    """A candidate placed in the world, clear of the table.

    Attributes:
        candidate: The candidate (object frame).
        T_world_tcp: The tcp at the grasp.
        T_world_pregrasp: The tcp backed off along the approach (the start of the straight approach).
        lowest_z_m: Lowest point of the gripper (pads, fingers, palm) from the pregrasp to the closed grasp (m).
    """

    candidate: GraspCandidate
    T_world_tcp: pin.SE3
    T_world_pregrasp: pin.SE3
    lowest_z_m: float


def world_candidates(
    candidates: Sequence[GraspCandidate],
    gripper: GripperGeometry,
    T_world_object: pin.SE3,
    table_z_m: float,
    *,
    gap_m: float = TABLE_GAP_M,
    approach_distance_m: float = CLEARANCE_M,
) -> tuple[WorldCandidate, ...]:
    """The candidates as world tcp poses, without those whose gripper would go below the table.

    The gripper's boxes (pads and fingers swept open along the approach and closing onto the contacts, the palm
    and coupling swept along the approach) must stay at least ``gap_m`` above the table top for the whole
    straight approach from the pregrasp: this drops grasps whose pads or fingers would reach below the table and
    approaches that come from below the table plane. The order of ``candidates`` is kept (rank them first).

    Candidates that differ only by a turn of the object's symmetry (``ObjectConfig.yaw_period_rad``) are
    different tcp poses and are all kept; :func:`synthesize` returns no exact duplicates.

    Args:
        candidates: The candidates (object frame).
        gripper: The gripper's measured geometry.
        T_world_object: The object's pose in the world.
        table_z_m: Height of the table top (m).
        gap_m: Least clearance of the gripper above the table top (m).
        approach_distance_m: Length of the straight approach (m): the pregrasp's distance from the grasp.

    Returns:
        :class:`WorldCandidate` records, in the order of ``candidates``.
    """
    gap_m = _check_positive("gap_m", gap_m, zero=True)
    approach_distance_m = _check_positive("approach_distance_m", approach_distance_m, zero=True)
    if not candidates:
        return ()
    hand = _Hand.of(gripper)
    width = np.array([c.width_m for c in candidates])
    lo, hi = hand.boxes(width, np.zeros((len(width), 2)), approach_distance_m, 0.0, 0.0)
    corners = _corners(lo, hi).reshape(len(width), -1, 3)
    out = []
    for i, c in enumerate(candidates):
        T = T_world_object * c.T_object_tcp
        lowest = float(np.min(corners[i] @ T.rotation[2]) + T.translation[2])
        if lowest >= table_z_m + gap_m - 1e-12:
            pre = pin.SE3(T.rotation.copy(), T.translation - approach_distance_m * T.rotation[:, 2])
            out.append(WorldCandidate(c, T, pre, lowest))
    return tuple(out)


__all__ = [
    "APPROACH_TILTS_RAD",
    "CONTACT_TOL_M",
    "EDGE_DROP_M",
    "EDGE_MARGIN_M",
    "MAX_PROTRUSION_M",
    "MIN_PATCH_SPAN_M",
    "SUPPORT_GAP_M",
    "SWEEP_CLEARANCE_M",
    "ApproachKind",
    "FeatureKind",
    "GraspCandidate",
    "RankWeights",
    "WorldCandidate",
    "approach_kind",
    "centre_of_mass",
    "costs",
    "rank",
    "synthesize",
    "world_candidates",
]
