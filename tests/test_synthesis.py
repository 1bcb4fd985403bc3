"""Grasp synthesis from an object's geometry (grasping/synthesis.py).

Every candidate of every library object is re-checked here by computations independent of the code under test:
distances to the surface mesh with trimesh, antipodality with ``closure.antipodal``, force closure with
``closure.analyze_grasp``, the pads' position on the faces from the primitives' dimensions, and the gripper's
volumes (built from ``GripperGeometry``'s measured boxes, sampled every few mm) against the object's analytic
signed distance (primitives) or a ray-parity inside test (meshes).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest
import trimesh

from pickplace.errors import ConfigError
from pickplace.grasping.closure import analyze_grasp, antipodal
from pickplace.grasping.synthesis import (
    ApproachKind,
    FeatureKind,
    GraspCandidate,
    RankWeights,
    costs,
    rank,
    synthesize,
    world_candidates,
)
from pickplace.grasping.targets import CLEARANCE_M, TABLE_GAP_M
from pickplace.robot import model
from pickplace.robot.gripper import GripperGeometry
from pickplace.world.objects import LIBRARY, MAX_GRIP_WIDTH_M, MIN_GRIP_WIDTH_M, ObjectConfig

PRIMITIVE_NAMES = [name for name, obj in LIBRARY.items() if obj.kind != "mesh"]
MESH_NAMES = [name for name, obj in LIBRARY.items() if obj.kind == "mesh"]
#: Settings the mug's wall pinch is looked for with: its 4.5 mm wall is below MIN_GRIP_WIDTH_M (see the test).
WALL_PINCH = {"min_width_m": 0.0042, "spacing_m": 0.06, "samples": 50}


@pytest.fixture(scope="module")
def gripper(robot: model.Robot) -> GripperGeometry:
    return GripperGeometry.measure(robot)


@pytest.fixture(scope="module")
def synth(gripper: GripperGeometry) -> Callable[..., tuple[GraspCandidate, ...]]:
    """``synth(name_or_object, **settings)``: the candidates, computed once per module for each argument set."""
    cache: dict[tuple, tuple[GraspCandidate, ...]] = {}

    def get(obj: str | ObjectConfig, **settings: float) -> tuple[GraspCandidate, ...]:
        key = (obj if isinstance(obj, str) else repr(obj), tuple(sorted(settings.items())))
        if key not in cache:
            cache[key] = synthesize(LIBRARY[obj] if isinstance(obj, str) else obj, gripper, **settings)
        return cache[key]

    return get


# --------------------------------------------------------------------------- #
# independent geometry
# --------------------------------------------------------------------------- #


def sdf(obj: ObjectConfig, points: np.ndarray) -> np.ndarray:
    """Signed distance (M,) of points (M, 3) to a primitive object (negative inside), exact per primitive."""
    out = np.full(len(points), np.inf)
    for part in obj.primitives():
        q = (points - np.asarray(part.pos_m)) @ part.rotation
        s = part.size_m
        if part.kind == "box":
            d = np.abs(q) - np.asarray(s) / 2
            dist = np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)
        elif part.kind == "cylinder":
            d = np.column_stack([np.hypot(q[:, 0], q[:, 1]) - s[0], np.abs(q[:, 2]) - s[1] / 2])
            dist = np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)
        else:
            dist = np.linalg.norm(q, axis=1) - s[0]
        out = np.minimum(out, dist)
    return out


def inside_mesh(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Ray parity along a skew direction: whether each point lies inside a closed mesh."""
    tri = vertices[faces]
    d = np.array([0.5773, 0.5774, 0.5775])
    d /= np.linalg.norm(d)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    h = np.cross(d, e2)
    a = np.einsum("fi,fi->f", e1, h)
    out = np.zeros(len(points), dtype=bool)
    for s in range(0, len(points), 200):
        P = points[s:s + 200, None, :]
        sv = P - tri[None, :, 0]
        f = 1.0 / a
        u = f * np.einsum("mfi,fi->mf", sv, h)
        q = np.cross(sv, e1[None])
        v = f * np.einsum("i,mfi->mf", d, q)
        t = f * np.einsum("fi,mfi->mf", e2, q)
        hit = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        out[s:s + 200] = hit.sum(axis=1) % 2 == 1
    return out


def surface_distance(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (M,) of each point to the triangle mesh (trimesh's closest point on every triangle)."""
    tri = vertices[faces]
    out = np.empty(len(points))
    for i, p in enumerate(points):
        closest = trimesh.triangles.closest_point(tri, np.repeat(p[None], len(tri), axis=0))
        out[i] = np.min(np.linalg.norm(closest - p, axis=1))
    return out


def box_points(lo: np.ndarray, hi: np.ndarray, step: float) -> np.ndarray:
    """A grid of points (N, 3) through the box [lo, hi] (its faces included), about ``step`` apart."""
    axes = [np.linspace(a, b, max(2, math.ceil((b - a) / step) + 1)) for a, b in zip(lo, hi, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def gripper_points(g: GripperGeometry, c: GraspCandidate, bounds: np.ndarray, step: float = 0.005
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Points of the gripper near the object, in the object's frame: ``(coming_in, closed)``.

    ``coming_in``: pads, fingers and palm boxes fully open, swept from the pregrasp (CLEARANCE_M back) to the
    grasp. ``closed``: pads and fingers moved in until the pads' faces are 0.3 mm short of the contact planes.
    Only the points within 2 mm of the object's bounds (m, (2, 3)) are returned.
    """
    T = c.T_object_tcp
    corners = np.array([[x, y, z] for x in bounds[:, 0] for y in bounds[:, 1] for z in bounds[:, 2]])
    local = (corners - T.translation) @ T.rotation  # the object's bounds in the tcp frame
    lo_t, hi_t = local.min(axis=0) - 0.002, local.max(axis=0) + 0.002

    def sample(boxes: list[tuple[np.ndarray, np.ndarray]], step: float) -> np.ndarray:
        pts = []
        for lo, hi in boxes:
            lo, hi = np.maximum(lo, lo_t), np.minimum(hi, hi_t)  # the part of the box near the object
            if np.all(hi >= lo):
                pts.append(box_points(lo, hi, step))
        pts = np.vstack(pts) if pts else np.zeros((0, 3))
        return near(pts @ T.rotation.T + T.translation, bounds)

    def mirrored(lo: np.ndarray, hi: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        m = np.array([1.0, -1.0, 1.0])
        return [(lo, hi), (np.minimum(lo * m, hi * m), np.maximum(lo * m, hi * m))]

    back = np.array([0.0, 0.0, CLEARANCE_M])
    coming: list[tuple[np.ndarray, np.ndarray]] = []
    for b in (np.array(g.pad_box_m), np.array(g.finger_box_m)):
        coming += mirrored(b[:3] - b[3:] - back, b[:3] + b[3:])
    coming += [(np.array(b[:3]) - np.array(b[3:]) - back, np.array(b[:3]) + np.array(b[3:])) for b in g.palm_boxes_m]
    closed: list[tuple[np.ndarray, np.ndarray]] = []
    shift = np.array([0.0, g.open_inner_face_y_m - (c.width_m / 2 + 0.0003), 0.0])
    for b in (np.array(g.pad_box_m), np.array(g.finger_box_m)):
        closed += mirrored(b[:3] - b[3:] - shift, b[:3] + b[3:] - shift)
    return sample(coming, step), sample(closed, step / 2)


def near(points: np.ndarray, bounds: np.ndarray, margin: float = 0.002) -> np.ndarray:
    return points[np.all((points >= bounds[0] - margin) & (points <= bounds[1] + margin), axis=1)]


# --------------------------------------------------------------------------- #
# every library object
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize("name", list(LIBRARY))
def test_candidates_are_valid_grasps(name: str, synth, gripper: GripperGeometry) -> None:
    obj = LIBRARY[name]
    geo = obj.geometry()
    cands = synth(name)
    assert cands, f"{name}: no candidates"
    contacts = np.vstack([c.contacts_m for c in cands])
    unique = np.unique(np.round(contacts, 7), axis=0)
    assert np.max(surface_distance(geo.vertices, geo.faces, unique)) < 0.0005
    for c in cands:
        assert MIN_GRIP_WIDTH_M - 1e-9 <= c.width_m <= MAX_GRIP_WIDTH_M + 1e-9
        p1, p2 = c.contacts_m
        n1, n2 = c.normals
        assert abs(np.linalg.norm(n1) - 1) < 1e-9 and abs(np.linalg.norm(n2) - 1) < 1e-9
        assert antipodal(p1, n1, p2, n2, obj.friction)
        assert c.width_m == pytest.approx(np.linalg.norm(p1 - p2), abs=1e-9)
        # the pads' centres on the contacts: tcp y along the closing line, the first contact on the +y pad
        T = c.T_object_tcp
        assert np.allclose(T.rotation.T @ T.rotation, np.eye(3), atol=1e-9) and np.linalg.det(T.rotation) > 0
        assert np.allclose(T.translation + T.rotation[:, 1] * c.width_m / 2, p1, atol=1e-9)
        assert np.allclose(T.translation - T.rotation[:, 1] * c.width_m / 2, p2, atol=1e-9)
        assert c.margin > 0
        assert 0 < c.support <= 1
        axis = (p1 - p2) / c.width_m
        com_r = c.com_offset_m
        assert 0 <= com_r <= np.max(geo.extent_m)
        del axis
    # force closure re-computed for a few, at the object's friction, about its centre of volume
    com = _centre_of_volume(obj)
    scale = 0.5 * float(np.max(geo.extent_m))
    for c in cands[:: max(1, len(cands) // 10)]:
        res = analyze_grasp(list(c.contacts(obj.friction, obj.torsional_friction_m)), com, scale)
        assert res.force_closure
        assert c.margin == pytest.approx(res.margin, rel=1e-6)


def _centre_of_volume(obj: ObjectConfig) -> np.ndarray:
    if obj.kind == "mesh":
        geo = obj.geometry()
        return np.asarray(trimesh.Trimesh(geo.vertices, geo.faces, process=False).center_mass)
    vols = np.array([p.volume_m3 for p in obj.primitives()])
    return vols @ np.array([p.pos_m for p in obj.primitives()]) / vols.sum()


@pytest.mark.parametrize("name", PRIMITIVE_NAMES)
def test_pads_inside_the_faces(name: str, synth) -> None:
    """The pads' centres at least 3 mm inside the face (box faces, end caps) or the side (cylinder) they touch."""
    obj = LIBRARY[name]
    for c in synth(name):
        part = obj.primitives()[c.part]
        R, h = part.rotation, np.asarray(part.size_m) / 2
        for p in c.contacts_m:
            q = R.T @ (p - np.asarray(part.pos_m))
            if c.feature is FeatureKind.BOX_FACES:
                across = int(np.argmax(np.abs(R.T @ c.T_object_tcp.rotation[:, 1])))
                others = [i for i in range(3) if i != across]
                assert np.all(np.abs(q[others]) <= h[others] - 0.003 + 1e-9)
            elif c.feature is FeatureKind.CYLINDER_SIDE:
                assert abs(q[2]) <= part.size_m[1] / 2 - 0.003 + 1e-9
            elif c.feature is FeatureKind.CYLINDER_CAPS:
                assert math.hypot(q[0], q[1]) <= part.size_m[0] - 0.003 + 1e-9


@pytest.mark.parametrize("name", PRIMITIVE_NAMES)
def test_gripper_clear_of_primitive_objects(name: str, synth, gripper: GripperGeometry) -> None:
    """The open gripper on its way in and the closed fingers stay outside the object (analytic distance)."""
    obj = LIBRARY[name]
    bounds = np.asarray(obj.geometry().bounds_m)
    for c in synth(name):
        coming, closed = gripper_points(gripper, c, bounds)
        if len(coming):
            assert sdf(obj, coming).min() > 0.0, f"{name}: the gripper coming in meets the object"
        if len(closed):
            assert sdf(obj, closed).min() > 0.0002, f"{name}: the closed fingers meet the object"


@pytest.mark.skipif(not MESH_NAMES, reason="no mesh object in the library")
@pytest.mark.parametrize("name", MESH_NAMES)
def test_gripper_clear_of_mesh_objects(name: str, synth, gripper: GripperGeometry) -> None:
    """As for primitives, against the mesh (ray parity); the closed check covers the fingers behind the pads
    only, since a pad may touch a concave surface before the contact plane."""
    obj = LIBRARY[name]
    geo = obj.geometry()
    cands = synth(name)
    for c in cands[:: max(1, len(cands) // 12)]:
        coming, _ = gripper_points(gripper, c, np.asarray(geo.bounds_m), step=0.004)
        assert not np.any(inside_mesh(geo.vertices, geo.faces, coming)), f"{name}: the gripper meets the object"


# --------------------------------------------------------------------------- #
# particular objects
# --------------------------------------------------------------------------- #


def closing_axis_index(c: GraspCandidate) -> int:
    y = c.T_object_tcp.rotation[:, 1]
    i = int(np.argmax(np.abs(y)))
    return i if abs(y[i]) > 1 - 1e-9 else -1


def test_cube_top_down_across_both_pairs_at_centre_height(synth) -> None:
    cands = synth("cube")
    top = [c for c in cands if c.approach is ApproachKind.TOP]
    centred = [c for c in top if abs(c.T_object_tcp.translation[2]) < 1e-9]
    assert {closing_axis_index(c) for c in centred} == {0, 1}
    assert all(np.allclose(c.T_object_tcp.rotation[:, 2], [0, 0, -1], atol=1e-9) for c in top)
    for kind in (ApproachKind.TILTED, ApproachKind.SIDE):
        assert any(c.approach is kind for c in cands)


def test_sugar_box_only_across_its_38_mm_side(synth) -> None:
    cands = synth("sugar_box")
    assert cands
    assert all(c.width_m == pytest.approx(0.038, abs=1e-9) and closing_axis_index(c) == 0 for c in cands)


def test_soda_can_tilted_and_side(synth) -> None:
    cands = synth("soda_can")
    assert {c.approach for c in cands} == set(ApproachKind)
    assert all(c.width_m == pytest.approx(2 * LIBRARY["soda_can"].size_m[0], abs=1e-9) for c in cands)


def test_lying_can_across_its_diameter_only(synth) -> None:
    can = LIBRARY["soda_can_lying"]
    cands = synth("soda_can_lying")
    assert all(c.width_m == pytest.approx(2 * can.size_m[0], abs=1e-9) for c in cands)
    assert all(abs(c.T_object_tcp.rotation[0, 1]) < 1e-9 for c in cands)  # closing across the axis (x)
    assert {ApproachKind.TOP, ApproachKind.SIDE} <= {c.approach for c in cands}


def test_too_small_and_too_large(gripper: GripperGeometry) -> None:
    ball = ObjectConfig(name="marble", kind="sphere", size_m=(0.010,))
    assert synthesize(ball, gripper) == ()  # the flat pads would touch it at a point (9 mm patch)
    big = ObjectConfig(name="big_cube", kind="box", size_m=(0.2, 0.2, 0.2))
    assert synthesize(big, gripper) == ()  # wider than the stroke every way


def test_compound_parts_block_each_other(synth) -> None:
    """On the L-bracket, no pad of a grasp on the flat leg sits where the upright covers the leg's top."""
    cands = synth("l_bracket")
    assert {round(c.width_m, 4) for c in cands} >= {0.010, 0.040}
    obj = LIBRARY["l_bracket"]
    for c in cands:
        mid = c.T_object_tcp.translation
        assert sdf(obj, mid[None])[0] < 0 or c.width_m > 0.05  # the pads squeeze material between them


def test_deterministic(gripper: GripperGeometry) -> None:
    for obj, kw in ((LIBRARY["l_bracket"], {}), *((LIBRARY[m], {"samples": 60, "seed": 3}) for m in MESH_NAMES)):
        a, b = synthesize(obj, gripper, **kw), synthesize(obj, gripper, **kw)
        assert len(a) == len(b) > 0
        for x, y in zip(a, b, strict=True):
            assert np.array_equal(x.T_object_tcp.homogeneous, y.T_object_tcp.homogeneous)
            assert x.margin == y.margin


def test_no_exact_duplicates(synth) -> None:
    for name in LIBRARY:
        keys = {tuple(np.round(c.T_object_tcp.homogeneous.ravel(), 9)) for c in synth(name)}
        assert len(keys) == len(synth(name))


def test_pregrasp_backs_off_along_the_approach(synth) -> None:
    c = synth("soda_can")[5]
    pre = c.pregrasp(0.1)
    assert np.allclose(pre.rotation, c.T_object_tcp.rotation)
    assert np.allclose(c.T_object_tcp.translation - pre.translation, 0.1 * c.approach_direction)


def test_bad_arguments(gripper: GripperGeometry) -> None:
    cube = LIBRARY["cube"]
    for kw in ({"samples": 0}, {"spacing_m": -0.01}, {"min_width_m": 0.001}, {"max_width_m": 0.09},
               {"clearance_m": float("nan")}):
        with pytest.raises(ConfigError):
            synthesize(cube, gripper, **kw)
    with pytest.raises(ConfigError):
        RankWeights(margin=-1.0)
    with pytest.raises(ConfigError):
        costs(synthesize(cube, gripper)[:3], extra_cost=[1.0, 2.0])


# --------------------------------------------------------------------------- #
# meshes: the mug
# --------------------------------------------------------------------------- #


def _mug_axis(name: str) -> tuple[np.ndarray, float]:
    """The body's axis (xy) and the rim's height: the centre of the mesh's highest ring of vertices."""
    v = LIBRARY[name].geometry().vertices
    top = v[v[:, 2] > v[:, 2].max() - 1e-4]
    return top[:, :2].mean(axis=0), float(v[:, 2].max())


@pytest.mark.skipif("mug" not in LIBRARY, reason="no mug in the library")
def test_mug_handle_pinch(synth) -> None:
    centre, _ = _mug_axis("mug")
    v = LIBRARY["mug"].geometry().vertices
    body_r = float(np.max(np.hypot(*(v[:, :2] - centre).T)[v[:, 2] > v[:, 2].max() - 1e-4]))
    cands = synth("mug")
    on_handle = [c for c in cands if np.all(np.hypot(*(c.contacts_m[:, :2] - centre).T) > body_r + 0.002)]
    assert on_handle, "no pinch across the handle"
    assert {ApproachKind.TOP, ApproachKind.SIDE} <= {c.approach for c in on_handle}
    # its 4.5 mm wall is below the stroke's minimum: no wall pinch with the default settings
    assert all(c.width_m >= MIN_GRIP_WIDTH_M - 1e-9 for c in cands)


@pytest.mark.skipif("mug" not in LIBRARY, reason="no mug in the library")
def test_mug_rim_wall_pinch_when_the_wall_is_allowed(synth) -> None:
    """With the minimum width lowered to take the mug's 4.5 mm wall, the rim pinch appears: one pad inside the
    cup on the inner wall, one outside, from the top, within 25 mm of the rim."""
    centre, rim_z = _mug_axis("mug")
    cands = synth("mug", **WALL_PINCH)
    rim = []
    for c in cands:
        radial = c.contacts_m[:, :2] - centre
        r = np.hypot(*radial.T)
        out_normal = np.einsum("ij,ij->i", c.normals[:, :2], radial / r[:, None])  # inward normal, radially
        inner = int(np.argmin(r))
        if (c.approach is ApproachKind.TOP and c.width_m < 0.008 and out_normal[inner] > 0.9
                and out_normal[1 - inner] < -0.9 and np.all(c.contacts_m[:, 2] > rim_z - 0.025)):
            rim.append(c)
    assert rim, "no rim-wall pinch"


# --------------------------------------------------------------------------- #
# ranking and the world
# --------------------------------------------------------------------------- #


def test_rank_prefers_margin_and_centred_grasps(synth) -> None:
    cands = synth("soda_can")
    top = [c for c in cands if c.approach is ApproachKind.TOP]
    ranked = rank(top)
    margins = [c.margin for c in ranked]
    offsets = [c.com_offset_m for c in ranked]
    assert margins[0] == pytest.approx(max(margins))
    assert offsets[0] == pytest.approx(min(offsets))
    assert ranked[-1].margin < ranked[0].margin and ranked[-1].com_offset_m > ranked[0].com_offset_m
    # all else equal (the same contacts), top before tilted before side
    first = rank(cands)
    same = [c for c in cands if np.allclose(c.contacts_m, first[0].contacts_m)]
    order = [c.approach for c in rank(same)]
    steps = [{ApproachKind.TOP: 0, ApproachKind.TILTED: 1, ApproachKind.SIDE: 2}[a] for a in order]
    assert steps == sorted(steps)


def test_grasps_whose_pads_meet_the_object_together_rank_first(synth) -> None:
    """Closing both pads alike, a grasp whose surface stands proud in front of one pad's contact only (the mug's
    handle bar met on its flank) has that pad meet the object first, pushing it alone: such grasps rank after those
    whose pads meet it together (every grasp of a box, a can, a ball does)."""
    for name in ("cube", "sugar_box", "soda_can", "tennis_ball", "l_bracket"):
        assert max(c.touch_lag_m for c in synth(name)) < 1e-6, name
    cands = synth("mug")
    lags = np.array([c.touch_lag_m for c in cands])
    print(f"\nmug: {len(cands)} grasps, {np.sum(lags > 1e-3)} with one pad meeting it over 1 mm before the other "
          f"(up to {lags.max() * 1e3:.2f} mm)")
    assert lags.max() > 1e-3 and np.any(lags < 1e-4)
    lagging = int(np.sum(lags > 1e-3))
    ranked = rank(cands)
    assert all(c.touch_lag_m > 1e-3 for c in ranked[len(ranked) - lagging:])  # after every other grasp
    unweighted = rank(cands, RankWeights(touch_lag=0.0))
    assert any(c.touch_lag_m > 1e-3 for c in unweighted[: len(ranked) - lagging])  # (they did not, unweighted)


def test_extra_cost_reorders(synth) -> None:
    cands = rank(synth("cube"))
    best, worst = cands[0], cands[-1]
    assert rank([worst, best]) == (best, worst)
    assert rank([best, worst], extra_cost=[1.0, 0.0]) == (worst, best)
    assert rank([best, worst], extra_cost=lambda c: 1.0 if c is best else 0.0) == (worst, best)
    assert rank([best, worst], RankWeights(extra=0.0), extra_cost=[1.0, 0.0]) == (best, worst)
    # a reference orientation pulls the nearest candidate to the front
    target = cands[7]
    assert rank(cands, RankWeights(orientation=10.0), reference=target.T_object_tcp)[0].T_object_tcp.isApprox(
        target.T_object_tcp)


def test_world_candidates_keep_the_gripper_above_the_table(synth, gripper: GripperGeometry) -> None:
    table = 0.75
    for name in ("cube", "soda_can", "tennis_ball"):
        obj = LIBRARY[name]
        T = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.4), np.array([0.5, 0.1, table - obj.geometry().z_min_m]))
        cands = rank(synth(name))
        placed = world_candidates(cands, gripper, T, table)
        assert placed and len(placed) < len(cands)
        assert [w.candidate for w in placed] == [c for c in cands if any(c is w.candidate for w in placed)]
        for w in placed:
            assert w.T_world_tcp.isApprox(T * w.candidate.T_object_tcp)
            # the pads closed on the contacts, and fully open: their lowest corner stays 5 mm above the table
            pad = np.array(gripper.pad_box_m)
            for shift in (0.0, gripper.open_inner_face_y_m - w.candidate.width_m / 2):
                for sign in (1.0, -1.0):
                    lo, hi = pad[:3] - pad[3:], pad[:3] + pad[3:]
                    corners = box_points(lo - [0, shift, 0], hi - [0, shift, 0], 1.0) * [1, sign, 1]
                    z = (corners @ w.T_world_tcp.rotation.T + w.T_world_tcp.translation)[:, 2]
                    assert z.min() >= table + TABLE_GAP_M - 1e-9
            assert w.T_world_pregrasp.translation[2] > table
    # the cube's side grasps put the coupling (37.5 mm radius) into the table; upside down, its top-down ones
    # come from below the table
    cube = LIBRARY["cube"]
    T = pin.SE3(np.eye(3), np.array([0.5, 0.1, table + 0.02]))
    assert all(w.candidate.approach is not ApproachKind.SIDE for w in world_candidates(synth("cube"), gripper, T,
                                                                                          table))
    flipped = pin.SE3(pin.rpy.rpyToMatrix(math.pi, 0.0, 0.0), T.translation)
    assert world_candidates(synth("cube"), gripper, flipped, table) == ()
    del cube
