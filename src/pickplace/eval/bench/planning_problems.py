"""Harder planning problems for the UR5e: a shelf, a cage, two deep bins and a slot in a wall.

In the manner of the public motion-planning benchmarks (MotionBenchMaker's bookshelf, cage and box problems, the
OMPL/MoveIt benchmark scenes), each problem is a scene of fixed boxes on the table (:class:`SceneConfig.boxes
<pickplace.world.config.SceneConfig>`) and two tcp poses, start and goal. Their arm configurations are solved by
the project's IK (:func:`~pickplace.robot.ik.solve_ik`) and checked collision-free, both deterministically: the
tcp is led from its ``home`` pose to the target in :data:`IK_STEPS` steps of a straight SE(3) interpolation, each
solved from the one before, so every end lies on the branch an arm coming from ``home`` would use (the elbow up,
the wrist outside the shelf), and the start and the goal of a problem on the same one.

The hand is free (no object carried, gripper open); the scene's object rests out of the way in a corner of the
table. Heights are above the floor; the table top is at 0.315 m, the robot's base at the origin.

============  =========================================================================================================
``shelf``     a shelf unit with three boards (0.2 m apart) and sides; from the lower compartment to the upper one, the
              hand horizontal, pointing in (the arm must take it out, up and back in)
``cage``      a closed cage (0.26 m inside, 0.36 m high) whose only opening is a 0.18 x 0.16 m window in the wall that
              faces the robot; from above the table beside it, pointing down, to inside the cage, pointing in
``bins``      two bins with 0.22 m walls (0.2 m inside); from near the floor of one to near the floor of the other,
              pointing down
``slot``      a wall across the table with a 0.26 x 0.20 m slot; from in front of the wall, beside the slot, to 0.11 m
              behind the wall through the slot, pointing through it
============  =========================================================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickplace.grasping.targets import top_down
from pickplace.motion.collision import CollisionChecker
from pickplace.robot.ik import IKConfig, solve_ik
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import Robot
from pickplace.world.config import BoxConfig, SceneConfig

#: Table top height of the default scene (m).
TABLE_Z_M = SceneConfig().table_height_m
#: A tcp pointing along +x (into a shelf, through a window), the fingers opening along y (the hand's 0.12 m width
#: lies horizontal): columns x = -z_world, y = y_world, z = x_world.
FORWARD = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
#: A tcp pointing straight down (yaw 0).
DOWN = top_down(0.0)
#: Steps of the SE(3) interpolation from ``home`` to each end (see the module docstring).
IK_STEPS = 10
#: Where the scene's object rests: in a corner of the table, away from every problem's boxes (x, y) (m).
OBJECT_START_XY_M = (0.25, 0.42)
OBJECT_GOAL_XY_M = (0.25, -0.42)


@dataclass(frozen=True)
class PlanningProblem:
    """One harder problem: the boxes and the tcp poses (position (3,) (m), rotation (3, 3)) of its two ends.

    Attributes:
        name: Short name, the benchmark's ``scene`` column.
        segment: What the move is, the benchmark's ``segment`` column.
        boxes: The fixed boxes.
        start_xyz_m, goal_xyz_m: tcp positions (m).
        start_rotation, goal_rotation: tcp orientations (:data:`FORWARD` or :data:`DOWN`).
    """

    name: str
    segment: str
    boxes: tuple[BoxConfig, ...]
    start_xyz_m: tuple[float, float, float]
    goal_xyz_m: tuple[float, float, float]
    start_rotation: str
    goal_rotation: str

    @property
    def scene(self) -> SceneConfig:
        """The scene: the default table and robot, these boxes, the object in a corner."""
        return SceneConfig(boxes=self.boxes, start_xy_m=OBJECT_START_XY_M, goal_xy_m=OBJECT_GOAL_XY_M)

    def tcp_poses(self) -> tuple[pin.SE3, pin.SE3]:
        """The start and goal tcp poses in the world."""
        rot = {"forward": FORWARD, "down": DOWN}
        return (pin.SE3(rot[self.start_rotation], np.array(self.start_xyz_m)),
                pin.SE3(rot[self.goal_rotation], np.array(self.goal_xyz_m)))


def _box(name: str, lo: tuple[float, float, float], hi: tuple[float, float, float]) -> BoxConfig:
    """A box between two corners (m)."""
    a, b = np.array(lo, dtype=float), np.array(hi, dtype=float)
    return BoxConfig(name, tuple((a + b) / 2), tuple(b - a))  # type: ignore[arg-type]


def _shelf() -> PlanningProblem:
    t, x0, x1, y0, y1 = TABLE_Z_M, 0.45, 0.71, -0.36, 0.36
    zb, zm, zt = 0.44, 0.64, 0.84  # tops of the bottom, middle and top boards
    boxes = (_box("shelf_board_bottom", (x0, y0, zb - 0.02), (x1, y1, zb)),
             _box("shelf_board_mid", (x0, y0, zm - 0.02), (x1, y1, zm)),
             _box("shelf_board_top", (x0, y0, zt - 0.02), (x1, y1, zt)),
             _box("shelf_side_left", (x0, y1, t), (x1, y1 + 0.02, zt)),
             _box("shelf_side_right", (x0, y0 - 0.02, t), (x1, y0, zt)),
             _box("shelf_back", (x1, y0 - 0.02, t), (x1 + 0.02, y1 + 0.02, zt)))
    return PlanningProblem("shelf", "lower->upper compartment", boxes, (0.55, 0.15, zb + 0.08),
                           (0.55, -0.15, zm + 0.08), "forward", "forward")


def _cage() -> PlanningProblem:
    t, th = TABLE_Z_M, 0.015  # wall thickness
    cx, cy, h = 0.56, -0.18, 0.13  # centre and inner half size
    x0, x1, y0, y1 = cx - h, cx + h, cy - h, cy + h
    top, wz, wy, wh = t + 0.36, t + 0.22, 0.09, 0.08  # roof, window centre height, half width, half height
    boxes = (_box("cage_back", (x1, y0 - th, t), (x1 + th, y1 + th, top)),
             _box("cage_left", (x0 - th, y1, t), (x1, y1 + th, top)),
             _box("cage_right", (x0 - th, y0 - th, t), (x1, y0, top)),
             _box("cage_roof", (x0 - th, y0 - th, top), (x1 + th, y1 + th, top + th)),
             _box("cage_front_low", (x0 - th, y0, t), (x0, y1, wz - wh)),
             _box("cage_front_high", (x0 - th, y0, wz + wh), (x0, y1, top)),
             _box("cage_front_left", (x0 - th, cy + wy, wz - wh), (x0, y1, wz + wh)),
             _box("cage_front_right", (x0 - th, y0, wz - wh), (x0, cy - wy, wz + wh)))
    return PlanningProblem("cage", "above the table->inside the cage", boxes, (0.40, 0.25, 0.50),
                           (x0 + 0.09, cy, wz), "down", "forward")


def _bins() -> PlanningProblem:
    t, inner, height, th = TABLE_Z_M, 0.10, 0.22, 0.015
    boxes: list[BoxConfig] = []
    for name, (cx, cy) in (("bin_a", (0.47, 0.22)), ("bin_b", (0.47, -0.22))):
        x0, x1, y0, y1 = cx - inner, cx + inner, cy - inner, cy + inner
        boxes += [_box(f"{name}_wall_far", (x1, y0 - th, t), (x1 + th, y1 + th, t + height)),
                  _box(f"{name}_wall_near", (x0 - th, y0 - th, t), (x0, y1 + th, t + height)),
                  _box(f"{name}_wall_left", (x0, y1, t), (x1, y1 + th, t + height)),
                  _box(f"{name}_wall_right", (x0, y0 - th, t), (x1, y0, t + height))]
    return PlanningProblem("bins", "into one bin->into the other", tuple(boxes), (0.47, 0.22, t + 0.09),
                           (0.47, -0.22, t + 0.09), "down", "down")


def _slot() -> PlanningProblem:
    t, x0, x1 = TABLE_Z_M, 0.50, 0.53
    z0, z1, half = 0.46, 0.66, 0.13  # slot bottom, top, half width
    boxes = (_box("wall_below", (x0, -0.5, t), (x1, 0.5, z0)), _box("wall_above", (x0, -0.5, z1), (x1, 0.5, 1.0)),
             _box("wall_left", (x0, half, z0), (x1, 0.5, z1)), _box("wall_right", (x0, -0.5, z0), (x1, -half, z1)))
    return PlanningProblem("slot", "in front of the wall->through the slot", boxes, (0.36, 0.30, 0.60),
                           (0.64, -0.02, 0.56), "forward", "forward")


def problems() -> tuple[PlanningProblem, ...]:
    """The harder problems, in the benchmark's order."""
    return (_shelf(), _cage(), _bins(), _slot())


def solve_ends(robot: Robot, problem: PlanningProblem, checker: CollisionChecker) -> tuple[np.ndarray, np.ndarray]:
    """The problem's start and goal arm configurations (6,) (rad), from ``home`` by IK continuation, each checked
    valid with ``checker``.

    Raises:
        UnreachableTarget: an end the IK does not reach, or reaches only in collision.
    """
    data = robot.pin.createData()
    T_home = frame_pose(robot.pin, data, robot.pin_q(robot.home_q), robot.pin_tcp_frame)
    ends = []
    for name, target in zip(("start", "goal"), problem.tcp_poses(), strict=True):
        q = robot.home_q.copy()
        for k in range(1, IK_STEPS + 1):
            last = k == IK_STEPS
            q = solve_ik(robot, pin.SE3.Interpolate(T_home, target, k / IK_STEPS), q, f"{problem.name} {name}",
                         IKConfig(restarts=0), is_valid=checker.is_valid if last else None).q
        ends.append(q)
    return ends[0], ends[1]


__all__ = ["DOWN", "FORWARD", "IK_STEPS", "PlanningProblem", "problems", "solve_ends"]
