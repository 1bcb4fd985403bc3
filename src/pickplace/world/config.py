"""Configuration: frozen, validated dataclasses, in SI units.

Every config validates itself on construction and raises
:class:`~pickplace.errors.ConfigError` naming the field, the value and what is
allowed. Nothing here touches MuJoCo or Pinocchio; :mod:`pickplace.robot.model`
turns a :class:`SceneConfig` into models.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from pickplace.errors import ConfigError

T = TypeVar("T")

# --------------------------------------------------------------------------- #
# validation helpers (shared by every config)
# --------------------------------------------------------------------------- #


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as a float, or raise if it is not a finite number (strings are not numbers)."""
    if isinstance(value, (str, bytes)):
        raise ConfigError(name, value, "must be a finite number")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(name, value, "must be a finite number") from None
    if isinstance(value, bool) or not math.isfinite(v):
        raise ConfigError(name, value, "must be a finite number")
    return v


def check_range(
    name: str,
    value: float,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
) -> float:
    """Check that ``value`` is finite and inside ``[lo, hi]`` (or the open variants).

    Returns:
        The value as a float.
    """
    v = check_finite(name, value)
    lo_ok = lo is None or (v > lo if lo_open else v >= lo)
    hi_ok = hi is None or (v < hi if hi_open else v <= hi)
    if not (lo_ok and hi_ok):
        left = "" if lo is None else f"{'>' if lo_open else '>='} {lo:g}"
        right = "" if hi is None else f"{'<' if hi_open else '<='} {hi:g}"
        allowed = " and ".join(s for s in (left, right) if s)
        raise ConfigError(name, value, f"must be {allowed}{' ' + unit if unit else ''}")
    return v


def check_int(name: str, value: int, lo: int, hi: int | None = None) -> int:
    """Check that ``value`` is an integer in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(name, value, "must be an integer")
    if value < lo or (hi is not None and value > hi):
        raise ConfigError(name, value, f"must be >= {lo}" + (f" and <= {hi}" if hi is not None else ""))
    return int(value)


def check_vector(
    name: str,
    value: Sequence[float],
    size: int,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    unit: str = "",
) -> tuple[float, ...]:
    """Check a fixed-size vector of finite numbers, each in range; return it as a tuple."""
    try:
        items = list(value)
    except TypeError:
        raise ConfigError(name, value, f"must be a sequence of {size} numbers") from None
    if len(items) != size:
        raise ConfigError(name, value, f"must have exactly {size} elements")
    return tuple(
        check_range(f"{name}[{i}]", v, lo, hi, lo_open=lo_open, unit=unit) for i, v in enumerate(items)
    )


# --------------------------------------------------------------------------- #
# scene
# --------------------------------------------------------------------------- #

#: Largest cube edge the gripper can take with 5 mm clearance per side (m); see gripper.xml.
MAX_CUBE_SIZE_M = 0.074
#: Smallest cube edge the closed gripper still squeezes (m); see gripper.xml.
MIN_CUBE_SIZE_M = 0.010


@dataclass(frozen=True)
class SceneConfig:
    """The world the robot works in. Positions are in the world frame (m), robot base at the origin.

    Attributes:
        cube_size_m: Edge length of the cube (m).
        cube_mass_kg: Mass of the cube (kg).
        cube_friction: Coulomb sliding friction coefficient of every contact with the cube.
        cube_torsional_friction_m: Torsional friction coefficient (m) of cube contacts (condim 4).
        cube_start_xy_m: Where the cube's centre starts on the table (x, y) (m).
        cube_yaw_rad: The cube's initial rotation about world z (rad).
        goal_xy_m: Where the cube's centre must be placed (x, y) (m).
        goal_yaw_rad: The cube's yaw at the goal (rad), modulo the cube's 90° symmetry.
        table_height_m: Height of the table surface above the floor (m).
        table_center_xy_m: Centre of the table top (x, y) (m).
        table_size_xy_m: Extent of the table top (x, y) (m).
        obstacle: Put a wall on the table between the start and the goal.
        obstacle_height_m: Height of the wall above the table surface (m).
        obstacle_thickness_m: Thickness of the wall along y (m).
        obstacle_length_m: Length of the wall along x (m).
        obstacle_offset_xy_m: Offset of the wall's centre from the midpoint between start and goal (m);
            by default 7 cm away from the robot, so the arm's forearm clears it at the grasp and the place.
        timestep_s: Simulation time step (s).
    """

    cube_size_m: float = 0.040
    cube_mass_kg: float = 0.150
    cube_friction: float = 1.0
    cube_torsional_friction_m: float = 0.005
    cube_start_xy_m: tuple[float, float] = (0.35, 0.20)
    cube_yaw_rad: float = 0.0
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
    timestep_s: float = 0.001

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "cube_size_m", check_range("scene.cube_size_m", self.cube_size_m,
                                               MIN_CUBE_SIZE_M, MAX_CUBE_SIZE_M, unit="m"))
        set_(self, "cube_mass_kg", check_range("scene.cube_mass_kg", self.cube_mass_kg, 0.0, 5.0,
                                                lo_open=True, unit="kg (UR5e payload is 5 kg)"))
        set_(self, "cube_friction", check_range("scene.cube_friction", self.cube_friction, 0.0, 5.0,
                                                 lo_open=True))
        set_(self, "cube_torsional_friction_m", check_range(
            "scene.cube_torsional_friction_m", self.cube_torsional_friction_m, 0.0, 0.1, unit="m"))
        set_(self, "cube_start_xy_m", check_vector("scene.cube_start_xy_m", self.cube_start_xy_m, 2, unit="m"))
        set_(self, "cube_yaw_rad", check_range("scene.cube_yaw_rad", self.cube_yaw_rad,
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
        set_(self, "timestep_s", check_range("scene.timestep_s", self.timestep_s, 1e-4, 0.005, unit="s"))
        self._check_on_table("scene.cube_start_xy_m", self.cube_start_xy_m)
        # The goal is checked by check_goal_on_table(), after its reachability: a goal far out of the
        # arm's reach must be reported as unreachable, which only the kinematics can tell.

    def check_goal_on_table(self) -> None:
        """Raise :class:`ConfigError` unless the cube's footprint at the goal (any yaw) lies on the table."""
        self._check_on_table("scene.goal_xy_m", self.goal_xy_m)

    def _check_on_table(self, name: str, xy: tuple[float, float]) -> None:
        """The cube's whole footprint (any yaw) must lie on the table top."""
        r = self.cube_size_m * math.sqrt(0.5)  # half-diagonal: the footprint radius at any yaw
        for i, axis in enumerate("xy"):
            lo = self.table_center_xy_m[i] - self.table_size_xy_m[i] / 2 + r
            hi = self.table_center_xy_m[i] + self.table_size_xy_m[i] / 2 - r
            if not lo <= xy[i] <= hi:
                raise ConfigError(
                    name, tuple(xy),
                    f"the cube must lie on the table: {axis} must be in [{lo:.3f}, {hi:.3f}] m",
                )

    @property
    def cube_start_z_m(self) -> float:
        """Height of the cube's centre resting on the table (m)."""
        return self.table_height_m + self.cube_size_m / 2

    @property
    def cube_start_pos_m(self) -> np.ndarray:
        """The cube's initial centre (3,) in the world (m)."""
        return np.array([*self.cube_start_xy_m, self.cube_start_z_m])

    @property
    def goal_pos_m(self) -> np.ndarray:
        """Where the cube's centre must come to rest (3,) in the world (m)."""
        return np.array([*self.goal_xy_m, self.cube_start_z_m])


def from_mapping(cls: type[T], data: Mapping[str, Any], section: str, base: T | None = None) -> T:
    """Build the frozen config dataclass ``cls`` from a mapping (e.g. one TOML table).

    Lists become tuples; every value is then validated by the class itself.

    Args:
        cls: The config class.
        data: Field name -> value.
        section: Name used in errors (``"scene"`` gives ``scene.cube_mass_kg``).
        base: Defaults to start from (default: ``cls()``).

    Raises:
        ConfigError: an unknown key (the allowed ones are listed) or an invalid value.
    """
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    for key, value in data.items():
        if key not in names:
            raise ConfigError(f"{section}.{key}", value, f"unknown key; allowed: {', '.join(names)}")
    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    start = base if base is not None else cls()
    return dataclasses.replace(start, **changes)  # type: ignore[type-var]


__all__ = [
    "MAX_CUBE_SIZE_M",
    "MIN_CUBE_SIZE_M",
    "SceneConfig",
    "check_finite",
    "check_int",
    "check_range",
    "check_vector",
    "from_mapping",
]
