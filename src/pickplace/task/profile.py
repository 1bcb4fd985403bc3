"""Robot profiles: how the robot knows the world. ``ideal`` isolates the algorithms' own error; ``realistic``
is a UR5e with a depth camera, its gripper and a wrist force/torque sensor.

* ``ideal``: the robot reads the object's pose, velocity and the pads' contact forces from the simulator,
  exactly and at once (:class:`~pickplace.task.observe.SimulatorObserver`).
* ``realistic``: the robot knows the object only through its sensors
  (:class:`~pickplace.task.observe.SensorObserver`): a fixed depth camera with the noise and the calibration
  error of an Intel RealSense D435 (:class:`~pickplace.perception.camera.CameraConfig`, every default with
  its source), the gripper's own force and finger travel, a wrist force/torque sensor
  (:class:`~pickplace.task.observe.SensingConfig`).

In a TOML config::

    [profile]
    name = "realistic"

    [profile.camera]           # any CameraConfig field
    subpixel_px = 0.15

    [profile.sensing]          # any SensingConfig field
    watch_period_s = 0.05

Fields left out keep the named profile's defaults.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from pickplace.errors import ConfigError
from pickplace.perception.camera import CameraConfig
from pickplace.robot.model import Robot
from pickplace.task.observe import Observer, SensingConfig, SensorObserver, SimulatorObserver
from pickplace.world.config import from_mapping

#: The profiles by name.
PROFILES = ("ideal", "realistic")


@dataclass(frozen=True)
class ProfileConfig:
    """What the robot can sense, and how well.

    Attributes:
        name: ``ideal`` (the simulator's truth) or ``realistic`` (sensors).
        camera: The depth camera (realistic only).
        sensing: The gripper and wrist sensors and how often the camera re-checks (realistic only).
    """

    name: str = "ideal"
    camera: CameraConfig = field(default_factory=CameraConfig)
    sensing: SensingConfig = field(default_factory=SensingConfig)

    def __post_init__(self) -> None:
        if self.name not in PROFILES:
            raise ConfigError("profile.name", self.name, f"must be one of {', '.join(PROFILES)}")
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError("profile.camera", self.camera, "must be a CameraConfig")
        if not isinstance(self.sensing, SensingConfig):
            raise ConfigError("profile.sensing", self.sensing, "must be a SensingConfig")

    @classmethod
    def named(cls, name: str) -> ProfileConfig:
        """The profile ``name`` with its defaults."""
        return cls(name=name)

    @property
    def realistic(self) -> bool:
        """Whether the robot senses the world rather than reading the simulator."""
        return self.name == "realistic"

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], base: ProfileConfig | None = None) -> ProfileConfig:
        """From a ``[profile]`` table: ``name`` and the ``camera`` and ``sensing`` sub-tables (unknown keys are
        errors naming the key)."""
        if not isinstance(data, Mapping):
            raise ConfigError("profile", data, "must be a table of keys")
        allowed = ("name", "camera", "sensing")
        for key in data:
            if key not in allowed:
                raise ConfigError(f"profile.{key}", data[key], f"unknown key; allowed: {', '.join(allowed)}")
        start = cls.named(data["name"]) if "name" in data else (base if base is not None else cls())
        parts: dict[str, Any] = {}
        for key, sub in (("camera", CameraConfig), ("sensing", SensingConfig)):
            value = data.get(key, {})
            if isinstance(value, sub):
                parts[key] = value
            elif isinstance(value, Mapping):
                parts[key] = from_mapping(sub, value, f"profile.{key}", getattr(start, key))
            else:
                raise ConfigError(f"profile.{key}", value, "must be a table of keys")
        return dataclasses.replace(start, **parts)

    def observer(self, robot: Robot, data: mujoco.MjData, rng: np.random.Generator) -> Observer:
        """The robot's observer in this profile.

        Args:
            robot: The models.
            data: The simulation.
            rng: Seeded generator of the sensors' noise and the camera's calibration error (realistic).
        """
        if self.realistic:
            return SensorObserver(robot, data, self.camera, self.sensing, rng)
        return SimulatorObserver(robot, data)


__all__ = ["PROFILES", "ProfileConfig"]
