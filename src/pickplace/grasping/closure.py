"""Grasp analysis for a parallel-jaw gripper: friction cones, contact wrenches, force closure.

Pure numpy/scipy; no MuJoCo. Conventions: positions in metres, normals are unit vectors pointing
*into* the object, forces are per unit normal force (dimensionless), friction coefficients are
Coulomb ``mu`` (sliding) and ``torsional_friction_m`` (MuJoCo's torsional coefficient, metres:
the largest torque about the normal is ``torsional_friction_m * f_n``).

Wrenches are 6-vectors ``[f; tau / torque_scale_m]``. Dividing the torque by a characteristic
length of the object (e.g. its half-size) makes force and torque commensurate (both in units of
the normal force), so the Ferrari–Canny margin does not depend on the choice of length unit and
does not weight torque arbitrarily against force.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError

from pickplace.errors import ConfigError
from pickplace.world.contact import Contact, as_nonneg, as_unit3, as_vec3

#: The origin is "strictly inside" the wrench hull when the margin exceeds this.
CLOSURE_TOL = 1e-9


@dataclass(frozen=True)
class ForceClosureResult:
    """Outcome of the 6D wrench-space force-closure test.

    Attributes:
        force_closure: True when the origin is strictly inside the hull of the contact wrenches.
        margin: Ferrari–Canny epsilon quality: radius of the largest origin-centred ball inside the
            hull (units of normal force); <= 0 when not force closure (0 if the hull is degenerate).
        method: ``"qhull"``, ``"rank-deficient"`` (wrenches span < 6D) or ``"qhull-error"``.
        n_contacts: Number of contacts the wrenches came from.
    """

    force_closure: bool
    margin: float
    method: str
    n_contacts: int


def friction_cone_edges(normal: Sequence[float] | np.ndarray, mu: float, n_edges: int = 8) -> np.ndarray:
    """Edges of the polyhedral (linearized) Coulomb friction cone, per unit normal force.

    The edges do not depend on the contact point, so it is not an argument.

    Args:
        normal: Unit inward contact normal (3,).
        mu: Coulomb friction coefficient (>= 0).
        n_edges: Number of edges ``m`` (>= 3).

    Returns:
        (m, 3) array of forces ``f_k = n + mu * t_k``, ``t_k`` unit tangents evenly spaced in angle;
        each makes exactly the angle ``atan(mu)`` with ``n``.
    """
    n = as_unit3("normal", normal)
    mu = as_nonneg("mu", mu)
    if isinstance(n_edges, bool) or not isinstance(n_edges, (int, np.integer)) or n_edges < 3:
        raise ConfigError("n_edges", n_edges, "must be an integer >= 3")
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]  # the axis least aligned with n
    t1 = helper - (helper @ n) * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    angles = 2.0 * np.pi * np.arange(n_edges) / n_edges
    tangents = np.outer(np.cos(angles), t1) + np.outer(np.sin(angles), t2)
    return n[None, :] + mu * tangents


def in_friction_cone(
    force: Sequence[float] | np.ndarray, normal: Sequence[float] | np.ndarray, mu: float, tol: float = 1e-9
) -> bool:
    """Whether a contact force lies inside the (exact, circular) Coulomb cone ``|f_t| <= mu f_n``.

    Args:
        force: Force (3,) applied by the finger on the object (N).
        normal: Unit inward contact normal (3,).
        mu: Coulomb friction coefficient (>= 0).
        tol: Absolute slack (N) on both the normal-force sign and the tangential bound.
    """
    f = as_vec3("force", force)
    n = as_unit3("normal", normal)
    mu = as_nonneg("mu", mu)
    tol = as_nonneg("tol", tol)
    f_n = float(f @ n)
    f_t = float(np.linalg.norm(f - f_n * n))
    return f_n >= -tol and f_t <= mu * f_n + tol


def contact_wrenches(
    position: Sequence[float] | np.ndarray,
    normal: Sequence[float] | np.ndarray,
    mu: float,
    p_ref: Sequence[float] | np.ndarray,
    torque_scale_m: float,
    *,
    cone_edges: int = 8,
    torsional_friction_m: float = 0.0,
) -> np.ndarray:
    """Primitive wrenches of one contact, per unit normal force.

    For each cone edge ``f_k``: ``w_k = [f_k; (p - p_ref) x f_k / torque_scale_m]``. With torsional
    (soft-finger, MuJoCo condim 4) friction, two more wrenches ``[n; ((p - p_ref) x n ± gamma n) / L]``:
    a torque ``±gamma f_n`` about the normal. They carry their unit normal force, because a torsional
    torque needs normal load; a pure ``[0; ±gamma n]`` would let the hull claim torque for free.

    Args:
        position: Contact point (3,) (m).
        normal: Unit inward normal (3,).
        mu: Coulomb friction coefficient (>= 0).
        p_ref: Reference point for torques (3,) (m), e.g. the object's centre of mass.
        torque_scale_m: Characteristic length ``L`` (m, > 0) dividing torques, e.g. the object's half-size.
        cone_edges: Number of friction-cone edges.
        torsional_friction_m: Torsional coefficient ``gamma`` (m, >= 0); 0 for a point contact.

    Returns:
        (cone_edges, 6) array, or (cone_edges + 2, 6) when ``torsional_friction_m > 0``.
    """
    p = as_vec3("position", position)
    n = as_unit3("normal", normal)
    r = p - as_vec3("p_ref", p_ref)
    scale = as_nonneg("torque_scale_m", torque_scale_m, positive=True)
    gamma = as_nonneg("torsional_friction_m", torsional_friction_m)
    forces = friction_cone_edges(n, mu, cone_edges)
    if gamma > 0.0:
        forces = np.vstack([forces, n, n])
    torques = np.cross(r, forces)
    if gamma > 0.0:
        torques[-2] += gamma * n
        torques[-1] -= gamma * n
    return np.hstack([forces, torques / scale])


def grasp_wrenches(
    contacts: Sequence[Contact],
    p_ref: Sequence[float] | np.ndarray,
    torque_scale_m: float,
    cone_edges: int = 8,
) -> np.ndarray:
    """Stack :func:`contact_wrenches` of every contact into a (K, 6) array."""
    if len(contacts) == 0 or not all(isinstance(c, Contact) for c in contacts):
        raise ConfigError("contacts", contacts, "must be a non-empty sequence of Contact")
    return np.vstack(
        [
            contact_wrenches(
                c.position,
                c.normal,
                c.mu,
                p_ref,
                torque_scale_m,
                cone_edges=cone_edges,
                torsional_friction_m=c.torsional_friction_m,
            )
            for c in contacts
        ]
    )


def force_closure(wrenches: np.ndarray, n_contacts: int, tol: float = CLOSURE_TOL) -> ForceClosureResult:
    """6D force-closure test and Ferrari–Canny margin from the convex hull (qhull) of the wrenches.

    The margin is ``min over facets of (-offset)``, qhull's facet equations being ``a.x + offset <= 0``
    with unit ``a``: the distance from the origin to the nearest facet plane (negative if outside).

    Args:
        wrenches: (K, 6) primitive wrenches.
        n_contacts: Number of contacts, copied into the result.
        tol: Force closure requires ``margin > tol``.
    """
    w = np.asarray(wrenches, dtype=float)
    if w.ndim != 2 or w.shape[1] != 6 or w.shape[0] < 7 or not np.all(np.isfinite(w)):
        raise ConfigError("wrenches", w.shape, "must be a finite (K, 6) array with K >= 7")
    if np.linalg.matrix_rank(w) < 6:  # the wrenches lie in a subspace: some wrench cannot be resisted
        return ForceClosureResult(False, 0.0, "rank-deficient", n_contacts)
    try:
        hull = ConvexHull(w)
        method = "qhull"
    except QhullError:
        # Contacts from a simulator are often nearly coplanar or duplicated (four corners of a face-face
        # contact share one normal), which can trip qhull's precision checks ("wide merge"). Joggling the
        # input by ~1e-11 relative is qhull's own remedy; the margin moves by about as much.
        try:
            hull = ConvexHull(w, qhull_options="QJ")
            method = "qhull-joggled"
        except QhullError:  # truly flat: decide by the linear program, no margin
            inside = origin_in_hull_lp(w, tol)
            return ForceClosureResult(inside, 0.0, "lp", n_contacts)
    margin = float(-np.max(hull.equations[:, -1]))
    return ForceClosureResult(margin > tol, margin, method, n_contacts)


def origin_in_hull_lp(wrenches: np.ndarray, tol: float = CLOSURE_TOL) -> bool:
    """Cross-check by LP: the origin is strictly inside the hull iff the wrenches span 6D and
    ``0 = sum_i l_i w_i`` with ``sum l_i = 1`` and every ``l_i >= t`` for some ``t > tol``.

    Args:
        wrenches: (K, 6) primitive wrenches.
        tol: Required minimum weight ``t``.
    """
    w = np.asarray(wrenches, dtype=float)
    k = w.shape[0]
    if np.linalg.matrix_rank(w) < 6:
        return False
    c = np.zeros(k + 1)
    c[-1] = -1.0  # maximise t
    a_eq = np.vstack([np.hstack([w.T, np.zeros((6, 1))]), np.hstack([np.ones(k), 0.0])])
    b_eq = np.append(np.zeros(6), 1.0)
    a_ub = np.hstack([-np.eye(k), np.ones((k, 1))])  # t - l_i <= 0
    res = linprog(c, A_ub=a_ub, b_ub=np.zeros(k), A_eq=a_eq, b_eq=b_eq, bounds=[(0, None)] * k + [(None, 1)])
    return bool(res.status == 0 and -res.fun > tol)


def analyze_grasp(
    contacts: Sequence[Contact],
    p_ref: Sequence[float] | np.ndarray,
    torque_scale_m: float,
    cone_edges: int = 8,
) -> ForceClosureResult:
    """Force closure and Ferrari–Canny margin of a set of contacts.

    Args:
        contacts: The finger contacts (each with its own mu and torsional coefficient).
        p_ref: Reference point for torques (3,) (m), normally the object's centre of mass.
        torque_scale_m: Characteristic length (m) dividing torques, e.g. the object's half-size.
        cone_edges: Edges of each linearized friction cone.
    """
    return force_closure(grasp_wrenches(contacts, p_ref, torque_scale_m, cone_edges), len(contacts))


def antipodal(
    p1: Sequence[float] | np.ndarray,
    n1: Sequence[float] | np.ndarray,
    p2: Sequence[float] | np.ndarray,
    n2: Sequence[float] | np.ndarray,
    mu: float,
) -> bool:
    """Cheap two-contact test: the line through the contacts lies inside both friction cones.

    True iff ``mu > 0``, the points are distinct, the angle between ``p2 - p1`` and ``n1`` is
    ``<= atan(mu)`` and the angle between ``p1 - p2`` and ``n2`` is ``<= atan(mu)``.

    Args:
        p1, p2: Contact points (3,) (m).
        n1, n2: Unit inward normals (3,).
        mu: Coulomb friction coefficient (>= 0).
    """
    a, b = as_vec3("p1", p1), as_vec3("p2", p2)
    na, nb = as_unit3("n1", n1), as_unit3("n2", n2)
    mu = as_nonneg("mu", mu)
    d = b - a
    length = float(np.linalg.norm(d))
    if mu == 0.0 or length < 1e-12:  # no friction, or no line through coincident points
        return False
    half_angle = math.atan(mu) + 1e-12

    def angle(u: np.ndarray, n: np.ndarray) -> float:
        return math.atan2(float(np.linalg.norm(np.cross(u, n))), float(u @ n))

    return angle(d, na) <= half_angle and angle(-d, nb) <= half_angle
