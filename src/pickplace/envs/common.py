"""What the environments share: the robot's own state as an observation, the objects' poses as the robot knows
them, per-reset scenes drawn from the seed, and images (offscreen, MuJoCo's renderer).

Observations are float32 arrays (SI units: m, rad, m/s, rad/s) bounded by :data:`POSITION_LIMIT_M` and
:data:`VELOCITY_LIMIT` (values are clipped into their boxes, so that an observation is always in its space).
Quaternions are ``(w, x, y, z)``.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin
from gymnasium import spaces

from pickplace.errors import ConfigError
from pickplace.perception.render import OffscreenScene
from pickplace.robot import gripper
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import Robot
from pickplace.world.checks import check_int
from pickplace.world.config import SceneConfig
from pickplace.world.objects import LIBRARY

log = logging.getLogger(__name__)

#: Bound of every position in an observation (m): the table and the arm's reach lie well inside.
POSITION_LIMIT_M = 5.0
#: Bound of every velocity in an observation (rad/s, m/s): far beyond the UR5e's 3.14 rad/s joint speeds.
VELOCITY_LIMIT = 100.0
#: The camera of the scene that ``render()`` and the image observations look through.
CAMERA = "overview"
#: Ranges of the per-reset draw of a single object's pose around the config's (the defaults of the campaigns'
#: ``[randomization]`` table, :class:`pickplace.eval.campaign.spec.RandomizationSpec`): start and goal offsets
#: (m) and start yaw offset (rad), each uniform in ``[-value, value]``.
START_DXY_M = 0.05
GOAL_DXY_M = 0.05
START_DYAW_RAD = math.pi / 4
#: Draws of a single object's scene before giving up (a draw off the table or into the wall is drawn again).
MAX_DRAWS = 100


def box(shape: tuple[int, ...], limit: float) -> spaces.Box:
    """A float32 box ``[-limit, limit]`` of ``shape``."""
    return spaces.Box(-limit, limit, shape=shape, dtype=np.float32)


def clipped(value: np.ndarray, limit: float) -> np.ndarray:
    """A new float32 array of ``value`` clipped to ``[-limit, limit]``."""
    return np.clip(np.asarray(value, dtype=np.float64), -limit, limit).astype(np.float32)


def robot_spaces() -> dict[str, spaces.Space[Any]]:
    """The robot's own state: joints (6,) (rad, rad/s), the opening between the pads (1,) (m), the tcp's position
    (3,) (m) and orientation (4,) (quaternion w, x, y, z)."""
    return {
        "joint_pos": box((6,), 2 * math.pi + 0.5),
        "joint_vel": box((6,), VELOCITY_LIMIT),
        "gripper_opening_m": spaces.Box(0.0, 0.2, shape=(1,), dtype=np.float32),
        "tcp_pos": box((3,), POSITION_LIMIT_M),
        "tcp_quat": box((4,), 1.0),
    }


def object_spaces(k: int) -> dict[str, spaces.Space[Any]]:
    """The poses of ``k`` objects (K, 3) (m) and (K, 4), which of them exist (K,), and their goals: the position
    their origin rests at there (K, 3) (m) and its yaw (K,) (rad)."""
    return {
        "object_pos": box((k, 3), POSITION_LIMIT_M),
        "object_quat": box((k, 4), 1.0),
        "object_mask": spaces.MultiBinary(k),
        "goal_pos": box((k, 3), POSITION_LIMIT_M),
        "goal_yaw": box((k,), 2 * math.pi),
    }


def image_spaces(width_px: int, height_px: int) -> dict[str, spaces.Space[Any]]:
    """An RGB image (H, W, 3) and a depth image (H, W) (m along the optical axis) of :data:`CAMERA`."""
    return {
        "rgb": spaces.Box(0, 255, shape=(height_px, width_px, 3), dtype=np.uint8),
        "depth": spaces.Box(0.0, 100.0, shape=(height_px, width_px), dtype=np.float32),
    }


def quat_wxyz(R: np.ndarray) -> np.ndarray:
    """The unit quaternion (4,) (w, x, y, z) of a rotation matrix (3, 3), with w >= 0."""
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.asarray(R, dtype=np.float64).ravel())
    return -q if q[0] < 0 else q


def open_face_y_m(robot: Robot) -> float:
    """Distance of each open pad's face from the tcp (m) (:class:`~pickplace.robot.gripper.GripperGeometry`: measured
    on the model, about 0.5 ms: once per scene)."""
    return gripper.GripperGeometry.measure(robot).open_inner_face_y_m


def robot_observation(robot: Robot, d: mujoco.MjData, open_face_m: float,
                      encoder_resolution_rad: float = 0.0) -> dict[str, np.ndarray]:
    """The robot's own state (:func:`robot_spaces`): its encoders (quantized to ``encoder_resolution_rad`` if > 0),
    the opening between the pads from the fingers' travel (``open_face_m``: :func:`open_face_y_m`) and the tcp by its
    kinematics."""
    h = robot.handles
    q = np.array(d.qpos[h.arm_qpos], dtype=np.float64)
    if encoder_resolution_rad > 0.0:
        q = np.round(q / encoder_resolution_rad) * encoder_resolution_rad
    opening = 2.0 * (open_face_m - gripper.finger_travel(robot, d))
    return {
        "joint_pos": clipped(q, 2 * math.pi + 0.5),
        "joint_vel": clipped(d.qvel[h.arm_dof], VELOCITY_LIMIT),
        "gripper_opening_m": np.clip(np.array([opening], dtype=np.float32), 0.0, 0.2),
        "tcp_pos": clipped(d.site_xpos[h.tcp_site], POSITION_LIMIT_M),
        "tcp_quat": quat_wxyz(d.site_xmat[h.tcp_site].reshape(3, 3)).astype(np.float32),
    }


def object_observation(poses: list[pin.SE3], goals: list[tuple[np.ndarray, float]], k: int) -> dict[str, np.ndarray]:
    """The objects' poses and goals as arrays of :func:`object_spaces` (rows past ``len(poses)`` are zero, their mask
    0).

    Args:
        poses: The objects' poses as the robot knows them.
        goals: Per object, where its origin rests at its goal (3,) (m) and its yaw there (rad).
        k: Rows.
    """
    pos = np.zeros((k, 3))
    quat = np.zeros((k, 4))
    mask = np.zeros(k, dtype=np.int8)
    goal_pos = np.zeros((k, 3))
    goal_yaw = np.zeros(k)
    for i, T in enumerate(poses):
        pos[i], quat[i], mask[i] = T.translation, quat_wxyz(T.rotation), 1
    for i, (p, yaw) in enumerate(goals):
        goal_pos[i], goal_yaw[i] = p, math.remainder(yaw, 2 * math.pi)
    return {"object_pos": clipped(pos, POSITION_LIMIT_M), "object_quat": quat.astype(np.float32), "object_mask": mask,
            "goal_pos": clipped(goal_pos, POSITION_LIMIT_M), "goal_yaw": goal_yaw.astype(np.float32)}


def check_size(name: str, value: Any) -> tuple[int, int]:
    """An image size ``(width, height)`` (px), each 16 to 1280 (the scene's offscreen buffer is 1280 x 720)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list)) or len(value) != 2:
        raise ConfigError(name, value, "must be (width, height) in pixels")
    return check_int(f"{name}[0]", value[0], 16, 1280), check_int(f"{name}[1]", value[1], 16, 720)


def check_objects(name: str, value: Any) -> tuple[str, ...] | None:
    """None, or a non-empty tuple of library object names."""
    if value is None:
        return None
    if isinstance(value, str) or not isinstance(value, (tuple, list)) or not value:
        raise ConfigError(name, value, f"must be None or a non-empty list of library objects ({', '.join(LIBRARY)})")
    for o in value:
        if o not in LIBRARY:
            raise ConfigError(name, o, f"must be one of {', '.join(LIBRARY)}")
    return tuple(value)


def check_bool(name: str, value: Any) -> bool:
    """A bool (not a number)."""
    if not isinstance(value, bool):
        raise ConfigError(name, value, "must be True or False")
    return value


def draw_scene(base: SceneConfig, rng: np.random.Generator, objects: tuple[str, ...] | None) -> SceneConfig:
    """One object's scene drawn around ``base``: the start offset by up to :data:`START_DXY_M` in x and y and turned
    by up to :data:`START_DYAW_RAD`, the goal offset by up to :data:`GOAL_DXY_M`, the object drawn from the library
    names ``objects`` if given (else ``base``'s); a draw off the table or into the wall is drawn again.

    Raises:
        ConfigError: no valid scene in :data:`MAX_DRAWS` draws.
    """
    last: ConfigError | None = None
    for _ in range(MAX_DRAWS):
        u = rng.uniform(-1.0, 1.0, 5)
        pick = float(rng.random())
        obj = base.object if objects is None else LIBRARY[objects[min(int(pick * len(objects)), len(objects) - 1)]]
        start = (base.start_xy_m[0] + START_DXY_M * u[0], base.start_xy_m[1] + START_DXY_M * u[1])
        goal = (base.goal_xy_m[0] + GOAL_DXY_M * u[3], base.goal_xy_m[1] + GOAL_DXY_M * u[4])
        yaw = math.remainder(base.start_yaw_rad + START_DYAW_RAD * u[2], 2 * math.pi)
        try:
            scene = dataclasses.replace(base, object=obj, start_xy_m=start, start_yaw_rad=yaw, goal_xy_m=goal)
            scene.check_goal_on_table()
        except ConfigError as exc:
            last = exc
            continue
        return scene
    assert last is not None
    raise ConfigError("randomize", True, f"no valid scene around the config's in {MAX_DRAWS} draws (last: {last})")


def start_pose(scene: SceneConfig) -> pin.SE3:
    """The object's pose at the start of ``scene`` (resting, turned by its start yaw)."""
    return pin.SE3(rot_z(scene.start_yaw_rad), scene.start_pos_m)


class Views:
    """Offscreen images of a scene through :data:`CAMERA`: a frame for ``render()`` and RGB-D observations.

    Each is rendered by an :class:`~pickplace.perception.render.OffscreenScene` (the images a ``mujoco.Renderer``
    gives, on the thread's shared OpenGL context: a new scene costs its MuJoCo render context, not an OpenGL
    context), made on first use and released by :meth:`close`.

    Args:
        robot: The models (the scene's MuJoCo model).
        render_size_px: ``render()``'s frame (width, height) (px).
        image_size_px: The image observations' (width, height) (px).
    """

    def __init__(self, robot: Robot, render_size_px: tuple[int, int], image_size_px: tuple[int, int]) -> None:
        self.m = robot.mj
        self.render_size_px, self.image_size_px = render_size_px, image_size_px
        self._frame: OffscreenScene | None = None
        self._image: OffscreenScene | None = None

    def frame(self, d: mujoco.MjData) -> np.ndarray:
        """An RGB frame (H, W, 3) uint8 of the simulation as it is."""
        if self._frame is None:
            self._frame = OffscreenScene(self.m, *self.render_size_px)
            log.debug("render(): %dx%d px on %s", *self.render_size_px, self._frame.backend)
        return self._frame.rgb(d, CAMERA)

    def rgbd(self, d: mujoco.MjData) -> dict[str, np.ndarray]:
        """An RGB image (H, W, 3) uint8 and the depth (H, W) (m, float32) of every pixel."""
        if self._image is None:
            self._image = OffscreenScene(self.m, *self.image_size_px)
        rgb = self._image.rgb(d, CAMERA)
        return {"rgb": rgb, "depth": np.clip(self._image.depth(d, CAMERA), 0.0, 100.0)}

    def close(self) -> None:
        """Release the render contexts."""
        for view in (self._frame, self._image):
            if view is not None:
                view.close()
        self._frame = self._image = None


class RenderedEnv:
    """What the environments share at their end: ``render()`` through their :class:`Views`, and the release of
    the renderers and of the observer's camera (its OpenGL context) on ``close()`` and before each new scene.

    A mixin for the :class:`gymnasium.Env` subclasses; they set ``render_mode``, ``_views``, ``_d`` (the
    simulation) and, if they have one, ``_observer``.
    """

    render_mode: str | None
    _views: Views | None
    _d: mujoco.MjData | None
    _observer: Any = None

    def render(self) -> np.ndarray | None:
        """An RGB frame (H, W, 3) of the scene's overview camera (render_mode ``rgb_array``), else None."""
        if self.render_mode != "rgb_array" or self._views is None or self._d is None:
            return None
        return self._views.frame(self._d)

    def _release(self) -> None:
        if self._views is not None:
            self._views.close()
            self._views = None
        if self._observer is not None:
            self._observer.close()
            self._observer = None

    def close(self) -> None:
        """Release the renderers and the camera's OpenGL contexts (closing twice is harmless)."""
        self._release()


__all__ = ["CAMERA", "POSITION_LIMIT_M", "VELOCITY_LIMIT", "RenderedEnv", "Views", "draw_scene", "object_observation",
           "object_spaces", "open_face_y_m", "robot_observation", "robot_spaces", "start_pose"]
