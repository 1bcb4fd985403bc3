"""Tests of pickplace.grasping.closure: friction cones, wrenches, 6D force closure, antipodal test."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pickplace.errors import ConfigError
from pickplace.grasping.closure import (
    Contact,
    analyze_grasp,
    antipodal,
    contact_wrenches,
    force_closure,
    friction_cone_edges,
    grasp_wrenches,
    in_friction_cone,
    origin_in_hull_lp,
)

HALF = 0.02  # half-size of a 40 mm cube (m); also the torque scale
CENTRE = np.zeros(3)
TORSION_M = 0.005


def pinch(mu: float, torsion_m: float = TORSION_M, shift: tuple[float, float] = (0.0, 0.0)) -> list[Contact]:
    """Two fingers on the centres of the -x and +x faces, both shifted by (dy, dz) along the face."""
    dy, dz = shift
    return [
        Contact(np.array([-HALF, dy, dz]), np.array([1.0, 0.0, 0.0]), mu, torsion_m),
        Contact(np.array([HALF, dy, dz]), np.array([-1.0, 0.0, 0.0]), mu, torsion_m),
    ]


def is_antipodal(contacts: list[Contact], mu: float) -> bool:
    c1, c2 = contacts
    return antipodal(c1.position, c1.normal, c2.position, c2.normal, mu)


def test_centred_soft_finger_pinch_is_force_closure() -> None:
    contacts = pinch(1.0)
    result = analyze_grasp(contacts, CENTRE, HALF)
    assert result.force_closure
    assert result.method in ("qhull", "qhull-joggled")  # which one is the CPU's floating point
    assert result.n_contacts == 2
    assert result.margin == pytest.approx(0.2413, abs=1e-3)
    assert result.margin == pytest.approx(inscribed_radius(grasp_wrenches(contacts, CENTRE, HALF)), abs=1e-6)
    assert origin_in_hull_lp(grasp_wrenches(contacts, CENTRE, HALF))
    assert is_antipodal(contacts, 1.0)


def test_point_contact_pinch_is_not_6d_force_closure() -> None:
    # Two point contacts can only push/rub through points on the x axis: every force f applied at
    # (±a, 0, 0) has zero moment about that axis, so no contact wrench has an x-torque component and
    # the wrenches span only 5D. A twist about the line joining the fingers is unresisted; torsional
    # (soft-finger) friction is what supplies that sixth direction.
    contacts = pinch(1.0, torsion_m=0.0)
    w = grasp_wrenches(contacts, CENTRE, HALF)
    assert np.max(np.abs(w[:, 3])) == pytest.approx(0.0, abs=1e-15)
    assert np.linalg.matrix_rank(w) == 5
    result = analyze_grasp(contacts, CENTRE, HALF)
    assert not result.force_closure
    assert result.margin == pytest.approx(0.0, abs=1e-12)
    assert result.method == "rank-deficient"
    assert not origin_in_hull_lp(w)
    assert is_antipodal(contacts, 1.0)  # the planar/line test does not see the twist


def test_two_contacts_on_the_same_face() -> None:
    n = np.array([1.0, 0.0, 0.0])
    contacts = [
        Contact([-HALF, -0.01, 0.0], n, 1.0, TORSION_M),
        Contact([-HALF, 0.01, 0.0], n, 1.0, TORSION_M),
    ]
    result = analyze_grasp(contacts, CENTRE, HALF)
    assert not result.force_closure
    assert result.margin <= 1e-12
    assert not is_antipodal(contacts, 1.0)


def test_frictionless_pinch() -> None:
    contacts = pinch(0.0)
    result = analyze_grasp(contacts, CENTRE, HALF)
    assert not result.force_closure
    assert result.margin <= 1e-12
    assert not is_antipodal(contacts, 0.0)


@pytest.mark.parametrize("shift", [(0.005, 0.0), (0.0, 0.005)])
def test_off_centre_pinch_has_smaller_margin(shift: tuple[float, float]) -> None:
    centred = analyze_grasp(pinch(1.0), CENTRE, HALF)
    off = analyze_grasp(pinch(1.0, shift=shift), CENTRE, HALF)
    assert off.force_closure
    assert off.margin == pytest.approx(0.2226, abs=1e-3)
    assert off.margin < centred.margin - 0.01
    assert is_antipodal(pinch(1.0, shift=shift), 1.0)


def test_angled_pinch_outside_the_cone() -> None:
    mu = 0.1  # cone half-angle atan(0.1) = 5.7 deg
    dy = HALF * math.tan(math.radians(20.0))  # contact line at 20 deg to both normals
    contacts = [
        Contact([-HALF, -dy, 0.0], [1.0, 0.0, 0.0], mu, TORSION_M),
        Contact([HALF, dy, 0.0], [-1.0, 0.0, 0.0], mu, TORSION_M),
    ]
    line = contacts[1].position - contacts[0].position
    assert math.degrees(math.acos(line[0] / np.linalg.norm(line))) == pytest.approx(20.0, abs=1e-9)
    assert not is_antipodal(contacts, mu)
    assert is_antipodal(contacts, math.tan(math.radians(20.0)) + 1e-9)  # just wide enough
    result = analyze_grasp(contacts, CENTRE, HALF)
    assert not result.force_closure
    assert result.margin < -0.1


def test_margin_grows_with_mu() -> None:
    margins = [analyze_grasp(pinch(mu), CENTRE, HALF).margin for mu in (0.2, 0.5, 1.0)]
    assert margins == pytest.approx([0.1296, 0.2199, 0.2413], abs=1e-3)
    assert all(b > a + 1e-3 for a, b in itertools.pairwise(margins))


def test_margin_of_known_hulls() -> None:
    cube = np.array(np.meshgrid(*[[-1.0, 1.0]] * 6)).reshape(6, -1).T  # {±1}^6: inscribed radius 1
    assert force_closure(cube, 0).margin == pytest.approx(1.0, abs=1e-12)
    cross = np.vstack([np.eye(6), -np.eye(6)])  # cross-polytope: inscribed radius 1/sqrt(6)
    assert force_closure(cross, 0).margin == pytest.approx(1.0 / math.sqrt(6.0), abs=1e-12)
    shifted = force_closure(cross + np.array([2.0, 0, 0, 0, 0, 0]), 0)  # origin outside
    assert not shifted.force_closure
    assert shifted.margin < 0.0
    assert not origin_in_hull_lp(cross + np.array([2.0, 0, 0, 0, 0, 0]))


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.5, 1.0, 2.0])
@pytest.mark.parametrize("normal", [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, -2.0, 0.5]])
def test_friction_cone_edges_make_atan_mu_with_normal(mu: float, normal: list[float]) -> None:
    n = np.asarray(normal) / np.linalg.norm(normal)
    edges = friction_cone_edges(n, mu, 8)
    assert edges.shape == (8, 3)
    np.testing.assert_allclose(edges @ n, 1.0, atol=1e-12)  # unit normal force
    angles = np.arctan2(np.linalg.norm(np.cross(edges, n), axis=1), edges @ n)
    np.testing.assert_allclose(angles, math.atan(mu), atol=1e-12)
    assert friction_cone_edges(n, mu, 5).shape == (5, 3)
    for edge in edges:
        assert in_friction_cone(edge, n, mu)


def test_in_friction_cone() -> None:
    n = np.array([0.0, 0.0, 1.0])
    assert in_friction_cone([0.4, 0.0, 1.0], n, 0.5)
    assert in_friction_cone([0.3, 0.4, 1.0], n, 0.5)  # |f_t| = 0.5 = mu f_n: on the boundary
    assert not in_friction_cone([0.3, 0.41, 1.0], n, 0.5)
    assert not in_friction_cone([0.0, 0.0, -1.0], n, 0.5)  # pulling
    assert in_friction_cone([0.0, 0.0, 2.0], n, 0.0)
    assert not in_friction_cone([1e-6, 0.0, 2.0], n, 0.0)


def test_torsional_wrenches() -> None:
    w = contact_wrenches(
        [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.5, [0.0, 0.0, 0.0], 0.02, torsional_friction_m=0.005
    )
    assert w.shape == (10, 6)
    np.testing.assert_allclose(w[-2:], [[0, 0, 1, 0, 0, 0.25], [0, 0, 1, 0, 0, -0.25]], atol=1e-15)
    # moment arm: a force along +x at (0, 0.02, 0) about the origin gives -z torque, scaled by 1/0.02
    w = contact_wrenches([0.0, 0.02, 0.0], [1.0, 0.0, 0.0], 0.0, [0.0, 0.0, 0.0], 0.02, cone_edges=3)
    np.testing.assert_allclose(w, np.tile([1.0, 0, 0, 0, 0, -1.0], (3, 1)), atol=1e-15)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Contact([0.0, 0.0], [1.0, 0.0, 0.0], 1.0), "contact.position"),
        (lambda: Contact([0.0, float("nan"), 0.0], [1.0, 0.0, 0.0], 1.0), "contact.position"),
        (lambda: Contact([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0), "contact.normal"),
        (lambda: Contact([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], 1.0), "contact.normal"),
        (lambda: Contact([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], -0.1), "contact.mu"),
        (lambda: Contact([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], float("nan")), "contact.mu"),
        (lambda: Contact([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0, -0.001), "contact.torsional_friction_m"),
        (lambda: analyze_grasp(pinch(1.0), CENTRE, 0.0), "torque_scale_m"),
        (lambda: analyze_grasp(pinch(1.0), [0.0, 0.0], HALF), "p_ref"),
        (lambda: analyze_grasp([], CENTRE, HALF), "contacts"),
        (lambda: friction_cone_edges([0.0, 0.0, 1.0], 0.5, 2), "n_edges"),
        (lambda: friction_cone_edges([0.0, 0.0, 1.0], -0.5), "mu"),
        (lambda: in_friction_cone([0.0, 0.0], [0.0, 0.0, 1.0], 0.5), "force"),
        (lambda: antipodal([0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 0], 0.5), "n2"),
        (lambda: antipodal([0, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0], -1.0), "mu"),
        (lambda: force_closure(np.zeros((10, 5)), 2), "wrenches"),
    ],
)
def test_bad_input_raises_config_error(call, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        call()
    assert info.value.field == field


# Eight contacts of a real pinch, as MuJoCo reported them (two 4-point face contacts on opposite faces). On some
# CPUs qhull's default options reject such near-coplanar, duplicated wrenches with a precision error ("wide
# merge"), on others they pass: which one happens is the CPU's floating point, not pickplace's behaviour. The
# tests below assert the behaviour (closure found, the margin checked independently, the LP agreeing) and force
# each fallback path deterministically by injecting the qhull failure.
FACE_NORMAL = [0.7125165758653385, 0.701655121997807, -0.00046785828643712714]
FACE_LEFT = [[0.3290249333035318, 0.1350614092652658, 0.325363379649924],
             [0.32903183206381564, 0.13507189205863812, 0.3453633750761873],
             [0.31219337782773565, 0.1521735422546842, 0.3453602188654027],
             [0.3121864790674518, 0.15216305946131187, 0.3253602234391394]]
FACE_RIGHT = [[0.3580079036839104, 0.16359408428909414, 0.32533250781947315],
              [0.35801480244419426, 0.16360456708246648, 0.34533250324573644],
              [0.34117634820811427, 0.18070621727851255, 0.3453293470349519],
              [0.3411694494478304, 0.18069573448514023, 0.3253293516086886]]
FACE_MU = 0.5979383791257202
FACE_P_REF = [0.33508632112569087, 0.15789522965323538, 0.3353520053484002]
FACE_SCALE_M = 0.020345096318206104


def face_contacts() -> list[Contact]:
    n = FACE_NORMAL
    return ([Contact(p, n, FACE_MU, 0.005) for p in FACE_LEFT]
            + [Contact(p, [-v for v in n], FACE_MU, 0.005) for p in FACE_RIGHT])


def inscribed_radius(wrenches: np.ndarray, n_dirs: int = 20000, n_refined: int = 20) -> float:
    """The Ferrari–Canny margin computed without qhull: the largest origin-centred ball inside the hull has the
    radius ``min over unit u of max_i w_i . u`` (the hull's support function). Sampled directions, the best
    ones refined by SLSQP on ``min t s.t. w_i . u <= t, |u| = 1``."""
    from scipy.optimize import minimize

    u = np.random.default_rng(0).normal(size=(n_dirs, 6))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    support = np.max(u @ wrenches.T, axis=1)
    constraints = [
        {"type": "ineq", "fun": lambda x: x[6] - wrenches @ x[:6],
         "jac": lambda x: np.hstack([-wrenches, np.ones((len(wrenches), 1))])},
        {"type": "eq", "fun": lambda x: x[:6] @ x[:6] - 1.0, "jac": lambda x: np.append(2.0 * x[:6], 0.0)},
    ]
    best = float(support.min())
    for j in np.argsort(support)[:n_refined]:
        res = minimize(lambda x: x[6], np.append(u[j], support[j]), jac=lambda x: np.eye(7)[6],
                       constraints=constraints, method="SLSQP", options={"ftol": 1e-12, "maxiter": 500})
        direction = res.x[:6] / np.linalg.norm(res.x[:6])
        best = min(best, float(np.max(wrenches @ direction)))  # any unit direction bounds the radius from above
    return best


def _qhull_failing(monkeypatch: pytest.MonkeyPatch, fail_joggled: bool) -> list[str | None]:
    """Make pickplace.grasping.closure's qhull raise its precision error for the default options (and for "QJ" too if
    ``fail_joggled``); returns the list of options it was called with."""
    from scipy.spatial import ConvexHull, QhullError

    import pickplace.grasping.closure as grasp_module

    calls: list[str | None] = []

    def hull(points: np.ndarray, qhull_options: str | None = None) -> ConvexHull:
        calls.append(qhull_options)
        if qhull_options is None or (fail_joggled and "QJ" in qhull_options):
            raise QhullError("QH6271 qhull precision error (injected by the test)")
        return ConvexHull(points, qhull_options=qhull_options)

    monkeypatch.setattr(grasp_module, "ConvexHull", hull)
    return calls


def test_simulated_face_contacts_are_force_closure_with_a_checked_margin() -> None:
    """Whatever qhull does with these contacts on this CPU, pickplace finds closure, its margin is a true
    inscribed radius (no direction's support is below it, and a facet touches it), and the LP agrees."""
    contacts = face_contacts()
    wrenches = grasp_wrenches(contacts, FACE_P_REF, FACE_SCALE_M)
    result = analyze_grasp(contacts, FACE_P_REF, FACE_SCALE_M)
    assert result.force_closure and result.n_contacts == 8
    assert result.method in ("qhull", "qhull-joggled")
    assert result.margin == pytest.approx(0.457, abs=0.01)
    assert result.margin == pytest.approx(inscribed_radius(wrenches), abs=1e-6)  # computed without qhull
    assert origin_in_hull_lp(wrenches)  # the LP agrees


def test_a_qhull_precision_error_is_retried_joggled(monkeypatch: pytest.MonkeyPatch) -> None:
    """The precision error is injected: the test no longer depends on whether this CPU's qhull trips."""
    contacts = face_contacts()
    plain = analyze_grasp(contacts, FACE_P_REF, FACE_SCALE_M)
    calls = _qhull_failing(monkeypatch, fail_joggled=False)
    result = analyze_grasp(contacts, FACE_P_REF, FACE_SCALE_M)
    assert calls == [None, "QJ"]
    assert result.force_closure and result.method == "qhull-joggled"
    assert result.margin == pytest.approx(plain.margin, abs=1e-6)  # joggling moves it by ~1e-11 relative
    assert origin_in_hull_lp(grasp_wrenches(contacts, FACE_P_REF, FACE_SCALE_M))


def test_when_joggling_fails_too_the_lp_decides(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _qhull_failing(monkeypatch, fail_joggled=True)
    inside = analyze_grasp(face_contacts(), FACE_P_REF, FACE_SCALE_M)
    assert calls == [None, "QJ"]
    assert inside.force_closure and inside.method == "lp" and inside.margin == 0.0
    mu = 0.1  # the same failure on a grip outside its friction cones: the LP says no
    dy = HALF * math.tan(math.radians(20.0))
    outside = analyze_grasp([Contact([-HALF, -dy, 0.0], [1.0, 0.0, 0.0], mu, TORSION_M),
                             Contact([HALF, dy, 0.0], [-1.0, 0.0, 0.0], mu, TORSION_M)], CENTRE, HALF)
    assert not outside.force_closure and outside.method == "lp"
