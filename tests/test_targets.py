"""The place targets re-aimed from the object as it sits in the hand (pickplace.grasping.targets.place_targets)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from pickplace.grasping.targets import (
    CLEARANCE_M,
    PLACE_DROP_M,
    grasp_targets,
    landing_orientation,
    place_targets,
    yaw_error,
)
from pickplace.robot.kinematics import rot_z
from pickplace.world.config import SceneConfig
from pickplace.world.objects import library_object

TOP_DOWN = np.diag([1.0, -1.0, -1.0])  # the tcp's z (approach) pointing down


def _planned(scene: SceneConfig):
    """The planned targets of a top-down grasp of the scene's object at its start, the grasp 10 mm below the top."""
    obj = scene.object
    T_world_object = pin.SE3(rot_z(scene.start_yaw_rad), scene.start_pos_m)
    top = float(obj.geometry().bounds_m[1][2])
    T_object_tcp = pin.SE3(TOP_DOWN, np.array([0.0, 0.0, top - 0.01]))
    home = pin.SE3(TOP_DOWN, np.array([0.4, 0.0, 0.6]))
    return grasp_targets(scene, T_world_object, T_object_tcp, 0.04, home)


def _rot(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    return pin.exp3(np.asarray(axis, dtype=float) * angle_rad)


def _held(targets, T_world_tcp: pin.SE3, R_tcp_turn: np.ndarray) -> pin.SE3:
    """The object held by the tcp at ``T_world_tcp`` as planned, then turned in the grip by ``R_tcp_turn`` (tcp
    frame) about the tcp."""
    T_tcp_object = targets.T_object_tcp.inverse()
    T_tcp_object = pin.SE3(R_tcp_turn @ T_tcp_object.rotation, R_tcp_turn @ T_tcp_object.translation)
    return T_world_tcp * T_tcp_object


@pytest.mark.parametrize("hand_tilt_rad", [0.0, math.pi / 2, 2.0])
def test_an_object_held_as_planned_is_placed_as_planned_whatever_the_hand_does_now(hand_tilt_rad: float) -> None:
    """Half way through turning the hand over (the tool axis horizontal, or past it), an object that sits in the
    grip as planned gets the planned place target: the re-aim depends on the grip, not on where the hand is."""
    scene = SceneConfig()
    targets = _planned(scene)
    tcp_now = pin.SE3(_rot([1.0, 0.0, 0.0], hand_tilt_rad) @ targets.lift.rotation, np.array([0.1, 0.3, 0.7]))
    obj_now = _held(targets, tcp_now, np.eye(3))
    pre, place = place_targets(scene, tcp_now, obj_now, targets.R_world_object_goal,
                               R_world_tcp_planned=targets.place.rotation)
    np.testing.assert_allclose(place.rotation, targets.place.rotation, atol=1e-9)
    np.testing.assert_allclose(place.translation, targets.place.translation, atol=1e-9)
    np.testing.assert_allclose(pre.translation - place.translation, [0.0, 0.0, CLEARANCE_M], atol=1e-9)


def test_a_box_turned_in_the_grip_lands_flat_the_hand_tilted_by_the_turn() -> None:
    """A cube that turned 5 deg about the pads' closing axis in the grip: the hand tilts 5 deg so that the cube
    comes down flat on its face at the goal's yaw (the drop above the table as planned)."""
    scene = SceneConfig()
    targets = _planned(scene)
    turn = _rot([0.0, 1.0, 0.0], math.radians(5.0))  # about the tcp's y: the closing axis
    obj_now = _held(targets, targets.lift, turn)
    _, place = place_targets(scene, targets.lift, obj_now, targets.R_world_object_goal,
                             R_world_tcp_planned=targets.place.rotation)
    T_object_at_goal = place * targets.lift.actInv(obj_now)
    R = T_object_at_goal.rotation
    assert abs(R[2, 2] - 1.0) < 1e-9  # flat: its z up
    assert abs(yaw_error(R, targets.R_world_object_goal, scene.object.yaw_period_rad)) < 1e-9
    tilt = math.degrees(np.linalg.norm(pin.log3(place.rotation.T @ targets.place.rotation)))
    assert tilt == pytest.approx(5.0, abs=1e-6)
    bottom = float(np.min(scene.object.geometry().vertices @ R[2]) + T_object_at_goal.translation[2])
    assert bottom - scene.table_height_m == pytest.approx(PLACE_DROP_M, abs=1e-9)
    np.testing.assert_allclose(T_object_at_goal.translation[:2], scene.goal_xy_m, atol=1e-9)


def test_a_square_box_turned_far_in_the_grip_lands_on_its_nearest_symmetric_yaw() -> None:
    """A cube turned 80 deg about the vertical in the grip looks the same turned by 90 deg: it is set down 10 deg
    from where the hand would put it untouched, not 80."""
    scene = SceneConfig()
    targets = _planned(scene)
    obj_now = _held(targets, targets.lift, _rot([0.0, 0.0, 1.0], math.radians(80.0)))
    _, place = place_targets(scene, targets.lift, obj_now, targets.R_world_object_goal,
                             R_world_tcp_planned=targets.place.rotation)
    tilt = math.degrees(np.linalg.norm(pin.log3(place.rotation.T @ targets.place.rotation)))
    assert tilt == pytest.approx(10.0, abs=1e-6)


def test_a_ball_that_rolled_in_the_grip_is_placed_with_the_hand_as_planned() -> None:
    """Any orientation of a ball rests alike: the hand keeps its planned orientation, the ball's centre lands on
    the goal."""
    scene = dataclasses.replace(SceneConfig(), object=library_object("tennis_ball"))
    targets = _planned(scene)
    obj_now = _held(targets, targets.lift, _rot([0.3, 1.0, 0.2], 0.4))
    _, place = place_targets(scene, targets.lift, obj_now, targets.R_world_object_goal,
                             R_world_tcp_planned=targets.place.rotation)
    np.testing.assert_allclose(place.rotation, targets.place.rotation, atol=1e-9)
    centre = place * targets.lift.actInv(obj_now)
    radius = scene.object.size_m[0]
    # its resting height from its model's vertices: an icosphere inscribed in the sphere, within 0.1 mm of it
    np.testing.assert_allclose(centre.translation, [*scene.goal_xy_m, scene.table_height_m + radius + PLACE_DROP_M],
                               atol=1e-4)
    R = landing_orientation(scene.object, targets.R_world_object_goal, targets.place.rotation,
                            targets.lift.actInv(obj_now).rotation.T)
    np.testing.assert_allclose(R, centre.rotation, atol=1e-9)
