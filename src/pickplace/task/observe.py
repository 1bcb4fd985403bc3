"""What the robot knows about the world: one interface, through which a skill learns everything about the object.

A skill never reads the simulator's object state itself. It asks an :class:`Observer` where the object is
(resting, or in the hand), how fast it moves, and what the pads feel. :class:`SimulatorObserver` answers from
the simulation, exactly and at once: the ideal profile, which isolates the algorithms' own error. A realistic
observer answers from sensors (a depth camera, the gripper, a wrist force/torque sensor) and has no path to
the simulator's object state.

The code that *measures* an episode (the place error in the result, the check 1 s after the release) reads the
truth on purpose; it uses a :class:`SimulatorObserver` of its own, kept apart from the robot's.
"""

from __future__ import annotations

from typing import Protocol

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.robot import gripper
from pickplace.robot.model import Robot
from pickplace.world.contact import Contact


class Observer(Protocol):
    """Everything a skill may know about the object and the grip (SI units, world frame)."""

    def object_pose(self) -> pin.SE3:
        """The object's pose, resting or held."""
        ...

    def object_position(self) -> np.ndarray:
        """The object's origin (3,) (m): cheaper than :meth:`object_pose`, for checks at every step."""
        ...

    def object_velocity(self) -> np.ndarray:
        """The object's linear and angular velocity (6,) (m/s, rad/s)."""
        ...

    def object_vertical_acceleration(self) -> float:
        """The object's vertical acceleration (m/s^2), for weighing it."""
        ...

    def pad_forces(self) -> np.ndarray:
        """The normal force of each pad on the object (2,) (N)."""
        ...

    def pad_load(self) -> tuple[np.ndarray, np.ndarray]:
        """The pads' normal forces (2,) (N) and their total force on the object (3,) (N)."""
        ...

    def pad_contacts(self) -> list[Contact]:
        """The pad-object contacts (points, normals, friction), for the force-closure test."""
        ...


class SimulatorObserver:
    """The ideal observer: the simulation's own state, exact and without delay.

    Args:
        robot: The models (the object's body and joint).
        data: The simulation state.
    """

    def __init__(self, robot: Robot, data: mujoco.MjData) -> None:
        self.robot, self.d = robot, data
        h = robot.handles
        self._body = h.object_body
        self._dof = h.object_dof

    def object_pose(self) -> pin.SE3:
        """The object's pose (its body frame)."""
        return pin.SE3(self.d.xmat[self._body].reshape(3, 3).copy(), self.d.xpos[self._body].copy())

    def object_position(self) -> np.ndarray:
        """The object's origin (3,) (m)."""
        return self.d.xpos[self._body].copy()

    def object_velocity(self) -> np.ndarray:
        """The free joint's velocity (6,): linear (world) then angular (m/s, rad/s)."""
        return self.d.qvel[self._dof:self._dof + 6].copy()

    def object_vertical_acceleration(self) -> float:
        """The free joint's world z acceleration (m/s^2)."""
        return float(self.d.qacc[self._dof + 2])

    def pad_forces(self) -> np.ndarray:
        """Normal force of each pad (2,) (N)."""
        return gripper.pad_forces(self.robot, self.d)

    def pad_load(self) -> tuple[np.ndarray, np.ndarray]:
        """The pads' normal forces (2,) and their total force on the object (3,) (N)."""
        return gripper.pad_load(self.robot, self.d)

    def pad_contacts(self) -> list[Contact]:
        """The pad-object contacts as the simulation has them."""
        return gripper.pad_contacts(self.robot, self.d)


__all__ = ["Observer", "SimulatorObserver"]
