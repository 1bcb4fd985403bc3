"""Is an arm configuration valid in the scene? Built on MuJoCo's own collision detection.

A :class:`CollisionChecker` owns a private copy of the scene's ``MjModel`` (so the simulation is never
touched) in which every robot geom carries a safety margin: MuJoCo then reports a contact for any pair
closer than the margin, and every reported contact that the checker's policy does not allow is a
collision. It covers the robot against the table, floor and obstacles, robot self-collision (MuJoCo's
parent-child filter excludes adjacent links), the gripper against the object (unless allowed), and, while the
object is carried, the object moving rigidly with the tcp.

The checker's model is the scene compiled with one extra body: a copy of the object welded to the gripper
(``held_object``), switched off unless the object is carried. Carrying is then pure forward kinematics: one
``mj_kinematics`` and one ``mj_collision`` per configuration, with no pose arithmetic in Python, so a check
with the object in hand costs the same as one without. Bodies out of the arm's reach (obstacles parked far away
until needed) are switched off, so that MuJoCo's broad phase does not pair them up on every check.
"""

from __future__ import annotations

import copy
import functools
import logging
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import CollisionError
from pickplace.robot.model import (
    SEEN_OBSTACLE_NAMES,
    Handles,
    Robot,
    add_object_geoms,
    quiet_attach,
    scene_spec,
    surface_geoms,
)
from pickplace.world.config import SceneConfig, check_range
from pickplace.world.objects import ObjectConfig

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CollisionPolicy:
    """What the checker counts as a collision.

    Attributes:
        margin_m: Safety margin (m): the robot (and the carried object) closer than this to the table, the
            floor or an obstacle counts as colliding; 0 means actual contact. Self-collision is checked at
            actual contact.
        object_held: The object is carried: it moves rigidly with the tcp (see ``T_tcp_object``) and its contacts
            with the table, the floor, obstacles and the arm are collisions.
        allow_gripper_object: Contacts between the gripper (pads, fingers) and the object are allowed
            (grasping, carrying, releasing).
        allow_object_table: Contacts between the object and the table are allowed (the object resting, or being
            set down).
        finger_m: Finger opening used for the check (m of slide travel; 0 = fully open).
        table_margin_m: Margin to the table top alone (m); None: ``margin_m``. Moves that work at the table
            (the fingers reach down beside an object resting on it) keep a cushion from walls with
            ``margin_m`` and none from the table.
    """

    margin_m: float = 0.01
    object_held: bool = False
    allow_gripper_object: bool = False
    allow_object_table: bool = True
    finger_m: float = 0.0
    table_margin_m: float | None = None

    def __post_init__(self) -> None:
        check_range("collision.margin_m", self.margin_m, 0.0, 0.1, unit="m")
        if self.table_margin_m is not None:
            check_range("collision.table_margin_m", self.table_margin_m, 0.0, 0.1, unit="m")
        check_range("collision.finger_m", self.finger_m, 0.0, 0.040, unit="m")


class CollisionChecker:
    """Configuration validity for the arm in one scene under one :class:`CollisionPolicy`.

    Args:
        robot: The models.
        policy: What counts as a collision.
        world: A simulation state giving the pose of everything that is not the arm (where the object rests,
            mocap bodies); default: the scene's initial state. See :meth:`set_world`.
        T_tcp_object: Pose of the object in the tcp frame while it is held (default: centred, aligned).
        cull_far: Switch off the bodies out of the arm's reach, such as the obstacles parked far away until fault
            injection or perception needs them (the answers are the same, only faster; redone whenever
            :meth:`set_world` or :meth:`set_held` moves something); False keeps every body in MuJoCo's broad phase.

    Attributes:
        checks: Configurations checked so far (reset it to count).
        far_bodies: How many bodies are switched off as out of reach (0 with ``cull_far=False``).
    """

    def __init__(
        self,
        robot: Robot,
        policy: CollisionPolicy | None = None,
        world: mujoco.MjData | None = None,
        T_tcp_object: pin.SE3 | None = None,
        *,
        cull_far: bool = True,
    ) -> None:
        self.robot = robot
        self.policy = policy or CollisionPolicy()
        self._m = copy.deepcopy(_checker_model(robot.world_scene, robot.scene.object))
        self._d = mujoco.MjData(self._m)
        h = self._handles = Handles.resolve(self._m, robot.mj.body(robot.handles.object_body).name)
        self._held_body = mujoco.mj_name2id(self._m, mujoco.mjtObj.mjOBJ_BODY, HELD_PREFIX + "object")
        self._robot_bodies = h.robot_bodies | {self._held_body}
        self._held_geoms = frozenset(int(g) for g in np.flatnonzero(self._m.geom_bodyid == self._held_body))
        self._arm = slice(int(h.arm_qpos[0]), int(h.arm_qpos[0]) + 6)
        assert np.array_equal(h.arm_qpos, np.arange(self._arm.start, self._arm.stop)), "arm qpos must be contiguous"
        mujoco.mj_resetDataKeyframe(self._m, self._d, 0)
        self._finger_m = self.policy.finger_m
        self._d.qpos[h.finger_qpos] = self._finger_m
        if world is not None:
            self.set_world(world)
        self._weld_held_object(T_tcp_object or pin.SE3.Identity())
        self.checks = 0
        self._cull_far = cull_far
        self.far_bodies = 0
        self._configure_filters()
        self._prepare_culling()
        self._cull_far_bodies()

    def set_world(self, d: mujoco.MjData) -> None:
        """Take the pose of everything that is not the arm from a simulation state (the object, mocap bodies).

        The arm joints in ``d`` are ignored (each check sets them); the fingers keep the policy's opening.
        """
        h = self._handles
        arm = self._d.qpos[self._arm].copy()
        self._d.qpos[:] = d.qpos
        self._d.qpos[self._arm] = arm
        self._d.qpos[h.finger_qpos] = self._finger_m
        self._d.mocap_pos[:] = d.mocap_pos
        self._d.mocap_quat[:] = d.mocap_quat
        if hasattr(self, "_far"):  # (set_world in __init__ runs before the filters exist)
            self._cull_far_bodies()

    def set_held(self, T_tcp_object: pin.SE3, finger_m: float | None = None) -> None:
        """Carry the object at ``T_tcp_object`` from now on, the fingers at ``finger_m`` (m of travel) if given:
        one checker serves grasp after grasp (the policy stays as it is)."""
        self._weld_held_object(T_tcp_object)
        if finger_m is not None:
            self._finger_m = check_range("collision.finger_m", finger_m, 0.0, 0.040, unit="m")
            self._d.qpos[self._handles.finger_qpos] = self._finger_m
        self._reach = self.reach_m() + float(self._m.geom_margin.max())  # the held object moved
        self._cull_far_bodies()

    def _weld_held_object(self, T_tcp_object: pin.SE3) -> None:
        """Pose the held object's body in its parent (the body carrying the tcp site): T_tcp_site * T_tcp_object."""
        m, tcp = self._m, self._handles.tcp_site
        R_parent_tcp = np.empty(9)
        mujoco.mju_quat2Mat(R_parent_tcp, m.site_quat[tcp])
        R_parent_tcp = R_parent_tcp.reshape(3, 3)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, (R_parent_tcp @ T_tcp_object.rotation).ravel())
        m.body_pos[self._held_body] = m.site_pos[tcp] + R_parent_tcp @ T_tcp_object.translation
        m.body_quat[self._held_body] = quat

    def _configure_filters(self) -> None:
        """Encode the policy in the model copy's contype/conaffinity bits and margins.

        Every geom that takes part in collisions gets one class bit as its contype and, as its conaffinity,
        the bits of the classes it must not touch. MuJoCo then only generates the contacts that count, so a
        configuration is valid exactly when ``ncon == 0`` (no per-contact filtering in Python).
        """
        m, h, policy = self._m, self._handles, self.policy
        OFF, ARM, GRIP, TABLE, ENV, OBJ = 0, 1, 2, 4, 8, 16
        table = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "table")
        cls = np.full(m.ngeom, ENV)
        cls[np.isin(m.geom_bodyid, list(h.robot_bodies))] = ARM
        cls[np.isin(m.geom_bodyid, list(h.gripper_bodies))] = GRIP
        cls[m.geom_bodyid == table] = TABLE
        # Surfaces objects are set down on count as the table: the bin's floor, and the object the one in hand is
        # set on (a tower's top). The other objects, the bin's walls and the obstacles are the environment.
        cls[surface_geoms(m, self.robot.world_scene, self.robot.scene)] = TABLE
        # Exactly one of the two objects takes part: the one resting in the world, or the one in the gripper.
        cls[m.geom_bodyid == h.object_body] = OFF if policy.object_held else OBJ
        cls[m.geom_bodyid == self._held_body] = OBJ if policy.object_held else OFF
        pairs = {(ARM, ARM), (ARM, GRIP), (ARM, TABLE), (ARM, ENV), (ARM, OBJ), (GRIP, GRIP), (GRIP, TABLE),
                 (GRIP, ENV)}
        if not (policy.allow_gripper_object or policy.object_held):
            pairs.add((GRIP, OBJ))
        if policy.object_held:
            pairs.add((OBJ, ENV))
            if not policy.allow_object_table:
                pairs.add((OBJ, TABLE))
        affinity = {c: 0 for c in (OFF, ARM, GRIP, TABLE, ENV, OBJ)}
        for a, b in pairs:
            affinity[a] |= b
            affinity[b] |= a
        active = (m.geom_contype | m.geom_conaffinity) != 0  # visual geoms stay out
        m.geom_contype[active] = cls[active]
        m.geom_conaffinity[active] = [affinity[c] for c in cls[active]]
        # MuJoCo uses the larger margin of a pair: margins on the environment (and on the carried object) keep
        # the robot clear of them, while robot self-collision is checked at actual contact (adjacent housings
        # of the UR5e sit closer than any useful margin).
        m.geom_margin[:] = 0.0
        m.geom_margin[cls == ENV] = policy.margin_m
        m.geom_margin[cls == TABLE] = policy.margin_m if policy.table_margin_m is None else policy.table_margin_m
        if policy.object_held:
            m.geom_margin[cls == OBJ] = policy.margin_m
        # The broad phase works on bodies: it filters body pairs by the OR of their geoms' bits and pads each
        # body's bounds by its largest geom margin, both computed at compile time, so they are redone here.
        for b in range(m.nbody):
            in_body = m.geom_bodyid == b
            m.body_contype[b] = np.bitwise_or.reduce(m.geom_contype[in_body], initial=0)
            m.body_conaffinity[b] = np.bitwise_or.reduce(m.geom_conaffinity[in_body], initial=0)
            m.body_margin[b] = m.geom_margin[in_body].max(initial=0.0)

    def reach_m(self) -> float:
        """Radius (m) of a sphere about the robot's base that holds every colliding robot geom (and the carried
        object) in every arm configuration, margins included.

        A bound along the kinematic chain: a geom's distance from the base is at most the sum of the body offsets
        from the base to its body (a slide joint adding its largest travel), plus the geom's offset in its body
        and its bounding radius (the triangle inequality, whatever the joint angles).
        """
        m = self._m
        offset = np.linalg.norm(m.body_pos, axis=1) + self._slide_travel
        chain = np.zeros(m.nbody)
        for b in self._chain_order:  # the robot's bodies after the base; MuJoCo numbers a body after its parent
            chain[b] = chain[m.body_parentid[b]] + offset[b]
        g = self._robot_geoms
        return float(np.max(chain[m.geom_bodyid[g]] + np.linalg.norm(m.geom_pos[g], axis=1) + m.geom_rbound[g]
                            + m.geom_margin[g]))

    def _prepare_culling(self) -> None:
        """Remember the policy's collision bits and which geoms could be switched off (see :meth:`_cull_far_bodies`)."""
        m = self._m
        self._contype = m.geom_contype.copy()  # the policy's bits, before far bodies are switched off
        self._conaffinity = m.geom_conaffinity.copy()
        active = (self._contype | self._conaffinity) != 0
        body = m.geom_bodyid
        unbounded = np.unique(body[active & (m.geom_rbound <= 0.0)])  # planes: always on, with their bodies
        robot = np.array(sorted(self._robot_bodies))
        candidates = active & ~np.isin(body, robot) & ~np.isin(body, unbounded) & (body > 0)
        self._cull_geoms = np.flatnonzero(candidates)
        self._cull_rbound = m.geom_rbound[self._cull_geoms].copy()
        self._base_body = int(robot.min())
        self._chain_order = [int(b) for b in robot[1:]]
        self._robot_geoms = np.flatnonzero(active & np.isin(body, robot))
        self._slide_travel = np.zeros(m.nbody)
        for j in np.flatnonzero(m.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE):
            b = m.jnt_bodyid[j]
            self._slide_travel[b] = max(self._slide_travel[b], float(np.abs(m.jnt_range[j]).max()))
        self._reach = self.reach_m() + float(m.geom_margin.max())
        self._far = np.zeros(m.nbody, dtype=bool)

    def _cull_far_bodies(self) -> None:
        """Switch off the collisions of every body out of the robot's reach (:meth:`reach_m`, plus the largest
        margin), and back on for those within it.

        The scene holds bodies parked far away until needed: the intruder and the 64 columns of seen obstacles,
        all parked at one spot, whose overlapping bounds the broad phase would otherwise pair up on every check
        (they made a check 1.6-2.7 times as costly, measured on the obstacle transfer's checker). A body far out
        of reach cannot touch the arm or what it carries, so switching it off changes no answer. Planes (an
        unbounded ``geom_rbound`` of 0) always stay on. Costs one ``mj_kinematics`` and a few array operations;
        the model is only written when a body crosses the bound.
        """
        if not self._cull_far or self._cull_geoms.size == 0:
            return
        m, d = self._m, self._d
        mujoco.mj_kinematics(m, d)  # where everything that is not the arm is (the arm's own pose does not matter)
        gap = np.linalg.norm(d.geom_xpos[self._cull_geoms] - d.xpos[self._base_body], axis=1) - self._cull_rbound
        nearest = np.full(m.nbody, np.inf)
        np.minimum.at(nearest, m.geom_bodyid[self._cull_geoms], gap)
        far_body = np.isfinite(nearest) & (nearest > self._reach)  # (inf: no geom that may be switched off)
        if np.array_equal(far_body, self._far):
            return
        self._far = far_body
        far = far_body[m.geom_bodyid]
        m.geom_contype[:] = np.where(far, 0, self._contype)
        m.geom_conaffinity[:] = np.where(far, 0, self._conaffinity)
        # the broad phase filters body pairs by the OR of their geoms' bits
        for bits, out in ((m.geom_contype, m.body_contype), (m.geom_conaffinity, m.body_conaffinity)):
            acc = np.zeros(m.nbody, dtype=bits.dtype)
            np.bitwise_or.at(acc, m.geom_bodyid, bits)
            out[:] = acc
        self.far_bodies = int(far_body.sum())

    # ------------------------------------------------------------------ #
    # The loops below repeat _place inline: a check costs a few µs, so the Python around it matters.
    def _place(self, q: np.ndarray) -> None:
        d = self._d
        d.qpos[self._arm] = q
        mujoco.mj_kinematics(self._m, d)
        mujoco.mj_collision(self._m, d)
        self.checks += 1

    def is_valid(self, q: np.ndarray) -> bool:
        """True if the arm configuration (6,) (rad) is collision free under the policy."""
        self._place(q)
        return self._d.ncon == 0

    def are_valid(self, qs: np.ndarray) -> np.ndarray:
        """Validity of a batch of configurations (N, 6) (rad) -> bool (N,)."""
        qs = np.atleast_2d(qs)
        out = np.empty(len(qs), dtype=bool)
        m, d, arm, kinematics, collision = self._m, self._d, self._d.qpos[self._arm], mujoco.mj_kinematics, \
            mujoco.mj_collision
        for i, q in enumerate(qs):
            arm[:] = q
            kinematics(m, d)
            collision(m, d)
            out[i] = d.ncon == 0
        self.checks += len(qs)
        return out

    def all_valid(self, qs: np.ndarray) -> bool:
        """Whether every configuration of a batch (N, 6) is valid; stops at the first collision."""
        return self.first_invalid(qs) < 0

    def first_invalid(self, qs: np.ndarray) -> int:
        """Index of the first invalid configuration of a batch (N, 6), in order, or -1 if all are valid; stops
        there."""
        qs = np.atleast_2d(qs)
        m, d, arm, kinematics, collision = self._m, self._d, self._d.qpos[self._arm], mujoco.mj_kinematics, \
            mujoco.mj_collision
        for i, q in enumerate(qs):
            arm[:] = q
            kinematics(m, d)
            collision(m, d)
            if d.ncon:
                self.checks += i + 1
                return i
        self.checks += len(qs)
        return -1

    def colliding_pairs(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Names of the geom pairs in collision at ``q`` (6,) (sorted, without repeats)."""
        self._place(q)
        geoms = self._d.contact.geom[: self._d.ncon]
        pairs = {tuple(sorted((self._geom_name(int(a)), self._geom_name(int(b))))) for a, b in geoms}
        return sorted(pairs)  # type: ignore[arg-type]

    def _geom_name(self, g: int) -> str:
        """A geom's name as the user knows it (the carried object's geoms by their own names)."""
        name = self._m.geom(g).name or f"geom{g}"
        return name.removeprefix(HELD_PREFIX) if g in self._held_geoms else name

    def require_valid(self, q: np.ndarray, what: str) -> None:
        """Raise :class:`CollisionError` naming the geoms if ``q`` is in collision."""
        pairs = self.colliding_pairs(q)
        if pairs:
            raise CollisionError(what, pairs)


HELD_PREFIX = "held_"
"""Prefix of the checker model's geoms that are the object while it is carried (in the body ``held_object``)."""


@functools.lru_cache(maxsize=16)
def _checker_model(scene: SceneConfig, held: ObjectConfig) -> mujoco.MjModel:
    """The scene compiled with a copy of the object ``held`` welded to the tcp's body (compiled once per scene and
    object).

    The seen-obstacle columns collide here (in the simulation they do not exist). Nothing else changes: the
    qpos and mocap layouts are the simulation's, so world states carry over. Each checker
    works on its own deep copy (it edits the collision bits, the margins and the held object's pose).
    """
    spec = scene_spec(scene)
    for name in SEEN_OBSTACLE_NAMES:  # the obstacles the robot has seen take part here (as the map's do)
        column = spec.geom(name)
        column.contype, column.conaffinity = 1, 1
    tcp_body = spec.site("tcp").parent
    body = tcp_body.add_body(name=HELD_PREFIX + "object")
    add_object_geoms(spec, body, held, contact=False, prefix=HELD_PREFIX)
    with quiet_attach():
        return spec.compile()
