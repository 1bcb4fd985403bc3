"""Mesh objects: an OBJ or STL file loaded, checked, and decomposed into convex parts for collisions.

A mesh object (``ObjectConfig(kind="mesh", mesh_path=..., mesh_scale=...)``) reaches the simulation through
two functions, both cached in-process:

* :func:`load_mesh`: the file read with trimesh, scaled to metres and checked: it must be **one
  watertight, consistently wound solid with a positive volume**, its largest extent must fit the scene
  (<= ``MAX_EXTENT_M``), and the gripper must be able to take it somewhere (see :func:`load_mesh`).
* :func:`convex_parts`: the vertices of the convex parts of its decomposition (CoACD). MuJoCo collides a
  mesh geom as its convex hull, so a non-convex object (a mug) needs one mesh geom per convex part.

Where the parts come from, in order:

1. a **sidecar file** ``<stem>.parts.npz`` next to the mesh, written for this very mesh (its geometry's
   SHA-256 is stored in it and checked): the library's meshes ship with theirs, written by
   ``tools/make_meshes.py``, so the library needs no CoACD at run time;
2. the **user cache** ``$XDG_CACHE_HOME/pickplace/meshes/`` (``~/.cache/pickplace/meshes/`` by default),
   keyed by the mesh geometry's SHA-256 and the decomposition settings (:data:`DECOMPOSITION`);
3. **CoACD** itself (the optional ``coacd`` package: ``pip install 'pickplace[mesh]'``), whose result is
   then written to the user cache (atomically). A mug takes CoACD ~10-30 s, once per mesh and machine.

Parts are stored in the mesh file's own units and scaled on load: a uniform scale maps a convex decomposition
onto one of the scaled mesh, so one decomposition serves every ``mesh_scale`` (and CoACD normalises its input
to a unit box anyway: an L shape in mm and in m gave the same parts to 1e-18 m).

A file name without a directory that names one of the library's assets (``"mug.obj"``) resolves to
``pickplace/world/assets/``; any other path is used as given (relative to the current directory). Write
``./mug.obj`` to use your own file of the same name.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import logging
import os
import tempfile
import time
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

from pickplace.errors import ConfigError
from pickplace.world.checks import check_range
from pickplace.world.objects import MAX_EXTENT_M, MAX_GRIP_WIDTH_M

log = logging.getLogger(__name__)

#: The configuration field every mesh error names.
FIELD = "object.mesh_path"
#: Where the library's mesh assets (and their precomputed convex parts) live.
ASSETS_DIR = Path(__file__).resolve().parent / "assets"
#: File types a mesh object may be read from (lower case).
MESH_SUFFIXES = (".obj", ".stl")
#: Smallest largest-extent of a mesh object (m): the smallest primitive edge the configs accept (1 mm).
MIN_EXTENT_M = 0.001
#: A convex part thinner than this is inflated to it (m): MuJoCo cannot compile a flat (coplanar) mesh.
MIN_PART_THICKNESS_M = 0.0005
#: A convex part whose hull holds less than this fraction of all the parts' volume is dropped.
MIN_PART_VOLUME_FRACTION = 1e-6
#: The minimum width of a hull with more vertices than this is bounded from below on this many of them.
MAX_WIDTH_VERTICES = 128
#: Opposite faces a pad pair can pinch: their normals are antiparallel within this angle (deg).
PINCH_MAX_ANGLE_DEG = 20.0
#: Faces cast a ray from when looking for a part thin enough to pinch (evenly spread over the faces).
MAX_PINCH_RAYS = 1024
#: Ray-triangle pairs tested per batch (bounds the memory of :func:`_pinch_width`: ~24 bytes per pair).
_PAIRS_PER_BATCH = 200_000
#: Sidecar suffix of precomputed convex parts: ``mug.obj`` -> ``mug.parts.npz``.
PARTS_SUFFIX = ".parts.npz"
#: Version of the parts file layout (stored in it; a file of another version is not used).
_PARTS_FORMAT = 1


@dataclass(frozen=True)
class DecompositionSettings:
    """Settings of the convex decomposition (the arguments of ``coacd.run_coacd`` that pickplace sets).

    Attributes:
        threshold: CoACD's concavity threshold, on the mesh normalised to a unit box (smaller: more, tighter
            parts). 0.03 leaves a mug's cavity free to within ~1.5 mm of its inner wall.
        max_convex_hull: Most convex parts (bounds the collision cost of one object).
        preprocess_mode: ``"auto"``: CoACD remeshes the input only if it is not a 2-manifold.
        preprocess_resolution: Voxel resolution of that remeshing.
        resolution: Samples of CoACD's concavity metric.
        mcts_nodes: Children per node of CoACD's cutting-plane tree search.
        mcts_iterations: Iterations of that search.
        mcts_max_depth: Depth of that search.
        merge: Merge parts while the concavity stays below the threshold.
        decimate: Simplify each part's hull to at most ``max_ch_vertex`` vertices.
        max_ch_vertex: Most vertices per part (keeps MuJoCo's collision support search cheap).
        seed: CoACD's random seed (its result is then the same run after run, thread count aside).
    """

    threshold: float = 0.03
    max_convex_hull: int = 32
    preprocess_mode: str = "auto"
    preprocess_resolution: int = 50
    resolution: int = 2000
    mcts_nodes: int = 20
    mcts_iterations: int = 150
    mcts_max_depth: int = 3
    merge: bool = True
    decimate: bool = True
    max_ch_vertex: int = 64
    seed: int = 0

    def key(self) -> str:
        """A short hash of the settings (names the user cache's files)."""
        text = json.dumps(dataclasses.asdict(self), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]


#: The settings pickplace decomposes every mesh with (the library's parts were made with these).
DECOMPOSITION = DecompositionSettings()


class _Invalid(Exception):
    """A mesh problem, raised inside the cached helpers and turned into a ConfigError naming the user's value."""


# --------------------------------------------------------------------------- #
# public API
# --------------------------------------------------------------------------- #


def load_mesh(path: str, scale: float) -> trimesh.Trimesh:
    """The mesh of an OBJ or STL file, scaled to metres and checked.

    Checks: the file exists and reads as triangles; the mesh is one watertight (every edge shared by exactly
    two triangles), consistently wound solid with a positive volume; its largest extent is 1 mm to
    ``MAX_EXTENT_M``; and the gripper can take it somewhere. That last check is a necessary condition,
    not a grasp: a mesh is rejected when the minimum width of its convex hull (its thinnest caliper width
    over all directions) exceeds ``MAX_GRIP_WIDTH_M`` (the 84 mm opening less 5 mm per side) **and** no
    part of it is thin enough to pinch: no face whose inward ray meets an opposite face (normals
    antiparallel within ``PINCH_MAX_ANGLE_DEG``) within ``MAX_GRIP_WIDTH_M``. So an 11 oz mug (81 mm
    across) would pass by its 5 mm wall and its handle, a 200 mm ball does not. So an object with a thin graspable
    part (a handle) inside a hull wider than 74 mm everywhere passes only if a ray finds that part; the
    rule does not ask whether a pad can reach the part, or whether the part is thicker than the closed
    gripper (``MIN_GRIP_WIDTH_M``): grasp synthesis is the real test. The hull's width is exact for
    hulls of up to ``MAX_WIDTH_VERTICES`` vertices and a lower bound beyond (so this never rejects a
    mesh that would fit); the thin-part search looks at up to ``MAX_PINCH_RAYS`` faces. Self-intersections
    are not checked.

    Args:
        path: The file (``.obj`` or ``.stl``): a library asset name (``"mug.obj"``) or a path used as given.
        scale: Factor from the file's units to metres (e.g. 0.001 for millimetres).

    Returns:
        A copy of the cached mesh (m), z up as in the file.

    Raises:
        ConfigError: on ``object.mesh_path``, saying what is wrong and how to fix it.
    """
    scale = check_range("object.mesh_scale", scale, 0.0, 10.0, lo_open=True)
    resolved, stat = _locate(path)
    try:
        mesh = _load_checked(str(resolved), stat.st_mtime_ns, stat.st_size, scale)
    except _Invalid as exc:
        raise ConfigError(FIELD, path, str(exc)) from None
    return mesh.copy()


def convex_parts(path: str, scale: float) -> list[np.ndarray]:
    """The convex parts of a mesh's decomposition (see the module docstring for where they come from).

    Each part is the vertices of its convex hull (only hull vertices), a proper 3-D solid at least
    ``MIN_PART_THICKNESS_M`` thick along its flattest principal axis (flat ones are inflated to that,
    needle-like and negligible ones dropped, so MuJoCo compiles each): one MuJoCo mesh geom each.

    Args:
        path: The mesh file, as for :func:`load_mesh`.
        scale: Factor from the file's units to metres.

    Returns:
        The parts' vertices, each (K_i, 3) in metres, read-only.

    Raises:
        ConfigError: on ``object.mesh_path``: the mesh is invalid (:func:`load_mesh`), or it must be
            decomposed and the ``coacd`` package is missing.
    """
    load_mesh(path, scale)  # the same checks (cached)
    scale = float(scale)
    resolved, stat = _locate(path)
    try:
        return list(_parts_cached(str(resolved), stat.st_mtime_ns, stat.st_size, scale))
    except _Invalid as exc:
        raise ConfigError(FIELD, path, str(exc)) from None


def resolve_mesh_path(path: str) -> Path:
    """Where a mesh path points: a bare library asset name to ``ASSETS_DIR``, anything else as given.

    Raises:
        ConfigError: the path is empty or not a string.
    """
    if not isinstance(path, str | os.PathLike) or not str(path):
        raise ConfigError(FIELD, path, "must be the path of an OBJ or STL file")
    text = os.fspath(path)
    given = Path(text).expanduser()
    bare = not any(sep in text for sep in (os.sep, os.altsep, "/") if sep)  # "./mug.obj" is not bare
    if bare:
        asset = ASSETS_DIR / given
        if asset.is_file():
            if given.is_file():
                log.warning("mesh path %r names a library asset; using %s, not the file in the current directory "
                            "(write './%s' for that one)", str(path), asset, given)
            return asset
    return given.absolute()


def cache_dir() -> Path:
    """The user cache directory of convex decompositions: ``$XDG_CACHE_HOME/pickplace/meshes``
    (``~/.cache/pickplace/meshes`` when ``XDG_CACHE_HOME`` is unset), read from the environment on each call."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "pickplace" / "meshes"


def parts_path(mesh_path: str | Path) -> Path:
    """The sidecar file of a mesh's precomputed convex parts: ``mug.obj`` -> ``mug.parts.npz``."""
    p = Path(mesh_path)
    return p.with_name(p.stem + PARTS_SUFFIX)


def clear_caches() -> None:
    """Forget every mesh and decomposition cached in this process (the files on disk stay)."""
    for f in (_read, _load_checked, _parts_cached):
        f.cache_clear()


def mesh_digest(mesh: trimesh.Trimesh) -> str:
    """SHA-256 (hex) of a mesh's geometry: its vertices (little-endian float64) and triangles (int64).

    Hashing the geometry rather than the file's bytes ignores formatting, comments and line endings.
    """
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())
    return h.hexdigest()


def decompose(mesh: trimesh.Trimesh, settings: DecompositionSettings = DECOMPOSITION) -> list[np.ndarray]:
    """Run CoACD on a mesh (slow: seconds to a minute).

    Args:
        mesh: A watertight mesh (any units).
        settings: CoACD's settings.

    Returns:
        The vertices (K_i, 3) of each convex part, in the mesh's units, as CoACD returns them.

    Raises:
        ConfigError: the ``coacd`` package is not installed (on ``object.mesh_path``, value None).
    """
    try:
        return _decompose(mesh, settings)
    except _Invalid as exc:
        raise ConfigError(FIELD, None, str(exc)) from None


def precompute_parts(path: str | Path, settings: DecompositionSettings = DECOMPOSITION) -> Path:
    """Decompose a mesh file and write its sidecar parts file next to it (what ``tools/make_meshes.py``
    does for the library's meshes).

    Args:
        path: The mesh file (checked at scale 1 for being a solid only; its size is not checked).
        settings: CoACD's settings.

    Returns:
        The sidecar file written (:func:`parts_path`).

    Raises:
        ConfigError: the mesh is invalid or ``coacd`` is missing.
    """
    resolved, stat = _locate(str(path))
    try:
        raw = _read(str(resolved), stat.st_mtime_ns, stat.st_size)
        parts = _decompose(raw, settings)
    except _Invalid as exc:
        raise ConfigError(FIELD, str(path), str(exc)) from None
    out = parts_path(resolved)
    write_parts(out, parts, mesh_digest(raw), settings)
    return out


def write_parts(path: Path, parts: Sequence[np.ndarray], digest: str, settings: DecompositionSettings) -> None:
    """Write convex parts to an ``.npz`` file, atomically and byte for byte reproducibly (fixed zip dates).

    Args:
        path: The file to write.
        parts: Vertices (K_i, 3) of each part, in the mesh file's units.
        digest: :func:`mesh_digest` of the mesh they belong to (checked when they are read).
        settings: The settings they were made with (recorded).
    """
    arrays = {
        "format": np.array(_PARTS_FORMAT, dtype="<i8"),
        "mesh_sha256": np.array(digest),
        "settings": np.array(json.dumps(dataclasses.asdict(settings), sort_keys=True)),
        "counts": np.array([len(p) for p in parts], dtype="<i8"),
        "vertices": np.concatenate([np.asarray(p, dtype="<f8").reshape(-1, 3) for p in parts])
        if parts else np.zeros((0, 3), dtype="<f8"),
    }
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, array in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.create_system = 3
            info.external_attr = 0o644 << 16
            with archive.open(info, "w") as member:
                np.lib.format.write_array(member, array, allow_pickle=False)
    _atomic_write(path, buffer.getvalue())


def read_parts(path: Path, digest: str) -> list[np.ndarray] | None:
    """Convex parts from an ``.npz`` file written by :func:`write_parts`, if it belongs to the mesh.

    Args:
        path: The file.
        digest: :func:`mesh_digest` of the mesh the parts must belong to.

    Returns:
        The vertices (K_i, 3) of each part in the mesh file's units, or None if the file is missing,
        unreadable, of another layout, or made for another mesh (logged).
    """
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if int(data["format"]) != _PARTS_FORMAT:
                log.warning("ignoring %s: parts file format %s, expected %s", path, int(data["format"]),
                            _PARTS_FORMAT)
                return None
            if str(data["mesh_sha256"]) != digest:
                log.warning("ignoring %s: it was made for another version of the mesh (regenerate it, e.g. with "
                            "tools/make_meshes.py for a library mesh)", path)
                return None
            counts, vertices = np.asarray(data["counts"]), np.asarray(data["vertices"], dtype=float)
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        log.warning("ignoring unreadable parts file %s: %s", path, exc)
        return None
    if counts.ndim != 1 or vertices.shape != (int(counts.sum()), 3) or np.any(counts < 0):
        log.warning("ignoring malformed parts file %s", path)
        return None
    return np.split(vertices, np.cumsum(counts)[:-1]) if len(counts) else []


def hull_min_width(points: np.ndarray, max_vertices: int = MAX_WIDTH_VERTICES) -> tuple[float, np.ndarray, bool]:
    """Minimum width of the convex hull of points: the smallest distance between two parallel planes that
    enclose them, over all directions.

    It is attained along a hull face's normal or along the cross product of two hull edges, so all these
    directions are tried. A hull with more than ``max_vertices`` vertices is replaced by the hull of
    ``max_vertices`` of its vertices spread by farthest-point sampling: an inner hull, so its width is a
    lower bound in every direction.

    Args:
        points: Points (N, 3), N >= 4, not all in one plane (m).
        max_vertices: Most hull vertices to work on exactly.

    Returns:
        The width (m), its direction (3,) (unit), and whether the width is exact (else a lower bound).
    """
    pts = np.asarray(points, dtype=float)
    try:
        verts = pts[np.sort(ConvexHull(pts).vertices)]
        exact = len(verts) <= max_vertices
        if not exact:
            verts = _farthest_points(verts, max_vertices)
        hull = ConvexHull(verts)
    except QhullError:  # flat (or the sample of its vertices is): no width to speak of
        return 0.0, np.array([0.0, 0.0, 1.0]), False
    edges = np.unique(np.sort(np.concatenate([hull.simplices[:, [0, 1]], hull.simplices[:, [1, 2]],
                                              hull.simplices[:, [2, 0]]]), axis=1), axis=0)
    vec = verts[edges[:, 1]] - verts[edges[:, 0]]
    best_w, best_dir = np.inf, np.array([0.0, 0.0, 1.0])
    size = float(np.max(np.ptp(verts, axis=0)))
    i, j = np.triu_indices(len(vec), k=1)
    batches = [hull.equations[:, :3]] + [
        np.cross(vec[i[s:s + 20_000]], vec[j[s:s + 20_000]]) for s in range(0, len(i), 20_000)]
    for dirs in batches:
        norm = np.linalg.norm(dirs, axis=1)
        dirs = dirs[norm > 1e-12 * size * size] / norm[norm > 1e-12 * size * size, None]
        if not len(dirs):
            continue
        proj = verts @ dirs.T
        widths = proj.max(axis=0) - proj.min(axis=0)
        k = int(np.argmin(widths))
        if widths[k] < best_w:
            best_w, best_dir = float(widths[k]), dirs[k]
    return best_w, best_dir, exact


# --------------------------------------------------------------------------- #
# reading and checking
# --------------------------------------------------------------------------- #


def _locate(path: str) -> tuple[Path, os.stat_result]:
    """The resolved file and its stat, or a ConfigError saying why it cannot be used."""
    resolved = resolve_mesh_path(path)
    if resolved.suffix.lower() not in MESH_SUFFIXES:
        raise ConfigError(FIELD, path, f"must be an OBJ or STL file ({', '.join(MESH_SUFFIXES)}), not "
                                       f"{resolved.suffix or 'a file without a suffix'!r}")
    if not resolved.exists():
        raise ConfigError(FIELD, path, f"no such file: {resolved} (a path is used as given, relative to the "
                                       f"current directory {Path.cwd()}; the library's assets are "
                                       f"{', '.join(sorted(_asset_names())) or 'none'})")
    if not resolved.is_file():
        raise ConfigError(FIELD, path, f"{resolved} is not a file")
    if not os.access(resolved, os.R_OK):
        raise ConfigError(FIELD, path, f"{resolved} is not readable (check its permissions)")
    return resolved, resolved.stat()


def _asset_names() -> list[str]:
    return [p.name for p in ASSETS_DIR.glob("*") if p.suffix.lower() in MESH_SUFFIXES] if ASSETS_DIR.is_dir() else []


@functools.lru_cache(maxsize=32)
def _read(path: str, mtime_ns: int, size: int) -> trimesh.Trimesh:
    """The file's mesh in its own units, vertices merged by position, checked to be one solid.

    ``mtime_ns`` and ``size`` only key the cache (a changed file is read again).
    """
    del mtime_ns, size
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # parsers raise anything on a corrupt file
        raise _Invalid(f"could not be read as a mesh: {type(exc).__name__}: {exc}") from None
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))))
    if not isinstance(loaded, trimesh.Trimesh) or len(faces) == 0:
        raise _Invalid("contains no triangles (is it a point cloud or an empty file?)")
    # A plain mesh (no normals, no texture): process=True merges vertices by position only, so seams of a
    # textured OBJ do not count as open edges.
    mesh = trimesh.Trimesh(vertices=np.asarray(loaded.vertices, dtype=float), faces=faces, process=True)
    if not np.all(np.isfinite(mesh.vertices)):
        raise _Invalid("has vertices that are not finite numbers")
    _check_solid(mesh)
    return mesh


def _check_solid(mesh: trimesh.Trimesh) -> None:
    """One watertight, consistently wound solid with a positive volume, or _Invalid saying how to fix it."""
    edges = mesh.edges_sorted
    _, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges, shared = int(np.sum(counts == 1)), int(np.sum(counts > 2))
    if open_edges or shared:
        what = " and ".join(s for s in (f"{open_edges} open edges (edges of one triangle only)" if open_edges else "",
                                         f"{shared} edges shared by more than two triangles" if shared else "") if s)
        raise _Invalid(f"the mesh is not watertight: {what}; close the holes and remove the extra faces in a "
                       "mesh tool (e.g. MeshLab's Close Holes, Blender's 3D-Print Toolbox) and export it again")
    if not mesh.is_winding_consistent:
        raise _Invalid("the mesh's triangles are not consistently wound (some face inward, some outward); "
                       "recalculate the normals outward in a mesh tool (e.g. Blender: Mesh > Normals > "
                       "Recalculate Outside)")
    bodies = int(mesh.body_count)
    if bodies != 1:
        raise _Invalid(f"the mesh has {bodies} separate pieces; an object must be one solid: join them (a boolean "
                       "union) or delete the extra ones in a mesh tool")
    volume = float(mesh.volume)
    if volume < 0:
        raise _Invalid(f"the mesh is inside out (its volume is {volume:.3g} in file units cubed): flip its "
                       "normals in a mesh tool")
    if not volume > 1e-12 * float(np.max(mesh.extents)) ** 3:
        raise _Invalid("the mesh encloses no volume (it is flat)")


@functools.lru_cache(maxsize=32)
def _load_checked(path: str, mtime_ns: int, size: int, scale: float) -> trimesh.Trimesh:
    """The file's mesh scaled to metres, checked for size and for the gripper."""
    mesh = _read(path, mtime_ns, size).copy()
    mesh.apply_scale(scale)
    extent = float(np.max(mesh.extents))
    if not MIN_EXTENT_M <= extent <= MAX_EXTENT_M:
        hint = ""
        for factor, unit in ((0.001, "millimetres"), (0.01, "centimetres"), (0.0254, "inches")):
            if MIN_EXTENT_M <= extent * factor <= MAX_EXTENT_M and scale == 1.0:
                hint = f" (if the file is in {unit}, set object.mesh_scale = {factor:g})"
                break
        size = f"{extent * 1e3:.1f}" if extent >= 0.001 else f"{extent * 1e3:.3g}"
        raise _Invalid(f"the mesh is {size} mm across after mesh_scale = {scale:g}; an object must be "
                       f"{MIN_EXTENT_M * 1e3:g} to {MAX_EXTENT_M * 1e3:g} mm{hint}")
    _check_grip(mesh)
    log.debug("loaded mesh %s x %g: %d vertices, %d faces, %.4g cm^3, extents %s mm", path, scale,
              len(mesh.vertices), len(mesh.faces), mesh.volume * 1e6, np.round(mesh.extents * 1e3, 1))
    return mesh


def _check_grip(mesh: trimesh.Trimesh) -> None:
    """_Invalid if the hull is wider than the gripper takes in every direction and nothing is thin enough."""
    width, _, exact = hull_min_width(np.asarray(mesh.vertices))
    if width <= MAX_GRIP_WIDTH_M:
        return
    pinch = _pinch_width(mesh, MAX_GRIP_WIDTH_M)
    if pinch is not None and pinch <= MAX_GRIP_WIDTH_M:
        log.debug("mesh hull is %.1f mm wide at its thinnest, but it has a part %.1f mm thick to pinch",
                  width * 1e3, pinch * 1e3)
        return
    raise _Invalid(
        f"too large for the gripper (84 mm opening): its thinnest width is {'' if exact else 'at least '}"
        f"{width * 1e3:.1f} mm (the minimum width of its convex hull; at most {MAX_GRIP_WIDTH_M * 1e3:.0f} mm fits "
        f"with 5 mm to spare per side) and no part of it is thinner than that between opposite faces; scale it "
        f"down (object.mesh_scale) or choose a smaller object")


def _pinch_width(mesh: trimesh.Trimesh, limit: float) -> float | None:
    """Thickness (m) of the thinnest pinchable part found, or None: from the centroids of up to
    ``MAX_PINCH_RAYS`` faces a ray goes inward along the face's normal to the first face it meets; the
    distance counts if that face's normal is antiparallel within ``PINCH_MAX_ANGLE_DEG``. Stops at the first
    thickness <= ``limit``."""
    tri = np.asarray(mesh.triangles, dtype=float)
    normals = np.asarray(mesh.face_normals, dtype=float)
    n_faces = len(tri)
    rays = np.unique(np.linspace(0, n_faces - 1, min(n_faces, MAX_PINCH_RAYS)).round().astype(int))
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cos_limit = np.cos(np.radians(PINCH_MAX_ANGLE_DEG))
    t_min = 1e-9 * float(np.max(mesh.extents))
    best: float | None = None
    step = max(1, _PAIRS_PER_BATCH // n_faces)
    for start in range(0, len(rays), step):
        idx = rays[start:start + step]
        origin, direction = tri[idx].mean(axis=1), -normals[idx]
        t, hit = _first_hits(origin, direction, v0, e1, e2, t_min)
        ok = np.isfinite(t) & (np.einsum("rk,rk->r", normals[idx], normals[np.where(np.isfinite(t), hit, 0)])
                               <= -cos_limit)
        if np.any(ok):
            thinnest = float(np.min(t[ok]))
            best = thinnest if best is None else min(best, thinnest)
            if best <= limit:
                return best
    return best


def _first_hits(origin: np.ndarray, direction: np.ndarray, v0: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                t_min: float) -> tuple[np.ndarray, np.ndarray]:
    """Möller-Trumbore: for rays (R, 3) against triangles (F, 3), the distance (R,) to the first triangle hit
    beyond ``t_min`` (inf if none) and its index (R,)."""
    p = np.cross(direction[:, None, :], e2[None, :, :])
    det = np.einsum("rfk,fk->rf", p, e1)
    valid = np.abs(det) > 1e-18
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=valid)
    s = origin[:, None, :] - v0[None, :, :]
    u = np.einsum("rfk,rfk->rf", s, p) * inv
    q = np.cross(s, e1[None, :, :])
    v = np.einsum("rfk,rk->rf", q, direction) * inv
    t = np.einsum("rfk,fk->rf", q, e2) * inv
    hit = valid & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > t_min)
    t = np.where(hit, t, np.inf)
    first = np.argmin(t, axis=1)
    return t[np.arange(len(t)), first], first


def _farthest_points(points: np.ndarray, k: int) -> np.ndarray:
    """``k`` of the points spread by farthest-point sampling (deterministic: starts from the farthest point
    from their mean)."""
    chosen = [int(np.argmax(np.linalg.norm(points - points.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(points - points[chosen[0]], axis=1)
    for _ in range(k - 1):
        nxt = int(np.argmax(dist))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(points - points[nxt], axis=1))
    return points[np.sort(chosen)]


# --------------------------------------------------------------------------- #
# convex decomposition
# --------------------------------------------------------------------------- #


@functools.lru_cache(maxsize=32)
def _parts_cached(path: str, mtime_ns: int, size: int, scale: float) -> tuple[np.ndarray, ...]:
    """The mesh's convex parts in metres: from its sidecar, the user cache, or CoACD (then cached on disk)."""
    raw = _read(path, mtime_ns, size)
    digest = mesh_digest(raw)
    parts = read_parts(parts_path(path), digest)
    if parts is not None:
        log.debug("convex parts of %s from its sidecar %s", path, parts_path(path))
    else:
        cached = cache_dir() / f"{digest[:32]}-{DECOMPOSITION.key()}.npz"
        parts = read_parts(cached, digest)
        if parts is not None:
            log.debug("convex parts of %s from the cache %s", path, cached)
        else:
            log.info("decomposing %s into convex parts with CoACD (once per mesh; it can take a minute)", path)
            parts = _decompose(raw, DECOMPOSITION)
            try:
                write_parts(cached, parts, digest, DECOMPOSITION)
                log.debug("cached the convex parts of %s in %s", path, cached)
            except OSError as exc:
                log.warning("could not cache the convex parts of %s in %s: %s", path, cached, exc)
    return _clean_parts(parts, scale)


def _decompose(mesh: trimesh.Trimesh, settings: DecompositionSettings) -> list[np.ndarray]:
    try:
        import coacd
    except ImportError:
        raise _Invalid("a mesh object's convex decomposition needs the coacd package, which is not installed: "
                       "pip install 'pickplace[mesh]'") from None
    coacd.set_log_level("error")  # its info level prints every step
    start = time.perf_counter()
    result = coacd.run_coacd(
        coacd.Mesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int32)),
        threshold=settings.threshold, max_convex_hull=settings.max_convex_hull,
        preprocess_mode=settings.preprocess_mode, preprocess_resolution=settings.preprocess_resolution,
        resolution=settings.resolution, mcts_nodes=settings.mcts_nodes, mcts_iterations=settings.mcts_iterations,
        mcts_max_depth=settings.mcts_max_depth, merge=settings.merge, decimate=settings.decimate,
        max_ch_vertex=settings.max_ch_vertex, seed=settings.seed)
    parts = [np.asarray(vertices, dtype=float) for vertices, _ in result]
    log.info("CoACD made %d convex parts in %.1f s", len(parts), time.perf_counter() - start)
    return parts


def _clean_parts(parts: Sequence[np.ndarray], scale: float) -> tuple[np.ndarray, ...]:
    """Scaled parts as proper 3-D hulls: only hull vertices; flat ones inflated to ``MIN_PART_THICKNESS_M``;
    points, needles and negligible slivers dropped."""
    solids: list[tuple[np.ndarray, float]] = []
    for index, part in enumerate(parts):
        v = np.unique(np.asarray(part, dtype=float).reshape(-1, 3) * scale, axis=0)
        if len(v) < 3:
            log.debug("dropping convex part %d: %d distinct vertices", index, len(v))
            continue
        centred = v - v.mean(axis=0)
        axes = np.linalg.svd(centred, full_matrices=False)[2]
        thickness = np.ptp(centred @ axes.T, axis=0)
        if len(thickness) < 3 or thickness[1] < MIN_PART_THICKNESS_M:
            log.debug("dropping convex part %d: needle-like (%s m)", index, thickness)
            continue
        if thickness[2] < MIN_PART_THICKNESS_M:
            offset = axes[2] * (MIN_PART_THICKNESS_M - thickness[2]) / 2.0
            v = np.concatenate([v + offset, v - offset])
            log.debug("inflating flat convex part %d from %.3g m to %.3g m thick", index, thickness[2],
                      MIN_PART_THICKNESS_M)
        try:
            hull = ConvexHull(v)
        except QhullError as exc:
            log.warning("dropping convex part %d: qhull failed on it (%s)", index, str(exc).splitlines()[0])
            continue
        solids.append((v[np.sort(hull.vertices)], float(hull.volume)))
    total = sum(volume for _, volume in solids)
    out = []
    for vertices, volume in solids:
        if volume < MIN_PART_VOLUME_FRACTION * total:
            continue
        vertices.setflags(write=False)
        out.append(vertices)
    if not out:
        raise _Invalid("its convex decomposition has no solid part")
    return tuple(out)


def _atomic_write(path: Path, data: bytes) -> None:
    """Write a file atomically: a temporary file in the same directory, then renamed over it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


__all__ = [
    "ASSETS_DIR",
    "DECOMPOSITION",
    "FIELD",
    "MAX_PINCH_RAYS",
    "MAX_WIDTH_VERTICES",
    "MIN_PART_THICKNESS_M",
    "PINCH_MAX_ANGLE_DEG",
    "DecompositionSettings",
    "cache_dir",
    "clear_caches",
    "convex_parts",
    "decompose",
    "hull_min_width",
    "load_mesh",
    "mesh_digest",
    "parts_path",
    "precompute_parts",
    "read_parts",
    "resolve_mesh_path",
    "write_parts",
]
