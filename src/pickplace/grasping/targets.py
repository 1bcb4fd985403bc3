"""Tcp targets for the pick and the place: top-down poses across the cube's faces.

The gripper closes along its y axis, so a grasp across two opposite faces of a cube with yaw ``psi`` needs
a tcp yaw in ``psi + k pi/2``. Of those four, :func:`grasp_targets` takes the one that keeps the wrist
closest to its ``home`` twist relative to the arm (the same rule at the goal), so a cube rotated by up to
+/-45 degrees is taken across its faces with less than 45 degrees of extra wrist rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickplace.robot.kinematics import rot_z, wrap_to_pi, yaw_of
from pickplace.world.config import SceneConfig

#: Height of the pregrasp and preplace poses above the grasp and place poses (m) (reference design).
CLEARANCE_M = 0.150
#: Gap kept between the finger tips and the table at the grasp (m).
TABLE_GAP_M = 0.005
#: Height above its resting height at which the cube is let go at the goal (m).
PLACE_DROP_M = 0.001

_TOP_DOWN = np.diag([1.0, -1.0, -1.0])  # tcp z along world -z, tcp x along world x


def top_down(yaw: float) -> np.ndarray:
    """Rotation (3, 3) of a tcp pointing straight down whose x axis has ``yaw`` (rad) about world z."""
    return rot_z(yaw) @ _TOP_DOWN


def face_yaw(object_yaw: float, reference_yaw: float) -> float:
    """The tcp yaw in ``object_yaw + k pi/2`` closest to ``reference_yaw`` (rad)."""
    k = np.round(float(wrap_to_pi(reference_yaw - object_yaw)) / (np.pi / 2))
    return float(wrap_to_pi(object_yaw + k * np.pi / 2))


def cube_yaw(R_world_cube: np.ndarray) -> float:
    """Yaw (rad) of a cube resting on any of its faces, defined modulo pi/2.

    The cube's own z axis need not point up (a dropped cube lands on any face): the yaw is that of the
    first of its axes that is not the (nearly) vertical one.
    """
    R = np.asarray(R_world_cube, dtype=float)
    up = int(np.argmax(np.abs(R[2])))
    side = R[:, (up + 1) % 3]
    return float(np.arctan2(side[1], side[0]))


def _bearing(xy: np.ndarray) -> float:
    return float(np.arctan2(xy[1], xy[0]))


@dataclass(frozen=True)
class GraspTargets:
    """The four tcp poses of a pick and place, ``T_world_tcp``.

    Attributes:
        pregrasp: Above the cube, ``CLEARANCE_M`` over the grasp.
        grasp: Pads centred on the cube's faces.
        preplace: Above the goal, ``CLEARANCE_M`` over the place.
        place: The cube at the goal (``PLACE_DROP_M`` above resting), pads still closed.
        grasp_yaw_rad: Tcp yaw at the grasp (rad).
        place_yaw_rad: Tcp yaw at the place (rad).
        tcp_above_cube_m: Height of the tcp above the cube's centre while it is held (m).
    """

    pregrasp: pin.SE3
    grasp: pin.SE3
    preplace: pin.SE3
    place: pin.SE3
    grasp_yaw_rad: float
    place_yaw_rad: float
    tcp_above_cube_m: float

    def named(self) -> list[tuple[str, pin.SE3]]:
        """``[(name, pose)]`` in the order they are visited."""
        return [("pregrasp", self.pregrasp), ("grasp", self.grasp), ("preplace", self.preplace),
                ("place", self.place)]


def grasp_targets(
    scene: SceneConfig,
    pad_half_height_m: float,
    T_world_tcp_home: pin.SE3,
    cube_pos_m: np.ndarray | None = None,
    cube_yaw_rad: float | None = None,
) -> GraspTargets:
    """Tcp poses to pick the cube and place it at the goal.

    Args:
        scene: The scene (goal, table height, cube size).
        pad_half_height_m: Half the pads' height (m): the grasp is raised if needed so the finger tips stay
            ``TABLE_GAP_M`` above the table (small cubes are then held above their centre).
        T_world_tcp_home: Tcp pose at ``home``; its twist relative to the arm's bearing is kept.
        cube_pos_m: The cube's centre (3,) (m); default: its start in the scene.
        cube_yaw_rad: The cube's yaw (rad); default: its start yaw in the scene.
    """
    cube = scene.cube_start_pos_m if cube_pos_m is None else np.asarray(cube_pos_m, dtype=float)
    cube_yaw = scene.cube_yaw_rad if cube_yaw_rad is None else cube_yaw_rad
    home_twist = yaw_of(T_world_tcp_home.rotation) - _bearing(T_world_tcp_home.translation)

    tcp_z = max(cube[2], scene.table_height_m + pad_half_height_m + TABLE_GAP_M)
    above = tcp_z - cube[2]
    grasp_yaw = face_yaw(cube_yaw, _bearing(cube) + home_twist)
    goal = scene.goal_pos_m
    place_yaw = face_yaw(scene.goal_yaw_rad, _bearing(goal) + home_twist)

    def pose(xy: np.ndarray, z: float, yaw: float) -> pin.SE3:
        return pin.SE3(top_down(yaw), np.array([xy[0], xy[1], z]))

    place_z = goal[2] + above + PLACE_DROP_M
    return GraspTargets(
        pregrasp=pose(cube, tcp_z + CLEARANCE_M, grasp_yaw),
        grasp=pose(cube, tcp_z, grasp_yaw),
        preplace=pose(goal, place_z + CLEARANCE_M, place_yaw),
        place=pose(goal, place_z, place_yaw),
        grasp_yaw_rad=grasp_yaw,
        place_yaw_rad=place_yaw,
        tcp_above_cube_m=above,
    )


def T_tcp_cube(targets: GraspTargets, cube_yaw_rad: float) -> pin.SE3:
    """Pose of the cube in the tcp frame once it is grasped at ``targets.grasp``."""
    R = targets.grasp.rotation.T @ rot_z(cube_yaw_rad)
    return pin.SE3(R, np.array([0.0, 0.0, targets.tcp_above_cube_m]))


def place_targets(
    scene: SceneConfig,
    T_world_tcp: pin.SE3,
    T_world_cube: pin.SE3,
    reference_yaw_rad: float,
) -> tuple[pin.SE3, pin.SE3, float]:
    """Preplace and place tcp poses that set the cube down at the goal *as it sits in the hand now*.

    The grasp never centres the cube perfectly (the pads push it while they close), so the place is
    computed from the measured hand-cube offset rather than the nominal one: the cube's horizontal offset
    and yaw relative to the tcp and its depth below the tcp are kept, and the tcp is placed so the cube's
    centre lands on the goal with the goal's yaw (modulo the cube's 90 degree symmetry).

    Args:
        scene: The scene (goal, table height, cube size).
        T_world_tcp: Tcp pose now (while holding the cube).
        T_world_cube: Cube pose now.
        reference_yaw_rad: Tcp yaw to stay close to among the four equivalent ones (rad), e.g. the
            nominal :attr:`GraspTargets.place_yaw_rad`.

    Returns:
        ``(preplace, place, place_yaw_rad)``: the two tcp poses and the tcp yaw at the place (rad).
    """
    tcp_yaw = yaw_of(T_world_tcp.rotation)
    offset_world = T_world_cube.translation - T_world_tcp.translation
    offset_tcp = rot_z(-tcp_yaw)[:2, :2] @ offset_world[:2]  # horizontal offset in the tcp's yaw frame
    below = -offset_world[2]  # tcp height above the cube's centre
    cube_in_hand_yaw = float(wrap_to_pi(cube_yaw(T_world_cube.rotation) - tcp_yaw))
    place_yaw = face_yaw(scene.goal_yaw_rad - cube_in_hand_yaw, reference_yaw_rad)
    goal = scene.goal_pos_m
    xy = goal[:2] - rot_z(place_yaw)[:2, :2] @ offset_tcp
    z = goal[2] + below + PLACE_DROP_M
    place = pin.SE3(top_down(place_yaw), np.array([xy[0], xy[1], z]))
    preplace = pin.SE3(top_down(place_yaw), np.array([xy[0], xy[1], z + CLEARANCE_M]))
    return preplace, place, place_yaw
