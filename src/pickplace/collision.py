"""Is an arm configuration valid in the scene? Built on MuJoCo's own collision detection.

A :class:`CollisionChecker` owns a private copy of the scene's ``MjModel`` (so the simulation is never
touched) in which every robot geom carries a safety margin: MuJoCo then reports a contact for any pair
closer than the margin, and every reported contact that the checker's policy does not allow is a
collision. It covers the robot against the table, floor and obstacles, robot self-collision (MuJoCo's
parent-child filter excludes adjacent links), the gripper against the cube (unless allowed), and, while the
cube is carried, the cube moving rigidly with the tcp.
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.config import check_range
from pickplace.errors import CollisionError
from pickplace.model import Robot

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CollisionPolicy:
    """What the checker counts as a collision.

    Attributes:
        margin_m: Safety margin (m): the robot (and the carried cube) closer than this to the table, the
            floor or an obstacle counts as colliding; 0 means actual contact. Self-collision is checked at
            actual contact.
        cube_held: The cube is carried: it moves rigidly with the tcp (see ``T_tcp_cube``) and its contacts
            with the table, the floor, obstacles and the arm are collisions.
        allow_gripper_cube: Contacts between the gripper (pads, fingers) and the cube are allowed
            (grasping, carrying, releasing).
        allow_cube_table: Contacts between the cube and the table are allowed (the cube resting, or being
            set down).
        finger_m: Finger opening used for the check (m of slide travel; 0 = fully open).
    """

    margin_m: float = 0.01
    cube_held: bool = False
    allow_gripper_cube: bool = False
    allow_cube_table: bool = True
    finger_m: float = 0.0

    def __post_init__(self) -> None:
        check_range("collision.margin_m", self.margin_m, 0.0, 0.1, unit="m")
        check_range("collision.finger_m", self.finger_m, 0.0, 0.040, unit="m")


class CollisionChecker:
    """Configuration validity for the arm in one scene under one :class:`CollisionPolicy`.

    Args:
        robot: The models.
        policy: What counts as a collision.
        world_qpos: Full MuJoCo qpos giving the pose of everything that is not the arm (the cube where it
            rests); default: the scene's initial state.
        T_tcp_cube: Pose of the cube in the tcp frame while it is held (default: centred, aligned).
    """

    def __init__(
        self,
        robot: Robot,
        policy: CollisionPolicy | None = None,
        world_qpos: np.ndarray | None = None,
        T_tcp_cube: pin.SE3 | None = None,
    ) -> None:
        self.robot = robot
        self.policy = policy or CollisionPolicy()
        self._m = _copy_model(robot.mj)
        self._d = mujoco.MjData(self._m)
        h = robot.handles
        if world_qpos is None:
            mujoco.mj_resetDataKeyframe(self._m, self._d, 0)
        else:
            self._d.qpos[:] = world_qpos
        self._d.qpos[h.finger_qpos] = self.policy.finger_m
        self._T_tcp_cube = T_tcp_cube or pin.SE3.Identity()
        self.checks = 0

        m = self._m
        robot_geoms = np.isin(m.geom_bodyid, list(h.robot_bodies))
        gripper_geoms = np.isin(m.geom_bodyid, list(h.gripper_bodies))
        cube_geoms = m.geom_bodyid == h.cube_body
        table_geoms = m.geom_bodyid == mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "table")
        # MuJoCo uses the larger margin of a pair: margins on the environment (and on the carried cube) keep
        # the robot clear of them, while robot self-collision is checked at actual contact (adjacent housings
        # of the UR5e sit closer than any useful margin).
        env_geoms = ~robot_geoms & ~cube_geoms
        m.geom_margin[env_geoms] = self.policy.margin_m
        if self.policy.cube_held:
            m.geom_margin[cube_geoms] = self.policy.margin_m
        # allowed[g1, g2]: contacts between these geoms are not collisions
        allowed = np.zeros((m.ngeom, m.ngeom), dtype=bool)
        if self.policy.allow_gripper_cube or self.policy.cube_held:
            allowed[np.ix_(gripper_geoms, cube_geoms)] = True
        if self.policy.allow_cube_table:
            allowed[np.ix_(cube_geoms, table_geoms)] = True
        if not self.policy.cube_held:
            # a cube left on the table may touch only the table; its other contacts are not the arm's concern
            allowed[np.ix_(cube_geoms, ~robot_geoms)] = True
        self._allowed = allowed | allowed.T

    # ------------------------------------------------------------------ #
    def _place(self, q: np.ndarray) -> None:
        h = self.robot.handles
        d = self._d
        d.qpos[h.arm_qpos] = q
        mujoco.mj_kinematics(self._m, d)
        if self.policy.cube_held:
            T_world_tcp = pin.SE3(d.site_xmat[h.tcp_site].reshape(3, 3), d.site_xpos[h.tcp_site])
            T_world_cube = T_world_tcp * self._T_tcp_cube
            d.qpos[h.cube_qpos:h.cube_qpos + 3] = T_world_cube.translation
            d.qpos[h.cube_qpos + 3:h.cube_qpos + 7] = pin.Quaternion(T_world_cube.rotation).coeffs()[[3, 0, 1, 2]]
            mujoco.mj_kinematics(self._m, d)
        mujoco.mj_collision(self._m, d)
        self.checks += 1

    def _bad_contacts(self) -> np.ndarray:
        n = self._d.ncon
        if n == 0:
            return np.zeros((0, 2), dtype=int)
        g = self._d.contact.geom[:n]
        return g[~self._allowed[g[:, 0], g[:, 1]]]

    def is_valid(self, q: np.ndarray) -> bool:
        """True if the arm configuration (6,) (rad) is collision free under the policy."""
        self._place(q)
        return len(self._bad_contacts()) == 0

    def are_valid(self, qs: np.ndarray) -> np.ndarray:
        """Validity of a batch of configurations (N, 6) (rad) -> bool (N,)."""
        qs = np.atleast_2d(qs)
        out = np.empty(len(qs), dtype=bool)
        for i, q in enumerate(qs):
            self._place(q)
            out[i] = len(self._bad_contacts()) == 0
        return out

    def colliding_pairs(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Names of the geom pairs in collision at ``q`` (6,) (sorted, without repeats)."""
        self._place(q)
        m = self._m
        pairs = {tuple(sorted((m.geom(int(a)).name or f"geom{a}", m.geom(int(b)).name or f"geom{b}")))
                 for a, b in self._bad_contacts()}
        return sorted(pairs)  # type: ignore[arg-type]

    def require_valid(self, q: np.ndarray, what: str) -> None:
        """Raise :class:`CollisionError` naming the geoms if ``q`` is in collision."""
        pairs = self.colliding_pairs(q)
        if pairs:
            raise CollisionError(what, pairs)


def _copy_model(m: mujoco.MjModel) -> mujoco.MjModel:
    """An independent copy of ``m`` (margins are edited on it)."""
    return copy.deepcopy(m)
