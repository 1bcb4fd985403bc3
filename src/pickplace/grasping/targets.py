"""Tcp targets for the pick and the place, from a grasp given in the object's frame.

A grasp is the tcp's pose in the object's resting frame, ``T_object_tcp`` (tcp z: the approach direction,
pointing into the object; tcp y: the closing axis). With the object observed at ``T_world_object``:

* ``grasp = T_world_object * T_object_tcp``; ``pregrasp`` is backed off from it along the approach by
  ``CLEARANCE_M`` (straight up for a top-down grasp, sideways for a side grasp);
* ``lift``: the grasp raised straight up by ``CLEARANCE_M`` (the object leaves the table vertically), or
  higher where the carried object would still be within the planner's margin of something (beside a wall:
  :func:`~pickplace.grasping.configurations.solve_grasp_configurations` raises it in ``LIFT_STEP_M`` steps);
* the place sets the object down at the goal **on the face it rested on**, turned to the goal's yaw: its
  orientation there is ``Rz(d) R_world_object`` with ``d`` the goal yaw minus the object's yaw (modulo the
  object's symmetry, :attr:`~pickplace.world.objects.ObjectConfig.yaw_period_rad`), so a standing can stays
  standing and a lying one lying; ``place`` is the tcp holding it there, ``PLACE_DROP_M`` above resting;
  ``preplace`` is ``CLEARANCE_M`` straight above (or higher, as the lift).

Where the object's symmetry leaves a choice (a cube looks the same turned by 90 degrees, a standing can by
any angle), the tcp orientation closest to the wrist's ``home`` orientation turned to face the object (or
the goal) is taken, so the wrist turns as little as it can.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickplace.robot.kinematics import rot_z, rotation_distance, wrap_to_pi
from pickplace.world.config import SceneConfig
from pickplace.world.objects import ObjectConfig

#: Distance of the pregrasp from the grasp along the approach, of the lift above the grasp and of the preplace
#: above the place (m) (reference design).
CLEARANCE_M = 0.150
#: Step (m) by which the lift and the preplace are raised above ``CLEARANCE_M`` until the carried object
#: clears everything by the planner's margin, up to ``MAX_RAISE_M``.
LIFT_STEP_M = 0.05
#: Highest lift and preplace above the grasp and the place (m).
MAX_RAISE_M = 0.40
#: Gap kept between the finger tips and the table at the grasp (m).
TABLE_GAP_M = 0.005
#: Height above its resting height at which the object is let go at the goal (m).
PLACE_DROP_M = 0.001
#: Turns tried for an object whose yaw is not defined (a standing can, a ball): every 15 degrees.
_FREE_YAW_STEPS = 24

_TOP_DOWN = np.diag([1.0, -1.0, -1.0])  # tcp z along world -z, tcp x along world x


def top_down(yaw: float) -> np.ndarray:
    """Rotation (3, 3) of a tcp pointing straight down whose x axis has ``yaw`` (rad) about world z."""
    return rot_z(yaw) @ _TOP_DOWN


def object_yaw(R_world_object: np.ndarray) -> float:
    """Yaw (rad) of a resting object: the heading of the first of its axes that is not (nearly) vertical.

    For an object on its resting face that is the heading of its x axis; for one that landed on another face
    (a dropped cube), the heading of the next axis round, so that the yaw is still defined.
    """
    R = np.asarray(R_world_object, dtype=float)
    up = int(np.argmax(np.abs(R[2])))
    side = R[:, (up + 1) % 3]
    return float(np.arctan2(side[1], side[0]))


def _bearing(xy: np.ndarray) -> float:
    return float(np.arctan2(xy[1], xy[0]))


def wrist_reference(T_world_tcp_home: pin.SE3, towards_xy: np.ndarray) -> np.ndarray:
    """The tcp's ``home`` orientation turned about world z to face the point ``towards_xy`` (3, 3).

    Among orientations the task leaves free, the one closest to this keeps the wrist nearest its home twist.
    """
    turn = _bearing(np.asarray(towards_xy)) - _bearing(T_world_tcp_home.translation)
    return rot_z(turn) @ T_world_tcp_home.rotation


def symmetric_turns(period_rad: float) -> np.ndarray:
    """The turns about the vertical (rad) under which an object with this yaw period looks the same."""
    if period_rad <= 0.0:  # any turn
        return np.arange(_FREE_YAW_STEPS) * (2.0 * math.pi / _FREE_YAW_STEPS)
    return np.arange(max(1, round(2.0 * math.pi / period_rad))) * period_rad


def place_orientation(
    R_world_object: np.ndarray,
    goal_yaw_rad: float,
    period_rad: float,
    T_object_tcp: pin.SE3,
    R_reference: np.ndarray,
) -> np.ndarray:
    """The object's orientation at the goal (3, 3): on the face it rests on now, at the goal's yaw.

    Args:
        R_world_object: The object's orientation now (resting, or held as it rested).
        goal_yaw_rad: The goal's yaw (rad).
        period_rad: The object's yaw symmetry (0: yaw not defined).
        T_object_tcp: The grasp, to compare the tcp orientations the choices give.
        R_reference: The tcp orientation to stay close to (e.g. :func:`wrist_reference` towards the goal).
    """
    base = goal_yaw_rad - object_yaw(R_world_object)
    best, best_d = None, math.inf
    for turn in symmetric_turns(period_rad):
        R = rot_z(base + turn) @ R_world_object
        d = rotation_distance(R @ T_object_tcp.rotation, R_reference)
        if d < best_d - 1e-12:
            best, best_d = R, d
    assert best is not None
    return best


@dataclass(frozen=True)
class GraspTargets:
    """The tcp poses of a pick and place, ``T_world_tcp``, and the grasp they come from.

    Attributes:
        pregrasp: ``CLEARANCE_M`` back from the grasp along the approach.
        grasp: The pads on the object.
        lift: The grasp raised ``CLEARANCE_M`` straight up.
        preplace: ``CLEARANCE_M`` above the place.
        place: The object at the goal (``PLACE_DROP_M`` above resting), pads still closed.
        T_object_tcp: The grasp in the object's frame.
        width_m: Width of the object between the pads (m).
        R_world_object_goal: The object's orientation at the goal (3, 3).
        retreat_back_m: After the release, how far the tcp backs off from the place along its approach (m).
        retreat_rise_m: Then how far it rises straight up before the arm plans its way home (m): 0 unless the
            hand would still be within the planner's margin of something there.
    """

    pregrasp: pin.SE3
    grasp: pin.SE3
    lift: pin.SE3
    preplace: pin.SE3
    place: pin.SE3
    T_object_tcp: pin.SE3
    width_m: float
    R_world_object_goal: np.ndarray
    retreat_back_m: float = 0.0
    retreat_rise_m: float = 0.0

    def named(self) -> list[tuple[str, pin.SE3]]:
        """``[(name, pose)]`` in the order they are visited."""
        return [("pregrasp", self.pregrasp), ("grasp", self.grasp), ("lift", self.lift),
                ("preplace", self.preplace), ("place", self.place), ("retreat", self.retreat)]

    @property
    def lift_height_m(self) -> float:
        """Height of the lift above the grasp (m)."""
        return float(self.lift.translation[2] - self.grasp.translation[2])

    @property
    def preplace_height_m(self) -> float:
        """Height of the preplace above the place (m)."""
        return float(self.preplace.translation[2] - self.place.translation[2])

    @property
    def retreat(self) -> pin.SE3:
        """The tcp's pose at the end of the retreat from the place."""
        return raised(backed_off(self.place, self.retreat_back_m), self.retreat_rise_m)

    def raised_by(self, lift_m: float, preplace_m: float, retreat_back_m: float = 0.0,
                  retreat_rise_m: float = 0.0) -> GraspTargets:
        """A copy whose lift and preplace are ``lift_m`` above the grasp and ``preplace_m`` above the place, and
        whose retreat backs off ``retreat_back_m`` and rises ``retreat_rise_m`` (m)."""
        return dataclasses.replace(self, lift=raised(self.grasp, lift_m), preplace=raised(self.place, preplace_m),
                                   retreat_back_m=retreat_back_m, retreat_rise_m=retreat_rise_m)

    @property
    def T_tcp_object(self) -> pin.SE3:
        """The object's pose in the tcp frame once it is grasped as planned."""
        return self.T_object_tcp.inverse()


def backed_off(T_world_tcp: pin.SE3, distance_m: float) -> pin.SE3:
    """The tcp moved ``distance_m`` back along its own z axis (away from what it approaches)."""
    return pin.SE3(T_world_tcp.rotation, T_world_tcp.translation - distance_m * T_world_tcp.rotation[:, 2])


def raised(T_world_tcp: pin.SE3, height_m: float) -> pin.SE3:
    """The tcp moved ``height_m`` straight up."""
    return pin.SE3(T_world_tcp.rotation, T_world_tcp.translation + np.array([0.0, 0.0, height_m]))


def grasp_targets(
    scene: SceneConfig,
    T_world_object: pin.SE3,
    T_object_tcp: pin.SE3,
    width_m: float,
    T_world_tcp_home: pin.SE3,
) -> GraspTargets:
    """Tcp poses to pick the object with the grasp ``T_object_tcp`` and place it at the goal.

    Args:
        scene: The scene (goal, table, object).
        T_world_object: The object's pose now.
        T_object_tcp: The grasp, in the object's frame.
        width_m: Width of the object between the pads (m).
        T_world_tcp_home: Tcp pose at ``home``: among equivalent places, the wrist stays closest to it.
    """
    grasp = T_world_object * T_object_tcp
    R_goal = place_orientation(T_world_object.rotation, scene.goal_yaw_rad, scene.object.yaw_period_rad,
                               T_object_tcp, wrist_reference(T_world_tcp_home, np.asarray(scene.goal_xy_m)))
    place = pin.SE3(R_goal, scene.goal_resting_m(R_goal) + np.array([0.0, 0.0, PLACE_DROP_M])) * T_object_tcp
    return GraspTargets(
        pregrasp=backed_off(grasp, CLEARANCE_M), grasp=grasp, lift=raised(grasp, CLEARANCE_M),
        preplace=raised(place, CLEARANCE_M), place=place, T_object_tcp=T_object_tcp, width_m=width_m,
        R_world_object_goal=R_goal)


def place_targets(scene: SceneConfig, T_world_tcp: pin.SE3, T_world_object: pin.SE3,
                  R_world_object_goal: np.ndarray, height_m: float = CLEARANCE_M,
                  R_world_tcp_planned: np.ndarray | None = None) -> tuple[pin.SE3, pin.SE3]:
    """Preplace and place tcp poses that set the object down at the goal *as it sits in the hand now*.

    The grasp never holds the object exactly as planned (the pads push it while they close, it settles in
    transit), so the place is computed from the measured hand-object pose: the tcp is placed so that the
    object, held as it is, lands at the goal.

    With ``R_world_tcp_planned`` (the tcp's planned orientation at the place), the object lands at
    ``R_world_object_goal`` or the orientation its symmetry makes equal to it (turned about the vertical by its
    yaw period; any orientation for a sphere) that leaves the hand nearest its planned orientation: the hand
    tilts by however far the object turned in the grip, so that the object comes down on its face. Without it,
    the object keeps the tilt it has in the world now and only its yaw is turned to the goal's: that assumes the
    hand is already upright as at the place (it is not half way through turning over, for one).

    Args:
        scene: The scene (goal, table, object).
        T_world_tcp: Tcp pose now (while holding the object).
        T_world_object: Object pose now.
        R_world_object_goal: The object's planned orientation at the goal (from :func:`grasp_targets`).
        height_m: Height of the preplace above the place (m) (:attr:`GraspTargets.preplace_height_m`).
        R_world_tcp_planned: The tcp's planned orientation at the place (3, 3) (:attr:`GraspTargets.place`).

    Returns:
        ``(preplace, place)``.
    """
    T_object_tcp = T_world_object.actInv(T_world_tcp)
    if R_world_tcp_planned is None:
        R = rot_z(float(wrap_to_pi(object_yaw(R_world_object_goal) - object_yaw(T_world_object.rotation)))) @ \
            T_world_object.rotation
    else:
        R = landing_orientation(scene.object, R_world_object_goal, np.asarray(R_world_tcp_planned),
                                T_object_tcp.rotation)
    place = pin.SE3(R, scene.goal_resting_m(R) + np.array([0.0, 0.0, PLACE_DROP_M])) * T_object_tcp
    return raised(place, height_m), place


def landing_orientation(obj: ObjectConfig, R_world_object_goal: np.ndarray, R_world_tcp_planned: np.ndarray,
                        R_object_tcp: np.ndarray) -> np.ndarray:
    """The object's orientation at the goal (3, 3) equal to ``R_world_object_goal`` by its symmetry (turned about
    the vertical by a multiple of its yaw period, by any angle if that is 0; any orientation for a sphere) that,
    held with ``R_object_tcp`` (the grip as it is now), puts the tcp nearest ``R_world_tcp_planned``."""
    if obj.kind == "sphere":  # any orientation rests alike: the hand as planned
        return R_world_tcp_planned @ R_object_tcp.T
    # the turn about the vertical that brings R_goal R_object_tcp nearest the planned tcp (max trace)
    M = R_world_object_goal @ R_object_tcp @ R_world_tcp_planned.T
    best = math.atan2(M[0, 1] - M[1, 0], M[0, 0] + M[1, 1])
    period = obj.yaw_period_rad
    turn = best if period <= 0.0 else period * round(best / period)
    return rot_z(turn) @ R_world_object_goal


def yaw_error(R_world_object: np.ndarray, R_world_object_goal: np.ndarray, period_rad: float) -> float:
    """Yaw error (rad) of a placed object against its goal orientation, modulo its symmetry (0 if yaw is not
    defined for it)."""
    if period_rad <= 0.0:
        return 0.0
    d = float(wrap_to_pi(object_yaw(R_world_object) - object_yaw(R_world_object_goal)))
    k = 2.0 * math.pi / period_rad
    return float(wrap_to_pi(k * d) / k)


__all__ = [
    "CLEARANCE_M",
    "LIFT_STEP_M",
    "MAX_RAISE_M",
    "PLACE_DROP_M",
    "TABLE_GAP_M",
    "GraspTargets",
    "backed_off",
    "grasp_targets",
    "landing_orientation",
    "object_yaw",
    "place_orientation",
    "place_targets",
    "raised",
    "symmetric_turns",
    "top_down",
    "wrist_reference",
    "yaw_error",
]
