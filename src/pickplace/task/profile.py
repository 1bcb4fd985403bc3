"""Robot profiles: what the robot knows and how it is controlled. ``ideal`` isolates the algorithms' own error;
``realistic`` is a UR5e as it is run: a depth camera, its gripper's and wrist's sensors, its controller.

* ``ideal``: the robot reads the object's pose, velocity and the pads' contact forces from the simulator,
  exactly and at once (:class:`~pickplace.task.observe.SimulatorObserver`); its controllers read the exact
  joint state every 1 ms physics step and act in the same step, with the simulated arm's own dynamics model.
* ``realistic``: the robot knows the object only through its sensors
  (:class:`~pickplace.task.observe.SensorObserver`): a fixed depth camera with the noise and the calibration
  error of an Intel RealSense D435 (:class:`~pickplace.perception.camera.CameraConfig`), the gripper's own
  force and finger travel, a wrist force/torque sensor (:class:`~pickplace.task.observe.SensingConfig`); its
  planners check against the world it believes in (``Observer.world``: its map, the object where the camera
  saw it, and the obstacles the camera sees, :mod:`pickplace.perception.obstacles`). Its
  controllers run at the e-Series' 500 Hz with one period of latency on quantized, noisy encoders
  (:class:`~pickplace.motion.loop.LoopConfig`), with a dynamics model whose links' masses, centres of mass and
  inertias are off by up to 10 % and an arm whose joints have friction the controller does not know
  (:class:`~pickplace.robot.model_error.ModelErrorConfig`), and gains for that
  (:meth:`~pickplace.motion.control.ControlConfig.realistic`, the ``[control]`` table's defaults in this
  profile, which also yield along the pads' closing axis while the gripper closes); the gripper closes at a
  Robotiq 2F-85's speed (:class:`~pickplace.robot.gripper.GripperConfig`).
  Every default names its source in its class.

In a TOML config::

    [profile]
    name = "realistic"

    [profile.camera]           # any CameraConfig field
    subpixel_px = 0.15

    [profile.sensing]          # any SensingConfig field
    watch_period_s = 0.05

    [profile.loop]             # LoopConfig; also [profile.model_error], [profile.gripper]
    latency_s = 0.004

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
from pickplace.motion.control import ControlConfig
from pickplace.motion.loop import ControlLoop, LoopConfig
from pickplace.perception.camera import CameraConfig
from pickplace.robot.gripper import GripperConfig, with_gripper
from pickplace.robot.model import Robot
from pickplace.robot.model_error import ModelErrorConfig, with_model_error
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
        loop: The control loop: rate, latency, encoders (every field 0: the ideal loop).
        model_error: The controller's model error and the arm's unknown joint friction (0: none).
        gripper: The gripper's closing speed and force.
    """

    name: str = "ideal"
    camera: CameraConfig = field(default_factory=CameraConfig)
    sensing: SensingConfig = field(default_factory=SensingConfig)
    loop: LoopConfig = field(default_factory=LoopConfig)
    model_error: ModelErrorConfig = field(default_factory=ModelErrorConfig)
    gripper: GripperConfig = field(default_factory=GripperConfig)

    def __post_init__(self) -> None:
        if self.name not in PROFILES:
            raise ConfigError("profile.name", self.name, f"must be one of {', '.join(PROFILES)}")
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError("profile.camera", self.camera, "must be a CameraConfig")
        for key, sub in _PARTS.items():
            if not isinstance(getattr(self, key), sub):
                raise ConfigError(f"profile.{key}", getattr(self, key), f"must be a {sub.__name__}")

    @classmethod
    def named(cls, name: str) -> ProfileConfig:
        """The profile ``name`` with its defaults."""
        if name == "realistic":
            return cls(name=name, loop=LoopConfig.realistic(), model_error=ModelErrorConfig.realistic(),
                       gripper=GripperConfig.realistic())
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
        allowed = ("name", *_PARTS)
        for key in data:
            if key not in allowed:
                raise ConfigError(f"profile.{key}", data[key], f"unknown key; allowed: {', '.join(allowed)}")
        start = cls.named(data["name"]) if "name" in data else (base if base is not None else cls())
        parts: dict[str, Any] = {}
        for key, sub in _PARTS.items():
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

    def plant(self, robot: Robot, rng: np.random.Generator) -> Robot:
        """The robot as this profile runs it: the controller's model error and the arm's joint friction
        (:func:`~pickplace.robot.model_error.with_model_error`), the gripper's drive
        (:func:`~pickplace.robot.gripper.with_gripper`); ``robot`` itself when the profile changes neither.

        Args:
            robot: The robot as built.
            rng: Seeded generator of the model error.
        """
        return with_gripper(with_model_error(robot, self.model_error, rng), self.gripper)

    def control_defaults(self) -> ControlConfig:
        """The controller's default gains for this profile's loop: :meth:`ControlConfig.realistic` for a
        realistic loop (the ideal gains do not hold a 500 Hz loop with latency; it says why), the ideal ones
        otherwise."""
        return ControlConfig() if self.loop.ideal else ControlConfig.realistic()

    def control_loop(self, rng: np.random.Generator) -> ControlLoop | None:
        """The control loop of this profile (None: the ideal loop).

        Args:
            rng: Seeded generator of the encoders' noise.
        """
        return None if self.loop.ideal else ControlLoop(self.loop, rng)


#: The parts of a profile: ``[profile.KEY]`` tables.
_PARTS: dict[str, type] = {"camera": CameraConfig, "sensing": SensingConfig, "loop": LoopConfig,
                           "model_error": ModelErrorConfig, "gripper": GripperConfig}


__all__ = ["PROFILES", "ProfileConfig"]
