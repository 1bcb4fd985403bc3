"""Configuration: frozen, validated dataclasses, in SI units.

Every config validates itself on construction and raises
:class:`~pickplace.errors.ConfigError` naming the field, the value and what is
allowed. Nothing here touches MuJoCo or Pinocchio; :mod:`pickplace.robot.model`
turns a :class:`SceneConfig` into models.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from pickplace.errors import ConfigError, InsideObstacle
from pickplace.world.checks import check_finite, check_int, check_range, check_vector
from pickplace.world.objects import MAX_GRIP_WIDTH_M, MIN_GRIP_WIDTH_M, ObjectConfig

T = TypeVar("T")

# --------------------------------------------------------------------------- #
# scene
# --------------------------------------------------------------------------- #

#: Largest cube edge the gripper can take with 5 mm clearance per side (m); see gripper.xml.
MAX_CUBE_SIZE_M = MAX_GRIP_WIDTH_M
#: Smallest cube edge the closed gripper still squeezes (m); see gripper.xml.
MIN_CUBE_SIZE_M = MIN_GRIP_WIDTH_M

#: ``[scene]`` keys of the cube-only scene of earlier versions, still accepted in TOML and on the command line:
#: each maps to the object's field (``object.*``) or to the scene's new name.
LEGACY_SCENE_KEYS = {
    "cube_start_xy_m": "start_xy_m", "cube_yaw_rad": "start_yaw_rad", "cube_size_m": "object.size_m",
    "cube_mass_kg": "object.mass_kg", "cube_friction": "object.friction",
    "cube_torsional_friction_m": "object.torsional_friction_m",
}


@dataclass(frozen=True)
class SceneObject:
    """One more object on the table (a task's ``[[objects]]`` beyond the first), named by its object's name.

    Attributes:
        object: The object (its ``name`` names its body and geoms, and must be unique in the scene).
        start_xy_m: Where its origin starts on the table (x, y) (m).
        start_yaw_rad: Its initial rotation about world z from its resting frame (rad).
        goal_xy_m: Where a ``place`` task must put it (x, y) (m); None: no goal of its own.
        goal_yaw_rad: Its yaw at the goal (rad), modulo its symmetry.
    """

    object: ObjectConfig
    start_xy_m: tuple[float, float]
    start_yaw_rad: float = 0.0
    goal_xy_m: tuple[float, float] | None = None
    goal_yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if not isinstance(self.object, ObjectConfig):
            raise ConfigError("objects.object", self.object, "must be an ObjectConfig")
        where = f"objects.{self.object.name}"
        set_(self, "start_xy_m", check_vector(f"{where}.start_xy_m", self.start_xy_m, 2, unit="m"))
        set_(self, "start_yaw_rad", check_range(f"{where}.start_yaw_rad", self.start_yaw_rad, -2 * math.pi,
                                                2 * math.pi, unit="rad"))
        if self.goal_xy_m is not None:
            set_(self, "goal_xy_m", check_vector(f"{where}.goal_xy_m", self.goal_xy_m, 2, unit="m"))
        set_(self, "goal_yaw_rad", check_range(f"{where}.goal_yaw_rad", self.goal_yaw_rad, -2 * math.pi,
                                               2 * math.pi, unit="rad"))

    @property
    def name(self) -> str:
        """Its name (its object's)."""
        return self.object.name


@dataclass(frozen=True)
class BinConfig:
    """An open box on the table (TOML ``[bin]``): a floor and four walls; a ``clear`` task fills it. By default the
    size of a common 400 x 300 mm tote's inside, its near edge 17 cm to the robot's right.

    Attributes:
        xy_m: Centre of the bin on the table (x, y) (m).
        inner_size_xy_m: Inside extent of the bin, wall to wall (x, y) (m).
        wall_height_m: Height of the walls above the table (m).
        wall_thickness_m: Thickness of the walls (m).
        floor_thickness_m: Thickness of the floor (m): objects in the bin rest this high above the table.
    """

    xy_m: tuple[float, float] = (0.45, -0.33)
    inner_size_xy_m: tuple[float, float] = (0.40, 0.30)
    wall_height_m: float = 0.05
    wall_thickness_m: float = 0.01
    floor_thickness_m: float = 0.005

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "xy_m", check_vector("bin.xy_m", self.xy_m, 2, unit="m"))
        set_(self, "inner_size_xy_m", check_vector("bin.inner_size_xy_m", self.inner_size_xy_m, 2, 0.1, 0.6,
                                                   unit="m"))
        set_(self, "wall_height_m", check_range("bin.wall_height_m", self.wall_height_m, 0.01, 0.15, unit="m"))
        set_(self, "wall_thickness_m", check_range("bin.wall_thickness_m", self.wall_thickness_m, 0.002, 0.05,
                                                   unit="m"))
        set_(self, "floor_thickness_m", check_range("bin.floor_thickness_m", self.floor_thickness_m, 0.001, 0.03,
                                                    unit="m"))
        if self.floor_thickness_m >= self.wall_height_m:
            raise ConfigError("bin.floor_thickness_m", self.floor_thickness_m,
                              f"must be below the walls' height ({self.wall_height_m:g} m)")

    @property
    def outer_box_xy_m(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``(lo, hi)`` (2,) of the bin's footprint, walls included (m)."""
        half = np.asarray(self.inner_size_xy_m) / 2 + self.wall_thickness_m
        return np.asarray(self.xy_m) - half, np.asarray(self.xy_m) + half

    @property
    def inner_box_xy_m(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``(lo, hi)`` (2,) of the bin's inside (m)."""
        half = np.asarray(self.inner_size_xy_m) / 2
        return np.asarray(self.xy_m) - half, np.asarray(self.xy_m) + half

    def floor_z_m(self, table_height_m: float) -> float:
        """Height of the bin's floor, where objects in it rest (m)."""
        return table_height_m + self.floor_thickness_m

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> BinConfig:
        """From a TOML ``[bin]`` table."""
        if not isinstance(data, Mapping):
            raise ConfigError("bin", data, "must be a table of keys")
        return from_mapping(cls, data, "bin")


#: What a box's name may be: it names the box's body and geom in the MJCF.
_BOX_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")


@dataclass(frozen=True)
class BoxConfig:
    """A fixed box in the scene (TOML: ``boxes = [{name = ..., center_m = [...], size_m = [...]}]`` in ``[scene]``):
    shelves, cages, bins and walls are built from them. To the arm and to a carried object a box is an obstacle
    (the collision checker's margin applies), never a surface objects are set down on.

    Attributes:
        name: Its name (snake_case, unique in the scene): its body is ``box_<name>``, its geom ``<name>``.
        center_m: Its centre (x, y, z) in the world (m).
        size_m: Its full extents (x, y, z) along its own axes (m).
        yaw_rad: Its rotation about world z (rad).
    """

    name: str
    center_m: tuple[float, float, float]
    size_m: tuple[float, float, float]
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if not isinstance(self.name, str) or not _BOX_NAME.fullmatch(self.name):
            raise ConfigError("scene.boxes.name", self.name, "must be snake_case: a lower-case letter, then lower-case "
                                                             "letters, digits or _ (at most 40)")
        where = f"scene.boxes.{self.name}"
        set_(self, "center_m", check_vector(f"{where}.center_m", self.center_m, 3, -5.0, 5.0, unit="m"))
        set_(self, "size_m", check_vector(f"{where}.size_m", self.size_m, 3, 0.002, 5.0, unit="m"))
        set_(self, "yaw_rad", check_range(f"{where}.yaw_rad", self.yaw_rad, -2 * math.pi, 2 * math.pi, unit="rad"))

    @property
    def footprint_xy_m(self) -> np.ndarray:
        """Corners (4, 2) of its footprint seen from above (m)."""
        c, s_ = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        hx, hy = self.size_m[0] / 2, self.size_m[1] / 2
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        return local @ np.array([[c, s_], [-s_, c]]) + np.asarray(self.center_m[:2])

    @property
    def z_range_m(self) -> tuple[float, float]:
        """Its bottom and top heights (m)."""
        return self.center_m[2] - self.size_m[2] / 2, self.center_m[2] + self.size_m[2] / 2

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> BoxConfig:
        """From one TOML table (lists become tuples)."""
        if isinstance(data, BoxConfig):
            return data
        if not isinstance(data, Mapping):
            raise ConfigError("scene.boxes", data, "must be a list of tables with name, center_m, size_m (yaw_rad)")
        return from_mapping(cls, data, "scene.boxes", base=cls("box", (0.0, 0.0, 0.0), (0.1, 0.1, 0.1)))


@dataclass(frozen=True)
class SceneConfig:
    """The world the robot works in. Positions are in the world frame (m), robot base at the origin.

    Attributes:
        object: The object to pick and place (default: the 40 mm cube).
        start_xy_m: Where the object's origin starts on the table (x, y) (m).
        start_yaw_rad: The object's initial rotation about world z from its resting frame (rad).
        goal_xy_m: Where the object's origin must be placed (x, y) (m).
        goal_yaw_rad: The object's yaw at the goal (rad), modulo its symmetry (``object.yaw_period_rad``).
        table_height_m: Height of the table surface above the floor (m).
        table_center_xy_m: Centre of the table top (x, y) (m).
        table_size_xy_m: Extent of the table top (x, y) (m).
        obstacle: Put a wall on the table between the start and the goal.
        obstacle_height_m: Height of the wall above the table surface (m).
        obstacle_thickness_m: Thickness of the wall along y (m).
        obstacle_length_m: Length of the wall along x (m).
        obstacle_offset_xy_m: Offset of the wall's centre from the midpoint between start and goal (m);
            by default 7 cm away from the robot, so the arm's forearm clears it at the grasp and the place.
        obstacle_xy_m: The wall's centre (x, y) on the table (m), fixed wherever the start and the goal are
            (e.g. for objects drawn anywhere around it); ``None`` (default): placed by ``obstacle_offset_xy_m``.
        timestep_s: Simulation time step (s).
        others: More objects on the table (a task's ``[[objects]]`` after the first), each named by its object's
            name: obstacles to the arm and to the carried object until a task picks them.
        bin: An open box on the table (``clear`` tasks empty the table into it), or None.
        goal_z_m: Height of the surface the object is set down on at the goal (m): the top of a tower, the bin's
            floor; None (default): the table top.
        goal_support: Name of the object it is set down on (the tower's top), or ``""`` (the table or the bin).
        boxes: Fixed boxes (shelves, cages, walls, ...): obstacles to the arm and to a carried object. No object may
            start inside one.
    """

    object: ObjectConfig = field(default_factory=ObjectConfig)
    start_xy_m: tuple[float, float] = (0.35, 0.20)
    start_yaw_rad: float = 0.0
    goal_xy_m: tuple[float, float] = (0.35, -0.20)
    goal_yaw_rad: float = 0.0
    table_height_m: float = 0.315
    table_center_xy_m: tuple[float, float] = (0.50, 0.0)
    table_size_xy_m: tuple[float, float] = (0.60, 1.00)
    obstacle: bool = False
    obstacle_height_m: float = 0.25
    obstacle_thickness_m: float = 0.04
    obstacle_length_m: float = 0.20
    obstacle_offset_xy_m: tuple[float, float] = (0.07, 0.0)
    obstacle_xy_m: tuple[float, float] | None = None
    timestep_s: float = 0.001
    others: tuple[SceneObject, ...] = ()
    bin: BinConfig | None = None
    goal_z_m: float | None = None
    goal_support: str = ""
    boxes: tuple[BoxConfig, ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if not isinstance(self.object, ObjectConfig):
            raise ConfigError("scene.object", self.object, "must be an ObjectConfig (the [object] table)")
        set_(self, "start_xy_m", check_vector("scene.start_xy_m", self.start_xy_m, 2, unit="m"))
        set_(self, "start_yaw_rad", check_range("scene.start_yaw_rad", self.start_yaw_rad,
                                                -2 * math.pi, 2 * math.pi, unit="rad"))
        set_(self, "goal_xy_m", check_vector("scene.goal_xy_m", self.goal_xy_m, 2, unit="m"))
        set_(self, "goal_yaw_rad", check_range("scene.goal_yaw_rad", self.goal_yaw_rad,
                                                -2 * math.pi, 2 * math.pi, unit="rad"))
        set_(self, "table_height_m", check_range("scene.table_height_m", self.table_height_m, 0.05, 0.8,
                                                  unit="m"))
        set_(self, "table_center_xy_m", check_vector("scene.table_center_xy_m", self.table_center_xy_m, 2,
                                                     unit="m"))
        set_(self, "table_size_xy_m", check_vector("scene.table_size_xy_m", self.table_size_xy_m, 2,
                                                   0.1, 3.0, unit="m"))
        if not isinstance(self.obstacle, bool):
            raise ConfigError("scene.obstacle", self.obstacle, "must be true or false")
        set_(self, "obstacle_height_m", check_range("scene.obstacle_height_m", self.obstacle_height_m,
                                                     0.01, 0.6, unit="m"))
        set_(self, "obstacle_thickness_m", check_range("scene.obstacle_thickness_m",
                                                        self.obstacle_thickness_m, 0.005, 0.2, unit="m"))
        set_(self, "obstacle_length_m", check_range("scene.obstacle_length_m", self.obstacle_length_m,
                                                     0.02, 1.0, unit="m"))
        set_(self, "obstacle_offset_xy_m", check_vector("scene.obstacle_offset_xy_m", self.obstacle_offset_xy_m,
                                                         2, -0.5, 0.5, unit="m"))
        if self.obstacle_xy_m is not None:
            set_(self, "obstacle_xy_m", check_vector("scene.obstacle_xy_m", self.obstacle_xy_m, 2, unit="m"))
        set_(self, "timestep_s", check_range("scene.timestep_s", self.timestep_s, 1e-4, 0.005, unit="s"))
        set_(self, "others", tuple(self.others))
        for o in self.others:
            if not isinstance(o, SceneObject):
                raise ConfigError("objects", o, "must be SceneObjects (the [[objects]] tables)")
        if self.bin is not None and not isinstance(self.bin, BinConfig):
            raise ConfigError("bin", self.bin, "must be a BinConfig (the [bin] table)")
        if self.goal_z_m is not None:
            set_(self, "goal_z_m", check_range("scene.goal_z_m", self.goal_z_m, self.table_height_m,
                                               self.table_height_m + 0.5, unit="m (at or above the table top)"))
        if not isinstance(self.goal_support, str):
            raise ConfigError("scene.goal_support", self.goal_support, "must be an object's name, or empty")
        set_(self, "boxes", tuple(self.boxes))
        for b in self.boxes:
            if not isinstance(b, BoxConfig):
                raise ConfigError("scene.boxes", b, "must be BoxConfigs (tables with name, center_m, size_m)")
        box_names = [b.name for b in self.boxes]
        for name in box_names:
            if box_names.count(name) > 1:
                raise ConfigError(f"scene.boxes.{name}", name, "box names must be unique")
        self._check_on_table("scene.start_xy_m", self.start_xy_m)
        self.check_start_clear_of_obstacle()
        self._check_clear_of_boxes()
        if self.others or self.bin is not None:
            self._check_objects()
        # The goal is checked by check_goal_on_table(), after its reachability: a goal far out of the
        # arm's reach must be reported as unreachable, which only the kinematics can tell.

    @property
    def objects(self) -> tuple[SceneObject, ...]:
        """Every object on the table, the scene's own first (its goal is the scene's), then :attr:`others`."""
        first = SceneObject(self.object, self.start_xy_m, self.start_yaw_rad, self.goal_xy_m, self.goal_yaw_rad)
        return (first, *self.others)

    def _check_objects(self) -> None:
        """Every object's start lies on the table, clear of the wall, the bin and every other object; names are
        unique (they name the bodies)."""
        objects = self.objects
        names = [o.name for o in objects]
        for i, o in enumerate(objects):
            where = "scene.start_xy_m" if i == 0 else f"objects.{o.name}.start_xy_m"
            if names.count(o.name) > 1:
                raise ConfigError(f"objects.{o.name}", o.name, "names must be unique (give each object a name)")
            if i > 0:
                self._check_on_table(where, o.start_xy_m, o.object)
                if self.obstacle:
                    gap = footprint_gap(o.object, o.start_xy_m, o.start_yaw_rad, *self.obstacle_box_xy_m)
                    if gap < 0.0:
                        raise InsideObstacle(where, tuple(o.start_xy_m), f"the {o.name} would start inside the "
                                                                         "obstacle wall")
            if self.bin is not None:
                gap = footprint_gap(o.object, o.start_xy_m, o.start_yaw_rad, *self.bin.outer_box_xy_m)
                if gap < 0.0:
                    lo, hi = self.bin.outer_box_xy_m
                    raise InsideObstacle(where, tuple(o.start_xy_m), f"the {o.name} would start on the bin (x in "
                                         f"[{lo[0]:.3f}, {hi[0]:.3f}], y in [{lo[1]:.3f}, {hi[1]:.3f}] m)")
            for p in objects[:i]:
                gap = objects_gap(p.object, p.start_xy_m, p.start_yaw_rad, o.object, o.start_xy_m, o.start_yaw_rad)
                if gap < 0.0:
                    raise ConfigError(where, tuple(o.start_xy_m), f"the {o.name} would overlap the {p.name} "
                                                                  f"(at {tuple(p.start_xy_m)} m) by "
                                                                  f"{-gap * 1e3:.1f} mm")

    def _check_clear_of_boxes(self) -> None:
        """Raise :class:`InsideObstacle` if an object at its start overlaps a box that reaches down to it (a box whose
        bottom lies below the object's top, and whose top lies above the table)."""
        if not self.boxes:
            return
        for i, o in enumerate(self.objects):
            top = self.table_height_m + float(o.object.geometry().extent_m[2])
            for b in self.boxes:
                bottom, box_top = b.z_range_m
                if bottom >= top or box_top <= self.table_height_m:
                    continue
                gap = polygon_gap(footprint(o.object, o.start_xy_m, o.start_yaw_rad), b.footprint_xy_m)
                if gap < 0.0:
                    where = "scene.start_xy_m" if i == 0 else f"objects.{o.name}.start_xy_m"
                    raise InsideObstacle(where, tuple(o.start_xy_m), f"the {o.name} would start inside the box "
                                                                     f"'{b.name}' (centre {b.center_m} m)")

    def check_goal_on_table(self) -> None:
        """Raise :class:`ConfigError` unless the object's footprint at the goal (any yaw) lies on the table,
        clear of the obstacle, and either inside the bin or clear of it."""
        self._check_on_table("scene.goal_xy_m", self.goal_xy_m)
        if self.bin is not None:  # at the goal's yaw (a turn by its symmetry leaves the footprint as it is)
            fp = footprint(self.object, self.goal_xy_m, self.goal_yaw_rad)
            lo, hi = self.bin.inner_box_xy_m
            inside = bool(np.all(fp >= lo) and np.all(fp <= hi))
            if not inside and footprint_gap(self.object, self.goal_xy_m, self.goal_yaw_rad,
                                            *self.bin.outer_box_xy_m) < 0.0:
                raise InsideObstacle("scene.goal_xy_m", tuple(self.goal_xy_m),
                                     f"the {self.object.name} at the goal would stand on the bin's wall: it must "
                                     f"lie inside x in [{lo[0]:.3f}, {hi[0]:.3f}], y in [{lo[1]:.3f}, {hi[1]:.3f}] "
                                     "m, or clear of the bin")
        if self.obstacle:
            lo, hi = self.obstacle_box_xy_m
            near = np.clip(np.asarray(self.goal_xy_m), lo, hi)
            gap = float(np.linalg.norm(np.asarray(self.goal_xy_m) - near)) - self.footprint_radius_m
            if gap < 0.0:
                raise InsideObstacle("scene.goal_xy_m", tuple(self.goal_xy_m),
                                     f"the {self.object.name} at the goal (any yaw) would overlap the obstacle wall "
                                  f"by {-gap * 1e3:.1f} mm (wall x in [{lo[0]:.3f}, {hi[0]:.3f}], y in "
                                  f"[{lo[1]:.3f}, {hi[1]:.3f}] m)")

    @property
    def obstacle_centre_xy_m(self) -> tuple[float, float]:
        """Centre (x, y) of the obstacle wall (m): ``obstacle_xy_m``, or midway between the object's start and
        the goal plus ``obstacle_offset_xy_m``."""
        if self.obstacle_xy_m is not None:
            return (float(self.obstacle_xy_m[0]), float(self.obstacle_xy_m[1]))
        mid = (np.asarray(self.start_xy_m) + np.asarray(self.goal_xy_m)) / 2 + np.asarray(self.obstacle_offset_xy_m)
        return float(mid[0]), float(mid[1])

    @property
    def obstacle_box_xy_m(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``(lo, hi)`` (2,) of the obstacle wall's footprint on the table (m)."""
        c = np.asarray(self.obstacle_centre_xy_m)
        half = np.array([self.obstacle_length_m, self.obstacle_thickness_m]) / 2
        return c - half, c + half

    def check_start_clear_of_obstacle(self) -> None:
        """Raise :class:`ConfigError` if the object at its start (its yaw) overlaps the obstacle wall."""
        if not self.obstacle:
            return
        lo, hi = self.obstacle_box_xy_m
        c, s_ = math.cos(self.start_yaw_rad), math.sin(self.start_yaw_rad)
        v = self.object.geometry().vertices[:, :2] @ np.array([[c, s_], [-s_, c]]) + np.asarray(self.start_xy_m)
        gap = float(np.max(np.concatenate([lo - v.max(axis=0), v.min(axis=0) - hi])))  # separating axis
        if gap < 0.0:
            raise InsideObstacle("scene.start_xy_m", tuple(self.start_xy_m),
                                 f"the {self.object.name} would start inside the obstacle wall (wall x in "
                                 f"[{lo[0]:.3f}, {hi[0]:.3f}], y in [{lo[1]:.3f}, {hi[1]:.3f}] m)")

    def _check_on_table(self, name: str, xy: tuple[float, float], obj: ObjectConfig | None = None) -> None:
        """The object's (default: the scene's) whole footprint (any yaw) must lie on the table top."""
        obj = obj if obj is not None else self.object
        v = obj.geometry().vertices
        r = float(np.max(np.hypot(v[:, 0], v[:, 1])))
        for i, axis in enumerate("xy"):
            lo = self.table_center_xy_m[i] - self.table_size_xy_m[i] / 2 + r
            hi = self.table_center_xy_m[i] + self.table_size_xy_m[i] / 2 - r
            if not lo <= xy[i] <= hi:
                raise ConfigError(
                    name, tuple(xy),
                    f"the {obj.name} must lie on the table: {axis} must be in [{lo:.3f}, {hi:.3f}] m",
                )

    @property
    def footprint_radius_m(self) -> float:
        """Largest horizontal distance of the object's surface from its origin, at rest (m)."""
        v = self.object.geometry().vertices
        return float(np.max(np.hypot(v[:, 0], v[:, 1])))

    @property
    def rest_z_m(self) -> float:
        """Height of the object's origin when it rests on the table (m)."""
        return self.table_height_m - self.object.geometry().z_min_m

    def resting_z_m(self, R_world_object: np.ndarray) -> float:
        """Height of the object's origin when it rests on the table turned by ``R_world_object`` (3, 3) (m):
        on another face than its resting one (a dropped box on its side), the origin sits at another height."""
        v = self.object.geometry().vertices
        return float(self.table_height_m - np.min(v @ np.asarray(R_world_object, dtype=float)[2]))

    @property
    def goal_surface_m(self) -> float:
        """Height of the surface the object is set down on at the goal (m): ``goal_z_m``, or the table top."""
        return self.table_height_m if self.goal_z_m is None else self.goal_z_m

    def goal_resting_m(self, R_world_object: np.ndarray) -> np.ndarray:
        """Where the object's origin comes to rest at the goal (3,) turned by ``R_world_object`` (m), on the goal's
        surface (:attr:`goal_surface_m`)."""
        v = self.object.geometry().vertices
        z = self.goal_surface_m - float(np.min(v @ np.asarray(R_world_object, dtype=float)[2]))
        return np.array([*self.goal_xy_m, z])

    @property
    def start_pos_m(self) -> np.ndarray:
        """The object's initial origin (3,) in the world (m)."""
        return np.array([*self.start_xy_m, self.rest_z_m])

    @property
    def goal_pos_m(self) -> np.ndarray:
        """Where the object's origin must come to rest (3,) in the world (m), on the goal's surface."""
        return np.array([*self.goal_xy_m, self.rest_z_m + self.goal_surface_m - self.table_height_m])

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], base: SceneConfig | None = None,
                     object_data: Mapping[str, Any] | None = None) -> SceneConfig:
        """From a TOML ``[scene]`` table (and an ``[object]`` table), legacy ``cube_*`` keys included.

        ``cube_size_m`` makes the object a cube of that edge (only if it is a box); the other ``cube_*`` keys
        set the object's mass and friction or the start pose (:data:`LEGACY_SCENE_KEYS`).
        """
        if not isinstance(data, Mapping):
            raise ConfigError("scene", data, "must be a table of keys")
        start = base if base is not None else cls()
        obj = start.object if object_data is None else ObjectConfig.from_mapping(object_data, start.object)
        data = dict(data)
        if isinstance(data.get("object"), ObjectConfig):  # a whole object, from Python
            obj = data.pop("object")
        scene_changes: dict[str, Any] = {}
        for key, value in data.items():
            target = LEGACY_SCENE_KEYS.get(key, key)
            if target.startswith("object."):
                obj = _legacy_object_change(obj, key, target.split(".", 1)[1], value)
            else:
                scene_changes[target] = value
        names = [f.name for f in dataclasses.fields(cls) if f.name not in ("object", "others", "bin")]
        if "boxes" in scene_changes:
            boxes = scene_changes["boxes"]
            if isinstance(boxes, (str, Mapping)) or not hasattr(boxes, "__iter__"):
                raise ConfigError("scene.boxes", boxes, "must be a list of tables with name, center_m, size_m")
            scene_changes["boxes"] = tuple(BoxConfig.from_mapping(b) for b in boxes)
        for key, value in scene_changes.items():
            if key not in names:
                raise ConfigError(f"scene.{key}", value, f"unknown key; allowed: {', '.join(names)} (and the "
                                                         f"legacy {', '.join(LEGACY_SCENE_KEYS)})")
        changes = {k: tuple(v) if isinstance(v, list) else v for k, v in scene_changes.items()}
        try:
            return dataclasses.replace(start, object=obj, **changes)
        except ConfigError as exc:  # name the key the user wrote, if it was a legacy one
            for old, new in LEGACY_SCENE_KEYS.items():
                if old in data and exc.field.startswith(f"scene.{new}"):
                    raise type(exc)(exc.field.replace(f"scene.{new}", f"scene.{old}", 1), exc.value,
                                    exc.allowed) from None
            raise

    def to_dict(self) -> dict[str, Any]:
        """Plain data (the ``[scene]`` table; the object, the other objects and the bin are tables of their own).
        Fields that are ``None`` (not set) are left out: TOML has no null, and their default is ``None``."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
               if f.name not in ("object", "others", "bin", "boxes") and getattr(self, f.name) is not None}
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}
        if self.boxes:  # only when there are any: a scene without boxes writes what it always wrote
            out["boxes"] = [{"name": b.name, "center_m": list(b.center_m), "size_m": list(b.size_m),
                             "yaw_rad": b.yaw_rad} for b in self.boxes]
        return out

    def with_object(self, **changes: Any) -> SceneConfig:
        """A copy whose object has some fields changed (validated)."""
        return dataclasses.replace(self, object=dataclasses.replace(self.object, **changes))


def _legacy_object_change(obj: ObjectConfig, key: str, fld: str, value: Any) -> ObjectConfig:
    """Apply a legacy ``cube_*`` scene key to the object."""
    if fld == "size_m":
        if obj.kind != "box":
            raise ConfigError(f"scene.{key}", value, f"sets a cube's edge; the object is a {obj.kind} (use [object])")
        edge = check_range(f"scene.{key}", value, MIN_GRIP_WIDTH_M, MAX_GRIP_WIDTH_M, unit="m")
        return dataclasses.replace(obj, size_m=(edge, edge, edge))
    try:
        return dataclasses.replace(obj, **{fld: value})
    except ConfigError as exc:  # name the key the user wrote
        raise ConfigError(f"scene.{key}", value, exc.allowed) from None


def footprint(obj: ObjectConfig, xy_m: tuple[float, float] | np.ndarray, yaw_rad: float) -> np.ndarray:
    """Corners (N, 2) of the convex hull of the object's footprint on the table at ``xy_m``, turned by ``yaw_rad``
    about z (m): its vertices seen from above."""
    from scipy.spatial import ConvexHull

    c, s_ = math.cos(yaw_rad), math.sin(yaw_rad)
    v = obj.geometry().vertices[:, :2] @ np.array([[c, s_], [-s_, c]]) + np.asarray(xy_m, dtype=float)
    return v[ConvexHull(v).vertices]


def polygon_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Separation of two convex polygons (N, 2), (M, 2) along the best separating axis (m): > 0 apart (a lower
    bound of their distance), < 0 overlapping (minus the smallest push that separates them)."""
    best = -math.inf
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        pa, pb = a @ normals.T, b @ normals.T
        sep = np.maximum(pb.min(axis=0) - pa.max(axis=0), pa.min(axis=0) - pb.max(axis=0))
        best = max(best, float(sep.max()))
    return best


def footprint_gap(obj: ObjectConfig, xy_m: tuple[float, float], yaw_rad: float, lo: np.ndarray,
                  hi: np.ndarray) -> float:
    """Separation of the object's footprint from an axis-aligned box ``[lo, hi]`` on the table (m), as
    :func:`polygon_gap`."""
    box = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    return polygon_gap(footprint(obj, xy_m, yaw_rad), box)


def objects_gap(a: ObjectConfig, a_xy: tuple[float, float], a_yaw: float, b: ObjectConfig,
                b_xy: tuple[float, float], b_yaw: float) -> float:
    """Separation of two objects' footprints on the table (m), as :func:`polygon_gap`."""
    return polygon_gap(footprint(a, a_xy, a_yaw), footprint(b, b_xy, b_yaw))


def from_mapping(cls: type[T], data: Mapping[str, Any], section: str, base: T | None = None,
                 aliases: Mapping[str, str] | None = None) -> T:
    """Build the frozen config dataclass ``cls`` from a mapping (e.g. one TOML table).

    Lists become tuples; every value is then validated by the class itself.

    Args:
        cls: The config class.
        data: Field name -> value.
        section: Name used in errors (``"faults"`` gives ``faults.mass_scale``).
        base: Defaults to start from (default: ``cls()``).
        aliases: Older key names still accepted, old -> field.

    Raises:
        ConfigError: an unknown key (the allowed ones are listed) or an invalid value.
    """
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    aliases = aliases or {}
    data = {aliases.get(k, k): v for k, v in data.items()}
    for key, value in data.items():
        if key not in names:
            raise ConfigError(f"{section}.{key}", value, f"unknown key; allowed: {', '.join(names)}")
    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    start = base if base is not None else cls()
    return dataclasses.replace(start, **changes)  # type: ignore[type-var]


__all__ = [
    "LEGACY_SCENE_KEYS",
    "MAX_CUBE_SIZE_M",
    "MIN_CUBE_SIZE_M",
    "BinConfig",
    "BoxConfig",
    "SceneConfig",
    "SceneObject",
    "check_finite",
    "check_int",
    "check_range",
    "check_vector",
    "footprint",
    "footprint_gap",
    "from_mapping",
    "objects_gap",
    "polygon_gap",
]
