"""Write the library's mesh assets: ``src/pickplace/world/assets/mug.obj`` and its convex parts ``mug.parts.npz``.

Usage (from the repository's root, with the ``mesh`` extra installed: manifold3d and coacd)::

    .venv/bin/python tools/make_meshes.py            # writes the mesh; decomposes it if it changed
    .venv/bin/python tools/make_meshes.py --force    # decomposes it again anyway (~10-30 s)

The mug is built from primitives with manifold3d's exact booleans (a cylinder less its cavity, plus a
C-shaped handle revolved from an ellipse), written as an OBJ with its vertices rounded to 1 nm, read back
through :func:`pickplace.world.meshes.load_mesh` (the same checks a user's mesh gets), decomposed with CoACD
(:data:`pickplace.world.meshes.DECOMPOSITION`, fixed seed) and the parts checked: they cover the wall and leave
the cavity free. Running it again writes the same bytes (CoACD with a fixed seed is deterministic; checked on
this machine with 1 and 2 threads). It prints a JSON summary: the numbers the library entry in
``pickplace/world/objects.py`` quotes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from pickplace.world import meshes  # noqa: E402


@dataclass(frozen=True)
class MugDesign:
    """A small ceramic coffee mug (~7 oz, in the 6-8 oz class of espresso-lungo / cappuccino mugs),
    straight-sided, in its resting frame: z up, standing on its bottom, the origin on the body's axis at
    mid-height, the handle towards +x. Lengths in m.

    Its size is set by the gripper (84 mm open; ``MAX_GRIP_WIDTH_M`` = 74 mm): the body, 69 mm across, is
    squeezed across with 5 mm to spare below 74 mm; and the cavity, 60 mm across, still takes the open
    inner finger of a top-down pinch of the wall at the rim. That finger's far face is 56 mm from the pad's
    centre on the wall and 24 mm wide, plus the synthesis' 2 mm sweep clearance all round; its corners stay
    inside the cavity only if the body is at least ~68.3 mm across with a 4.5 mm wall (~69.0 mm with 5 mm):
    69 mm leaves them 0.7 mm.

    Attributes:
        outer_radius_m: Body's outer radius: 69 mm across (assumed: the smallest with the rim pinch above).
        height_m: Body's height: 80 mm (assumed; with the wall and bottom below it holds 208 ml to the brim).
        wall_m: Side wall's thickness (assumed, typical of a glazed stoneware / porcelain mug).
        bottom_m: Bottom's thickness (assumed).
        handle_radius_m: Radius of the handle's centre line (a half circle in the xz plane; assumed).
        handle_thickness_m: Handle's section in the loop's plane (assumed).
        handle_width_m: Handle's section along y (assumed).
        handle_root_x_m: x of the handle's two flat ends: inside the wall (30 to 34.5 mm), mid-wall.
        handle_centre_z_m: Height of the handle's centre (slightly above the body's middle).
        body_segments: Facets around the body.
        handle_segments: Facets along the handle's half circle.
        section_segments: Facets around the handle's section.
        density_kg_m3: Fired stoneware / porcelain (~2.3-2.4 g/cm^3; the lower end).
    """

    outer_radius_m: float = 0.0345
    height_m: float = 0.080
    wall_m: float = 0.0045
    bottom_m: float = 0.0065
    handle_radius_m: float = 0.026
    handle_thickness_m: float = 0.010
    handle_width_m: float = 0.014
    handle_root_x_m: float = 0.03225
    handle_centre_z_m: float = 0.004
    body_segments: int = 96
    handle_segments: int = 64
    section_segments: int = 32
    density_kg_m3: float = 2300.0

    @property
    def inner_radius_m(self) -> float:
        """Cavity's radius (m)."""
        return self.outer_radius_m - self.wall_m

    @property
    def z_min_m(self) -> float:
        """Lowest point: the bottom's underside (m)."""
        return -self.height_m / 2

    @property
    def cavity_floor_z_m(self) -> float:
        """Height of the cavity's floor (m)."""
        return -self.height_m / 2 + self.bottom_m

    @property
    def handle_reach_x_m(self) -> float:
        """Largest x of the handle (m)."""
        return self.handle_root_x_m + self.handle_radius_m + self.handle_thickness_m / 2

    @property
    def capacity_m3(self) -> float:
        """Volume of the cavity to the brim (m^3), of the round cylinder."""
        return math.pi * self.inner_radius_m ** 2 * (self.height_m - self.bottom_m)


MUG = MugDesign()
ASSETS = ROOT / "src" / "pickplace" / "world" / "assets"


def build_mug(design: MugDesign = MUG) -> tuple[np.ndarray, np.ndarray]:
    """The mug as a closed triangle mesh: vertices (V, 3) in m, triangles (F, 3) wound outward."""
    import manifold3d as mf

    d = design
    body = mf.Manifold.cylinder(d.height_m, d.outer_radius_m, d.outer_radius_m, d.body_segments)
    cavity = mf.Manifold.cylinder(d.height_m, d.inner_radius_m, d.inner_radius_m, d.body_segments)
    cup = body.translate((0.0, 0.0, -d.height_m / 2)) - cavity.translate((0.0, 0.0, d.cavity_floor_z_m))
    # The handle: an ellipse (thickness x width) revolved half a turn about z at handle_radius_m, turned to
    # the x >= 0 half, then stood up into the xz plane, its flat ends at x = handle_root_x_m inside the wall.
    section = mf.CrossSection.circle(1.0, d.section_segments).scale(
        (d.handle_thickness_m / 2, d.handle_width_m / 2)).translate((d.handle_radius_m, 0.0))
    handle = mf.Manifold.revolve(section, d.handle_segments, 180.0).rotate((0.0, 0.0, -90.0)).rotate(
        (90.0, 0.0, 0.0)).translate((d.handle_root_x_m, 0.0, d.handle_centre_z_m))
    mug = cup + handle
    if mug.status() != mf.Error.NoError or mug.genus() != 1:
        raise RuntimeError(f"the mug's booleans failed: status {mug.status()}, genus {mug.genus()}")
    mesh = mug.to_mesh64()
    vertices = np.round(np.asarray(mesh.vert_properties, dtype=float)[:, :3], 9) + 0.0  # 1 nm, no -0.0
    return vertices, np.asarray(mesh.tri_verts, dtype=np.int64)


def obj_text(vertices: np.ndarray, faces: np.ndarray, header: list[str]) -> str:
    """An OBJ file's text: comment lines, then ``v`` lines (m, 9 decimals) and ``f`` lines (1-based)."""
    lines = [f"# {h}" for h in header]
    lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def check_parts(parts: list[np.ndarray], design: MugDesign = MUG) -> dict[str, float]:
    """How well the convex parts fit the mug: wall coverage, and how far into the cavity they reach.

    Returns:
        ``wall_covered``: fraction of points in the middle of the wall (every 5 deg, from 1 mm up to 1 mm
        below the rim) inside some part; ``bottom_covered``: same for the middle of the bottom;
        ``cavity_intrusion_m``: the smallest inset from the inner wall at which points around the cavity
        (every 2 deg, from 1 mm above its floor to 0.5 mm below the rim) are inside no part (m);
        ``centre_free``: 1 if the cavity's centre is inside no part.
    """
    from scipy.spatial import ConvexHull

    planes = [ConvexHull(p).equations for p in parts]

    def inside(points: np.ndarray) -> np.ndarray:
        return np.array([any(np.all(eq[:, :3] @ q + eq[:, 3] <= 1e-9) for eq in planes) for q in points])

    d = design
    r_mid = d.inner_radius_m + d.wall_m / 2
    ang = np.radians(np.arange(0.0, 360.0, 5.0))
    zs = np.linspace(d.z_min_m + 0.001, -d.z_min_m - 0.001, 12)
    wall = np.array([[r_mid * math.cos(a), r_mid * math.sin(a), z] for a in ang for z in zs])
    bottom = np.array([[r * math.cos(a), r * math.sin(a), d.z_min_m + d.bottom_m / 2]
                       for a in ang[::3] for r in (0.0, 0.01, 0.02, 0.03)])
    ang2 = np.radians(np.arange(0.0, 360.0, 2.0))
    zc = np.linspace(d.cavity_floor_z_m + 0.001, -d.z_min_m - 0.0005, 12)
    intrusion = float("nan")
    for inset in np.arange(0.0, 0.0101, 0.00025):
        r = d.inner_radius_m - inset
        ring = np.array([[r * math.cos(a), r * math.sin(a), z] for a in ang2 for z in zc])
        if not inside(ring).any():
            intrusion = float(inset)
            break
    centre = np.array([[0.0, 0.0, (d.cavity_floor_z_m - d.z_min_m) / 2]])
    return {"wall_covered": float(inside(wall).mean()), "bottom_covered": float(inside(bottom).mean()),
            "cavity_intrusion_m": intrusion, "centre_free": float(not inside(centre)[0])}


def main(argv: list[str] | None = None) -> int:
    """Write the mug's mesh and parts; print a JSON summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--force", action="store_true", help="decompose even if the parts file is current")
    args = parser.parse_args(argv)

    d = MUG
    vertices, faces = build_mug(d)
    header = [
        "pickplace library mug: generated by tools/make_meshes.py, do not edit (run the script).",
        f"ceramic mug, metres, z up, standing on its bottom, origin on the body's axis at mid-height, handle to +x; "
        f"outer diameter {2e3 * d.outer_radius_m:g} mm, height {1e3 * d.height_m:g} mm, wall {1e3 * d.wall_m:g} mm, "
        f"bottom {1e3 * d.bottom_m:g} mm",
    ]
    obj_path = ASSETS / "mug.obj"
    ASSETS.mkdir(parents=True, exist_ok=True)
    text = obj_text(vertices, faces, header)
    if not obj_path.is_file() or obj_path.read_text() != text:
        obj_path.write_text(text)
    meshes.clear_caches()
    mesh = meshes.load_mesh("mug.obj", 1.0)  # the checks a user's mesh gets
    digest = meshes.mesh_digest(mesh)
    sidecar = meshes.parts_path(obj_path)
    decompose_s = 0.0
    if args.force or meshes.read_parts(sidecar, digest) is None:
        start = time.perf_counter()
        meshes.precompute_parts(obj_path)
        decompose_s = time.perf_counter() - start
    meshes.clear_caches()
    parts = meshes.convex_parts("mug.obj", 1.0)
    fit = check_parts(parts, d)
    volume = float(mesh.volume)
    summary = {
        "design": asdict(d),
        "mesh": {"file": str(obj_path.relative_to(ROOT)), "vertices": len(mesh.vertices), "faces": len(mesh.faces),
                 "volume_cm3": round(volume * 1e6, 3), "mass_kg": round(volume * d.density_kg_m3, 4),
                 "capacity_ml": round(d.capacity_m3 * 1e6, 1), "bounds_m": np.round(mesh.bounds, 6).tolist(),
                 "hull_min_width_mm": round(meshes.hull_min_width(mesh.vertices)[0] * 1e3, 2),
                 "sha256": digest},
        "parts": {"file": str(sidecar.relative_to(ROOT)), "count": len(parts),
                  "vertices": [len(p) for p in parts], "decompose_s": round(decompose_s, 1),
                  "settings": asdict(meshes.DECOMPOSITION), **fit},
    }
    print(json.dumps(summary, indent=2))
    if fit["wall_covered"] < 1.0 or fit["centre_free"] < 1.0 or not fit["cavity_intrusion_m"] <= 0.003:
        print("the convex parts do not fit the mug (see 'parts')", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
