"""Obstacles the camera sees (pickplace.perception.obstacles) and the believed world the planners check against
(``Observer.world``)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.perception.camera import CameraConfig
from pickplace.perception.obstacles import MIN_CELL_POINTS, ObstacleCamera, height_map
from pickplace.perception.view import TableCamera
from pickplace.robot.ik import IKConfig, solve_ik
from pickplace.robot.model import (
    INTRUDER,
    INTRUDER_HALF_SIZE_M,
    SEEN_CELL_M,
    SEEN_COLUMNS,
    SEEN_HALF_HEIGHT_M,
    SEEN_PARKED_POS,
    Robot,
    build,
)
from pickplace.task.observe import SensingConfig, SensorObserver, SimulatorObserver
from pickplace.world.config import SceneConfig
from pickplace.world.objects import library_object


def test_height_map_bins_points_into_cells_with_their_highest_point() -> None:
    rng = np.random.default_rng(0)
    cell = SEEN_CELL_M
    # 40 points in the cell [0, cell)^2 up to 0.3 m, 30 in the cell [2 cell, 3 cell) x [-cell, 0) up to 0.5 m
    a = np.column_stack([rng.uniform(0.001, cell - 0.001, (40, 2)), rng.uniform(0.1, 0.3, 40)])
    b = np.column_stack([rng.uniform(2 * cell + 0.001, 3 * cell - 0.001, 30), rng.uniform(-cell + 0.001, -0.001, 30),
                         rng.uniform(0.2, 0.5, 30)])
    stray = np.array([[1.0, 1.0, 0.9]] * (MIN_CELL_POINTS - 1))  # too few points for a cell
    cols = height_map(np.concatenate([a, b, stray]))
    assert cols.shape == (2, 3)
    np.testing.assert_allclose(cols[0], [2.5 * cell, -0.5 * cell, b[:, 2].max()], rtol=0, atol=1e-12)  # highest 1st
    np.testing.assert_allclose(cols[1], [0.5 * cell, 0.5 * cell, a[:, 2].max()], rtol=0, atol=1e-12)
    assert height_map(np.zeros((0, 3))).shape == (0, 3)


def _intruder_at(robot: Robot, d: mujoco.MjData, xy: tuple[float, float], heading_rad: float) -> np.ndarray:
    """Stand the fault's wall on the table at ``xy``; its footprint's corners (4, 2) (m)."""
    mocap = robot.mj.body_mocapid[mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY, INTRUDER)]
    hx, hy, hz = INTRUDER_HALF_SIZE_M
    d.mocap_pos[mocap] = [xy[0], xy[1], robot.scene.table_height_m + hz]
    d.mocap_quat[mocap] = [math.cos(heading_rad / 2), 0.0, 0.0, math.sin(heading_rad / 2)]
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    R = np.array([[c, -s], [s, c]])
    return np.asarray(xy) + np.array([[hx, hy], [hx, -hy], [-hx, -hy], [-hx, hy]]) @ R.T


def _inside(points: np.ndarray, corners: np.ndarray, margin_m: float) -> np.ndarray:
    """Which points (k, 2) lie within ``margin_m`` of the convex footprint ``corners`` (4, 2)."""
    inside = np.ones(len(points), dtype=bool)
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        edge = b - a
        outward = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)
        if np.dot(outward, corners.mean(axis=0) - a) > 0:
            outward = -outward
        inside &= (points - a) @ outward <= margin_m
    return inside


@pytest.mark.parametrize("trial", range(4))
def test_the_camera_sees_a_wall_it_was_not_told_about_as_columns_over_its_footprint(robot: Robot, trial: int) -> None:
    """The fault's wall (0.04 x 0.2 x 0.25 m) stood on the table at a random place and heading, the cube where
    the robot believes it is: the height map's columns lie over the wall's footprint (within a cell's half
    diagonal and the calibration error), cover it, and reach its top within the depth noise; the cube (left out
    by its sphere) and the arm (the self-filter) make none."""
    rng = np.random.default_rng([trial, 7])
    d = robot.make_data()
    corners = _intruder_at(robot, d, (rng.uniform(0.35, 0.55), rng.uniform(0.0, 0.25)), rng.uniform(-math.pi, math.pi))
    mujoco.mj_forward(robot.mj, d)
    view = TableCamera(robot, CameraConfig(), rng)
    obstacles = ObstacleCamera(view, rng.spawn(1)[0])
    try:
        cube = pin.SE3(d.xmat[robot.handles.object_body].reshape(3, 3).copy(),
                       d.xpos[robot.handles.object_body].copy())
        cols = obstacles.columns(d, [view.object_sphere(cube)])
    finally:
        view.close()
        obstacles.close()
    top = robot.scene.table_height_m + 2 * INTRUDER_HALF_SIZE_M[2]
    assert 3 <= len(cols) <= SEEN_COLUMNS
    near = SEEN_CELL_M / math.sqrt(2) + 0.01  # a cell's half diagonal and the calibration error (2 mm, 0.2 deg)
    assert np.all(_inside(cols[:, :2], corners, near)), cols
    # the footprint is covered: every point of it is within a cell's half diagonal of a column's centre
    u, v = np.meshgrid(np.linspace(0.0, 1.0, 5), np.linspace(0.0, 1.0, 9))
    a, b, c = corners[0], corners[1], corners[3]
    samples = a + u.reshape(-1, 1) * (c - a) + v.reshape(-1, 1) * (b - a)
    gaps = np.min(np.linalg.norm(samples[:, None, :] - cols[None, :, :2], axis=2), axis=1)
    assert np.max(gaps) < near, np.max(gaps)
    assert abs(cols[0, 2] - top) < 0.02, (cols[0, 2], top)


def test_the_believed_world_has_the_object_where_it_was_seen_and_the_wall_only_as_the_camera_saw_it(
        robot: Robot) -> None:
    """The realistic observer's world: the object at the camera's estimate (not the simulator's pose), the
    fault's mocap wall parked where the map has it even after it appeared, and in its place the camera's
    columns; a checker in that world collides with the columns. The ideal observer's world is the simulation."""
    d = robot.make_data()
    mujoco.mj_forward(robot.mj, d)
    assert SimulatorObserver(robot, d).world() is d
    obs = SensorObserver(robot, d, CameraConfig(), SensingConfig(), np.random.default_rng(3))
    try:
        seen = obs.observe()
        w = obs.world()
        assert w is not d
        a = robot.handles.object_qpos
        np.testing.assert_array_equal(w.qpos[a:a + 3], seen.translation)
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, w.qpos[a + 3:a + 7])
        np.testing.assert_allclose(R.reshape(3, 3), seen.rotation, rtol=0, atol=1e-12)
        truth = d.qpos[a:a + 3]
        assert 0.0 < np.linalg.norm(w.qpos[a:a + 3] - truth) < 0.015  # the estimate's error, a few mm
        mocap = robot.mj.body_mocapid[mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY, INTRUDER)]
        parked = w.mocap_pos[mocap].copy()
        assert np.all(w.mocap_pos[mocap] == robot.mj.body_pos[mujoco.mj_name2id(robot.mj, mujoco.mjtObj.mjOBJ_BODY,
                                                                                 INTRUDER)])
        # no obstacle yet: every column parked
        used = np.flatnonzero(np.any(w.mocap_pos != SEEN_PARKED_POS, axis=1))
        assert set(used) <= {mocap}
        # the wall appears; the next look (a period later) sees it
        _intruder_at(robot, d, (0.45, 0.15), 0.3)
        d.time += SensingConfig().obstacle_period_s
        mujoco.mj_forward(robot.mj, d)
        w = obs.world()
        np.testing.assert_array_equal(w.mocap_pos[mocap], parked)
        columns = np.flatnonzero(np.any(w.mocap_pos != SEEN_PARKED_POS, axis=1) & (np.arange(len(w.mocap_pos))
                                                                                    != mocap))
        assert len(columns) >= 3
        tops = w.mocap_pos[columns, 2] + SEEN_HALF_HEIGHT_M
        assert np.all(tops > robot.scene.table_height_m + 0.1)
        # a configuration with the hand in the wall collides with the columns in the believed world
        checker = CollisionChecker(robot, CollisionPolicy(margin_m=0.0), world=w)
        target = w.mocap_pos[columns[0]].copy()
        target[2] += SEEN_HALF_HEIGHT_M - 0.05
        T = pin.SE3(np.diag([1.0, -1.0, -1.0]), target)
        q = solve_ik(robot, T, robot.home_q, "wall", IKConfig()).q
        assert any(name.startswith("seen_obstacle") for pair in checker.colliding_pairs(q) for name in pair)
    finally:
        obs.close()


@pytest.mark.parametrize("name", ["l_bracket", "mug", "gelatin_box"])
def test_the_objects_sphere_holds_it_whatever_its_believed_yaw(name: str) -> None:
    """The sphere the obstacle images leave out covers every point of the object for any yaw error about its
    believed origin (resting), and for any grasp point inside it (held: around the tcp)."""
    obj = library_object(name)
    robot = build(SceneConfig(object=obj))
    view = TableCamera(robot, CameraConfig(), np.random.default_rng(0))
    try:
        verts = obj.geometry().vertices
        believed = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.4), np.array([0.4, 0.1, 0.35]))
        for yaw in np.linspace(0.0, 2 * math.pi, 13):
            true = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.4 + yaw), believed.translation)
            centre, radius = view.object_sphere(believed)
            assert np.all(np.linalg.norm((verts @ true.rotation.T + true.translation) - centre, axis=1) < radius)
        rng = np.random.default_rng(1)
        for grasp in verts[rng.choice(len(verts), 10)]:  # the pads at a point of the object
            tcp = believed.act(grasp)
            centre, radius = view.object_sphere(believed, held_at=tcp)
            for yaw in np.linspace(0.0, 2 * math.pi, 7):  # the object turned about the grasp point
                R = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ believed.rotation
                pts = (verts - grasp) @ R.T + tcp
                assert np.all(np.linalg.norm(pts - centre, axis=1) < radius)
    finally:
        view.close()
