"""One contact between a finger and an object: where, along which normal, with which friction.

The record that the gripper builds from the simulated contacts (:mod:`pickplace.robot.gripper`) and that the
grasp analysis reads (:mod:`pickplace.grasping.closure`); it sits below both. Positions in metres, normals are
unit vectors pointing *into* the object, ``mu`` is Coulomb's sliding coefficient and ``torsional_friction_m``
MuJoCo's torsional coefficient (m): the largest torque about the normal is ``torsional_friction_m * f_n``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pickplace.errors import ConfigError

#: How far ``|normal|`` may be from 1 before a normal is rejected.
UNIT_TOL = 1e-6


def as_vec3(name: str, value: object) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (3,):
        raise ConfigError(name, value, "must be a vector of shape (3,)")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(name, value, "must contain only finite numbers")
    return arr


def as_unit3(name: str, value: object) -> np.ndarray:
    arr = as_vec3(name, value)
    norm = float(np.linalg.norm(arr))
    if abs(norm - 1.0) > UNIT_TOL:
        raise ConfigError(name, value, f"must be a unit vector (|n| = {norm:.3g}, tolerance {UNIT_TOL:g})")
    return arr / norm


def as_nonneg(name: str, value: object, *, positive: bool = False) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(name, value, "must be a finite number") from None
    if isinstance(value, bool) or not math.isfinite(v) or (v <= 0.0 if positive else v < 0.0):
        raise ConfigError(name, value, "must be a finite number " + ("> 0" if positive else ">= 0"))
    return v


@dataclass(frozen=True, eq=False)
class Contact:
    """One contact between a finger and the object (validated on construction).

    Attributes:
        position: Contact point (3,) in the object/world frame (m).
        normal: Unit contact normal (3,), pointing into the object.
        mu: Coulomb sliding friction coefficient (>= 0).
        torsional_friction_m: Torsional (soft-finger) coefficient (m), >= 0; 0 is a point contact.
    """

    position: np.ndarray
    normal: np.ndarray
    mu: float
    torsional_friction_m: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", as_vec3("contact.position", self.position))
        object.__setattr__(self, "normal", as_unit3("contact.normal", self.normal))
        object.__setattr__(self, "mu", as_nonneg("contact.mu", self.mu))
        object.__setattr__(
            self, "torsional_friction_m", as_nonneg("contact.torsional_friction_m", self.torsional_friction_m)
        )
        self.position.flags.writeable = False
        self.normal.flags.writeable = False


__all__ = ["UNIT_TOL", "Contact", "as_nonneg", "as_unit3", "as_vec3"]
