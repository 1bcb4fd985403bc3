"""Tasks with several objects: what to do with each (its goal) and in which order.

A task is a sequence of pick and places (:mod:`pickplace.task.skill`, one per object and move) chosen from
what the robot observes before each one:

* ``place``: every object to its own goal. An object whose goal another object still occupies waits for it;
  when every remaining object waits for another (two objects to swap), the first of them goes to a free
  *buffer* spot on the table and comes back to its goal later.
* ``stack``: a tower at ``stack_xy_m``, each object set on the one below: its goal is the observed top of the
  tower (the lower object's pose and its highest point), so the tower's own error does not add up. The planned
  order puts the widest base first.
* ``clear``: every object into the bin, each to a free spot on the bin's floor. The planned order takes the
  objects nearest the bin first, so that they are out of the way of those behind them.

With ``order = "listed"`` the objects go in the order they are listed, without buffer spots: the naive order the
planned one is measured against. In either order an object whose pick cannot start (no grasp reaches it
collision free, as the skill's IDLE finds before the arm moves) is put back and the next one is tried: an
object that blocks another's grasps is taken first.

This module decides (pure geometry on the observed poses); :mod:`pickplace.task.task_episode` runs it.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from pickplace.errors import ConfigError, PickPlaceError
from pickplace.grasping.targets import object_yaw, yaw_error
from pickplace.robot.kinematics import rot_z
from pickplace.world.config import (
    BinConfig,
    SceneConfig,
    SceneObject,
    check_int,
    check_range,
    check_vector,
    footprint,
    footprint_gap,
    from_mapping,
    polygon_gap,
)


class TaskKind(enum.StrEnum):
    """What a task does with its objects."""

    PLACE = "place"
    STACK = "stack"
    CLEAR = "clear"


class TaskOrder(enum.StrEnum):
    """How a task orders its objects."""

    PLANNED = "planned"
    LISTED = "listed"


@dataclass(frozen=True)
class TaskConfig:
    """A task with several objects (TOML ``[task]``; the objects are the scene's ``[[objects]]``).

    Attributes:
        kind: ``place`` (each object to its goal), ``stack`` (a tower) or ``clear`` (everything into the bin).
        order: ``planned`` (the task planner's order, buffer spots included) or ``listed`` (as listed).
        stack_xy_m: Where the tower stands (x, y) (m).
        stack_yaw_rad: The tower's bottom object's yaw (rad); each level takes the observed yaw of the one below.
        level_tolerance_xy_m: Largest horizontal offset of a tower's level from the one below at the end (m).
        level_tolerance_yaw_rad: Largest yaw of a level from the one below at the end (rad, modulo symmetry).
        knock_tolerance_m: An object not being handled that moves more than this was knocked (m).
        knock_tolerance_rad: ... or turns more than this (rad).
        repair: A knocked object that was already done is picked and placed again (otherwise the task fails).
        max_picks_per_object: Most pick and places per object (buffer moves and repairs included).
        spot_clearance_m: Gap a buffer spot or a spot in the bin keeps from every other object (and its goal) and
            from the bin's walls (m): room for the open fingers (the skill's IDLE checks the actual grasp there, and
            another spot is tried if it does not fit).
    """

    kind: str = "place"
    order: str = "planned"
    stack_xy_m: tuple[float, float] = (0.45, -0.20)
    stack_yaw_rad: float = 0.0
    level_tolerance_xy_m: float = 0.002
    level_tolerance_yaw_rad: float = math.radians(2.0)
    knock_tolerance_m: float = 0.005
    knock_tolerance_rad: float = 0.05
    repair: bool = True
    max_picks_per_object: int = 3
    spot_clearance_m: float = 0.035

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        kinds = [k.value for k in TaskKind]
        if self.kind not in kinds:
            raise ConfigError("task.kind", self.kind, f"must be one of {', '.join(kinds)}")
        orders = [o.value for o in TaskOrder]
        if self.order not in orders:
            raise ConfigError("task.order", self.order, f"must be one of {', '.join(orders)}")
        set_(self, "stack_xy_m", check_vector("task.stack_xy_m", self.stack_xy_m, 2, unit="m"))
        set_(self, "stack_yaw_rad", check_range("task.stack_yaw_rad", self.stack_yaw_rad, -2 * math.pi,
                                                2 * math.pi, unit="rad"))
        for name, hi, unit in (("level_tolerance_xy_m", 0.05, "m"), ("level_tolerance_yaw_rad", 0.5, "rad"),
                               ("knock_tolerance_m", 0.1, "m"), ("knock_tolerance_rad", 1.0, "rad"),
                               ("spot_clearance_m", 0.1, "m")):
            set_(self, name, check_range(f"task.{name}", getattr(self, name), 0.0, hi, lo_open=True, unit=unit))
        if not isinstance(self.repair, bool):
            raise ConfigError("task.repair", self.repair, "must be true or false")
        set_(self, "max_picks_per_object", check_int("task.max_picks_per_object", self.max_picks_per_object, 1, 10))

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> TaskConfig:
        """From a TOML ``[task]`` table."""
        if not isinstance(data, Mapping):
            raise ConfigError("task", data, "must be a table of keys")
        return from_mapping(cls, data, "task")

    def check_scene(self, scene: SceneConfig) -> None:
        """Raise :class:`ConfigError` if the scene does not suit the task: a ``clear`` needs a bin, a ``stack``
        a tower spot that no object starts on, a ``place`` a goal per object that no two objects share."""
        objects = scene.objects
        if self.kind == TaskKind.CLEAR and scene.bin is None:
            raise ConfigError("bin", None, "a clear task needs a bin (a [bin] table)")
        if self.kind == TaskKind.STACK:
            for o in objects:
                gap = polygon_gap(footprint(o.object, o.start_xy_m, o.start_yaw_rad),
                                  footprint(objects[0].object, self.stack_xy_m, self.stack_yaw_rad))
                if gap < self.spot_clearance_m:
                    raise ConfigError("task.stack_xy_m", tuple(self.stack_xy_m),
                                      f"the {o.name} starts {gap * 1e3:.0f} mm from where the tower goes (at least "
                                      f"{self.spot_clearance_m * 1e3:.0f} mm: room for the fingers)")
        if self.kind == TaskKind.PLACE:
            for i, o in enumerate(objects):
                if o.goal_xy_m is None:
                    raise ConfigError(f"objects.{o.name}.goal_xy_m", None, "a place task needs a goal per object")
                for p in objects[:i]:
                    assert p.goal_xy_m is not None
                    gap = polygon_gap(footprint(o.object, o.goal_xy_m, o.goal_yaw_rad),
                                      footprint(p.object, p.goal_xy_m, p.goal_yaw_rad))
                    if gap < 0.0:
                        raise ConfigError(f"objects.{o.name}.goal_xy_m", tuple(o.goal_xy_m),
                                          f"the {o.name} at its goal would overlap the {p.name} at its goal")


@dataclass(frozen=True)
class Goal:
    """Where one pick and place sets its object down.

    Attributes:
        xy_m: The object's origin (x, y) at the goal (m).
        yaw_rad: Its yaw there (rad).
        surface_z_m: Height of the surface it is set on (m): the table, the bin's floor, the tower's top.
        support: Name of the object it is set on (a tower's top), or ``""``.
        label: What the goal is: ``goal``, ``buffer``, ``bin`` or ``level N``.
    """

    xy_m: tuple[float, float]
    yaw_rad: float
    surface_z_m: float
    support: str = ""
    label: str = "goal"


@dataclass(frozen=True)
class Pick:
    """The next pick and place of a task: which object, and where to."""

    name: str
    goal: Goal


def top_z_m(obj: SceneObject, T_world_object: pin.SE3) -> float:
    """Height of the object's highest point at ``T_world_object`` (m)."""
    v = obj.object.geometry().vertices
    return float(np.max(v @ T_world_object.rotation[2]) + T_world_object.translation[2])


def bottom_z_m(obj: SceneObject, T_world_object: pin.SE3) -> float:
    """Height of the object's lowest point at ``T_world_object`` (m)."""
    v = obj.object.geometry().vertices
    return float(np.min(v @ T_world_object.rotation[2]) + T_world_object.translation[2])


class TaskPlanner:
    """Chooses each pick and place of a task from the poses the robot observes.

    Args:
        scene: The world (every object, the bin, the table).
        task: The task.
        place_tolerance_xy_m: An object this close to its goal (and within ``place_tolerance_yaw_rad``) is done.
        place_tolerance_yaw_rad: See above (rad).
    """

    def __init__(self, scene: SceneConfig, task: TaskConfig, place_tolerance_xy_m: float,
                 place_tolerance_yaw_rad: float) -> None:
        self.scene, self.task = scene, task
        self.objects = {o.name: o for o in scene.objects}
        self.tol_xy, self.tol_yaw = place_tolerance_xy_m, place_tolerance_yaw_rad
        names = list(self.objects)
        if task.kind == TaskKind.STACK and task.order == TaskOrder.PLANNED:  # the widest base first
            names.sort(key=lambda n: -self._base_area(self.objects[n]))
        self.preference = names
        self.tower: list[str] = []  # stack: the names in the tower, bottom first
        self.buffered: set[str] = set()  # place: objects parked on a buffer spot

    @staticmethod
    def _base_area(o: SceneObject) -> float:
        from scipy.spatial import ConvexHull

        return float(ConvexHull(footprint(o.object, (0.0, 0.0), 0.0)).volume)

    # ------------------------------------------------------------------ what is done
    def done(self, name: str, poses: Mapping[str, pin.SE3]) -> bool:
        """Whether the object ``name`` is where the task wants it, as observed."""
        o, T = self.objects[name], poses[name]
        if self.task.kind == TaskKind.PLACE:
            assert o.goal_xy_m is not None
            xy = float(np.hypot(*(T.translation[:2] - np.asarray(o.goal_xy_m))))
            R_goal = rot_z(o.goal_yaw_rad)
            return xy <= self.tol_xy and abs(yaw_error(T.rotation, R_goal, o.object.yaw_period_rad)) <= self.tol_yaw
        if self.task.kind == TaskKind.CLEAR:
            return self.in_bin(name, T)
        return name in self.tower

    def in_bin(self, name: str, T_world_object: pin.SE3) -> bool:
        """Whether the object's footprint lies inside the bin and it rests on the bin's floor (within 5 mm)."""
        b = self.scene.bin
        if b is None:
            return False
        o = self.objects[name]
        lo, hi = b.inner_box_xy_m
        fp = footprint(o.object, T_world_object.translation[:2], object_yaw(T_world_object.rotation))
        low = bottom_z_m(o, T_world_object)
        return bool(np.all(fp >= lo) and np.all(fp <= hi)
                    and abs(low - b.floor_z_m(self.scene.table_height_m)) < 0.005)

    def check_tower(self, poses: Mapping[str, pin.SE3]) -> int:
        """Keep the tower's levels that still stand on the one below as observed; return how many were lost."""
        for k in range(1, len(self.tower)):
            if not self.level_stands(self.tower[k], self.tower[k - 1], poses, self.task.knock_tolerance_m):
                lost = len(self.tower) - k
                del self.tower[k:]
                return lost
        if self.tower:
            base = poses[self.tower[0]]
            off = float(np.hypot(*(base.translation[:2] - np.asarray(self.task.stack_xy_m))))
            if off > self.task.knock_tolerance_m:
                lost = len(self.tower)
                self.tower.clear()
                return lost
        return 0

    def level_stands(self, upper: str, lower: str, poses: Mapping[str, pin.SE3], tol_xy_m: float) -> bool:
        """Whether ``upper`` rests on top of ``lower`` within ``tol_xy_m`` horizontally (and 3 mm vertically)."""
        Tu, Tl = poses[upper], poses[lower]
        xy = float(np.hypot(*(Tu.translation[:2] - Tl.translation[:2])))
        gap = bottom_z_m(self.objects[upper], Tu) - top_z_m(self.objects[lower], Tl)
        return xy <= tol_xy_m and abs(gap) <= 0.003

    # ------------------------------------------------------------------ what next
    def next_pick(self, poses: Mapping[str, pin.SE3], skip: set[str] | None = None) -> Pick | None:
        """The next pick and place, or None when every object is done.

        Args:
            poses: Every object's observed pose.
            skip: Objects whose pick could not start from where they are now (tried after the others).

        Raises:
            TaskStuck: objects remain but none can be taken (every one waits, or was skipped).
        """
        skip = skip or set()
        pending = [n for n in self.preference if not self.done(n, poses)]
        if not pending:
            return None
        if self.task.kind == TaskKind.STACK:
            name = next((n for n in pending if n not in skip), None)
            if name is None:
                raise TaskStuck(f"no pick can start: {', '.join(pending)} cannot be grasped where they are")
            return Pick(name, self._level_goal(poses))
        if self.task.kind == TaskKind.CLEAR:
            if self.task.order == TaskOrder.PLANNED:
                centre = np.asarray(self.scene.bin.xy_m) if self.scene.bin is not None else np.zeros(2)
                pending.sort(key=lambda n: float(np.linalg.norm(poses[n].translation[:2] - centre)))
            for name in pending:
                if name in skip:
                    continue
                spot = self.bin_spot(name, poses)
                if spot is not None:
                    return Pick(name, spot)
            raise TaskStuck(f"no pick can start: {', '.join(pending)} cannot be grasped where they are or have no "
                            "free spot in the bin")
        # place
        free = [n for n in pending if n not in skip and self._goal_free(n, poses)]
        if self.task.order == TaskOrder.LISTED:
            name = next((n for n in pending if n not in skip), None)
            if name is None:
                raise TaskStuck(f"no pick can start: {', '.join(pending)} cannot be picked and placed from where they "
                                "are (in the listed order, without buffer spots)")
            return Pick(name, self._own_goal(name))
        if free:
            return Pick(free[0], self._own_goal(free[0]))
        # every remaining object waits for another (a swap): park one on a buffer spot (one parked already may move
        # on to another spot, last: where it was parked, it kept another's grasp from fitting)
        for name in sorted(pending, key=lambda n: n in self.buffered):
            if name in skip:
                continue
            spot = self.buffer_spot(name, poses)
            if spot is not None:
                self.buffered.add(name)
                return Pick(name, spot)
        stuck = [n for n in pending if n in skip]
        waiting = [n for n in pending if n not in skip]
        why = ([f"{', '.join(stuck)} cannot be picked and placed from where they are"] if stuck else []) + \
            ([f"{', '.join(waiting)} wait for another's goal to be freed, and no free buffer spot is left"]
             if waiting else [])
        raise TaskStuck(f"no pick can start: {'; '.join(why)}")

    def _own_goal(self, name: str) -> Goal:
        o = self.objects[name]
        assert o.goal_xy_m is not None
        return Goal(tuple(o.goal_xy_m), o.goal_yaw_rad, self.scene.table_height_m)

    def _goal_free(self, name: str, poses: Mapping[str, pin.SE3]) -> bool:
        """Whether no other object lies within the spot clearance of the object's goal footprint."""
        o = self.objects[name]
        assert o.goal_xy_m is not None
        at_goal = footprint(o.object, o.goal_xy_m, o.goal_yaw_rad)
        return all(polygon_gap(at_goal, self._footprint_now(n, poses)) >= self.task.spot_clearance_m
                   for n in self.objects if n != name)

    def _footprint_now(self, name: str, poses: Mapping[str, pin.SE3]) -> np.ndarray:
        T = poses[name]
        return footprint(self.objects[name].object, T.translation[:2], object_yaw(T.rotation))

    def _level_goal(self, poses: Mapping[str, pin.SE3]) -> Goal:
        """On the observed top of the tower (its top object's pose and highest point), or at the tower's spot."""
        if not self.tower:
            return Goal(tuple(self.task.stack_xy_m), self.task.stack_yaw_rad, self.scene.table_height_m,
                        label="level 1")
        top = self.tower[-1]
        T = poses[top]
        return Goal((float(T.translation[0]), float(T.translation[1])), object_yaw(T.rotation),
                    top_z_m(self.objects[top], T), support=top, label=f"level {len(self.tower) + 1}")

    def placed(self, pick: Pick, poses: Mapping[str, pin.SE3]) -> None:
        """Note that ``pick`` succeeded (a stack's tower grows by it)."""
        if self.task.kind == TaskKind.STACK:
            self.tower.append(pick.name)
        if pick.goal.label != "buffer":
            self.buffered.discard(pick.name)

    def _spots(self, name: str, lo: np.ndarray, hi: np.ndarray, step_m: float, others: list[np.ndarray],
               yaws: tuple[float, ...], inside: tuple[np.ndarray, np.ndarray] | None,
               avoid: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple[float, float, float]]:
        """Spots ``(x, y, yaw)`` on a grid over ``[lo, hi]`` where the object keeps the spot clearance from the
        footprints ``others``, lies ``inside`` a box by that clearance too (if given) and stays clear of the
        boxes ``avoid``."""
        o, c = self.objects[name], self.task.spot_clearance_m
        out = []
        for x in np.arange(lo[0], hi[0] + 1e-9, step_m):
            for y in np.arange(lo[1], hi[1] + 1e-9, step_m):
                for yaw in yaws:
                    fp = footprint(o.object, (x, y), yaw)
                    if inside is not None and (np.any(fp < inside[0] + c) or np.any(fp > inside[1] - c)):
                        continue
                    if any(footprint_gap(o.object, (x, y), yaw, a, b) < c for a, b in avoid):
                        continue
                    if all(polygon_gap(fp, p) >= c for p in others):
                        out.append((float(x), float(y), float(yaw)))
                        break
        return out

    def bin_spot(self, name: str, poses: Mapping[str, pin.SE3], exclude: list[tuple[float, float]] | None = None
                 ) -> Goal | None:
        """A free spot on the bin's floor for the object: clear of the walls and of what is in the bin by the spot
        clearance, the one nearest the robot's base (the bin fills from its near corner outwards: far out, the arm
        reaches a spot only with its elbow and wrist flipped, and a carried object slips while the hand turns
        over to get there), with the object's yaw as it lies now (the wrist need not turn it on the way), or a
        quarter turn from it, or along the bin's sides, where only that fits; None if there is none."""
        b = self.scene.bin
        assert b is not None
        lo, hi = b.inner_box_xy_m
        in_bin = [self._footprint_now(n, poses) for n in self.objects if n != name and self.in_bin(n, poses[n])]
        yaw_now = object_yaw(poses[name].rotation)  # as it lies (the hand need not turn it), else a quarter turn
        spots = self._spots(name, lo, hi, 0.01, in_bin, (yaw_now, yaw_now + math.pi / 2, 0.0, math.pi / 2), (lo, hi),
                            [])
        spots = [s for s in spots if not any(math.hypot(s[0] - e[0], s[1] - e[1]) < 0.03 for e in exclude or [])]
        if not spots:
            return None
        x, y, yaw = min(spots, key=lambda s: math.hypot(s[0], s[1]))
        return Goal((x, y), yaw, b.floor_z_m(self.scene.table_height_m), label="bin")

    def buffer_spot(self, name: str, poses: Mapping[str, pin.SE3], exclude: list[tuple[float, float]] | None = None
                    ) -> Goal | None:
        """A free spot on the table for the object while its goal is freed: clear of every object, of every other
        object's goal, of the bin and of the wall, nearest to where it is; None if there is none."""
        scene = self.scene
        others = [self._footprint_now(n, poses) for n in self.objects if n != name]
        for n, o in self.objects.items():  # around another's goal, that one's open fingers need room as well
            if n != name and o.goal_xy_m is not None:
                others.append(_grown(footprint(o.object, o.goal_xy_m, o.goal_yaw_rad), GOAL_FINGER_ROOM_M))
        avoid = []
        if scene.bin is not None:
            avoid.append(scene.bin.outer_box_xy_m)
        if scene.obstacle:
            avoid.append(scene.obstacle_box_xy_m)
        centre, half = np.asarray(scene.table_center_xy_m), np.asarray(scene.table_size_xy_m) / 2
        table = (centre - half, centre + half)
        # where the arm reaches down well: 0.25 to 0.65 m out from the base
        lo, hi = np.maximum(table[0], [0.25, -0.40]), np.minimum(table[1], [0.60, 0.40])
        yaw_now = object_yaw(poses[name].rotation)
        spots = self._spots(name, lo, hi, 0.02, others, (yaw_now,), table, avoid)
        here = poses[name].translation[:2]
        spots = [s for s in spots if math.hypot(*s[:2]) >= 0.30 and math.hypot(s[0] - here[0], s[1] - here[1]) > 0.05
                 and not any(math.hypot(s[0] - e[0], s[1] - e[1]) < 0.03 for e in exclude or [])]
        if not spots:
            return None
        x, y, yaw = min(spots, key=lambda s: math.hypot(s[0] - here[0], s[1] - here[1]))
        return Goal((x, y), yaw, scene.table_height_m, label="buffer")


def check_reachable(scene: SceneConfig, kind: str, clearance_m: float, upright: bool = False) -> None:
    """Raise :class:`ConfigError` naming the first object the arm cannot pick where it starts, or (``place``) set
    down at its goal, each alone on the table with the bin and the obstacle (the other objects move while a task
    runs): its reachable workspace, which depends on its size and its grasps.

    Args:
        scene: The scene with its objects.
        kind: The task (``place`` checks the goals too).
        clearance_m: Clearance the pregrasp, lift, preplace and retreat keep from the table and obstacles (m): the
            planner's margin.
        upright: A goal reached only by turning the object over on the way (another IK branch) counts as out of
            reach.
    """
    from pickplace.errors import CannotHold, UnreachableTarget
    from pickplace.grasping.configurations import (
        candidate_grasps,
        feasible_grasps,
        solve_grasp_configurations,
        start_pose,
    )
    from pickplace.robot.model import build

    for o in scene.objects:
        goal = o.goal_xy_m if kind == TaskKind.PLACE else None
        single = dataclasses.replace(scene, object=o.object, start_xy_m=o.start_xy_m, start_yaw_rad=o.start_yaw_rad,
                                     goal_xy_m=goal if goal is not None else scene.goal_xy_m,
                                     goal_yaw_rad=o.goal_yaw_rad if goal is not None else scene.goal_yaw_rad,
                                     others=())
        robot = build(single)
        if goal is None:
            grasps = candidate_grasps(robot, start_pose(robot))
            if not any(feasible_grasps(robot, grasps[k:k + 8], clearance_m=clearance_m)
                       for k in range(0, len(grasps), 8)):  # in ranked order, up to the first that reaches
                raise ConfigError(f"objects.{o.name}.start_xy_m", tuple(o.start_xy_m),
                                  f"out of the arm's reach for the {o.name}: no grasp reaches it there collision free")
            continue
        try:
            solve_grasp_configurations(robot, clearance_m=clearance_m, turn_over=not upright)
        except (UnreachableTarget, CannotHold) as exc:
            field = "goal_xy_m" if exc.target in ("preplace", "place", "retreat") else "start_xy_m"
            where = goal if field == "goal_xy_m" else o.start_xy_m
            raise ConfigError(f"objects.{o.name}.{field}", tuple(where),
                              f"out of the arm's reach for the {o.name}{' carried upright' if upright else ''}: "
                              f"{exc}") from None


#: Library objects a random ``stack`` draws from: flat on top and bottom.
STACKABLE = ("cube", "gelatin_box", "soda_can")
#: Where random objects start and (``place``) go: well inside the arm's reach on the default table (x, y) (m).
RANDOM_REGION_XY_M = ((0.28, -0.10), (0.62, 0.40))
#: Where random ``place`` goals go (no bin on the table then) (x, y) (m).
RANDOM_GOAL_REGION_XY_M = ((0.28, -0.40), (0.62, 0.40))
#: Gap kept between random objects' footprints (m): room for the fingers around each.
RANDOM_GAP_M = 0.05
#: Draws of a whole random task scene before giving up on one whose objects the arm reaches.
REACH_DRAWS = 50


def random_task_scene(kind: str, n: int, rng: np.random.Generator, base: SceneConfig | None = None,
                      names: tuple[str, ...] | None = None, swap: bool = True, tries: int = 2000,
                      clearance_m: float = 0.01) -> SceneConfig:
    """A scene of ``n`` library objects for a task, drawn at random: starts (and goals) at free spots, any yaw
    within ±45°, each object's start (and goal) within its reachable workspace carried upright
    (:func:`check_reachable`; the whole draw is repeated otherwise, up to :data:`REACH_DRAWS` times).

    Args:
        kind: The task (``stack`` draws from :data:`STACKABLE`, ``clear`` adds the default bin).
        n: How many objects (1 to 8).
        rng: The random stream.
        base: The scene to start from (table, obstacle); default: the default scene.
        names: Library objects to draw from; default: the whole library (``stack``: :data:`STACKABLE`).
        swap: For ``place``, the first two objects trade places (each one's goal is the other's start).
        tries: Draws per object before giving up.
        clearance_m: The planner's margin the reachability check keeps (m).

    Raises:
        ConfigError: ``n`` is out of range, or the objects do not fit on the table.
    """
    from pickplace.world.objects import LIBRARY

    n = check_int("--objects", n, 1, 8)
    base = base if base is not None else SceneConfig()
    pool = names if names is not None else (STACKABLE if kind == TaskKind.STACK else tuple(LIBRARY))
    for name in pool:
        if name not in LIBRARY:
            raise ConfigError("objects.library", name, f"must be one of {', '.join(LIBRARY)}")
    bin_ = BinConfig() if kind == TaskKind.CLEAR else None
    chosen = [LIBRARY[str(rng.choice(pool))] for _ in range(n)]
    objs = [dataclasses.replace(o, name=f"{o.name}_{i + 1}") for i, o in enumerate(chosen)]
    starts: list[tuple[np.ndarray, float]] = []
    goals: list[tuple[np.ndarray, float]] = []
    last: ConfigError | None = None
    avoid = [bin_.outer_box_xy_m] if bin_ is not None else []
    if base.obstacle:
        avoid.append(base.obstacle_box_xy_m)
    tower = TaskConfig().stack_xy_m

    def draw(obj: Any, region: tuple[tuple[float, float], tuple[float, float]],
             taken: list[tuple[Any, np.ndarray, float]]) -> tuple[np.ndarray, float]:
        for _ in range(tries):
            xy = rng.uniform(region[0], region[1])
            yaw = float(rng.uniform(-math.pi / 4, math.pi / 4))
            fp = footprint(obj, xy, yaw)
            if any(footprint_gap(obj, xy, yaw, a, b) < RANDOM_GAP_M for a, b in avoid):
                continue
            if kind == TaskKind.STACK and float(np.linalg.norm(xy - np.asarray(tower))) < 0.12:
                continue
            if all(polygon_gap(fp, footprint(o, p, y)) >= RANDOM_GAP_M for o, p, y in taken):
                return xy, yaw
        raise ConfigError("--objects", n, f"{n} objects do not fit at random on the table (gap "
                                          f"{RANDOM_GAP_M * 1e3:.0f} mm)")

    for _ in range(REACH_DRAWS):
        starts, goals = [], []
        for o in objs:
            starts.append(draw(o, RANDOM_REGION_XY_M, [(q, p, y) for q, (p, y) in zip(objs, starts, strict=False)]))
        if kind == TaskKind.PLACE:
            first = 0
            if swap and n >= 2:
                goals = [starts[1], starts[0]]
                first = 2
            avoid_goals = list(goals)
            for o in objs[first:]:
                taken = [(q, p, y) for q, (p, y) in zip(objs, avoid_goals, strict=False)]
                goals.append(draw(o, RANDOM_GOAL_REGION_XY_M, taken))
                avoid_goals.append(goals[-1])
        others = []
        for i, o in enumerate(objs):
            (xy, yaw) = starts[i]
            goal = goals[i] if goals else None
            others.append(SceneObject(o, (float(xy[0]), float(xy[1])), yaw,
                                      None if goal is None else (float(goal[0][0]), float(goal[0][1])),
                                      0.0 if goal is None else goal[1]))
        first_obj = others[0]
        scene = dataclasses.replace(
            base, object=first_obj.object, start_xy_m=first_obj.start_xy_m, start_yaw_rad=first_obj.start_yaw_rad,
            goal_xy_m=first_obj.goal_xy_m if first_obj.goal_xy_m is not None else base.goal_xy_m,
            goal_yaw_rad=first_obj.goal_yaw_rad, others=tuple(others[1:]), bin=bin_)
        try:  # within each object's reachable workspace, carried upright (a place's goals too)
            check_reachable(scene, kind, clearance_m, upright=True)
        except ConfigError as exc:
            last = exc
            continue
        return scene
    raise ConfigError("--objects", n, f"no draw of {n} objects whose starts (and goals) the arm reaches in "
                                      f"{REACH_DRAWS} draws (last: {last})")


#: Room a buffer spot leaves around another object's goal besides the spot clearance (m): the open fingers reach
#: up to (84 mm - the object's width) / 2 plus their own thickness beyond an object set down there.
GOAL_FINGER_ROOM_M = 0.02


def _grown(polygon: np.ndarray, margin_m: float) -> np.ndarray:
    """A convex polygon (N, 2) with every corner pushed ``margin_m`` further from its centroid (m): its edges move
    out by up to that much (by about that much for a compact shape such as a box's footprint)."""
    c = polygon.mean(axis=0)
    d = polygon - c
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return c + d * (1.0 + margin_m / np.maximum(n, 1e-9))


class TaskStuck(PickPlaceError):
    """No pick of the task can start (every remaining object waits for another, or cannot be grasped)."""


__all__ = ["RANDOM_GAP_M", "REACH_DRAWS", "STACKABLE", "Goal", "Pick", "TaskConfig", "TaskKind", "TaskOrder",
           "TaskPlanner", "TaskStuck", "bottom_z_m", "check_reachable", "random_task_scene", "top_z_m"]
