"""Tests of pickplace.world.config: SceneConfig defaults, the object in it, the ``cube_*`` keys of earlier
versions, and the ConfigError messages of bad values."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pickplace.errors import ConfigError, InsideObstacle, PickPlaceError
from pickplace.world.config import MAX_CUBE_SIZE_M, MIN_CUBE_SIZE_M, SceneConfig
from pickplace.world.objects import ObjectConfig, library_object


def test_defaults_are_valid() -> None:
    s = SceneConfig()
    assert s.object == library_object("cube")
    assert s.object.size_m == (0.040, 0.040, 0.040)
    assert s.object.mass_kg == 0.150
    assert s.object.friction == 1.0
    assert s.start_xy_m == (0.35, 0.20)
    assert s.goal_xy_m == (0.35, -0.20)
    assert s.table_height_m == 0.315
    assert s.obstacle is False
    assert s.timestep_s == 0.001
    assert s.rest_z_m == pytest.approx(0.335, abs=1e-12)
    np.testing.assert_allclose(s.start_pos_m, [0.35, 0.20, 0.335], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.goal_pos_m, [0.35, -0.20, 0.335], rtol=0, atol=1e-12)
    # validated values are stored as floats / tuples of floats
    assert isinstance(SceneConfig(start_yaw_rad=1).start_yaw_rad, float)
    assert SceneConfig(start_xy_m=np.array([0.4, 0.1])).start_xy_m == (0.4, 0.1)


def test_config_is_frozen() -> None:
    s = SceneConfig()
    with pytest.raises(AttributeError):
        s.goal_yaw_rad = 1.0  # type: ignore[misc]


def test_legacy_cube_keys_set_the_object_and_the_start() -> None:
    s = SceneConfig.from_mapping({"cube_size_m": 0.03, "cube_mass_kg": 0.3, "cube_friction": 0.7,
                                  "cube_start_xy_m": [0.4, 0.1], "cube_yaw_rad": 0.3})
    assert s.object.size_m == (0.03, 0.03, 0.03) and s.object.mass_kg == 0.3 and s.object.friction == 0.7
    assert s.start_xy_m == (0.4, 0.1) and s.start_yaw_rad == 0.3
    assert s.rest_z_m == pytest.approx(0.315 + 0.015, abs=1e-12)
    can = SceneConfig.from_mapping({"cube_mass_kg": 0.3}, object_data={"library": "soda_can"})
    assert can.object.kind == "cylinder" and can.object.mass_kg == 0.3
    with pytest.raises(ConfigError, match=r"scene\.cube_size_m .* the object is a cylinder"):
        SceneConfig.from_mapping({"cube_size_m": 0.03}, object_data={"library": "soda_can"})


def _message(field: str, value: object) -> str:
    """The start of a ConfigError message: ``<field> = <repr(value)> is invalid: ``, as a regex."""
    return re.escape(f"{field} = {value!r} is invalid: ")


@pytest.mark.parametrize(
    ("kwargs", "field", "value", "allowed"),
    [
        ({"cube_mass_kg": -0.1}, "scene.cube_mass_kg", -0.1, "must be > 0 and <= 5 kg"),
        ({"cube_mass_kg": 0.0}, "scene.cube_mass_kg", 0.0, "must be > 0 and <= 5 kg"),
        ({"cube_mass_kg": 6.0}, "scene.cube_mass_kg", 6.0, "must be > 0 and <= 5 kg"),
        ({"cube_size_m": math.nan}, "scene.cube_size_m", math.nan, "must be a finite number"),
        ({"cube_size_m": 0.2}, "scene.cube_size_m", 0.2,
         f"must be >= {MIN_CUBE_SIZE_M:g} and <= {MAX_CUBE_SIZE_M:g} m"),
        ({"cube_friction": math.inf}, "scene.cube_friction", math.inf, "must be a finite number"),
        ({"cube_friction": -math.inf}, "scene.cube_friction", -math.inf, "must be a finite number"),
        ({"cube_friction": 0.0}, "scene.cube_friction", 0.0, "must be > 0 and <= 5"),
        ({"cube_mass_kg": "heavy"}, "scene.cube_mass_kg", "heavy", "must be a finite number"),
        ({"cube_mass_kg": None}, "scene.cube_mass_kg", None, "must be a finite number"),
        ({"cube_mass_kg": True}, "scene.cube_mass_kg", True, "must be a finite number"),
        ({"obstacle": "false"}, "scene.obstacle", "false", "must be true or false"),
        ({"obstacle": 1}, "scene.obstacle", 1, "must be true or false"),
        ({"timestep_s": 0.01}, "scene.timestep_s", 0.01, "must be >= 0.0001 and <= 0.005 s"),
        ({"timestep_s": 1e-5}, "scene.timestep_s", 1e-5, "must be >= 0.0001 and <= 0.005 s"),
        ({"timestep_s": 0.0}, "scene.timestep_s", 0.0, "must be >= 0.0001 and <= 0.005 s"),
        ({"cube_start_xy_m": (0.35,)}, "scene.cube_start_xy_m", (0.35,), "must have exactly 2 elements"),
        ({"start_xy_m": (0.35,)}, "scene.start_xy_m", (0.35,), "must have exactly 2 elements"),
        ({"goal_xy_m": (0.35, -0.2, 0.0)}, "scene.goal_xy_m", (0.35, -0.2, 0.0),
         "must have exactly 2 elements"),
        ({"cube_start_xy_m": 0.35}, "scene.cube_start_xy_m", 0.35, "must be a sequence of 2 numbers"),
        ({"cube_start_xy_m": (0.35, "left")}, "scene.cube_start_xy_m[1]", "left", "must be a finite number"),
        ({"start_xy_m": (math.nan, 0.2)}, "scene.start_xy_m[0]", math.nan, "must be a finite number"),
        ({"cube_yaw_rad": 7.0}, "scene.cube_yaw_rad", 7.0, "must be >="),
        ({"start_yaw_rad": 7.0}, "scene.start_yaw_rad", 7.0, "must be >="),
        ({"table_height_m": 0.9}, "scene.table_height_m", 0.9, "must be >= 0.05 and <= 0.8 m"),
        ({"table_size_xy_m": (0.05, 1.0)}, "scene.table_size_xy_m[0]", 0.05, "must be >= 0.1 and <= 3 m"),
    ],
)
def test_bad_values_raise_config_error(kwargs: dict, field: str, value: object, allowed: str) -> None:
    """As a TOML [scene] table would give them (legacy keys included): the error names the key written."""
    with pytest.raises(ConfigError, match=_message(field, value) + re.escape(allowed)) as info:
        SceneConfig.from_mapping(kwargs)
    err = info.value
    assert err.field == field
    assert err.allowed.startswith(allowed)
    if isinstance(value, float) and math.isnan(value):
        assert math.isnan(err.value)
    else:
        assert err.value == value
    # one type to catch, and a ValueError for callers that do not know pickplace
    assert isinstance(err, PickPlaceError)
    assert isinstance(err, ValueError)


def test_unknown_scene_key_lists_the_allowed_ones() -> None:
    with pytest.raises(ConfigError, match=r"scene\.cube_colour .* unknown key; allowed: start_xy_m.*cube_mass_kg"):
        SceneConfig.from_mapping({"cube_colour": "red"})


@pytest.mark.parametrize("field", ["start_xy_m", "goal_xy_m"])
@pytest.mark.parametrize(
    ("xy", "axis"),
    [((0.10, 0.0), "x"), ((0.85, 0.0), "x"), ((0.35, 0.55), "y"), ((0.35, -0.49), "y")],
)
def test_object_off_the_table(field: str, xy: tuple[float, float], axis: str) -> None:
    # default table: x in [0.20, 0.80], y in [-0.50, 0.50]; a 40 mm cube's footprint radius is 28.3 mm
    with pytest.raises(ConfigError, match=_message(f"scene.{field}", xy)) as info:
        SceneConfig(**{field: xy}).check_goal_on_table()  # the start is checked on construction
    msg = str(info.value)
    assert "the cube must lie on the table" in msg
    r = 0.040 * math.sqrt(0.5)
    lo, hi = {"x": (0.20 + r, 0.80 - r), "y": (-0.50 + r, 0.50 - r)}[axis]
    assert f"{axis} must be in [{lo:.3f}, {hi:.3f}] m" in msg


def test_footprint_limit_is_the_half_diagonal() -> None:
    r = 0.040 * math.sqrt(0.5)
    SceneConfig(start_xy_m=(0.20 + r + 1e-9, 0.0))  # just on the table
    with pytest.raises(ConfigError, match=r"scene\.start_xy_m"):
        SceneConfig(start_xy_m=(0.20 + r - 1e-6, 0.0))
    # a bigger table accepts what the default one rejects
    SceneConfig(goal_xy_m=(0.10, 0.0), table_size_xy_m=(1.0, 1.0)).check_goal_on_table()
    # a can's footprint radius is its radius
    can = library_object("soda_can")
    assert SceneConfig(object=can).footprint_radius_m == pytest.approx(can.size_m[0], rel=1e-3)


def test_valid_non_defaults_are_accepted() -> None:
    s = SceneConfig.from_mapping(dict(cube_size_m=MIN_CUBE_SIZE_M, cube_mass_kg=5.0, cube_friction=0.05,
                                      obstacle=True, timestep_s=0.005, cube_yaw_rad=-2 * math.pi))
    assert s.object.size_m == (MIN_CUBE_SIZE_M,) * 3
    assert s.object.mass_kg == 5.0
    assert s.obstacle is True
    assert s.timestep_s == 0.005
    SceneConfig.from_mapping(dict(cube_size_m=MAX_CUBE_SIZE_M, timestep_s=1e-4))
    assert SceneConfig(object=ObjectConfig(kind="sphere", size_m=(0.03,), name="ball")).rest_z_m == pytest.approx(
        0.345, abs=1e-12)


def test_the_wall_can_be_fixed_and_nothing_starts_or_ends_inside_it() -> None:
    from pickplace.world.config import SceneConfig

    scene = SceneConfig(obstacle=True, obstacle_xy_m=(0.40, 0.05))
    assert scene.obstacle_centre_xy_m == (0.40, 0.05)
    assert SceneConfig(obstacle=True, start_xy_m=(0.30, 0.20)).obstacle_centre_xy_m == pytest.approx((0.395, 0.0))
    with pytest.raises(InsideObstacle, match=r"scene\.start_xy_m.*inside the obstacle wall"):  # a ConfigError
        SceneConfig(obstacle=True, obstacle_xy_m=(0.40, 0.05), start_xy_m=(0.45, 0.07))
    # 40 mm cube turned by 45 degrees: its corners reach 28 mm from its centre, the wall's face is at y = 0.07
    SceneConfig(obstacle=True, obstacle_xy_m=(0.40, 0.05), start_xy_m=(0.45, 0.099))
    with pytest.raises(ConfigError, match=r"scene\.start_xy_m"):
        SceneConfig(obstacle=True, obstacle_xy_m=(0.40, 0.05), start_xy_m=(0.45, 0.095), start_yaw_rad=0.785)
    with pytest.raises(InsideObstacle, match=r"scene\.goal_xy_m.*overlap the obstacle wall"):
        SceneConfig(obstacle=True, obstacle_xy_m=(0.35, -0.20)).check_goal_on_table()
