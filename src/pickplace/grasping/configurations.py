"""Joint configurations for the four tcp targets, each solved by IK and checked for collisions.

The chain follows the motion: ``pregrasp`` is solved from ``home``, ``grasp`` from ``pregrasp`` (so the
descent stays on one IK branch), ``preplace`` from ``pregrasp`` and ``place`` from ``preplace``. Each is
checked with the collision policy of the moment it is reached: open gripper around the resting cube at the
grasp, cube carried at ``preplace`` and ``place`` (where it may touch the table).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from pickplace.errors import UnreachableTarget
from pickplace.grasping.targets import GraspTargets, T_tcp_cube, grasp_targets
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.robot.gripper import GripperGeometry
from pickplace.robot.ik import IKConfig, IKResult, solve_ik
from pickplace.robot.kinematics import frame_pose
from pickplace.robot.model import Robot


@dataclass(frozen=True)
class GraspConfigurations:
    """IK solutions of the four targets.

    Attributes:
        targets: The tcp poses they reach.
        pregrasp, grasp, preplace, place: The IK results (``.q`` is the arm configuration (6,) in rad).
        held_finger_m: Finger travel while the cube is held (m).
        cube_yaw_rad: Yaw of the cube that is grasped (rad).
    """

    targets: GraspTargets
    pregrasp: IKResult
    grasp: IKResult
    preplace: IKResult
    place: IKResult
    held_finger_m: float
    cube_yaw_rad: float

    def results(self) -> list[IKResult]:
        """The four results in visiting order."""
        return [self.pregrasp, self.grasp, self.preplace, self.place]

    def carrying_checker(self, robot: Robot, margin_m: float, allow_cube_table: bool = False) -> CollisionChecker:
        """A checker for the arm carrying the cube as grasped here (see :func:`carrying_checker`)."""
        return carrying_checker(robot, self.targets, self.cube_yaw_rad, self.held_finger_m, margin_m,
                                allow_cube_table)


def carrying_checker(
    robot: Robot,
    targets: GraspTargets,
    cube_yaw_rad: float,
    finger_m: float,
    margin_m: float,
    allow_cube_table: bool = False,
) -> CollisionChecker:
    """A collision checker for the arm carrying the cube, held at ``targets.grasp`` with the given yaw.

    Args:
        robot: The models.
        targets: The tcp targets (the cube's pose in the tcp frame follows from the grasp).
        cube_yaw_rad: Yaw of the grasped cube (rad).
        finger_m: Finger travel while holding it (m).
        margin_m: Safety margin to the table, floor and obstacles (m).
        allow_cube_table: Whether the cube may touch the table (setting it down).
    """
    policy = CollisionPolicy(margin_m=margin_m, cube_held=True, allow_cube_table=allow_cube_table, finger_m=finger_m)
    return CollisionChecker(robot, policy, T_tcp_cube=T_tcp_cube(targets, cube_yaw_rad))


def solve_grasp_configurations(
    robot: Robot,
    ik_config: IKConfig | None = None,
    cube_pos_m: np.ndarray | None = None,
    cube_yaw_rad: float | None = None,
    world: mujoco.MjData | None = None,
    clearance_m: float = 0.0,
) -> GraspConfigurations:
    """Targets for the scene's cube and goal, solved to joint configurations.

    Args:
        robot: The models.
        ik_config: IK settings.
        cube_pos_m: The cube's centre (3,) (m); default: its start in the scene.
        cube_yaw_rad: The cube's yaw (rad); default: its start yaw in the scene.
        world: The simulation state the solutions must be collision free in (where the cube rests, anything
            that moved); default: the scene's initial state.
        clearance_m: Clearance the pregrasp and preplace configurations must keep from the table, floor and
            obstacles (m), e.g. the planner's margin so that it accepts them as goals. The grasp and the place
            are checked at contact (the fingers work 5 mm above the table).

    Raises:
        UnreachableTarget: naming the target that cannot be reached collision free.
    """
    scene = robot.scene
    geom = GripperGeometry.measure(robot)
    T_home = frame_pose(robot.pin, robot.pin.createData(), robot.pin_q(robot.home_q), robot.pin_tcp_frame)
    cube_yaw = scene.cube_yaw_rad if cube_yaw_rad is None else cube_yaw_rad
    targets = grasp_targets(scene, geom.pad_half_height_m, T_home, cube_pos_m, cube_yaw)
    held = geom.contact_travel_m(scene.cube_size_m)
    free = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    above = CollisionChecker(robot, CollisionPolicy(margin_m=clearance_m))
    carry = carrying_checker(robot, targets, cube_yaw, held, margin_m=clearance_m)
    place = carrying_checker(robot, targets, cube_yaw, held, margin_m=0.0, allow_cube_table=True)
    if world is not None:
        for checker in (free, above, carry, place):
            checker.set_world(world)

    def solve(name: str, q0: np.ndarray, checker: CollisionChecker) -> IKResult:
        try:
            return solve_ik(robot, dict(targets.named())[name], q0, name, ik_config, checker.is_valid)
        except UnreachableTarget as exc:
            raise _with_collisions(exc, checker, robot, dict(targets.named())[name], q0, ik_config) from None

    pre = solve("pregrasp", robot.home_q, above)
    grasp = solve("grasp", pre.q, free)
    preplace = solve("preplace", pre.q, carry)
    placed = solve("place", preplace.q, place)
    return GraspConfigurations(targets, pre, grasp, preplace, placed, held, cube_yaw)


def _with_collisions(exc: UnreachableTarget, checker: CollisionChecker, robot: Robot, target, q0,
                     ik_config: IKConfig | None) -> UnreachableTarget:
    """Add the colliding geoms to an IK failure caused by collisions."""
    if "collision" not in exc.reason:
        return exc
    q = solve_ik(robot, target, q0, exc.target, ik_config).q
    pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(q))
    return UnreachableTarget(exc.target, f"{exc.reason}; colliding: {pairs}", exc.position_error_m,
                             exc.orientation_error_rad)
