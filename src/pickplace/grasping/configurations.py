"""Joint configurations for the tcp targets of a pick and place, each solved by IK and checked for collisions.

The grasps come from the object's own geometry (:mod:`pickplace.grasping.synthesis`), placed where the object
is and filtered against the table (:func:`candidate_grasps`), and ranked by the cost of
:class:`~pickplace.grasping.synthesis.RankWeights`: the force-closure margin of the two pads, the centre of
mass's distance from the grip axis, top-down before tilted before side approaches, and how far the wrist must
turn from its ``home`` orientation turned to face the object (a proxy for the joint-space distance that costs no
IK). Clearance from the obstacles and reachability are what the IK below checks.

Grasps are tried in that order until one works (at most ``max_grasps``). For each, the targets are solved in
the order the arm visits them, each from the one before (see :class:`_Chain`): the moves the arm makes along
a straight line (approach, lift, set-down, retreat) are followed the way the controller makes them, waypoint
by waypoint, so a grasp whose approach sweeps the forearm through a wall, or whose lift leaves the carried
object beside one, is rejected here, before the arm moves, and the next grasp is tried.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.errors import TurnsOver, UnreachableTarget
from pickplace.grasping.grip import TURN_OVER_RAD, GripCapacity, carried_tilt_rad, grip_capacity, joint_line
from pickplace.grasping.synthesis import GraspCandidate, RankWeights, rank, synthesize, world_candidates
from pickplace.grasping.targets import (
    CLEARANCE_M,
    LIFT_STEP_M,
    MAX_RAISE_M,
    GraspTargets,
    backed_off,
    grasp_targets,
    raised,
    wrist_reference,
)
from pickplace.motion.collision import CollisionChecker, CollisionPolicy
from pickplace.robot.gripper import GripperGeometry
from pickplace.robot.ik import IKConfig, IKResult, solve_ik, solve_line
from pickplace.robot.kinematics import frame_jacobian, frame_pose, ik_branch, rot_z
from pickplace.robot.model import Robot
from pickplace.world.objects import ObjectConfig

log = logging.getLogger(__name__)

#: Most grasps tried (in ranked order) before the object is declared out of reach.
MAX_GRASPS = 64
#: Clearance the straight moves keep from walls, obstacles and the floor (m) (not from the table, which the
#: fingers reach down to): the Cartesian controller keeps the tcp within 0.5 mm of its line (the largest tcp
#: error of 200 episodes of the mixed obstacle campaign) and the line is checked every ``LINE_STEP_M``.
LINE_CUSHION_M = 0.003
#: How far the tcp backs off from the place along its approach after the release (m), by default
#: (``MachineConfig.retract_height_m``).
RETREAT_M = 0.06


@dataclass(frozen=True)
class GraspConfigurations:
    """IK solutions of the targets of the grasp that worked.

    Attributes:
        targets: The tcp poses they reach.
        pregrasp, grasp, lift, preplace, place, retreat: The IK results (``.q`` is the arm configuration (6,) in
            rad); ``retreat`` is where the hand ends after backing off from the place (and rising if needed).
        held_finger_m: Finger travel while the object is held (m).
        chosen: The grasp.
        grasps_tried: How many grasps were tried before this one worked (1: the first).
    """

    targets: GraspTargets
    pregrasp: IKResult
    grasp: IKResult
    lift: IKResult
    preplace: IKResult
    place: IKResult
    retreat: IKResult
    held_finger_m: float
    chosen: GraspCandidate
    grasps_tried: int = 1

    def results(self) -> list[IKResult]:
        """The results in visiting order."""
        return [self.pregrasp, self.grasp, self.lift, self.preplace, self.place, self.retreat]

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
    retreat_m: float = RETREAT_M,
    safety_factor: float | None = None,
    turn_over: bool = True,
) -> GraspConfigurations:
    """Targets for the scene's object and goal, solved to joint configurations with the first grasp that works.

    A grasp whose preplace the arm reaches only on another IK branch than its lift's would tilt the object on its
    side on the way there (:data:`~pickplace.grasping.grip.TURN_OVER_RAD`, measured along the straight joint
    line between the two): every grasp is tried with the object kept upright first, and such a grasp is taken only
    when none keeps it upright and ``turn_over`` allows it.

    Args:
        robot: The models.
        ik_config: IK settings.
        T_world_object: The object's pose; default: its start in the scene.
        world: The simulation state the solutions must be collision free in (where the object rests, anything
            that moved); default: the scene's initial state.
        clearance_m: Clearance the pregrasp, lift, preplace and retreat configurations must keep from the
            table, floor and obstacles (m), e.g. the planner's margin so that it accepts them as the ends of
            its paths. The straight moves between them keep ``LINE_CUSHION_M`` from walls and touch the table
            only where they must.
        grasps: The grasps to try, in order; default: :func:`candidate_grasps`.
        max_grasps: Most grasps tried.
        retreat_m: How far the tcp backs off from the place after the release (m).
        safety_factor: If given, grasps whose pads cannot hold the object's (believed) weight with this margin
            are skipped (:mod:`pickplace.grasping.grip`): a narrow grasp squeezes less.
        turn_over: Whether a grasp that turns the hand over on the way to the place may be taken, as a last
            resort (a caller with other places to try says no).

    Raises:
        CannotHold: ``safety_factor`` is given and no grasp's pads can hold the object (the strongest is named).
        UnreachableTarget: no grasp reaches every target collision free (the first grasp's failure is named),
            or none fits the gripper and clears the table where the object rests.
        TurnsOver: ``turn_over`` is False and the first grasp reaches the place only by turning the hand over
            (and no other grasp reaches it at all).
    """
    T_world_object = start_pose(robot) if T_world_object is None else T_world_object
    geom = GripperGeometry.measure(robot)
    T_home = home_tcp(robot)
    grasps = candidate_grasps(robot, T_world_object) if grasps is None else list(grasps)
    if grasps and safety_factor is not None:
        grasps = holdable(robot, grasps, safety_factor, T_world_object)
    grasps = grasps[:max_grasps]
    if not grasps:
        raise UnreachableTarget("grasp", f"no grasp of the {robot.scene.object.name} fits the gripper and clears "
                                         "the table where it rests")
    first_error: UnreachableTarget | None = None
    turning: list[tuple[int, GraspCandidate]] = []  # grasps that reach the place only by turning the hand over
    for upright in (True, False):
        chain = _Chain(robot, ik_config, world, clearance_m, retreat_m, upright)
        tries = list(enumerate(grasps, start=1)) if upright else turning
        for tried, grasp in tries:
            targets = grasp_targets(robot.scene, T_world_object, grasp.T_object_tcp, grasp.width_m, T_home)
            held = geom.contact_travel_m(grasp.width_m)
            try:
                targets, results = chain.solve(targets, held)
            except TurnsOver as exc:
                first_error = first_error or exc
                turning.append((tried, grasp))
                continue
            except UnreachableTarget as exc:
                first_error = first_error or exc
                continue
            if not upright:
                log.info("grasp %d reaches the place only by tilting the object on its side on the way (another IK "
                         "branch); no grasp keeps it upright", tried)
            return GraspConfigurations(targets, *results, held_finger_m=held, chosen=grasp, grasps_tried=tried)
        if not turn_over or not turning:
            break
    assert first_error is not None
    if len(grasps) == 1:
        raise first_error
    raise UnreachableTarget(first_error.target, f"{first_error.reason} (and {len(grasps) - 1} other grasps failed)",
                            first_error.position_error_m, first_error.orientation_error_rad)


def feasible_grasps(robot: Robot, grasps: Sequence[GraspCandidate], T_world_object: pin.SE3 | None = None,
                    clearance_m: float = 0.0, ik_config: IKConfig | None = None,
                    retreat_m: float = RETREAT_M) -> list[GraspCandidate]:
    """The grasps (in their order) that the arm can reach where the object rests: the pregrasp solves collision
    free and so does the straight approach from it to the grasp, each grasp on its own (the first two links of
    the chain :func:`solve_grasp_configurations` checks; the rest depends on the goal). Arguments as there."""
    T_world_object = start_pose(robot) if T_world_object is None else T_world_object
    T_home = home_tcp(robot)
    chain = _Chain(robot, ik_config, None, clearance_m, retreat_m)
    out = []
    for grasp in grasps:
        targets = grasp_targets(robot.scene, T_world_object, grasp.T_object_tcp, grasp.width_m, T_home)
        try:
            chain.reach(targets)
        except UnreachableTarget:
            continue
        out.append(grasp)
    return out


def holdable(robot: Robot, grasps: Sequence[GraspCandidate], safety_factor: float,
             T_world_object: pin.SE3) -> list[GraspCandidate]:
    """The grasps whose pads hold the object's believed weight with ``safety_factor``, in their order: the
    force along the pads and its torque about the closing axis (:class:`~pickplace.grasping.grip.GripCapacity`).

    Raises:
        CannotHold: none does; the grasp that comes closest is named with its forces (or torques).
    """
    obj, geom = robot.scene.object, GripperGeometry.measure(robot)
    capacities = [grip_capacity(robot, obj, g.T_object_tcp.inverse(), g.width_m, safety_factor,
                                up_tcp=(T_world_object * g.T_object_tcp).rotation[2], geom=geom) for g in grasps]
    kept = [g for g, c in zip(grasps, capacities, strict=True) if c.holds_at_rest]
    if not kept:
        def shortfall(c: GripCapacity) -> float:
            return max(c.needed_at_rest_n / c.friction_force_n if c.friction_force_n > 0 else math.inf,
                       c.needed_torque_at_rest_nm / c.torque_capacity_nm if c.torque_capacity_nm > 0 else math.inf)
        min(capacities, key=shortfall).require_holdable(obj.name)
    return kept


def _raise_steps(first_m: float) -> np.ndarray:
    """Heights tried for a rise that must end clear of everything: ``first_m`` then up in ``LIFT_STEP_M`` steps
    to ``MAX_RAISE_M`` (m)."""
    return np.concatenate([[first_m], np.arange(first_m + LIFT_STEP_M, MAX_RAISE_M + 1e-9, LIFT_STEP_M)])


class _Chain:
    """Solves the targets of one grasp in the order the arm visits them, each from the one before.

    ``pregrasp`` is solved from ``home`` (restarts allowed: a planned path leads there). The moves that the
    Cartesian controller makes along a straight line (the approach to the grasp, the lift, the set-down from
    the preplace, the retreat) are followed waypoint by waypoint from where they start
    (:func:`~pickplace.robot.ik.solve_line`), so that a collision half way, or a change of IK branch, fails
    the grasp here rather than the arm in the middle of the move. ``preplace`` is solved from ``lift``
    (a planned path leads there too).

    The collision policy of each: the open hand around the resting object on the approach; the object
    carried, allowed to touch the table, on the lift and the set-down; the open hand leaving the object
    at the goal on the retreat. The lift, the preplace and the retreat end where a planned path starts or
    ends, so they must clear the table, floor and obstacles by ``clearance_m``; the lift and the retreat rise
    (and the preplace is raised) in ``LIFT_STEP_M`` steps until they do (an object beside a wall is lifted
    above it).
    """

    def __init__(self, robot: Robot, ik_config: IKConfig | None, world: mujoco.MjData | None, clearance_m: float,
                 retreat_m: float, upright: bool = False) -> None:
        self.robot, self.ik, self.world, self.clearance_m, self.retreat_m = robot, ik_config, world, clearance_m, \
            retreat_m
        self.upright = upright
        self._data = robot.pin.createData()
        # Built once and re-aimed per grasp: the held object's pose and the fingers' opening change, the object
        # at the goal moves with the grasp's place orientation.
        self.above = self._checker(CollisionPolicy(margin_m=clearance_m))
        self.approach = self._checker(CollisionPolicy(margin_m=LINE_CUSHION_M, table_margin_m=0.0))
        self.lifting = self._checker(CollisionPolicy(margin_m=LINE_CUSHION_M, table_margin_m=0.0, object_held=True,
                                                     allow_object_table=True))
        self.carry = self._checker(CollisionPolicy(margin_m=clearance_m, object_held=True, allow_object_table=False))
        self.at_goal = _world_copy(robot, world)  # the object moves to the goal per grasp (solve)
        self.leaving = self._checker(CollisionPolicy(margin_m=LINE_CUSHION_M, table_margin_m=0.0,
                                                     allow_gripper_object=True))
        self.clear = self._checker(CollisionPolicy(margin_m=clearance_m, allow_gripper_object=True))

    def _checker(self, policy: CollisionPolicy) -> CollisionChecker:
        checker = CollisionChecker(self.robot, policy)
        if self.world is not None:
            checker.set_world(self.world)
        return checker

    def solve(self, targets: GraspTargets, held_m: float) -> tuple[GraspTargets, list[IKResult]]:
        """The IK results ``[pregrasp, grasp, lift, preplace, place, retreat]`` and the targets as raised."""
        robot = self.robot
        lifting, carry, leaving, clear = self.lifting, self.carry, self.leaving, self.clear
        for checker in (lifting, carry):
            checker.set_held(targets.T_tcp_object, held_m)
        R_goal = targets.R_world_object_goal
        _place_object(robot, self.at_goal, pin.SE3(R_goal, robot.scene.goal_resting_m(R_goal)))
        for checker in (leaving, clear):
            checker.set_world(self.at_goal)

        pre, grasp = self.reach(targets)
        lift_m, lift = self._rise("lift", targets.grasp, grasp, CLEARANCE_M, lifting, carry, held_m)
        first: UnreachableTarget | None = None
        for h in _raise_steps(CLEARANCE_M):  # the preplace: the lowest that is clear
            try:
                preplace = self._point("preplace", raised(targets.place, float(h)), lift.q, carry, held_m,
                                       upright_from=lift.q if self.upright else None)
            except UnreachableTarget as exc:
                if not isinstance(exc, TurnsOver) and "collision" not in exc.reason:
                    # out of reach: higher is no better; a lower failure says more
                    if first is None:
                        raise
                    raise type(first)(first.target, f"{first.reason} (and out of reach higher)",
                                      first.position_error_m, first.orientation_error_rad, first.q) from None
                first = first or exc
                continue
            preplace_m = float(h)
            break
        else:
            assert first is not None
            raise _raised_error(first)
        placed = self._line("place", targets.place, preplace.q, lifting, held_m)
        back = backed_off(targets.place, self.retreat_m)
        backed = self._line("retreat", back, placed.q, leaving)
        rise_m, retreat = self._rise("retreat", back, backed, 0.0, leaving, clear)
        return (targets.raised_by(lift_m, preplace_m, self.retreat_m, rise_m),
                [pre, grasp, lift, preplace, placed, retreat])

    def reach(self, targets: GraspTargets) -> tuple[IKResult, IKResult]:
        """The pregrasp (from ``home``) and the grasp at the end of the straight approach from it."""
        pre = self._point("pregrasp", targets.pregrasp, self.robot.home_q, self.above)
        return pre, self._line("grasp", targets.grasp, pre.q, self.approach)

    def _point(self, name: str, target: pin.SE3, q0: np.ndarray, checker: CollisionChecker,
               finger_m: float = 0.0, upright_from: np.ndarray | None = None) -> IKResult:
        """A target reached by a planned path: IK with restarts, checked.

        With ``upright_from`` (a configuration carrying the object), the solution must keep the object upright on
        the way from there (:meth:`_upright`): if the first one does not, IK from ``q0`` and from ``q0`` with the
        shoulder turned to face the target looks for one that does.

        Raises:
            UnreachableTarget: no collision-free solution.
            TurnsOver: there is one, but the object would be turned over on the way to it.
        """
        try:
            result = solve_ik(self.robot, target, q0, name, self.ik, checker.is_valid, finger_m)
        except UnreachableTarget as exc:
            if "collision" not in exc.reason:
                raise
            q = solve_ik(self.robot, target, q0, name, self.ik, None, finger_m).q
            raise _naming(exc, checker, q) from None
        if upright_from is None or self._upright(upright_from, result.q):
            return result
        once = dataclasses.replace(self.ik or IKConfig(), restarts=0)
        for seed in (q0, _facing(self.robot, q0, target)):
            try:
                return solve_ik(self.robot, target, seed, name, once,
                                lambda q: self._upright(upright_from, q) and checker.is_valid(q), finger_m)
            except UnreachableTarget:
                continue
        tilt = carried_tilt_rad(self.robot, joint_line(upright_from, result.q))
        raise TurnsOver(name, f"reachable collision free only on another IK branch than the lift's: the object "
                              f"would tilt {math.degrees(tilt):.0f} deg on the straight joint line there",
                        q=result.q)

    def _upright(self, q_from: np.ndarray, q: np.ndarray) -> bool:
        """Whether the arm carries the object from ``q_from`` to ``q`` on one IK branch
        (:func:`~pickplace.robot.kinematics.ik_branch`) and without tilting it more than :data:`TURN_OVER_RAD`
        on the straight joint line between them."""
        if self._branch(q_from) != self._branch(q):
            return False
        return carried_tilt_rad(self.robot, joint_line(q_from, q)) <= TURN_OVER_RAD

    def _branch(self, q: np.ndarray) -> tuple[int, int, int]:
        robot = self.robot
        return ik_branch(frame_jacobian(robot.pin, self._data, robot.pin_q(q), robot.pin_tcp_frame), q)

    def _line(self, name: str, target: pin.SE3, q0: np.ndarray, checker: CollisionChecker,
              finger_m: float = 0.0) -> IKResult:
        """A target reached by a straight move from ``q0``: followed waypoint by waypoint, each checked."""
        try:
            return solve_line(self.robot, target, q0, name, self.ik, checker.is_valid, finger_m)
        except UnreachableTarget as exc:
            if exc.q is None or "collision" not in exc.reason:
                raise
            raise _naming(exc, checker, exc.q) from None

    def _rise(self, name: str, base: pin.SE3, start: IKResult, first_m: float, line: CollisionChecker,
              end: CollisionChecker, finger_m: float = 0.0) -> tuple[float, IKResult]:
        """Rise straight up from ``base`` (reached at ``start``) to ``first_m`` and on, in ``LIFT_STEP_M``
        steps, until the configuration passes ``end``; the whole rise is one straight move checked with ``line``.

        Returns:
            The height risen (m) and the IK result there (``start`` itself if it passes at height 0).
        """
        result = start
        for h in _raise_steps(first_m):
            if h > 0.0:
                result = self._line(name, raised(base, float(h)), result.q, line, finger_m)
            if end.is_valid(result.q):
                return float(h), result
        raise _raised_error(_naming(UnreachableTarget(name, "in collision at the end of the rise"), end, result.q))


def _facing(robot: Robot, q: np.ndarray, target: pin.SE3) -> np.ndarray:
    """``q`` with the shoulder pan turned by the target's bearing from the tcp's at ``q`` (about the base's z)."""
    p = frame_pose(robot.pin, robot.pin.createData(), robot.pin_q(q), robot.pin_tcp_frame).translation
    t = target.translation
    out = np.array(q, dtype=float)
    out[0] += math.remainder(math.atan2(t[1], t[0]) - math.atan2(p[1], p[0]), 2 * math.pi)
    return out


def _raised_error(exc: UnreachableTarget) -> UnreachableTarget:
    return type(exc)(exc.target, f"{exc.reason} (also raised up to {MAX_RAISE_M:.2f} m)",
                             exc.position_error_m, exc.orientation_error_rad, exc.q)


def _naming(exc: UnreachableTarget, checker: CollisionChecker, q: np.ndarray) -> UnreachableTarget:
    """The failure with the colliding geoms at ``q`` named."""
    pairs = ", ".join(f"{a} <-> {b}" for a, b in checker.colliding_pairs(q))
    return UnreachableTarget(exc.target, f"{exc.reason}; colliding: {pairs}", exc.position_error_m,
                             exc.orientation_error_rad, q)


def _world_copy(robot: Robot, world: mujoco.MjData | None) -> mujoco.MjData:
    """A copy of ``world``'s positions (default: the scene's initial state), to move the object in."""
    d = mujoco.MjData(robot.mj)
    if world is None:
        mujoco.mj_resetDataKeyframe(robot.mj, d, 0)
    else:
        d.qpos[:], d.mocap_pos[:], d.mocap_quat[:] = world.qpos, world.mocap_pos, world.mocap_quat
    return d


def _place_object(robot: Robot, d: mujoco.MjData, T_world_object: pin.SE3) -> None:
    """Set the object's free joint in ``d`` to ``T_world_object``."""
    a = robot.handles.object_qpos
    d.qpos[a:a + 3] = T_world_object.translation
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T_world_object.rotation).ravel())
    d.qpos[a + 3:a + 7] = quat
