"""The object to pick: its shape, mass and friction (:class:`ObjectConfig`), its geometry, and the library.

An object is described in its **resting frame**: the frame it has when it lies on the table the way it is
meant to (the z axis up, the origin anywhere; the lowest point of the shape, ``Geometry.z_min_m``, touches
the table). A can lying on its side is therefore a different library object from the same can standing: its
cylinder's axis is along x. Kinds:

* ``box``: ``size_m = (x, y, z)`` edge lengths;
* ``cylinder``: ``size_m = (radius, height)``, the axis along z, or along x with ``axis = "x"`` (lying);
* ``sphere``: ``size_m = (radius,)``;
* ``compound``: ``parts``, several primitives (:class:`Part`) posed in the object's frame (an L-bracket);
* ``mesh``: ``mesh_path``, an OBJ or STL file (scaled by ``mesh_scale``), watertight; collisions use its
  convex decomposition (MuJoCo takes each mesh geom as its convex hull), see :mod:`pickplace.world.meshes`.

Mass is given; the inertia follows from the geometry at uniform density unless ``inertia_kg_m2`` gives the
principal moments. Every contact with the object uses its friction (it has the higher contact priority):
``friction`` (sliding, Coulomb), ``torsional_friction_m`` (MuJoCo's torsional coefficient, m) and
``rolling_friction_m`` (MuJoCo's rolling coefficient, m: the rolling-resistance coefficient times the
radius), the last two only for the contacts' ``condim`` that uses them (4 and 6).

:data:`LIBRARY` holds the built-in objects, each with the source of its numbers.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pickplace.errors import ConfigError
from pickplace.world.checks import check_range, check_vector

#: Largest edge a box may have across the gripper's 84 mm opening with 5 mm to spare per side (m).
MAX_GRIP_WIDTH_M = 0.074
#: Smallest width the closed gripper still squeezes: 4 mm between the closed pads, and some travel left (m).
MIN_GRIP_WIDTH_M = 0.010
#: Largest extent of an object in any direction (m): it must fit on the table and past the arm.
MAX_EXTENT_M = 0.40
#: Heaviest object (kg): the UR5e's rated payload is 5 kg, the gripper included.
MAX_MASS_KG = 5.0


class ShapeKind(enum.StrEnum):
    """The kinds of object shape."""

    BOX = "box"
    CYLINDER = "cylinder"
    SPHERE = "sphere"
    COMPOUND = "compound"
    MESH = "mesh"


#: Number of ``size_m`` values per primitive kind, and what they are.
_SIZES = {"box": (3, "(x, y, z) edge lengths"), "cylinder": (2, "(radius, height)"), "sphere": (1, "(radius,)")}


def _check_sizes(name: str, kind: str, size: Any) -> tuple[float, ...]:
    n, what = _SIZES[kind]
    return check_vector(name, size, n, 0.001, MAX_EXTENT_M, unit=f"m, a {kind}'s {what}")


@dataclass(frozen=True)
class Part:
    """One primitive of a compound object, posed in the object's resting frame.

    Attributes:
        kind: ``"box"``, ``"cylinder"`` (axis along the part's z) or ``"sphere"``.
        size_m: Box edge lengths (x, y, z); cylinder (radius, height); sphere (radius,) (m).
        pos_m: Centre of the part in the object's frame (m).
        quat_wxyz: Orientation of the part in the object's frame (unit quaternion, w first).
    """

    kind: str
    size_m: tuple[float, ...]
    pos_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.kind not in _SIZES:
            raise ConfigError("object.parts.kind", self.kind, f"must be one of {', '.join(_SIZES)}")
        object.__setattr__(self, "size_m", _check_sizes("object.parts.size_m", self.kind, self.size_m))
        object.__setattr__(self, "pos_m", check_vector("object.parts.pos_m", self.pos_m, 3, -MAX_EXTENT_M,
                                                       MAX_EXTENT_M, unit="m"))
        q = np.array(check_vector("object.parts.quat_wxyz", self.quat_wxyz, 4, -1.0, 1.0))
        if abs(float(np.linalg.norm(q)) - 1.0) > 1e-6:
            raise ConfigError("object.parts.quat_wxyz", self.quat_wxyz, "must be a unit quaternion (w, x, y, z)")
        object.__setattr__(self, "quat_wxyz", tuple(float(v) for v in q))

    @property
    def rotation(self) -> np.ndarray:
        """Rotation (3, 3) of the part in the object's frame."""
        return quat_to_matrix(self.quat_wxyz)

    @property
    def volume_m3(self) -> float:
        """Volume (m^3)."""
        s = self.size_m
        if self.kind == "box":
            return s[0] * s[1] * s[2]
        if self.kind == "cylinder":
            return math.pi * s[0] ** 2 * s[1]
        return 4.0 / 3.0 * math.pi * s[0] ** 3

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> Part:
        """A part from a TOML table (``kind``, ``size_m``, ``pos_m``, ``quat_wxyz``)."""
        names = [f.name for f in dataclasses.fields(cls)]
        if not isinstance(data, Mapping):
            raise ConfigError("object.parts", data, "must be a list of tables with kind, size_m, pos_m, quat_wxyz")
        for key in data:
            if key not in names:
                raise ConfigError(f"object.parts.{key}", data[key], f"unknown key; allowed: {', '.join(names)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})


def quat_to_matrix(q: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


#: Rotation of a cylinder part lying along x: its z axis turned onto x (a quarter turn about y).
LYING_ALONG_X = (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0)


@dataclass(frozen=True)
class ObjectConfig:
    """The object to pick (TOML table ``[object]``). SI units; see the module docstring for the frame.

    Attributes:
        name: Its name (reported in contacts and results).
        kind: ``box``, ``cylinder``, ``sphere``, ``compound`` or ``mesh``.
        size_m: Box (x, y, z) edge lengths; cylinder (radius, height); sphere (radius,) (m). Unused for
            compound and mesh.
        axis: A cylinder's axis at rest: ``"z"`` (standing) or ``"x"`` (lying).
        parts: The primitives of a compound object.
        mesh_path: OBJ or STL file of a mesh object (metres after ``mesh_scale``).
        mesh_scale: Factor applied to the mesh's coordinates (e.g. 0.001 for a file in millimetres).
        mass_kg: Mass (kg).
        friction: Coulomb sliding friction of its contacts.
        torsional_friction_m: Torsional friction coefficient of its contacts (m).
        rolling_friction_m: Rolling friction coefficient of its contacts (m); > 0 gives its contacts condim 6.
        inertia_kg_m2: Principal moments of inertia about the centre of mass, along the object's axes
            (kg m^2); None: from the geometry at uniform density.
        source: Where the numbers come from.
    """

    name: str = "cube"
    kind: str = "box"
    size_m: tuple[float, ...] = (0.040, 0.040, 0.040)
    axis: str = "z"
    parts: tuple[Part, ...] = ()
    mesh_path: str = ""
    mesh_scale: float = 1.0
    mass_kg: float = 0.150
    friction: float = 1.0
    torsional_friction_m: float = 0.005
    rolling_friction_m: float = 0.0
    inertia_kg_m2: tuple[float, float, float] | None = None
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ConfigError("object.name", self.name, "must be a name of letters, digits and underscores")
        kinds = [k.value for k in ShapeKind]
        if self.kind not in kinds:
            raise ConfigError("object.kind", self.kind, f"must be one of {', '.join(kinds)}")
        if self.kind in _SIZES:
            set_(self, "size_m", _check_sizes("object.size_m", self.kind, self.size_m))
        if self.axis not in ("z", "x"):
            raise ConfigError("object.axis", self.axis, "must be 'z' (standing) or 'x' (lying)")
        if self.axis == "x" and self.kind != "cylinder":
            raise ConfigError("object.axis", self.axis, "only a cylinder lies along x")
        parts = tuple(p if isinstance(p, Part) else Part.from_mapping(p) for p in self.parts)
        set_(self, "parts", parts)
        if self.kind == "compound" and not parts:
            raise ConfigError("object.parts", self.parts, "a compound object needs at least one part")
        if self.kind != "compound" and parts:
            raise ConfigError("object.parts", "...", f"only a compound object has parts (kind is {self.kind!r})")
        if self.kind == "mesh" and not self.mesh_path:
            raise ConfigError("object.mesh_path", self.mesh_path, "a mesh object needs an OBJ or STL file")
        set_(self, "mesh_scale", check_range("object.mesh_scale", self.mesh_scale, 0.0, 10.0, lo_open=True))
        set_(self, "mass_kg", check_range("object.mass_kg", self.mass_kg, 0.0, MAX_MASS_KG, lo_open=True,
                                          unit="kg (the UR5e's payload is 5 kg)"))
        set_(self, "friction", check_range("object.friction", self.friction, 0.0, 5.0, lo_open=True))
        set_(self, "torsional_friction_m", check_range("object.torsional_friction_m", self.torsional_friction_m,
                                                       0.0, 0.1, unit="m"))
        set_(self, "rolling_friction_m", check_range("object.rolling_friction_m", self.rolling_friction_m,
                                                     0.0, 0.1, unit="m"))
        if self.inertia_kg_m2 is not None:
            set_(self, "inertia_kg_m2", check_vector("object.inertia_kg_m2", self.inertia_kg_m2, 3, 0.0, 10.0,
                                                     lo_open=True, unit="kg m^2"))
            a, b, c = sorted(self.inertia_kg_m2)
            if c > a + b + 1e-12:
                raise ConfigError("object.inertia_kg_m2", self.inertia_kg_m2,
                                  "principal moments must satisfy the triangle inequality (I3 <= I1 + I2)")

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], base: ObjectConfig | None = None) -> ObjectConfig:
        """From a TOML ``[object]`` table: ``library = "NAME"`` starts from a library object, the other keys
        (the fields) change it; without ``library`` the fields describe a new object."""
        if not isinstance(data, Mapping):
            raise ConfigError("object", data, "must be a table of keys")
        data = dict(data)
        start = base if base is not None else cls()
        if "library" in data:
            start = library_object(data.pop("library"))
        names = [f.name for f in dataclasses.fields(cls)]
        for key, value in data.items():
            if key not in names:
                raise ConfigError(f"object.{key}", value, f"unknown key; allowed: library, {', '.join(names)}")
        changes = {k: tuple(v) if isinstance(v, list) and k != "parts" else v for k, v in data.items()}
        if "parts" in changes:
            changes["parts"] = tuple(Part.from_mapping(p) if not isinstance(p, Part) else p for p in changes["parts"])
        if "kind" in changes and changes["kind"] != start.kind:  # a new shape: drop the old shape's fields
            fresh: dict[str, Any] = dict(size_m=_default_size(changes["kind"]), axis="z", parts=(), mesh_path="")
            return dataclasses.replace(start, **{**fresh, **changes})
        return dataclasses.replace(start, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for TOML (the inverse of :meth:`from_mapping` without ``library``)."""
        out = dataclasses.asdict(self)
        out["parts"] = [dataclasses.asdict(p) for p in self.parts]
        if out["inertia_kg_m2"] is None:
            del out["inertia_kg_m2"]
        return out

    def geometry(self) -> Geometry:
        """The object's shape in its resting frame (cached per object)."""
        return _geometry(self)

    def primitives(self) -> tuple[Part, ...]:
        """The object as primitives in its resting frame (empty for a mesh)."""
        if self.kind == "compound":
            return self.parts
        if self.kind == "mesh":
            return ()
        quat = LYING_ALONG_X if self.axis == "x" else (1.0, 0.0, 0.0, 0.0)
        return (Part(self.kind, self.size_m, (0.0, 0.0, 0.0), quat),)

    @property
    def yaw_period_rad(self) -> float:
        """Angle of the object's symmetry about the vertical at rest (rad): it looks the same turned by this.

        pi/2 for a box with a square footprint, pi for other boxes and a lying cylinder, 0 for a standing
        cylinder and a sphere (any turn: their yaw is not defined), 2 pi otherwise (no symmetry assumed).
        """
        if self.kind == "box":
            return math.pi / 2 if abs(self.size_m[0] - self.size_m[1]) < 1e-9 else math.pi
        if self.kind == "cylinder":
            return 0.0 if self.axis == "z" else math.pi
        if self.kind == "sphere":
            return 0.0
        return 2.0 * math.pi


def scaled(obj: ObjectConfig, factor: float) -> ObjectConfig:
    """The object with every dimension multiplied by ``factor`` (its mass and friction unchanged).

    Raises:
        ConfigError: the factor is not positive, or the scaled object is invalid (too large, too small).
    """
    k = check_range("object.scale", factor, 0.0, 10.0, lo_open=True)
    if obj.kind == "compound":
        parts = tuple(dataclasses.replace(p, size_m=tuple(v * k for v in p.size_m), pos_m=tuple(v * k for v in p.pos_m))
                      for p in obj.parts)
        return dataclasses.replace(obj, parts=parts)
    if obj.kind == "mesh":
        return dataclasses.replace(obj, mesh_scale=obj.mesh_scale * k)
    return dataclasses.replace(obj, size_m=tuple(v * k for v in obj.size_m))


def _default_size(kind: str) -> tuple[float, ...]:
    return {"box": (0.04, 0.04, 0.04), "cylinder": (0.03, 0.1), "sphere": (0.03,)}.get(kind, ())


# --------------------------------------------------------------------------- #
# geometry
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class Geometry:
    """An object's shape in its resting frame.

    Attributes:
        primitives: Its primitives (box, cylinder, sphere), empty for a mesh object.
        hulls: Vertices (K_i, 3) of the convex parts its collisions use (m): one per primitive's hull for
            primitives is not needed (MuJoCo has them natively), so this is empty unless it is a mesh.
        vertices: Vertices (V, 3) of a triangle mesh of the whole surface (m): the mesh itself, or the
            primitives tessellated (for sampling grasps and for bounds).
        faces: Triangles (F, 3) of that mesh (vertex indices).
        volume_m3: Volume (m^3).
        z_min_m: Lowest point (m): the object rests on the table with its origin ``-z_min_m`` above it.
        bounds_m: Axis-aligned bounds (2, 3) (m), min then max.
    """

    primitives: tuple[Part, ...]
    hulls: tuple[np.ndarray, ...]
    vertices: np.ndarray
    faces: np.ndarray
    volume_m3: float
    z_min_m: float
    bounds_m: np.ndarray

    @property
    def extent_m(self) -> np.ndarray:
        """Size (3,) of the axis-aligned bounds (m)."""
        return self.bounds_m[1] - self.bounds_m[0]


@functools.lru_cache(maxsize=64)
def _geometry(obj: ObjectConfig) -> Geometry:
    import trimesh

    if obj.kind == "mesh":
        from pickplace.world.meshes import convex_parts, load_mesh

        mesh = load_mesh(obj.mesh_path, obj.mesh_scale)
        hulls = tuple(convex_parts(obj.mesh_path, obj.mesh_scale))
        vertices, faces, volume = np.asarray(mesh.vertices), np.asarray(mesh.faces), float(mesh.volume)
    else:
        pieces = [_part_mesh(trimesh, p) for p in obj.primitives()]
        whole = trimesh.util.concatenate(pieces)
        vertices, faces, hulls = np.asarray(whole.vertices), np.asarray(whole.faces), ()
        volume = sum(p.volume_m3 for p in obj.primitives())
    for arr in (vertices, faces):
        arr.setflags(write=False)
    bounds = np.array([vertices.min(axis=0), vertices.max(axis=0)])
    bounds.setflags(write=False)
    return Geometry(obj.primitives(), hulls, vertices, faces, volume, float(bounds[0, 2]), bounds)


def _part_mesh(trimesh: Any, part: Part) -> Any:
    """A triangle mesh of a primitive, posed in the object's frame (fine enough for sampling and bounds)."""
    s = part.size_m
    if part.kind == "box":
        mesh = trimesh.creation.box(extents=s)
    elif part.kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=s[0], height=s[1], sections=64)
    else:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=s[0])
    T = np.eye(4)
    T[:3, :3] = part.rotation
    T[:3, 3] = part.pos_m
    mesh.apply_transform(T)
    return mesh


# --------------------------------------------------------------------------- #
# the library
# --------------------------------------------------------------------------- #

#: Sources cited by the library.
YCB = ("B. Calli et al., 'Benchmarking in manipulation research: the YCB object and model set', IEEE Robotics & "
       "Automation Magazine 22(3), 2015, table of objects")
ITF = "ITF Rules of Tennis, Appendix I (ball: 56.0-59.4 g, 6.54-6.86 cm)"


def _l_bracket() -> ObjectConfig:
    """An aluminium equal angle 60 x 60 x 10 mm, 40 mm long, resting on one leg (the other one upright)."""
    leg, thick, length = 0.060, 0.010, 0.040
    rho = 2700.0  # aluminium (kg/m^3)
    flat = Part("box", (leg, length, thick), (0.0, 0.0, -leg / 2 + thick / 2))
    upright = Part("box", (thick, length, leg - thick), (-leg / 2 + thick / 2, 0.0, thick / 2))
    mass = rho * (flat.volume_m3 + upright.volume_m3)
    return ObjectConfig(
        name="l_bracket", kind="compound", parts=(flat, upright), mass_kg=round(mass, 4), friction=0.8,
        source="aluminium equal angle 60 x 60 x 10 mm (EN 755-9 size), 40 mm long: 44 cm^3 at 2700 kg/m^3; "
               "friction 0.8 assumed (rubber pads on bare aluminium)")


def _library() -> dict[str, ObjectConfig]:
    can_r, can_h, can_m = 0.0331, 0.1152, 0.350
    can_src = ("330 ml drink can: 66.2 mm x 115.2 mm (the standard European 330 ml can body); 350 g = 330 ml of "
               "soft drink at ~1.04 kg/l plus a ~13 g aluminium can; friction 0.7 assumed (rubber on painted "
               "aluminium)")
    roll_src = ("; rolling friction {:.2g} m = C_rr {:.2g} x radius (MuJoCo's rolling friction is a length: the "
                "resisting torque over the normal force). C_rr: R. Cross, 'Coulomb's law for rolling friction', Am. "
                "J. Phys. 84, 221 (2016), measured 0.001-0.03 for balls and cylinders rolling on hard and soft "
                "surfaces, growing with the softness of the contact; a firm object on a wooden table top is taken "
                "in that range")
    ball_r = 0.0335
    entries = [
        ObjectConfig(name="cube", kind="box", size_m=(0.040, 0.040, 0.040), mass_kg=0.150, friction=1.0,
                     source="pickplace's default cube: 40 mm edge, 150 g, friction 1.0"),
        ObjectConfig(name="sugar_box", kind="box", size_m=(0.038, 0.089, 0.175), mass_kg=0.514, friction=0.6,
                     source=f"YCB 004 sugar box: 38 x 89 x 175 mm, 514 g ({YCB}); standing on its end; it fits "
                            "the 84 mm opening only across its 38 mm side; friction 0.6 assumed (rubber on "
                            "cardboard)"),
        ObjectConfig(name="gelatin_box", kind="box", size_m=(0.085, 0.073, 0.028), mass_kg=0.097, friction=0.6,
                     source=f"YCB 009 gelatin box: 85 x 73 x 28 mm, 97 g ({YCB}); lying flat; friction 0.6 "
                            "assumed (rubber on cardboard)"),
        ObjectConfig(name="soda_can", kind="cylinder", size_m=(can_r, can_h), mass_kg=can_m, friction=0.7,
                     source=can_src + "; standing"),
        ObjectConfig(name="soda_can_lying", kind="cylinder", size_m=(can_r, can_h), axis="x", mass_kg=can_m,
                     friction=0.7, rolling_friction_m=round(0.01 * can_r, 6),
                     source=can_src + "; lying on its side" + roll_src.format(0.01 * can_r, 0.01)),
        ObjectConfig(name="tennis_ball", kind="sphere", size_m=(ball_r,), mass_kg=0.058, friction=0.6,
                     rolling_friction_m=round(0.03 * ball_r, 6),
                     source=f"tennis ball: 67 mm, 58 g ({ITF}); friction 0.6 assumed (rubber on felt)"
                            + roll_src.format(0.03 * ball_r, 0.03).replace("firm object", "felt ball")),
        _l_bracket(),
        ObjectConfig(name="mug", kind="mesh", mesh_path="mug.obj", mass_kg=0.229, friction=0.6,
                     source="small ceramic coffee mug, ~7 oz (208 ml to the brim), in the 6-8 oz (180-240 ml) "
                            "class of espresso-lungo / cappuccino mugs: 69 mm across x 80 mm tall (assumed: sized "
                            "for the gripper, its body squeezed across at 69 mm < 74 mm, its 60 mm cavity taking the "
                            "open inner finger of a pinch on the rim's wall), 4.5 mm wall and 6.5 mm bottom "
                            "(assumed); a C handle 28.75 mm out from the wall, 10 x 14 mm section, a finger hole "
                            "18.75 mm deep x 42 mm tall (assumed); 229 g = its 99.7 cm^3 of ceramic (the mesh's "
                            "volume) x 2.3 g/cm^3 (fired stoneware / porcelain, ~2.3-2.4 g/cm^3); friction 0.6 "
                            "assumed (rubber pads on glazed ceramic); standing on its bottom, origin on the body's "
                            "axis at mid-height, handle towards +x; mesh and convex parts written by "
                            "tools/make_meshes.py"),
    ]
    return {o.name: o for o in entries}


LIBRARY: dict[str, ObjectConfig] = _library()


def library_object(name: str) -> ObjectConfig:
    """The library object called ``name``.

    Raises:
        ConfigError: no such object (the message lists the library).
    """
    try:
        return LIBRARY[name]
    except (KeyError, TypeError):
        raise ConfigError("object.library", name, f"must be one of {', '.join(LIBRARY)}") from None


__all__ = [
    "LIBRARY",
    "MAX_EXTENT_M",
    "MAX_GRIP_WIDTH_M",
    "MAX_MASS_KG",
    "MIN_GRIP_WIDTH_M",
    "Geometry",
    "ObjectConfig",
    "Part",
    "ShapeKind",
    "library_object",
    "quat_to_matrix",
    "scaled",
]
