"""The exception tree of pickplace.

Every error the library raises on purpose derives from :class:`PickPlaceError`,
so a caller (or the CLI) can catch one type and print one clear line. Each
subclass carries the numbers that explain it in its message.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


class PickPlaceError(Exception):
    """Base class of every error raised on purpose by pickplace."""


class ConfigError(PickPlaceError, ValueError):
    """A configuration value is invalid.

    The message names the field, the value and what is allowed, e.g.
    ``scene.object.mass_kg = -1.0 is invalid: must be > 0 kg``.

    Attributes:
        field: Dotted name of the offending field.
        value: The rejected value.
        allowed: Human-readable description of the allowed values.
    """

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field} = {value!r} is invalid: {allowed}")


class InsideObstacle(ConfigError):
    """The object would start, or be placed, inside the obstacle wall (a :class:`ConfigError` of the scene; a
    campaign that draws such a pose draws again)."""


class ModelError(PickPlaceError):
    """The MJCF model could not be built or a named element does not exist."""


class UnreachableTarget(PickPlaceError):
    """Inverse kinematics could not reach a target pose.

    Attributes:
        target: Name of the target (e.g. ``"pregrasp"``).
        position_error_m: Residual position error at the best iterate (m).
        orientation_error_rad: Residual orientation error at the best iterate (rad).
        q: The arm configuration (6,) (rad) where it failed, when one is known (e.g. the waypoint of a straight
            move that collides), else None.
    """

    def __init__(
        self,
        target: str,
        reason: str,
        position_error_m: float = float("nan"),
        orientation_error_rad: float = float("nan"),
        q: np.ndarray | None = None,
    ) -> None:
        self.target = target
        self.q = q
        self.reason = reason
        self.position_error_m = position_error_m
        self.orientation_error_rad = orientation_error_rad
        super().__init__(
            f"target '{target}' is unreachable: {reason} "
            f"(residual {position_error_m * 1e3:.3g} mm, {orientation_error_rad:.3g} rad)"
        )


class TurnsOver(UnreachableTarget):
    """A target reached while an object is carried is reachable only by tilting the object on its side on the
    way (:func:`~pickplace.grasping.grip.carried_tilt_rad`): the arm must change IK branch to get there."""


class CollisionError(PickPlaceError):
    """A configuration that must be collision-free is in collision.

    Attributes:
        pairs: The colliding geom pairs, as ``(geom_a, geom_b)`` names.
    """

    def __init__(self, what: str, pairs: list[tuple[str, str]]) -> None:
        self.pairs = pairs
        names = ", ".join(f"{a} <-> {b}" for a, b in pairs) or "unknown geoms"
        super().__init__(f"{what} is in collision: {names}")


class PlanningFailed(PickPlaceError):
    """The motion planner could not produce a path (invalid start/goal or budget exhausted)."""


class SearchExhausted(PlanningFailed):
    """The planner's search ended (iterations or time budget spent) without reaching the goal; start and goal
    were valid, so another search (another seed, more budget) may succeed."""


class TimingFailed(PickPlaceError):
    """Time scaling (TOPP-RA) failed for a path."""


class GraspFailed(PickPlaceError):
    """A grasp could not be established or was lost."""


class ControlError(PickPlaceError):
    """A controller could not finish its motion: timeout, tracking error beyond its bound, or divergence.

    Attributes:
        phase: What was running (e.g. ``"move_vertical"``).
        reason: What went wrong, with the numbers.
        record: The record of the motion up to the failure (a ``control`` record), or None.
    """

    def __init__(self, phase: str, reason: str, record: object | None = None) -> None:
        self.phase = phase
        self.reason = reason
        self.record = record
        super().__init__(f"{phase}: {reason}")


class CannotHold(PickPlaceError):
    """The pads cannot hold the object: its weight (or its inertia in a motion) needs more friction than the
    squeeze gives, with the safety factor.

    Attributes:
        needed_n: Friction force the object needs, safety factor included (N) (nan if it is the torque).
        available_n: Friction force the pads can transmit, ``2 mu F`` (N).
        needed_nm: Torque about the closing axis the object needs, safety factor included (N m), when the
            weight turns it in the grip (:meth:`turning`), else nan.
        available_nm: Torque the pads' torsional friction resists (N m), or nan.
    """

    def __init__(self, name: str, needed_n: float, available_n: float, mass_kg: float, friction: float,
                 pad_force_n: float, safety_factor: float, accel_m_s2: float = 9.81) -> None:
        self.needed_n = needed_n
        self.available_n = available_n
        self.needed_nm = self.available_nm = float("nan")
        super().__init__(
            f"the pads cannot hold the {name}: it needs {needed_n:.1f} N of friction ({mass_kg:.3f} kg x "
            f"{accel_m_s2:.2f} m/s^2 x safety factor {safety_factor:g}) and the pads give {available_n:.1f} N "
            f"(2 x friction {friction:g} x {pad_force_n:.1f} N per pad)")

    @classmethod
    def turning(cls, name: str, needed_nm: float, available_nm: float, mass_kg: float, lever_m: float,
                torsion_m: float, pad_force_n: float, safety_factor: float) -> CannotHold:
        """The object's weight turns it in the grip: its torque about the closing axis exceeds what the pads'
        torsional friction resists (``needed_nm``, ``available_nm``: N m)."""
        exc = cls.__new__(cls)
        exc.needed_n = exc.available_n = float("nan")
        exc.needed_nm, exc.available_nm = needed_nm, available_nm
        PickPlaceError.__init__(
            exc, f"the pads cannot hold the {name}: its weight turns it about the grip axis with {needed_nm:.3f} N m "
                 f"({mass_kg:.3f} kg x 9.81 m/s^2 x its centre of mass {lever_m * 1e3:.1f} mm off the axis x safety "
                 f"factor {safety_factor:g}) and the pads resist {available_nm:.3f} N m (2 x torsional friction "
                 f"{torsion_m * 1e3:.1f} mm x {pad_force_n:.1f} N per pad)")
        return exc
