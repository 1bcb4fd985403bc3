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

Checkers are cheap to build: the model is compiled once per scene and object, its collision bits are set once per
policy, checkers in the same state share one model (never written once shared), and the checkers of a scene share
one ``MjData``, each loading its own state into it when another used it last.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import itertools
import logging
import threading
from collections import OrderedDict
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

    Building one is cheap (about 0.1 ms): the checker's model is compiled once per scene and held object, its
    collision bits are set once per policy, checkers in the same state (the same held pose, the same bodies switched
    off) share one model, which is never written once shared (:class:`_ModelFamily`), and the checkers of a scene
    share one ``MjData``, each loading its own state into it when another one used it last (:class:`_SharedData`).
    Checkers are not to be used from several threads at once (each thread gets its own data).

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
        family = self._family = _model_family(robot.world_scene, robot.scene, robot.mj.body(
            robot.handles.object_body).name, dataclasses.replace(self.policy, finger_m=0.0))
        self._m = family.model
        shared = self._shared = _shared_data(robot.world_scene, robot.scene.object, threading.get_ident())
        self._d = shared.d
        self._arm_qpos = shared.d.qpos[family.arm]  # (a view: the arm's joints in the shared data)
        self._token = next(_TOKENS)  # who this checker is to the shared data
        self._handles, self._held_body, self._arm = family.handles, family.held_body, family.arm
        self._contype, self._conaffinity = family.contype, family.conaffinity
        # This checker's state: the poses of what is not the arm, the fingers' opening (loaded into the shared data
        # whenever this checker uses it after another one did).
        self._qpos, self._mocap_pos, self._mocap_quat = (shared.qpos0.copy(), shared.mocap_pos0.copy(),
                                                         shared.mocap_quat0.copy())
        self._finger_m = self.policy.finger_m
        self._qpos[family.handles.finger_qpos] = self._finger_m
        if world is not None:
            self._copy_world(world)
        self.checks = 0
        self._cull_far = cull_far
        self._held_pose = family.held_pose(T_tcp_object or pin.SE3.Identity())
        self._reach = family.reach(self._held_pose[0])
        self._far = np.zeros(self._m.nbody, dtype=bool)
        self.far_bodies = 0
        self._held_changed = False
        self._update_model()

    def set_world(self, d: mujoco.MjData) -> None:
        """Take the pose of everything that is not the arm from a simulation state (the object, mocap bodies).

        The arm joints in ``d`` are ignored (each check sets them); the fingers keep the policy's opening.
        """
        self._copy_world(d)
        self._update_model()

    def world_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The world this checker answers for (:meth:`set_world`): ``qpos`` (the arm's entries mean nothing, the
        fingers' are the policy's opening), ``mocap_pos`` and ``mocap_quat``; copies."""
        return self._qpos.copy(), self._mocap_pos.copy(), self._mocap_quat.copy()

    def _copy_world(self, d: mujoco.MjData) -> None:
        self._qpos[:] = d.qpos  # (the arm's part is set by each check)
        self._qpos[self._handles.finger_qpos] = self._finger_m
        self._mocap_pos[:] = d.mocap_pos
        self._mocap_quat[:] = d.mocap_quat
        self._shared.owner = None  # (reload)

    def _load(self) -> None:
        """Load this checker's state into the shared data (another checker used it last)."""
        d = self._d
        d.qpos[:] = self._qpos
        d.mocap_pos[:] = self._mocap_pos
        d.mocap_quat[:] = self._mocap_quat
        self._shared.owner = self._token

    def set_held(self, T_tcp_object: pin.SE3, finger_m: float | None = None) -> None:
        """Carry the object at ``T_tcp_object`` from now on, the fingers at ``finger_m`` (m of travel) if given:
        one checker serves grasp after grasp (the policy stays as it is)."""
        if finger_m is not None:
            self._finger_m = check_range("collision.finger_m", finger_m, 0.0, 0.040, unit="m")
            self._qpos[self._handles.finger_qpos] = self._finger_m
            self._shared.owner = None  # (reload)
        self._held_pose = self._family.held_pose(T_tcp_object)
        self._reach = self._family.reach(self._held_pose[0])  # the held object moved
        self._held_changed = True
        self._update_model()

    def reach_m(self) -> float:
        """Radius (m) of a sphere about the robot's base that holds every colliding robot geom (and the carried
        object) in every arm configuration, margins included.

        A bound along the kinematic chain: a geom's distance from the base is at most the sum of the body offsets
        from the base to its body (a slide joint adding its largest travel), plus the geom's offset in its body
        and its bounding radius (the triangle inequality, whatever the joint angles).
        """
        return self._family.chain_reach(self._held_pose[0])

    def _update_model(self) -> None:
        """Switch off the collisions of every body out of the robot's reach (:meth:`reach_m`, plus the largest
        margin), and back on for those within it; then take the shared model for this state (held pose, bodies
        switched off).

        The scene holds bodies parked far away until needed: the intruder and the 64 columns of seen obstacles,
        all parked at one spot, whose overlapping bounds the broad phase would otherwise pair up on every check
        (they made a check 1.6-2.7 times as costly, measured on the obstacle transfer's checker). A body far out
        of reach cannot touch the arm or what it carries, so switching it off changes no answer. Planes (an
        unbounded ``geom_rbound`` of 0) always stay on. Costs one ``mj_kinematics`` and a few array operations.
        """
        family = self._family
        far = self._far
        if self._cull_far and family.cull_geoms.size:
            if self._shared.owner != self._token:
                self._load()
            m, d = self._m, self._d
            mujoco.mj_kinematics(m, d)  # where everything that is not the arm is (the arm's pose does not matter)
            gap = (np.linalg.norm(d.geom_xpos[family.cull_geoms] - d.xpos[family.base_body], axis=1)
                   - family.cull_rbound)
            nearest = np.full(m.nbody, np.inf)
            np.minimum.at(nearest, family.cull_bodies, gap)
            far = np.isfinite(nearest) & (nearest > self._reach)  # (inf: no geom that may be switched off)
        if self._m is family.model or self._held_changed or not np.array_equal(far, self._far):
            self._far, self.far_bodies, self._held_changed = far, int(far.sum()), False
            self._m = family.variant(self._held_pose, far)

    # ------------------------------------------------------------------ #
    # The loops below repeat _place inline: a check costs a few µs, so the Python around it matters.
    def _place(self, q: np.ndarray) -> None:
        if self._shared.owner != self._token:
            self._load()
        d = self._d
        self._arm_qpos[:] = q
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
        if self._shared.owner != self._token:
            self._load()
        m, d, arm, kinematics, collision = self._m, self._d, self._arm_qpos, mujoco.mj_kinematics, mujoco.mj_collision
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
        if qs.ndim != 2:
            qs = np.atleast_2d(qs)
        if self._shared.owner != self._token:
            self._load()
        m, d, arm, kinematics, collision = self._m, self._d, self._arm_qpos, mujoco.mj_kinematics, mujoco.mj_collision
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
        return name.removeprefix(HELD_PREFIX) if g in self._family.held_geoms else name

    def require_valid(self, q: np.ndarray, what: str) -> None:
        """Raise :class:`CollisionError` naming the geoms if ``q`` is in collision."""
        pairs = self.colliding_pairs(q)
        if pairs:
            raise CollisionError(what, pairs)


class _ModelFamily:
    """The checker models of one scene, object and policy: the compiled model with the policy's collision bits and
    margins (:meth:`_configure_filters`), what culling needs, and the variants of that model that checkers share.

    A variant is the model with the held object welded at one pose and the far bodies switched off; checkers in
    the same state use the same variant, and a variant is never written once made (a checker whose state changes
    takes another one), so sharing changes no answer. The family keeps the last :data:`_VARIANTS` variants made.
    """

    def __init__(self, world: SceneConfig, scene: SceneConfig, object_body: str, policy: CollisionPolicy) -> None:
        m = self.model = copy.deepcopy(_checker_model(world, scene.object))
        h = self.handles = Handles.resolve(m, object_body)
        self.held_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, HELD_PREFIX + "object")
        self.robot_bodies = h.robot_bodies | {self.held_body}
        self.held_geoms = frozenset(int(g) for g in np.flatnonzero(m.geom_bodyid == self.held_body))
        self.arm = slice(int(h.arm_qpos[0]), int(h.arm_qpos[0]) + 6)
        assert np.array_equal(h.arm_qpos, np.arange(self.arm.start, self.arm.stop)), "arm qpos must be contiguous"
        self._configure_filters(world, scene, policy)
        self._prepare_culling()
        self._variants: OrderedDict[bytes, mujoco.MjModel] = OrderedDict()

    def _configure_filters(self, world: SceneConfig, scene: SceneConfig, policy: CollisionPolicy) -> None:
        """Encode the policy in the model's contype/conaffinity bits and margins.

        Every geom that takes part in collisions gets one class bit as its contype and, as its conaffinity,
        the bits of the classes it must not touch. MuJoCo then only generates the contacts that count, so a
        configuration is valid exactly when ``ncon == 0`` (no per-contact filtering in Python).
        """
        m, h = self.model, self.handles
        OFF, ARM, GRIP, TABLE, ENV, OBJ = 0, 1, 2, 4, 8, 16
        table = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "table")
        cls = np.full(m.ngeom, ENV)
        cls[np.isin(m.geom_bodyid, list(h.robot_bodies))] = ARM
        cls[np.isin(m.geom_bodyid, list(h.gripper_bodies))] = GRIP
        cls[m.geom_bodyid == table] = TABLE
        # Surfaces objects are set down on count as the table: the bin's floor, and the object the one in hand is
        # set on (a tower's top). The other objects, the bin's walls and the obstacles are the environment.
        cls[surface_geoms(m, world, scene)] = TABLE
        # Exactly one of the two objects takes part: the one resting in the world, or the one in the gripper.
        cls[m.geom_bodyid == h.object_body] = OFF if policy.object_held else OBJ
        cls[m.geom_bodyid == self.held_body] = OBJ if policy.object_held else OFF
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
        m.geom_conaffinity[active] = [affinity[int(c)] for c in cls[active]]
        # The margins sit on the environment and the table only: they keep the robot and the carried object clear
        # of them, while robot self-collision, and the arm against the object it carries, are checked at actual
        # contact (adjacent housings of the UR5e sit closer than any useful margin). Every counted pair then has at
        # most one geom with a margin, so its margin is that one whatever rule combines a pair's two margins:
        # MuJoCo 4 adds them (older versions took the larger), and a margin on the carried object as well kept it
        # twice the margin from walls and table (tests/test_collision.py).
        m.geom_margin[:] = 0.0
        m.geom_margin[cls == ENV] = policy.margin_m
        m.geom_margin[cls == TABLE] = policy.margin_m if policy.table_margin_m is None else policy.table_margin_m
        # The broad phase works on bodies: it filters body pairs by the OR of their geoms' bits and pads each
        # body's bounds by its largest geom margin, both computed at compile time, so they are redone here.
        _body_bits(m, m.geom_contype, m.geom_conaffinity)
        body_margin = np.zeros(m.nbody)
        np.maximum.at(body_margin, m.geom_bodyid, m.geom_margin)
        m.body_margin[:] = body_margin
        self.contype, self.conaffinity = m.geom_contype.copy(), m.geom_conaffinity.copy()
        for a in (self.contype, self.conaffinity):
            a.setflags(write=False)

    def _prepare_culling(self) -> None:
        """Which geoms could be switched off as out of reach, and the kinematic chain that bounds the reach."""
        m = self.model
        active = (self.contype | self.conaffinity) != 0
        body = m.geom_bodyid
        unbounded = np.unique(body[active & (m.geom_rbound <= 0.0)])  # planes: always on, with their bodies
        robot = np.array(sorted(self.robot_bodies))
        candidates = active & ~np.isin(body, robot) & ~np.isin(body, unbounded) & (body > 0)
        self.cull_geoms = np.flatnonzero(candidates)
        self.cull_bodies = body[self.cull_geoms]
        self.cull_rbound = m.geom_rbound[self.cull_geoms].copy()
        self.base_body = int(robot.min())
        self._chain_order = [int(b) for b in robot[1:]]
        self._robot_geoms = np.flatnonzero(active & np.isin(body, robot))
        self._slide_travel = np.zeros(m.nbody)
        for j in np.flatnonzero(m.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE):
            b = m.jnt_bodyid[j]
            self._slide_travel[b] = max(self._slide_travel[b], float(np.abs(m.jnt_range[j]).max()))
        self._max_margin = float(m.geom_margin.max())
        self._reach: dict[bytes, float] = {}

    def held_pose(self, T_tcp_object: pin.SE3) -> tuple[np.ndarray, np.ndarray]:
        """The held object's body pose in its parent (the body carrying the tcp site): T_tcp_site * T_tcp_object, as
        (position (3,), quaternion (4,))."""
        m, tcp = self.model, self.handles.tcp_site
        R_parent_tcp = np.empty(9)
        mujoco.mju_quat2Mat(R_parent_tcp, m.site_quat[tcp])
        R_parent_tcp = R_parent_tcp.reshape(3, 3)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, (R_parent_tcp @ T_tcp_object.rotation).ravel())
        return m.site_pos[tcp] + R_parent_tcp @ T_tcp_object.translation, quat

    def chain_reach(self, held_pos: np.ndarray) -> float:
        """:meth:`CollisionChecker.reach_m` with the held object's body at ``held_pos`` (3,) in its parent (m)."""
        m = self.model
        body_pos = m.body_pos.copy()
        body_pos[self.held_body] = held_pos
        offset = np.linalg.norm(body_pos, axis=1) + self._slide_travel
        chain = np.zeros(m.nbody)
        for b in self._chain_order:  # the robot's bodies after the base; MuJoCo numbers a body after its parent
            chain[b] = chain[m.body_parentid[b]] + offset[b]
        g = self._robot_geoms
        return float(np.max(chain[m.geom_bodyid[g]] + np.linalg.norm(m.geom_pos[g], axis=1) + m.geom_rbound[g]
                            + m.geom_margin[g]))

    def reach(self, held_pos: np.ndarray) -> float:
        """The culling bound (m): :meth:`chain_reach` plus the largest margin (remembered per held position)."""
        key = held_pos.tobytes()
        if key not in self._reach:
            if len(self._reach) >= _VARIANTS:
                self._reach.pop(next(iter(self._reach)))
            self._reach[key] = self.chain_reach(held_pos) + self._max_margin
        return self._reach[key]

    def variant(self, held: tuple[np.ndarray, np.ndarray], far: np.ndarray) -> mujoco.MjModel:
        """The shared model with the held object's body at ``held`` (position (3,), quaternion (4,) in its parent)
        and the collisions of the bodies ``far`` (nbody,) bool switched off; made on first use, never written
        after."""
        key = held[0].tobytes() + held[1].tobytes() + np.packbits(far).tobytes()
        m = self._variants.get(key)
        if m is not None:
            self._variants.move_to_end(key)
            return m
        m = copy.deepcopy(self.model)
        m.body_pos[self.held_body], m.body_quat[self.held_body] = held
        if far.any():
            off = far[m.geom_bodyid]
            _body_bits(m, np.where(off, 0, self.contype), np.where(off, 0, self.conaffinity))
        self._variants[key] = m
        if len(self._variants) > _VARIANTS:
            self._variants.popitem(last=False)
        return m


_TOKENS = itertools.count()


class _SharedData:
    """One ``MjData`` for all the checkers of one compiled checker model in one thread (making one costs about
    0.3 ms, more than the rest of a checker): a checker loads its own state into it (the poses of what is not the
    arm, the fingers; ``qpos``, ``mocap_pos`` and ``mocap_quat``) whenever another checker used it last, a few
    microseconds. Every model a family derives from the compiled model has its sizes."""

    def __init__(self, m: mujoco.MjModel) -> None:
        self.d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, self.d, 0)
        self.qpos0, self.mocap_pos0, self.mocap_quat0 = (self.d.qpos.copy(), self.d.mocap_pos.copy(),
                                                         self.d.mocap_quat.copy())
        # whose state the data holds: a checker's token, not the checker (a reference would make a cycle that keeps a
        # scene's checkers, models and data alive until the cyclic garbage collector runs, long after the episode)
        self.owner: int | None = None


@functools.lru_cache(maxsize=16)
def _shared_data(world: SceneConfig, held: ObjectConfig, thread: int) -> _SharedData:
    """The :class:`_SharedData` of the checker model of a scene and held object, for the thread ``thread``."""
    return _SharedData(_checker_model(world, held))


_VARIANTS = 8
"""Variants of a checker model kept per family (held poses and sets of far bodies): a task re-aims a checker at a
few grasps at a time; an older variant stays alive for as long as a checker uses it."""


def _body_bits(m: mujoco.MjModel, contype: np.ndarray, conaffinity: np.ndarray) -> None:
    """Write the geoms' collision bits (ngeom,) into ``m`` and each body's OR of its geoms' bits, which the broad
    phase filters body pairs by (computed at compile time, so redone here)."""
    m.geom_contype[:] = contype
    m.geom_conaffinity[:] = conaffinity
    for bits, out in ((contype, m.body_contype), (conaffinity, m.body_conaffinity)):
        acc = np.zeros(m.nbody, dtype=bits.dtype)
        np.bitwise_or.at(acc, m.geom_bodyid, bits)
        out[:] = acc


@functools.lru_cache(maxsize=32)
def _model_family(world: SceneConfig, scene: SceneConfig, object_body: str, policy: CollisionPolicy) -> _ModelFamily:
    """The :class:`_ModelFamily` of a scene (``world``, the one the simulation was built from), the pick and place
    worked on (``scene``: its object is the one carried, its support a surface), the resting object's body and a
    policy whose ``finger_m`` is 0 (the fingers are state, not model); made once per process and kept for the last
    32 such combinations."""
    return _ModelFamily(world, scene, object_body, policy)


HELD_PREFIX = "held_"
"""Prefix of the checker model's geoms that are the object while it is carried (in the body ``held_object``)."""


@functools.lru_cache(maxsize=16)
def _checker_model(scene: SceneConfig, held: ObjectConfig) -> mujoco.MjModel:
    """The scene compiled with a copy of the object ``held`` welded to the tcp's body (compiled once per scene and
    object).

    The seen-obstacle columns collide here (in the simulation they do not exist). Nothing else that collides
    changes: the qpos and mocap layouts are the simulation's, so world states carry over. Each
    :class:`_ModelFamily` works on its own deep copy (it edits the collision bits, the margins and the held
    object's pose).
    """
    spec = scene_spec(scene)
    for name in SEEN_OBSTACLE_NAMES:  # the obstacles the robot has seen take part here (as the map's do)
        column = spec.geom(name)
        column.contype, column.conaffinity = 1, 1
    tcp_body = spec.site("tcp").parent
    body = tcp_body.add_body(name=HELD_PREFIX + "object")
    add_object_geoms(spec, body, held, contact=False, prefix=HELD_PREFIX)
    # No textures: nothing renders this model, and they were most of its compile time (27 -> 4 ms) and of its
    # size (5 MB -> 0.1 MB), which every copy of it paid for.
    for material in spec.materials:
        material.textures = [""] * len(material.textures)
    for texture in list(spec.textures):
        spec.delete(texture)
    with quiet_attach():
        return spec.compile()
