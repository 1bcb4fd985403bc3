"""Build the MuJoCo scene and the Pinocchio robot model from one MJCF description.

The robot is written once, in ``assets/ur5e.xml`` with ``assets/gripper.xml`` attached to ``tool0``.
:func:`robot_spec` composes the two with :class:`mujoco.MjSpec`; :func:`build` compiles that spec inside
the scene for MuJoCo and hands the *same* spec, serialised to MJCF, to Pinocchio's MJCF parser. There is no
second robot description to drift apart (``tests/test_model.py`` checks the two engines agree to 1e-9).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import logging
import math
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import ModelError
from pickplace.world.config import SceneConfig
from pickplace.world.objects import Geometry, ObjectConfig

log = logging.getLogger(__name__)

ASSETS = Path(__file__).parent / "assets"

#: The UR5e's joints, base to flange.
ARM_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
#: The gripper's finger slides (the right one follows the left through an equality constraint).
FINGER_JOINTS = ("left_finger_joint", "right_finger_joint")
#: The arm's actuators, joints 1-6.
ARM_ACTUATORS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
#: Published UR5e torque limits (N m), joints 1-6 (UR5e technical specification).
TORQUE_LIMITS_NM = np.array([150.0, 150.0, 150.0, 28.0, 28.0, 28.0])

_EMPTY_PREFIX_WARNING = "Attaching a spec with an empty prefix"


@contextlib.contextmanager
def quiet_attach() -> Iterator[None]:
    """Silence MuJoCo's warning about attaching with an empty prefix.

    We attach the gripper and the robot without name prefixes on purpose (the names in the XML files are
    already unique and are the public names: ``tcp``, ``tool0``, ``left_pad``). MuJoCo warns about it
    through its C warning hook (which would also write ``MUJOCO_LOG.TXT`` into the working directory) and
    through Python's ``warnings``; both are scoped to this block.
    """
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None if _EMPTY_PREFIX_WARNING in msg else log.warning(msg))
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=_EMPTY_PREFIX_WARNING)
            yield
    finally:
        mujoco.set_mju_user_warning(previous)


def robot_spec() -> mujoco.MjSpec:
    """The UR5e with the gripper mounted on ``tool0``: the one robot description (arm + gripper)."""
    spec = mujoco.MjSpec.from_file(str(ASSETS / "ur5e.xml"))
    gripper = mujoco.MjSpec.from_file(str(ASSETS / "gripper.xml"))
    with quiet_attach():
        spec.body("tool0").add_frame().attach_body(gripper.body("gripper_base"), "", "")
    return spec


def _quat_yaw(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


#: Name of the mocap body (and geom) of the obstacle that fault injection makes appear.
INTRUDER = "intruder"
#: Where the intruder waits, far from everything (m).
INTRUDER_PARKED_POS = (5.0, 5.0, 5.0)
#: Half sizes of the intruder box (m): thin along x, 0.2 m across, 0.25 m tall.
INTRUDER_HALF_SIZE_M = (0.02, 0.10, 0.125)

#: Prefix of the mocap bodies (and geoms) that hold obstacles the robot has seen but its map does not have: a
#: column per occupied cell of a height map (:mod:`pickplace.perception.obstacles`). They exist for the
#: planners' believed world only: in the simulation they collide with nothing and no sensor sees them.
SEEN_OBSTACLE = "seen_obstacle"
#: How many such columns the believed world holds.
SEEN_COLUMNS = 64
#: Their names (of each mocap body and of its one geom).
SEEN_OBSTACLE_NAMES = tuple(f"{SEEN_OBSTACLE}{i:02d}" for i in range(SEEN_COLUMNS))
#: Side of a column's square cross-section (m): the height map's cell.
SEEN_CELL_M = 0.04
#: Half height of a column (m): from its top (the highest point seen in its cell) down past the table top.
SEEN_HALF_HEIGHT_M = 0.3
#: Where unused columns wait, far from everything (m).
SEEN_PARKED_POS = (-5.0, -5.0, -5.0)


def scene_spec(scene: SceneConfig) -> mujoco.MjSpec:
    """The full scene for MuJoCo: world, robot, table, object, goal marker, optional obstacle and fixed boxes.

    Args:
        scene: What to build. Nothing in the XML files needs editing to vary it.

    Returns:
        An uncompiled spec. The robot is the first body tree under the world body.
    """
    spec = mujoco.MjSpec.from_file(str(ASSETS / "scene.xml"))
    spec.option.timestep = scene.timestep_s
    robot = robot_spec()
    with quiet_attach():
        spec.worldbody.add_frame().attach_body(robot.body("base"), "", "")
    _add_arm_sensors(spec)

    # Table: a 40 mm top whose upper face is at table_height_m, on four legs.
    top_half = 0.02
    sx, sy = (s / 2 for s in scene.table_size_xy_m)
    cx, cy = scene.table_center_xy_m
    table = spec.worldbody.add_body(name="table", pos=[cx, cy, scene.table_height_m - top_half])
    table.add_geom(name="table_top", type=mujoco.mjtGeom.mjGEOM_BOX, size=[sx, sy, top_half],
                   material="table", friction=[1.0, 0.005, 0.0001])
    leg_half = (scene.table_height_m - 2 * top_half) / 2
    for i, (lx, ly) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        table.add_geom(name=f"table_leg_{i}", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.025, leg_half, 0],
                       pos=[lx * (sx - 0.04), ly * (sy - 0.04), -top_half - leg_half], material="table")

    # The object: a free body. priority=1 makes its friction, condim and solver parameters the ones used for
    # every contact it takes part in (pads, table), so ObjectConfig.friction is the contact friction.
    obj = scene.object
    body = spec.worldbody.add_body(name=OBJECT, pos=scene.start_pos_m.tolist(), quat=_quat_yaw(scene.start_yaw_rad))
    body.add_freejoint(name=f"{OBJECT}_joint")
    add_object_geoms(spec, body, obj, contact=True)
    body.add_site(name=f"{OBJECT}_origin", size=[0.003, 0, 0], rgba=[1, 0, 1, 1], group=4)

    # The goal: a translucent marker (no contacts) with the object's footprint (its bounds) at the goal yaw.
    _add_goal_marker(spec, "goal", obj, scene.goal_xy_m, scene.goal_yaw_rad, scene.goal_surface_m)

    # More objects (a task's): free bodies named after them, each with its goal's marker if it has one.
    for other in scene.others:
        b = spec.worldbody.add_body(name=other.name, quat=_quat_yaw(other.start_yaw_rad),
                                    pos=[*other.start_xy_m, scene.table_height_m - other.object.geometry().z_min_m])
        b.add_freejoint(name=f"{other.name}_joint")
        add_object_geoms(spec, b, other.object, contact=True)
        if other.goal_xy_m is not None:
            _add_goal_marker(spec, f"goal_{other.name}", other.object, other.goal_xy_m, other.goal_yaw_rad,
                             scene.table_height_m)
    if scene.bin is not None:
        _add_bin(spec, scene)

    # An obstacle parked far away (a mocap body): fault injection moves it into the robot's path mid-episode.
    intruder = spec.worldbody.add_body(name=INTRUDER, pos=list(INTRUDER_PARKED_POS), mocap=True)
    intruder.add_geom(name=INTRUDER, type=mujoco.mjtGeom.mjGEOM_BOX, size=list(INTRUDER_HALF_SIZE_M),
                      material="obstacle")
    # Obstacles the robot has seen (the believed world's): parked, collision-free and hidden in the simulation.
    for name in SEEN_OBSTACLE_NAMES:
        column = spec.worldbody.add_body(name=name, pos=list(SEEN_PARKED_POS), mocap=True)
        column.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                        size=[SEEN_CELL_M / 2, SEEN_CELL_M / 2, SEEN_HALF_HEIGHT_M], contype=0, conaffinity=0,
                        group=5, rgba=[1.0, 0.5, 0.0, 0.4])

    for name in [OBJECT, *(other.name for other in scene.others)]:
        _add_object_sensors(spec, name)

    if scene.obstacle:
        ox, oy = obstacle_xy(scene)
        wall = spec.worldbody.add_body(name="obstacle", pos=[ox, oy, scene.table_height_m
                                                             + scene.obstacle_height_m / 2])
        wall.add_geom(name="obstacle", type=mujoco.mjtGeom.mjGEOM_BOX,
                      size=[scene.obstacle_length_m / 2, scene.obstacle_thickness_m / 2,
                            scene.obstacle_height_m / 2], material="obstacle")
    for box in scene.boxes:  # fixed boxes: shelves, cages, walls (SceneConfig.boxes)
        body = spec.worldbody.add_body(name=f"box_{box.name}", pos=list(box.center_m), quat=_quat_yaw(box.yaw_rad))
        body.add_geom(name=box.name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[v / 2 for v in box.size_m],
                      material="obstacle")
    return spec


#: The arm's sensors, in this order at the start of ``sensordata`` (:data:`ARM_STATE_WIDTH` values): the six joints'
#: positions (rad), their velocities (rad/s), the torques their actuators applied (N m), then the tcp's position in
#: the world (3,) (m). The control loops copy the block once per physics step (``motion.loop``).
ARM_STATE_FIELDS = ("q", "qd", "tau", "tcp")
ARM_STATE_WIDTH = 21


def _add_arm_sensors(spec: mujoco.MjSpec) -> None:
    """The arm's state block (:data:`ARM_STATE_FIELDS`), computed by MuJoCo at every step."""
    kinds = ((mujoco.mjtSensor.mjSENS_JOINTPOS, mujoco.mjtObj.mjOBJ_JOINT, "q"),
             (mujoco.mjtSensor.mjSENS_JOINTVEL, mujoco.mjtObj.mjOBJ_JOINT, "qd"),
             (mujoco.mjtSensor.mjSENS_ACTUATORFRC, mujoco.mjtObj.mjOBJ_ACTUATOR, "tau"))
    for kind, objtype, field_name in kinds:
        for joint, actuator in zip(ARM_JOINTS, ARM_ACTUATORS, strict=True):
            name = joint if objtype == mujoco.mjtObj.mjOBJ_JOINT else actuator
            s = spec.add_sensor(name=f"arm_{field_name}_{name}", type=kind)
            s.objtype, s.objname = objtype, name
    s = spec.add_sensor(name="arm_tcp", type=mujoco.mjtSensor.mjSENS_FRAMEPOS)
    s.objtype, s.objname = mujoco.mjtObj.mjOBJ_SITE, "tcp"
    _add_contact_count(spec, "robot_contacts", (mujoco.mjtObj.mjOBJ_XBODY, "base"))


#: A contact sensor's data fields (``mjtConDataField`` bits: found, force) and its reduction (net force of all the
#: matching contacts), as MuJoCo's XML parser encodes ``data="found force" reduce="netforce"``.
_CONTACT_FOUND_FORCE = (1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND)) | (
    1 << int(mujoco.mjtConDataField.mjCONDATA_FORCE))
_REDUCE_NETFORCE = 3
_CONTACT_FOUND = 1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND)


def _add_object_sensors(spec: mujoco.MjSpec, body: str) -> None:
    """The sensors MuJoCo computes at every step for the object body ``body`` (read by the per-step checks in C's
    time instead of Python's): the net force of each pad's contacts with it (``found`` then the force, 4 values
    each: :func:`pickplace.robot.gripper.pad_load`), its origin in the tcp frame (3 values) and in the world (3
    values), the number of its contacts, and the number of its contacts with the gripper (pads included)."""
    for pad in PAD_GEOMS:
        s = spec.add_sensor(name=f"{body}_{pad}", type=mujoco.mjtSensor.mjSENS_CONTACT)
        s.objtype, s.objname = mujoco.mjtObj.mjOBJ_GEOM, pad
        s.reftype, s.refname = mujoco.mjtObj.mjOBJ_BODY, body
        s.intprm[:3] = [_CONTACT_FOUND_FORCE, _REDUCE_NETFORCE, 1]
    # the body's own frame (mjOBJ_XBODY: its origin); a frame sensor of an mjOBJ_BODY reads its centre of mass
    s = spec.add_sensor(name=f"{body}_in_tcp", type=mujoco.mjtSensor.mjSENS_FRAMEPOS)
    s.objtype, s.objname = mujoco.mjtObj.mjOBJ_XBODY, body
    s.reftype, s.refname = mujoco.mjtObj.mjOBJ_SITE, "tcp"
    s = spec.add_sensor(name=f"{body}_position", type=mujoco.mjtSensor.mjSENS_FRAMEPOS)
    s.objtype, s.objname = mujoco.mjtObj.mjOBJ_XBODY, body
    _add_contact_count(spec, f"{body}_contacts", (mujoco.mjtObj.mjOBJ_BODY, body))
    _add_contact_count(spec, f"{body}_hand_contacts", (mujoco.mjtObj.mjOBJ_XBODY, "gripper_base"),
                       (mujoco.mjtObj.mjOBJ_BODY, body))


def _add_contact_count(spec: mujoco.MjSpec, name: str, first: tuple[mujoco.mjtObj, str],
                       second: tuple[mujoco.mjtObj, str] | None = None) -> None:
    """A sensor of the number of contacts between ``first`` and ``second`` (anything if None), each an object type
    (``mjOBJ_BODY``: a body's geoms; ``mjOBJ_XBODY``: its subtree's) and a name."""
    s = spec.add_sensor(name=name, type=mujoco.mjtSensor.mjSENS_CONTACT)
    s.objtype, s.objname = first
    if second is not None:
        s.reftype, s.refname = second
    s.intprm[:3] = [_CONTACT_FOUND, 0, 1]


#: The pads' geoms, left then right.
PAD_GEOMS = ("left_pad", "right_pad")
#: Name of the object's body (its geoms are named after the object, see :func:`object_geom_names`).
OBJECT = "object"
#: Name of the bin's body; its floor geom is :data:`BIN_FLOOR` (a surface, like the table), its walls ``bin_wall_*``.
BIN = "bin"
BIN_FLOOR = "bin_floor"


def object_body_name(scene: SceneConfig, name: str) -> str:
    """The body of the scene's object called ``name``: :data:`OBJECT` for the scene's own (first) object, its name
    for the others. Raises :class:`ModelError` listing the names if there is none."""
    names = [o.name for o in scene.objects]
    if name not in names:
        raise ModelError(f"the scene has no object named '{name}'; it has {', '.join(names)}")
    return OBJECT if name == scene.object.name else name


def surface_geoms(m: mujoco.MjModel, world: SceneConfig, scene: SceneConfig) -> np.ndarray:
    """Ids of the geoms of ``m`` that objects are set down on besides the table: the bin's floor, and the object that
    ``scene``'s object is set on (``goal_support``, a tower's top). ``world`` is the scene ``m`` was built from
    (the checker's model has the same names, not the same ids)."""
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, BIN_FLOOR)] if world.bin is not None else []
    if scene.goal_support:
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, object_body_name(world, scene.goal_support))
        ids += np.flatnonzero(m.geom_bodyid == body).tolist()
    return np.array(ids, dtype=int)


def _add_goal_marker(spec: mujoco.MjSpec, name: str, obj: ObjectConfig, xy: tuple[float, float], yaw: float,
                     z: float) -> None:
    """A translucent marker of the object's footprint (its bounds) at a goal, without contacts, and a site."""
    lo, hi = obj.geometry().bounds_m
    goal = spec.worldbody.add_body(name=name, pos=[*xy, z], quat=_quat_yaw(yaw))
    goal.add_geom(name=f"{name}_marker", type=mujoco.mjtGeom.mjGEOM_BOX,
                  size=[(hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, 0.0005],
                  pos=[(hi[0] + lo[0]) / 2, (hi[1] + lo[1]) / 2, 0.0], contype=0, conaffinity=0, group=1,
                  material="goal")
    goal.add_site(name=name, size=[0.003, 0, 0], rgba=[0, 1, 0, 1], group=4)


def _add_bin(spec: mujoco.MjSpec, scene: SceneConfig) -> None:
    """The bin: a floor and four walls, fixed to the table."""
    b = scene.bin
    assert b is not None
    t, h, f = b.wall_thickness_m, b.wall_height_m, b.floor_thickness_m
    ix, iy = (s / 2 for s in b.inner_size_xy_m)
    body = spec.worldbody.add_body(name=BIN, pos=[*b.xy_m, scene.table_height_m])
    body.add_geom(name=BIN_FLOOR, type=mujoco.mjtGeom.mjGEOM_BOX, size=[ix, iy, f / 2], pos=[0, 0, f / 2],
                  material="obstacle", friction=[1.0, 0.005, 0.0001])
    walls = (("x+", [ix + t / 2, 0], [t / 2, iy + t]), ("x-", [-ix - t / 2, 0], [t / 2, iy + t]),
             ("y+", [0, iy + t / 2], [ix, t / 2]), ("y-", [0, -iy - t / 2], [ix, t / 2]))
    for name, (x, y), (sx, sy) in walls:
        body.add_geom(name=f"bin_wall_{name}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[sx, sy, h / 2],
                      pos=[x, y, h / 2], material="obstacle")


def object_geom_names(obj: ObjectConfig) -> list[str]:
    """Names of the object's geoms: its name for a single geom, ``NAME_i`` for several."""
    n = len(obj.primitives()) or len(obj.geometry().hulls)
    return [obj.name] if n == 1 else [f"{obj.name}_{i}" for i in range(n)]


def add_object_geoms(spec: mujoco.MjSpec, body: mujoco.MjsBody, obj: ObjectConfig, *, contact: bool,
                     prefix: str = "") -> None:
    """Add the object's geoms to ``body``: its primitives, or the convex parts of its mesh.

    The mass is shared by volume (uniform density), so MuJoCo computes the inertia from the shapes, unless
    ``obj.inertia_kg_m2`` is given (then the body's inertial is set explicitly, at the centre of mass).

    Args:
        spec: The spec (mesh assets are added to it).
        body: The body to add the geoms to.
        obj: The object.
        contact: Give the geoms the object's contact parameters (the simulated object); otherwise plain
            geoms whose collision bits the caller sets (the collision checker's copy).
        prefix: Prefix of the geom (and mesh) names.
    """
    geo = obj.geometry()
    names = [prefix + n for n in object_geom_names(obj)]
    condim = 6 if obj.rolling_friction_m > 0 else 4
    extra: dict[str, object] = dict(
        material="object", condim=condim, priority=1, solref=[0.004, 1.0], solimp=[0.95, 0.99, 0.001, 0.5, 2.0],
        friction=[obj.friction, obj.torsional_friction_m, obj.rolling_friction_m]) if contact else dict(group=5)
    if geo.primitives:
        volumes = [p.volume_m3 for p in geo.primitives]
        kinds = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
                 "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}
        for name, part, vol in zip(names, geo.primitives, volumes, strict=True):
            s = part.size_m
            if part.kind == "box":
                size = [s[0] / 2, s[1] / 2, s[2] / 2]
            elif part.kind == "cylinder":
                size = [s[0], s[1] / 2, 0.0]
            else:
                size = [s[0], 0.0, 0.0]
            body.add_geom(name=name, type=kinds[part.kind], size=size, pos=list(part.pos_m),
                          quat=list(part.quat_wxyz), mass=obj.mass_kg * vol / sum(volumes), **extra)
    else:
        from scipy.spatial import ConvexHull

        volumes = [float(ConvexHull(h).volume) for h in geo.hulls]
        for name, hull, vol in zip(names, geo.hulls, volumes, strict=True):
            spec.add_mesh(name=name, uservert=np.asarray(hull, dtype=float).ravel().tolist())
            body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name,
                          mass=obj.mass_kg * vol / sum(volumes), **extra)
    if obj.inertia_kg_m2 is not None:
        body.explicitinertial = True
        body.mass = obj.mass_kg
        body.inertia = list(obj.inertia_kg_m2)
        body.ipos = _centroid(geo, volumes).tolist()


def _centroid(geo: Geometry, volumes: list[float]) -> np.ndarray:
    """Centre of volume (3,) of the object's parts (m)."""
    centres = [np.asarray(p.pos_m) for p in geo.primitives] or [np.mean(h, axis=0) for h in geo.hulls]
    return np.average(np.array(centres), axis=0, weights=volumes)


def scene_xml(scene: SceneConfig) -> str:
    """The scene as one self-contained MJCF string (e.g. to open in MuJoCo's own viewer)."""
    with quiet_attach():
        return scene_spec(scene).to_xml()


def obstacle_xy(scene: SceneConfig) -> tuple[float, float]:
    """Centre (x, y) of the obstacle wall (m) (:attr:`SceneConfig.obstacle_centre_xy_m`)."""
    return scene.obstacle_centre_xy_m


def arm_state_address(m: mujoco.MjModel) -> int:
    """The ``sensordata`` address of the arm's state block (:data:`ARM_STATE_FIELDS`) in ``m``.

    Raises:
        ModelError: ``m`` lacks those sensors or they are not one contiguous block in that order.
    """
    names = [f"arm_{f}_{n}" for f, group in (("q", ARM_JOINTS), ("qd", ARM_JOINTS), ("tau", ARM_ACTUATORS))
             for n in group] + ["arm_tcp"]
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, n) for n in names]
    if min(ids) < 0:
        missing = [n for n, i in zip(names, ids, strict=True) if i < 0]
        raise ModelError(f"the model lacks the arm's state sensors {', '.join(missing)}")
    adr = [int(m.sensor_adr[i]) for i in ids]
    start = adr[0]
    if adr != [start + k for k in range(18)] + [start + 18]:
        raise ModelError("the arm's state sensors are not one contiguous block of sensordata")
    return start


@dataclass(frozen=True)
class Handles:
    """Indices of the named elements the rest of the code needs, resolved once.

    Attributes:
        arm_qpos: qpos addresses of the six arm joints (6,).
        arm_dof: dof addresses of the six arm joints (6,).
        arm_actuators: actuator ids of the six arm motors (6,).
        finger_qpos: qpos addresses of the two finger slides (2,).
        finger_dof: dof addresses of the two finger slides (2,).
        gripper_actuator: id of the gripper's position actuator.
        tcp_site: id of the ``tcp`` site.
        tool0_body: id of the ``tool0`` body.
        object_body: id of the object's body.
        object_geoms: ids of the object's geoms (one per primitive or convex part).
        object_qpos: first qpos address of the object's free joint (7 values: position, quaternion).
        object_dof: first dof address of the object's free joint (6 values).
        pad_geoms: ids of the left and right pad geoms (2,).
        robot_bodies: ids of every body of the arm and the gripper.
        gripper_bodies: ids of the gripper's bodies (base and fingers).
        arm_state_sensor: ``sensordata`` address of the arm's state block (:data:`ARM_STATE_FIELDS`).
        pad_sensors: ``sensordata`` addresses of the object's contact sensors with the left and right pad (2,): each
            ``found`` (contacts), then the net force (3,) the pad exerts on the object, world axes (N).
        object_in_tcp_sensor: ``sensordata`` address of the object's origin in the tcp frame (3,) (m).
        object_position_sensor: ``sensordata`` address of the object's origin in the world (3,) (m).
        contact_count_sensors: ``sensordata`` addresses of three contact counts: the robot's (arm and gripper, with
            anything), the object's (with anything), the gripper's with the object.
        finger_joints: ids of the two finger slide joints (2,).
    """

    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    arm_actuators: np.ndarray
    finger_qpos: np.ndarray
    finger_dof: np.ndarray
    gripper_actuator: int
    tcp_site: int
    tool0_body: int
    object_body: int
    object_geoms: np.ndarray
    object_qpos: int
    object_dof: int
    pad_geoms: np.ndarray
    robot_bodies: frozenset[int]
    gripper_bodies: frozenset[int]
    arm_state_sensor: int
    pad_sensors: np.ndarray
    object_in_tcp_sensor: int
    object_position_sensor: int
    contact_count_sensors: np.ndarray
    finger_joints: np.ndarray

    @functools.cached_property
    def object_geom_set(self) -> frozenset[int]:
        """The object's geom ids as a set (fast membership tests)."""
        return frozenset(int(g) for g in self.object_geoms)

    @classmethod
    def resolve(cls, m: mujoco.MjModel, object_body: str = OBJECT) -> Handles:
        """Look every name up in ``m``; raise :class:`ModelError` listing valid names if one is missing.

        Args:
            m: The compiled model.
            object_body: The body of the object the skill works on (default: the scene's own object).
        """

        def find(kind: mujoco.mjtObj, name: str) -> int:
            i = mujoco.mj_name2id(m, kind, name)
            if i < 0:
                raise ModelError(f"the model has no {kind.name[6:].lower()} named '{name}'")
            return i

        J, B, G, S, A, N = (mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM,
                            mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtObj.mjOBJ_ACTUATOR, mujoco.mjtObj.mjOBJ_SENSOR)
        arm = [find(J, n) for n in ARM_JOINTS]
        fingers = [find(J, n) for n in FINGER_JOINTS]
        object_id = find(B, object_body)
        object_joint = m.body_jntadr[object_id]
        base = find(B, "base")
        gripper_base = find(B, "gripper_base")

        def subtree(root: int) -> frozenset[int]:
            out = {root}
            for b in range(root + 1, m.nbody):
                if m.body_parentid[b] in out:
                    out.add(b)
            return frozenset(out)

        return cls(
            arm_qpos=m.jnt_qposadr[arm].copy(),
            arm_dof=m.jnt_dofadr[arm].copy(),
            arm_actuators=np.array([find(A, n) for n in ARM_ACTUATORS]),
            finger_qpos=m.jnt_qposadr[fingers].copy(),
            finger_dof=m.jnt_dofadr[fingers].copy(),
            gripper_actuator=find(A, "gripper"),
            tcp_site=find(S, "tcp"),
            tool0_body=find(B, "tool0"),
            object_body=object_id,
            object_geoms=np.flatnonzero(m.geom_bodyid == object_id),
            object_qpos=int(m.jnt_qposadr[object_joint]),
            object_dof=int(m.jnt_dofadr[object_joint]),
            pad_geoms=np.array([find(G, "left_pad"), find(G, "right_pad")]),
            robot_bodies=subtree(base),
            gripper_bodies=subtree(gripper_base),
            arm_state_sensor=arm_state_address(m),
            pad_sensors=np.array([m.sensor_adr[find(N, f"{object_body}_{pad}")] for pad in PAD_GEOMS]),
            object_in_tcp_sensor=int(m.sensor_adr[find(N, f"{object_body}_in_tcp")]),
            object_position_sensor=int(m.sensor_adr[find(N, f"{object_body}_position")]),
            contact_count_sensors=np.array([m.sensor_adr[find(N, n)] for n in
                                            ("robot_contacts", f"{object_body}_contacts",
                                             f"{object_body}_hand_contacts")]),
            finger_joints=np.array(fingers),
        )


@dataclass(frozen=True)
class Robot:
    """The scene compiled for MuJoCo and the robot for Pinocchio, from the same MJCF.

    Attributes:
        scene: The configuration the models were built from.
        mj: The MuJoCo model of the whole scene.
        pin: The Pinocchio model of the robot (arm + gripper: 6 arm joints then the 2 finger slides).
        handles: Resolved MuJoCo element ids.
        pin_tcp_frame: Pinocchio frame id of the ``tcp`` site.
        pin_tool0_frame: Pinocchio frame id of the ``tool0`` body.
        home_q: The arm's ``home`` keyframe (6,) (rad).
        arm_lower: Lower joint limits (6,) (rad).
        arm_upper: Upper joint limits (6,) (rad).
        torque_limits_nm: Actuator torque limits (6,) (N m), read from the actuators' forcerange.
        robot_mjcf: The robot MJCF that both engines were built from.
        world: The scene the MuJoCo model was built from, every object in it; None: ``scene``. A robot focused on
            one object of a task (:meth:`focus`) has that object's pick and place as its ``scene``.
    """

    scene: SceneConfig
    mj: mujoco.MjModel
    pin: pin.Model
    handles: Handles
    pin_tcp_frame: int
    pin_tool0_frame: int
    home_q: np.ndarray
    arm_lower: np.ndarray
    arm_upper: np.ndarray
    torque_limits_nm: np.ndarray
    robot_mjcf: str
    world: SceneConfig | None = None

    @property
    def world_scene(self) -> SceneConfig:
        """The scene the MuJoCo model was built from (every object, the bin)."""
        return self.world if self.world is not None else self.scene

    def focus(self, scene: SceneConfig, name: str) -> Robot:
        """The same models, working on the object ``name`` of the world: ``scene`` is its pick and place (its
        object, where it is, its goal), the handles point at its body.

        Raises:
            ModelError: the world has no object of that name.
        """
        world = self.world_scene
        body = object_body_name(world, name)
        return dataclasses.replace(self, scene=scene, world=world, handles=Handles.resolve(self.mj, body))

    def make_data(self) -> mujoco.MjData:
        """A fresh MuJoCo data at the ``home`` keyframe (gripper open, object at its start), forward-computed."""
        d = mujoco.MjData(self.mj)
        mujoco.mj_resetDataKeyframe(self.mj, d, 0)
        mujoco.mj_forward(self.mj, d)
        return d

    def pin_q(self, q_arm: np.ndarray, finger_m: float = 0.0) -> np.ndarray:
        """Pinocchio configuration (8,) from arm joints (6,) (rad) and a finger opening (m)."""
        q = np.empty(self.pin.nq)
        q[:6] = q_arm
        q[6:] = finger_m
        return q


def build(scene: SceneConfig | None = None) -> Robot:
    """Build both engines' models of ``scene`` (default scene if ``None``).

    Raises:
        ModelError: if the MJCF does not compile or Pinocchio builds a different tree than expected.
    """
    scene = scene or SceneConfig()
    spec = scene_spec(scene)
    try:
        with quiet_attach():
            m = spec.compile()
            robot_xml = robot_spec().to_xml()
    except ValueError as exc:
        raise ModelError(f"the MJCF scene does not compile: {exc}") from exc
    pmodel = _pinocchio_from_mjcf(robot_xml)
    _place_site_frames(pmodel, m)
    _copy_inertias(pmodel, m)
    handles = Handles.resolve(m)

    expected = ("universe", *ARM_JOINTS, *FINGER_JOINTS)
    if tuple(pmodel.names) != expected:
        raise ModelError(f"Pinocchio built joints {tuple(pmodel.names)}, expected {expected}")
    home = m.key_qpos[0][handles.arm_qpos].copy()
    ranges = m.jnt_range[[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in ARM_JOINTS]]
    torque = np.abs(m.actuator_forcerange[handles.arm_actuators, 1]).copy()
    return Robot(
        scene=scene,
        mj=m,
        pin=pmodel,
        handles=handles,
        pin_tcp_frame=pmodel.getFrameId("tcp", pin.FrameType.OP_FRAME),
        pin_tool0_frame=pmodel.getFrameId("tool0", pin.FrameType.BODY),
        home_q=home,
        arm_lower=ranges[:, 0].copy(),
        arm_upper=ranges[:, 1].copy(),
        torque_limits_nm=torque,
        robot_mjcf=robot_xml,
    )


def _place_site_frames(pmodel: pin.Model, m: mujoco.MjModel) -> None:
    """Give every site frame of the Pinocchio model its placement from the compiled MJCF.

    Pinocchio 4.1's MJCF parser places a site relative to its parent *joint* instead of its body when the
    body is welded below the joint (here ``tcp`` in ``gripper_base``, 0.0996 m below wrist 3): the tcp
    came out 0.0996 m off. The site's pose in its body is taken from the same MJCF, compiled by MuJoCo,
    so there is still one description; tests/test_model.py checks both engines' tcp agree to 1e-9.
    """
    for s in range(m.nsite):
        name = m.site(s).name
        if not pmodel.existFrame(name, pin.FrameType.OP_FRAME):
            continue
        body = m.body(m.site_bodyid[s]).name
        body_frame = pmodel.frames[pmodel.getFrameId(body, pin.FrameType.BODY)]
        quat = m.site_quat[s]  # MuJoCo (w, x, y, z)
        local = pin.SE3(pin.Quaternion(quat[0], quat[1], quat[2], quat[3]).matrix(), m.site_pos[s].copy())
        fid = pmodel.getFrameId(name, pin.FrameType.OP_FRAME)
        frame = pmodel.frames[fid]
        frame.placement = body_frame.placement * local
        frame.parentJoint = body_frame.parentJoint
        pmodel.frames[fid] = frame


def _copy_inertias(pmodel: pin.Model, m: mujoco.MjModel) -> None:
    """Set each Pinocchio joint's inertia from MuJoCo's compiled bodies, at full precision.

    ``MjSpec.to_xml`` writes 6 significant digits, so the XML Pinocchio parses rounds UR's 7-digit inertias
    (e.g. 0.3338809 -> 0.333881 kg m^2). Each Pinocchio joint carries its body plus every body welded to it
    (``tool0`` and ``gripper_base`` ride on wrist 3); their inertias are summed in the joint's frame.
    """
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    for j in range(1, pmodel.njoints):
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, pmodel.names[j])
        body = int(m.jnt_bodyid[jid])
        X_world_body = pin.SE3(d.xmat[body].reshape(3, 3).copy(), d.xpos[body].copy())
        total = pin.Inertia.Zero()
        for b in np.flatnonzero(m.body_weldid == body):
            X_world_inertial = pin.SE3(d.ximat[b].reshape(3, 3).copy(), d.xipos[b].copy())
            local = pin.Inertia(float(m.body_mass[b]), np.zeros(3), np.diag(m.body_inertia[b]))
            total += X_world_body.actInv(X_world_inertial).act(local)
        pmodel.inertias[j] = total


def _pinocchio_from_mjcf(xml: str) -> pin.Model:
    """Parse an MJCF string with Pinocchio (its parser reads files only)."""
    with tempfile.TemporaryDirectory(prefix="pickplace_") as tmp:
        path = Path(tmp) / "robot.xml"
        path.write_text(xml)
        try:
            return pin.buildModelFromMJCF(str(path))
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"Pinocchio could not parse the robot MJCF: {exc}") from exc
