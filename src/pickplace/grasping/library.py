"""The object library as a table: each object's size, mass, friction, and the grasps it offers.

``pickplace objects`` prints it. "Feasible" counts the grasps that work at the default pose: the object where
the default scene starts it, each candidate placed there and clear of the table
(:func:`~pickplace.grasping.configurations.candidate_grasps`), whose pregrasp solves collision free (with the
planner's default 10 mm margin) and whose straight approach from there to the grasp does too, waypoint by
waypoint (:func:`~pickplace.grasping.configurations.feasible_grasps`). The lift, the place and the retreat
depend on the goal and are solved when the episode runs.
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from dataclasses import dataclass

from pickplace.grasping.configurations import candidate_grasps, feasible_grasps, object_grasps, start_pose
from pickplace.robot.gripper import GripperGeometry
from pickplace.robot.model import build
from pickplace.world.config import SceneConfig
from pickplace.world.objects import LIBRARY, ObjectConfig

#: Clearance the ends of the planned paths keep (m): ``MachineConfig.planning_margin_m``'s default.
PLANNING_MARGIN_M = 0.01


@dataclass(frozen=True)
class ObjectSummary:
    """One library object and its grasps.

    Attributes:
        name: Its library name.
        kind: ``box``, ``cylinder``, ``sphere``, ``compound`` or ``mesh``.
        extent_m: Size of its bounding box at rest (x, y, z) (m).
        mass_kg: Mass (kg).
        friction: Friction coefficient.
        rolling_friction_m: Rolling friction length (m) (0: it does not roll, or rolling is not modelled).
        grasps: Grasp candidates of its geometry (object frame, every filter of the synthesis).
        grasps_at_default_pose: Of those, the ones clear of the table at the default pose.
        feasible: Of those, the ones the arm reaches collision free (pregrasp and straight approach).
        feasible_by_approach: ``feasible`` per approach (``top``, ``tilted``, ``side``).
        source: Where its numbers come from.
    """

    name: str
    kind: str
    extent_m: tuple[float, float, float]
    mass_kg: float
    friction: float
    rolling_friction_m: float
    grasps: int
    grasps_at_default_pose: int
    feasible: int
    feasible_by_approach: dict[str, int]
    source: str

    def to_dict(self) -> dict[str, object]:
        """Plain JSON-ready data."""
        return dataclasses.asdict(self)


def summarize_object(obj: ObjectConfig, scene: SceneConfig | None = None) -> ObjectSummary:
    """The summary of ``obj`` at the start of ``scene`` (default: the default scene) with ``obj`` in it."""
    scene = dataclasses.replace(scene if scene is not None else SceneConfig(), object=obj)
    robot = build(scene)
    geom = GripperGeometry.measure(robot)
    T = start_pose(robot)
    every = object_grasps(obj, geom)
    placed = candidate_grasps(robot, T)
    feasible = Counter(c.approach.value for c in feasible_grasps(robot, placed, T, PLANNING_MARGIN_M))
    ext = obj.geometry().extent_m
    return ObjectSummary(obj.name, obj.kind, (float(ext[0]), float(ext[1]), float(ext[2])), obj.mass_kg,
                         obj.friction, obj.rolling_friction_m, len(every), len(placed), sum(feasible.values()),
                         dict(sorted(feasible.items())), obj.source)


def summarize_library(scene: SceneConfig | None = None) -> list[ObjectSummary]:
    """:func:`summarize_object` of every library object, in library order."""
    return [summarize_object(obj, scene) for obj in LIBRARY.values()]


__all__ = ["ObjectSummary", "summarize_library", "summarize_object"]
