"""Mesh objects: the library mug (its mesh, its convex parts, in MuJoCo), bad meshes, and the parts caches."""

from __future__ import annotations

import importlib.util
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import mujoco
import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from pickplace.errors import ConfigError
from pickplace.world import meshes
from pickplace.world.objects import MAX_GRIP_WIDTH_M, library_object

ROOT = Path(__file__).resolve().parents[1]


def _load_tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_meshes", ROOT / "tools" / "make_meshes.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_meshes"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


TOOL = _load_tool()
MUG = TOOL.MUG


@pytest.fixture(autouse=True)
def _isolated_caches(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Every test starts with empty in-process caches and a user cache under tmp_path (never ~/.cache)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg_cache"))
    meshes.clear_caches()
    yield
    meshes.clear_caches()


def _inside_any(parts: list[np.ndarray], points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Whether each point (N, 3) is inside (or on) the convex hull of some part."""
    planes = [ConvexHull(p).equations for p in parts]
    return np.array([any(np.all(eq[:, :3] @ q + eq[:, 3] <= tol) for eq in planes) for q in points])


def _ring(radius: float, zs: np.ndarray, step_deg: float) -> np.ndarray:
    return np.array([[radius * math.cos(a), radius * math.sin(a), z]
                     for a in np.radians(np.arange(0.0, 360.0, step_deg)) for z in zs])


# --------------------------------------------------------------------------- #
# the library mug
# --------------------------------------------------------------------------- #


def test_mug_mesh_is_a_solid_with_the_design_dimensions() -> None:
    mesh = meshes.load_mesh("mug.obj", 1.0)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.body_count == 1
    lo, hi = mesh.bounds
    np.testing.assert_allclose(lo, [-MUG.outer_radius_m, -MUG.outer_radius_m, MUG.z_min_m], atol=1e-6)
    np.testing.assert_allclose(hi, [MUG.handle_reach_x_m, MUG.outer_radius_m, -MUG.z_min_m], atol=1e-6)
    # Volume against the design: the body's shell as 96-gon prisms (exact for the mesh) plus the handle by
    # Pappus (its ellipse times its half-circle path); the part of the handle inside the wall counts twice
    # there, so 2 % (the handle is ~6 % of the whole).
    n = MUG.body_segments
    polygon = 0.5 * n * math.sin(2 * math.pi / n)
    shell = polygon * (MUG.outer_radius_m ** 2 * MUG.height_m
                       - MUG.inner_radius_m ** 2 * (MUG.height_m - MUG.bottom_m))
    handle = math.pi * MUG.handle_thickness_m / 2 * MUG.handle_width_m / 2 * math.pi * MUG.handle_radius_m
    assert mesh.volume == pytest.approx(shell + handle, rel=0.02)
    assert mesh.volume > shell


def test_mug_asset_is_what_the_script_builds() -> None:
    pytest.importorskip("manifold3d")
    vertices, faces = TOOL.build_mug(MUG)
    built = trimesh.Trimesh(vertices, faces, process=True)
    committed = meshes.load_mesh("mug.obj", 1.0)
    assert len(committed.faces) == len(built.faces)
    assert committed.volume == pytest.approx(built.volume, rel=1e-6)
    np.testing.assert_allclose(committed.bounds, built.bounds, atol=1e-8)


def test_mug_library_entry_matches_its_mesh() -> None:
    mug = library_object("mug")
    geometry = mug.geometry()
    mesh = meshes.load_mesh(mug.mesh_path, mug.mesh_scale)
    assert geometry.z_min_m == pytest.approx(MUG.z_min_m, abs=1e-7)
    assert geometry.volume_m3 == pytest.approx(mesh.volume, rel=1e-9)
    # mass = ceramic volume x density, as its source says
    assert mug.mass_kg == pytest.approx(mesh.volume * MUG.density_kg_m3, rel=0.005)
    assert 4 <= len(geometry.hulls) <= meshes.DECOMPOSITION.max_convex_hull
    assert all(len(h) <= meshes.DECOMPOSITION.max_ch_vertex for h in geometry.hulls)
    # its body fits the gripper across, with margin: the hull's thinnest width is across the body (at most its
    # 96-gon's width across the flats), and the body is at least 5 mm narrower than the widest grasp
    width, _, _ = meshes.hull_min_width(mesh.vertices)
    assert width <= 2 * MUG.outer_radius_m * math.cos(math.pi / MUG.body_segments) + 1e-9
    assert 2 * MUG.outer_radius_m <= MAX_GRIP_WIDTH_M - 0.005 + 1e-9


def test_mug_parts_come_from_the_sidecar_without_coacd(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_coacd(*args: object) -> None:
        raise AssertionError("CoACD must not run for a library mesh")

    monkeypatch.setattr(meshes, "_decompose", no_coacd)
    parts = meshes.convex_parts("mug.obj", 1.0)
    digest = meshes.mesh_digest(meshes.load_mesh("mug.obj", 1.0))
    stored = meshes.read_parts(meshes.parts_path(meshes.ASSETS_DIR / "mug.obj"), digest)
    assert stored is not None and len(stored) == len(parts)
    assert all(not p.flags.writeable and p.shape[1] == 3 and len(p) >= 4 for p in parts)


def test_mug_parts_cover_the_wall_and_leave_the_cavity_open() -> None:
    parts = meshes.convex_parts("mug.obj", 1.0)
    top = -MUG.z_min_m
    # inside the material: the middle of the side wall from 1 mm up to 1 mm below the rim, and of the bottom
    wall = _ring(MUG.inner_radius_m + MUG.wall_m / 2, np.linspace(MUG.z_min_m + 0.001, top - 0.001, 10), 5.0)
    bottom = np.array([[r * math.cos(a), r * math.sin(a), MUG.z_min_m + MUG.bottom_m / 2]
                       for a in np.radians(np.arange(0.0, 360.0, 30.0)) for r in (0.0, 0.015, 0.03)])
    assert _inside_any(parts, wall).all()
    assert _inside_any(parts, bottom).all()
    # the cavity: its centre, and a ring 2 mm inside the inner wall from 1 mm above the floor to the rim
    # (a pad can go down inside the rim); the parts bulge into it by ~1.25 mm where the hulls span the curve
    centre = np.array([[0.0, 0.0, (MUG.cavity_floor_z_m + top) / 2]])
    assert not _inside_any(parts, centre).any()
    cavity = _ring(MUG.inner_radius_m - 0.002, np.linspace(MUG.cavity_floor_z_m + 0.001, top, 10), 3.0)
    assert not _inside_any(parts, cavity).any()
    # the parts stay close to the mesh: their hulls hold at most 15 % more than the mug itself
    volume = sum(ConvexHull(p).volume for p in parts)
    mesh_volume = meshes.load_mesh("mug.obj", 1.0).volume
    assert mesh_volume <= volume <= 1.15 * mesh_volume


def test_mug_compiles_in_mujoco_and_rests_upright() -> None:
    mug = library_object("mug")
    parts = list(mug.geometry().hulls)
    volumes = [ConvexHull(p).volume for p in parts]
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.5, 0.5, 0.05])
    body = spec.worldbody.add_body(name="mug", pos=[0.0, 0.0, -MUG.z_min_m + 0.002])
    body.add_freejoint()
    for i, (part, volume) in enumerate(zip(parts, volumes, strict=True)):
        spec.add_mesh(name=f"mug_{i}", uservert=part.ravel().tolist())
        body.add_geom(name=f"mug_{i}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"mug_{i}",
                      mass=mug.mass_kg * volume / sum(volumes), friction=[mug.friction, 0.005, 0.0])
    model = spec.compile()
    assert model.nmesh == len(parts) and model.ngeom == len(parts) + 1
    assert model.body("mug").mass[0] == pytest.approx(mug.mass_kg, rel=1e-6)
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=500)  # 1 s: it drops 2 mm and settles
    z_axis = np.empty(9)
    mujoco.mju_quat2Mat(z_axis, data.qpos[3:7])
    tilt_deg = math.degrees(math.acos(min(1.0, z_axis[8])))
    assert tilt_deg < 0.5
    assert data.qpos[2] == pytest.approx(-MUG.z_min_m, abs=0.001)  # standing on its bottom (contacts ~sub-mm)
    np.testing.assert_allclose(data.qpos[:2], [0.0, 0.0], atol=0.001)
    assert np.linalg.norm(data.qvel[:3]) < 1e-3 and np.linalg.norm(data.qvel[3:]) < 1e-2


# --------------------------------------------------------------------------- #
# bad meshes: one ConfigError on object.mesh_path each
# --------------------------------------------------------------------------- #


def _box(extents_m: tuple[float, float, float]) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=extents_m)


def _rejected(path: Path | str, scale: float = 1.0) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        meshes.load_mesh(str(path), scale)
    assert info.value.field == "object.mesh_path"
    assert info.value.value == str(path)
    return info.value


def test_missing_file_and_wrong_type_are_rejected(tmp_path: Path) -> None:
    assert "no such file" in str(_rejected(tmp_path / "nothing.obj"))
    ply = tmp_path / "box.ply"
    _box((0.03, 0.03, 0.03)).export(ply)
    assert "OBJ or STL" in str(_rejected(ply))
    garbage = tmp_path / "garbage.stl"
    garbage.write_text("this is not a mesh\n")
    message = str(_rejected(garbage))
    assert "could not be read" in message or "no triangles" in message
    (tmp_path / "dir.obj").mkdir()
    assert "not a file" in str(_rejected(tmp_path / "dir.obj"))


def test_non_watertight_mesh_is_rejected(tmp_path: Path) -> None:
    box = _box((0.03, 0.03, 0.03))
    path = tmp_path / "open_box.stl"
    trimesh.Trimesh(box.vertices, box.faces[1:], process=False).export(path)
    message = str(_rejected(path))
    assert "not watertight: 3 open edges" in message and "mesh tool" in message


def test_badly_wound_inside_out_and_split_meshes_are_rejected(tmp_path: Path) -> None:
    box = _box((0.03, 0.03, 0.03))
    flipped_one = box.faces.copy()
    flipped_one[0] = flipped_one[0, ::-1]
    path = tmp_path / "one_flipped.obj"
    trimesh.Trimesh(box.vertices, flipped_one, process=False).export(path)
    assert "not consistently wound" in str(_rejected(path))
    path = tmp_path / "inside_out.obj"
    trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False).export(path)
    assert "inside out" in str(_rejected(path))
    path = tmp_path / "two_boxes.obj"
    trimesh.util.concatenate([box, _box((0.02, 0.02, 0.02)).apply_translation((0.1, 0, 0))]).export(path)
    assert "2 separate pieces" in str(_rejected(path))


def test_meshes_too_wide_for_the_gripper_are_rejected(tmp_path: Path) -> None:
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=3, radius=0.100).export(path)  # 200 mm
    message = str(_rejected(path))
    assert "too large for the gripper (84 mm opening)" in message
    width_mm = float(message.split("thinnest width is ")[1].removeprefix("at least ").split(" mm")[0])
    assert 190.0 <= width_mm <= 200.0  # a lower bound from 128 of its 642 vertices: within ~1 %
    path = tmp_path / "big_cube.obj"
    _box((0.080, 0.080, 0.080)).export(path)  # a solid 80 mm cube: no thinner part anywhere
    assert "thinnest width is 80.0 mm" in str(_rejected(path))
    path = tmp_path / "ok_box.obj"
    _box((0.070, 0.120, 0.120)).export(path)  # 70 mm across one way: fits
    assert meshes.load_mesh(str(path), 1.0).volume == pytest.approx(0.070 * 0.120 * 0.120, rel=1e-9)


def test_extent_is_checked_after_scaling(tmp_path: Path) -> None:
    path = tmp_path / "cube_mm.stl"
    _box((40.0, 40.0, 40.0)).export(path)  # a 40 mm cube written in millimetres
    message = str(_rejected(path))
    assert "40000.0 mm across" in message and "object.mesh_scale = 0.001" in message
    mesh = meshes.load_mesh(str(path), 0.001)
    np.testing.assert_allclose(mesh.extents, [0.04, 0.04, 0.04], rtol=1e-12)
    with pytest.raises(ConfigError) as info:
        meshes.load_mesh(str(path), -1.0)
    assert info.value.field == "object.mesh_scale"


# --------------------------------------------------------------------------- #
# the minimum width, paths and caches
# --------------------------------------------------------------------------- #


def test_hull_min_width_is_exact_on_known_solids() -> None:
    rotation = trimesh.transformations.random_rotation_matrix(np.random.default_rng(3).random(3))
    box = _box((0.03, 0.05, 0.07)).apply_transform(rotation)
    width, direction, exact = meshes.hull_min_width(box.vertices)
    assert exact and width == pytest.approx(0.03, abs=1e-12)
    assert abs(direction @ rotation[:3, 0]) == pytest.approx(1.0, abs=1e-9)
    # a regular tetrahedron's thinnest width is between two opposite edges: a / sqrt(2) (not a face's height)
    a = 0.05
    tetra = a / (2 * math.sqrt(2)) * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    width, _, exact = meshes.hull_min_width(tetra)
    assert exact and width == pytest.approx(a / math.sqrt(2), abs=1e-12)


def test_library_names_resolve_to_the_assets_and_paths_are_used_as_given(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    assert meshes.resolve_mesh_path("mug.obj") == meshes.ASSETS_DIR / "mug.obj"
    monkeypatch.chdir(tmp_path)
    _box((0.03, 0.03, 0.03)).export(tmp_path / "mug.obj")
    assert meshes.resolve_mesh_path("./mug.obj") == tmp_path / "mug.obj"
    assert meshes.load_mesh("./mug.obj", 1.0).volume == pytest.approx(0.03 ** 3, rel=1e-9)
    assert meshes.resolve_mesh_path("other.obj") == tmp_path / "other.obj"


def test_a_changed_file_is_read_again_and_callers_get_copies(tmp_path: Path) -> None:
    path = tmp_path / "box.obj"
    _box((0.03, 0.03, 0.03)).export(path)
    first = meshes.load_mesh(str(path), 1.0)
    first.apply_scale(2.0)  # the caller's copy: the cache is untouched
    assert meshes.load_mesh(str(path), 1.0).extents[0] == pytest.approx(0.03, rel=1e-12)
    _box((0.05, 0.03, 0.03)).export(path)  # another size (and file size and mtime)
    assert meshes.load_mesh(str(path), 1.0).extents[0] == pytest.approx(0.05, rel=1e-12)


def test_parts_file_round_trip_and_digest_check(tmp_path: Path) -> None:
    parts = [np.eye(3, 3) * 0.01, np.ones((4, 3)) * 0.02]
    path = tmp_path / "x.parts.npz"
    meshes.write_parts(path, parts, "abc", meshes.DECOMPOSITION)
    first = path.read_bytes()
    meshes.write_parts(path, parts, "abc", meshes.DECOMPOSITION)
    assert path.read_bytes() == first  # reproducible bytes (fixed zip dates)
    back = meshes.read_parts(path, "abc")
    assert back is not None and all(np.array_equal(a, b) for a, b in zip(parts, back, strict=True))
    assert meshes.read_parts(path, "another mesh") is None
    path.write_bytes(b"not a zip")
    assert meshes.read_parts(path, "abc") is None


def _l_shape_mm() -> trimesh.Trimesh:
    """An L profile (40 x 40 mm, legs 10 mm thick) extruded 20 mm: a small non-convex solid, in millimetres."""
    profile = np.array([[0, 0], [40, 0], [40, 10], [10, 10], [10, 40], [0, 40]], dtype=float)
    fan = np.array([[3, 4, 5], [3, 5, 0], [3, 0, 1], [3, 1, 2]])  # from the inner corner (it sees every vertex)
    return trimesh.creation.extrude_triangulation(profile, fan, 20.0)


def test_user_mesh_is_decomposed_once_then_read_from_the_disk_cache(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("coacd")
    path = tmp_path / "l_shape.stl"
    _l_shape_mm().export(path)
    first = meshes.convex_parts(str(path), 0.001)  # CoACD: ~0.4 s
    cached = list((tmp_path / "xdg_cache" / "pickplace" / "meshes").glob("*.npz"))
    assert len(cached) == 1
    assert len(first) >= 2  # not convex: at least two parts
    lo = np.min([p.min(axis=0) for p in first], axis=0)
    hi = np.max([p.max(axis=0) for p in first], axis=0)
    np.testing.assert_allclose(lo, [0.0, 0.0, 0.0], atol=2e-4)
    np.testing.assert_allclose(hi, [0.04, 0.04, 0.02], atol=2e-4)
    assert not _inside_any(first, np.array([[0.025, 0.025, 0.01]])).any()  # the L's notch stays empty

    def no_coacd(*args: object) -> None:
        raise AssertionError("the second call must read the disk cache")

    meshes.clear_caches()
    monkeypatch.setattr(meshes, "_decompose", no_coacd)
    second = meshes.convex_parts(str(path), 0.001)
    assert all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))
    doubled = meshes.convex_parts(str(path), 0.002)  # another scale: the same cached parts, scaled
    assert all(np.allclose(a * 2, b, rtol=1e-12) for a, b in zip(first, doubled, strict=True))


def test_missing_coacd_gives_one_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "l_shape.obj"
    _l_shape_mm().export(path)
    monkeypatch.setitem(sys.modules, "coacd", None)  # import coacd -> ImportError
    with pytest.raises(ConfigError) as info:
        meshes.convex_parts(str(path), 0.001)
    assert info.value.field == "object.mesh_path"
    assert "pip install 'pickplace[mesh]'" in str(info.value)
    assert not (tmp_path / "xdg_cache" / "pickplace" / "meshes").exists() or not any(
        (tmp_path / "xdg_cache" / "pickplace" / "meshes").iterdir())
