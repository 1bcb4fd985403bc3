"""Joint configurations for the tcp targets of a pick and place, each solved by IK and checked for collisions.

The grasps come from the object's own geometry (:mod:`pickplace.grasping.synthesis`), placed where the object
is and filtered against the table (:func:`candidate_grasps`), and ranked by the cost of
:class:`~pickplace.grasping.synthesis.RankWeights`: the force-closure margin of the two pads, the centre of
mass's distance from the grip axis, top-down before tilted before side approaches, and how far the wrist must
turn from its ``home`` orientation turned to face the object (a proxy for the joint-space distance that costs no
IK). Clearance from the obstacles and reachability are what the IK below checks.

Grasps are tried in that order until one works (at most ``max_grasps``). For each, the chain follows the
motion: ``pregrasp`` is solved from ``home``, ``grasp`` from ``pregrasp`` (so the straight approach stays on
one IK branch), ``lift`` from ``grasp``, ``preplace`` from ``lift`` and ``place`` from ``preplace``. Each is
checked with the collision policy of the moment it is reached: open gripper around the resting object at the
grasp, the object carried at ``lift``, ``preplace`` and ``place`` (where it may touch the table).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import UnreachableTarget
from pickplace.grasping.synthesis import GraspCandidate, RankWeights, rank, synthesize, world_candidates
from pickplace.grasping.targets import (
    CLEARANCE_M,
    LIFT_STEP_M,
    MAX_RAISE_M,
    GraspTargets,
    grasp_targets,
    raised,
    wrist_reference,
)
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.robot.gripper import GripperGeometry
from pickplace.robot.ik import IKConfig, IKResult, solve_ik
from pickplace.robot.kinematics import frame_pose, rot_z, rotation_distance
from pickplace.robot.model import Robot
from pickplace.world.objects import ObjectConfig

#: Below this distance (m) the lift target is the pregrasp (a top-down grasp): it is not solved twice.
_SAME_POSE_M = 1e-6
#: Most grasps tried (in ranked order) before the object is declared out of reach.
MAX_GRASPS = 64


@dataclass(frozen=True)
class GraspConfigurations:
    """IK solutions of the targets of the grasp that worked.

    Attributes:
        targets: The tcp poses they reach.
        pregrasp, grasp, lift, preplace, place: The IK results (``.q`` is the arm configuration (6,) in rad).
        held_finger_m: Finger travel while the object is held (m).
        grasps_tried: How many grasps were tried before this one worked (1: the first).
    """

    targets: GraspTargets
    pregrasp: IKResult
    grasp: IKResult
    lift: IKResult
    preplace: IKResult
    place: IKResult
    held_finger_m: float
    chosen: GraspCandidate
    grasps_tried: int = 1

    def results(self) -> list[IKResult]:
        """The results in visiting order (the lift only if it is not the pregrasp, as for a top-down grasp)."""
        lift = [] if self.lift is self.pregrasp else [self.lift]
        return [self.pregrasp, self.grasp, *lift, self.preplace, self.place]

    def carrying_checker(self, robot: Robot, margin_m: float, allow_object_table: bool = False) -> CollisionChecker:
        """A checker for the arm carrying the object as grasped here (see :func:`carrying_checker`)."""
        return carrying_checker(robot, self.targets.T_tcp_object, self.held_finger_m, margin_m, allow_object_table)


def carrying_checker(
    robot: Robot,
    T_tcp_object: pin.SE3,
    finger_m: float,
    margin_m: float,
    allow_object_table: bool = False,
) -> CollisionChecker:
    """A collision checker for the arm carrying the object, held at ``T_tcp_object``.

    Args:
        robot: The models.
        T_tcp_object: The object's pose in the tcp frame.
        finger_m: Finger travel while holding it (m).
        margin_m: Safety margin to the table, floor and obstacles (m).
        allow_object_table: Whether the object may touch the table (setting it down).
    """
    policy = CollisionPolicy(margin_m=margin_m, object_held=True, allow_object_table=allow_object_table,
                             finger_m=finger_m)
    return CollisionChecker(robot, policy, T_tcp_object=T_tcp_object)


def home_tcp(robot: Robot) -> pin.SE3:
    """The tcp's pose at the ``home`` keyframe."""
    return frame_pose(robot.pin, robot.pin.createData(), robot.pin_q(robot.home_q), robot.pin_tcp_frame)


def start_pose(robot: Robot) -> pin.SE3:
    """The object's pose at the start of the scene (resting, turned by the start yaw)."""
    scene = robot.scene
    return pin.SE3(rot_z(scene.start_yaw_rad), scene.start_pos_m)


@functools.lru_cache(maxsize=32)
def object_grasps(obj: ObjectConfig, gripper: GripperGeometry) -> tuple[GraspCandidate, ...]:
    """Every grasp of ``obj`` in its resting frame that fits ``gripper`` (:func:`synthesis.synthesize
    <pickplace.grasping.synthesis.synthesize>`, cached per object and gripper)."""
    return synthesize(obj, gripper)


def candidate_grasps(robot: Robot, T_world_object: pin.SE3, weights: RankWeights | None = None
                     ) -> list[GraspCandidate]:
    """Grasps of the object where it rests (on any face), clear of the table, best first.

    Args:
        robot: The models (the scene's object and table).
        T_world_object: The object's pose.
        weights: The ranking's weights (default :class:`~pickplace.grasping.synthesis.RankWeights`).
    """
    scene, geom = robot.scene, GripperGeometry.measure(robot)
    placed = world_candidates(object_grasps(scene.object, geom), geom, T_world_object, scene.table_height_m)
    ref = wrist_reference(home_tcp(robot), T_world_object.translation[:2])
    return list(rank([w.candidate for w in placed], weights, reference=T_world_object.rotation.T @ ref))


def solve_grasp_configurations(
    robot: Robot,
    ik_config: IKConfig | None = None,
    T_world_object: pin.SE3 | None = None,
    world: mujoco.MjData | None = None,
    clearance_m: float = 0.0,
    grasps: Sequence[GraspCandidate] | None = None,
    max_grasps: int = MAX_GRASPS,
) -> GraspConfigurations:
    """Targets for the scene's object and goal, solved to joint configurations with the first grasp that works.

    Args:
        robot: The models.
        ik_config: IK settings.
        T_world_object: The object's pose; default: its start in the scene.
        world: The simulation state the solutions must be collision free in (where the object rests, anything
            that moved); default: the scene's initial state.
        clearance_m: Clearance the pregrasp, lift and preplace configurations must keep from the table, floor
            and obstacles (m), e.g. the planner's margin so that it accepts them as goals. The grasp and the
            place are checked at contact (the fingers work 5 mm above the table).
        grasps: The grasps to try, in order; default: :func:`candidate_grasps`.
        max_grasps: Most grasps tried.

    Raises:
        UnreachableTarget: no grasp reaches every target collision free (the first grasp's failure is named),
            or none fits the gripper and clears the table where the object rests.
    """
    T_world_object = start_pose(robot) if T_world_object is None else T_world_object
    geom = GripperGeometry.measure(robot)
    T_home = home_tcp(robot)
    grasps = (candidate_grasps(robot, T_world_object) if grasps is None else list(grasps))[:max_grasps]
    if not grasps:
        raise UnreachableTarget("grasp", f"no grasp of the {robot.scene.object.name} fits the gripper and clears "
                                         "the table where it rests")
    free = CollisionChecker(robot, CollisionPolicy(margin_m=0.0))
    above = CollisionChecker(robot, CollisionPolicy(margin_m=clearance_m))
    for checker in (free, above):
        if world is not None:
            checker.set_world(world)
    first_error: UnreachableTarget | None = None
    for tried, grasp in enumerate(grasps, start=1):
        targets = grasp_targets(robot.scene, T_world_object, grasp.T_object_tcp, grasp.width_m, T_home)
        held = geom.contact_travel_m(grasp.width_m)
        carry = carrying_checker(robot, targets.T_tcp_object, held, margin_m=clearance_m)
        place = carrying_checker(robot, targets.T_tcp_object, held, margin_m=0.0, allow_object_table=True)
        if world is not None:
            for checker in (carry, place):
                checker.set_world(world)
        try:
            targets, results = _solve_chain(robot, targets, ik_config, free, above, carry, place)
        except UnreachableTarget as exc:
            first_error = first_error or exc
            continue
        return GraspConfigurations(targets, *results, held_finger_m=held, chosen=grasp, grasps_tried=tried)
    assert first_error is not None
    if len(grasps) == 1:
        raise first_error
    raise UnreachableTarget(first_error.target, f"{first_error.reason} (and {len(grasps) - 1} other grasps failed)",
                            first_error.position_error_m, first_error.orientation_error_rad)


def _solve_chain(robot: Robot, targets: GraspTargets, ik_config: IKConfig | None, free: CollisionChecker,
                 above: CollisionChecker, carry: CollisionChecker, place: CollisionChecker
                 ) -> tuple[GraspTargets, list[IKResult]]:
    """IK of pregrasp, grasp, lift, place and preplace, each from the previous one, each checked.

    The lift and the preplace are raised in ``LIFT_STEP_M`` steps (up to ``MAX_RAISE_M``) while the carried
    object is within the margin of something there (an object beside a wall is lifted above it).
    """
    def solve(name: str, target: pin.SE3, q0: np.ndarray, checker: CollisionChecker) -> IKResult:
        try:
            return solve_ik(robot, target, q0, name, ik_config, checker.is_valid)
        except UnreachableTarget as exc:
            raise _with_collisions(exc, checker, robot, target, q0, ik_config) from None

    def solve_raised(name: str, base: pin.SE3, q0: np.ndarray) -> tuple[float, IKResult]:
        heights = np.arange(CLEARANCE_M, MAX_RAISE_M + 1e-9, LIFT_STEP_M)
        first: UnreachableTarget | None = None
        for h in heights:
            try:
                return float(h), solve(name, raised(base, float(h)), q0, carry)
            except UnreachableTarget as exc:
                if "collision" not in exc.reason:  # out of reach: higher is no better
                    raise
                first = first or exc
        assert first is not None
        raise UnreachableTarget(first.target, f"{first.reason} (also raised up to {MAX_RAISE_M:.2f} m)",
                                first.position_error_m, first.orientation_error_rad)

    pre = solve("pregrasp", targets.pregrasp, robot.home_q, above)
    grasp = solve("grasp", targets.grasp, pre.q, free)
    lift_target = raised(targets.grasp, CLEARANCE_M)
    same = (np.linalg.norm(lift_target.translation - targets.pregrasp.translation) < _SAME_POSE_M
            and rotation_distance(lift_target.rotation, targets.pregrasp.rotation) < 1e-9)
    lift_m, lift = (CLEARANCE_M, pre) if same else solve_raised("lift", targets.grasp, grasp.q)
    placed_at = targets.place
    preplace_m, preplace = solve_raised("preplace", placed_at, lift.q)
    placed = solve("place", placed_at, preplace.q, place)
    return targets.raised_by(lift_m, preplace_m), [pre, grasp, lift, preplace, placed]


def _with_collisions(exc: UnreachableTarget, checker: CollisionChecker, robot: Robot, target, q0,
                     ik_config: IKConfig | None) -> UnreachableTarget:
    """Add the colliding geoms to an IK failure caused by collisions."""
    if "collision" not in exc.reason:
        return exc
    q = solve_ik(robot, target, q0, exc.target, ik_config).q
    pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(q))
    return UnreachableTarget(exc.target, f"{exc.reason}; colliding: {pairs}", exc.position_error_m,
                             exc.orientation_error_rad)
