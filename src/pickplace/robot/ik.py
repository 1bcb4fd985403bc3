"""Damped least-squares inverse kinematics for the tcp.

One iteration (the reference design's update)::

    dq = a * J^T (J J^T + lambda^2 I)^-1 e

with ``a = 0.5``, ``lambda^2 = 1e-4`` and ``e = [dp; log3(R_target R^T)]`` the world-aligned 6D error. A
solution is accepted only if it is within the joint limits and, when a validity check is given, collision
free; otherwise the solver restarts from seeded random perturbations of the initial guess before it gives
up with :class:`~pickplace.errors.UnreachableTarget`.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickplace.errors import UnreachableTarget
from pickplace.robot.kinematics import ARM_DOF, frame_jacobian, frame_pose, pose_error, wrap_to_pi
from pickplace.robot.model import Robot
from pickplace.world.config import check_int, check_range

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class IKConfig:
    """Settings of the DLS solver.

    Attributes:
        step: Step size ``a`` of each update (dimensionless, 0 < a <= 1).
        damping_sq: Damping ``lambda^2`` (m^2 / rad^2 mix, as the 6D error mixes them).
        tolerance: Convergence threshold on the norm of the 6D error.
        max_iterations: Iterations per attempt.
        restarts: Extra attempts from random perturbations of the initial guess.
        restart_spread_rad: Standard deviation of those perturbations (rad).
        seed: Seed of the perturbations (the solver is deterministic).
    """

    step: float = 0.5
    damping_sq: float = 1e-4
    tolerance: float = 1e-4
    max_iterations: int = 300
    restarts: int = 8
    restart_spread_rad: float = 0.5
    seed: int = 0

    def __post_init__(self) -> None:
        check_range("ik.step", self.step, 0.0, 1.0, lo_open=True)
        check_range("ik.damping_sq", self.damping_sq, 0.0, 1.0)
        check_range("ik.tolerance", self.tolerance, 1e-14, 1e-2)
        check_int("ik.max_iterations", self.max_iterations, 1, 100_000)
        check_int("ik.restarts", self.restarts, 0, 1000)
        check_range("ik.restart_spread_rad", self.restart_spread_rad, 0.0, 2 * np.pi, unit="rad")
        check_int("ik.seed", self.seed, 0)


class IKStatus(enum.Enum):
    """Outcome of one IK solve."""

    CONVERGED = "converged"
    NOT_CONVERGED = "not converged"
    JOINT_LIMITS = "outside joint limits"
    COLLISION = "in collision"


@dataclass(frozen=True)
class IKResult:
    """A solved (or best-effort) IK configuration.

    Attributes:
        name: Name of the target (for messages).
        q: Arm joint configuration (6,) (rad).
        position_error_m: Residual tcp position error (m).
        orientation_error_rad: Residual tcp orientation error (rad).
        iterations: DLS iterations spent over all attempts.
        attempts: Number of attempts (1 + restarts used).
        status: Why the solver stopped.
        path: For a straight move (:func:`solve_line`): the configurations it passes through (N, 6) (rad), its
            start and every waypoint to ``q``; None for a single target.
    """

    name: str
    q: np.ndarray
    position_error_m: float
    orientation_error_rad: float
    iterations: int
    attempts: int
    status: IKStatus
    path: np.ndarray | None = None

    @property
    def success(self) -> bool:
        """True when the solution converged, is within limits and (if checked) collision free."""
        return self.status is IKStatus.CONVERGED


def _wrap_near(q: np.ndarray, reference: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Shift each angle by multiples of 2 pi to the equivalent closest to ``reference`` within the limits.

    DLS may wind a joint by whole turns; the same pose with the least motion from the initial guess is
    what the planner should be asked to reach.
    """
    out = reference + wrap_to_pi(q - reference)
    out = np.where(out > upper, out - 2 * np.pi, out)
    return np.where(out < lower, out + 2 * np.pi, out)


def dls_iterate(
    robot: Robot,
    data: pin.Data,
    T_world_target: pin.SE3,
    q0: np.ndarray,
    config: IKConfig,
    finger_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Run DLS iterations from ``q0`` until the 6D error is below tolerance or the budget is spent.

    Returns:
        ``(q (6,), final 6D error (6,), iterations)``.
    """
    q = robot.pin_q(q0, finger_m)
    eye = np.eye(6) * config.damping_sq
    e = pose_error(frame_pose(robot.pin, data, q, robot.pin_tcp_frame), T_world_target)
    it = 0
    while it < config.max_iterations and np.linalg.norm(e) > config.tolerance:
        J = frame_jacobian(robot.pin, data, q, robot.pin_tcp_frame)
        q[:ARM_DOF] += config.step * (J.T @ np.linalg.solve(J @ J.T + eye, e))
        e = pose_error(frame_pose(robot.pin, data, q, robot.pin_tcp_frame), T_world_target)
        it += 1
    return q[:ARM_DOF].copy(), e, it


def solve_ik(
    robot: Robot,
    T_world_target: pin.SE3,
    q_init: np.ndarray,
    name: str = "target",
    config: IKConfig | None = None,
    is_valid: Callable[[np.ndarray], bool] | None = None,
    finger_m: float = 0.0,
) -> IKResult:
    """Solve for arm joints that put the tcp at ``T_world_target``.

    Args:
        robot: The models.
        T_world_target: Desired tcp pose in the world.
        q_init: Initial guess (6,) (rad); the solution tends to stay on its branch (elbow up/down...).
        name: Target name, used in the result and in errors.
        config: Solver settings (defaults: the reference design's a = 0.5, lambda^2 = 1e-4, tol 1e-4).
        is_valid: Optional collision check of an arm configuration; an invalid solution is rejected.
        finger_m: Finger opening used for the kinematics (m); it does not move the tcp.

    Returns:
        The converged :class:`IKResult`.

    Raises:
        UnreachableTarget: when no attempt converges to a valid solution; the message names the target, the
            residual and the reason (not converged, joint limits or collision).
    """
    config = config or IKConfig()
    data = robot.pin.createData()
    rng = np.random.default_rng(config.seed)
    q_init = np.asarray(q_init, dtype=float)
    best: IKResult | None = None
    total_it = 0
    for attempt in range(config.restarts + 1):
        q0 = q_init if attempt == 0 else q_init + rng.normal(0.0, config.restart_spread_rad, ARM_DOF)
        q, e, it = dls_iterate(robot, data, T_world_target, q0, config, finger_m)
        total_it += it
        q = _wrap_near(q, q_init, robot.arm_lower, robot.arm_upper)
        pos_err, rot_err = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
        if np.linalg.norm(e) > config.tolerance:
            status = IKStatus.NOT_CONVERGED
        elif np.any(q < robot.arm_lower) or np.any(q > robot.arm_upper):
            status = IKStatus.JOINT_LIMITS
        elif is_valid is not None and not is_valid(q):
            status = IKStatus.COLLISION
        else:
            status = IKStatus.CONVERGED
        result = IKResult(name, q, pos_err, rot_err, total_it, attempt + 1, status)
        if status is IKStatus.CONVERGED:
            log.debug("IK %s converged: %.2e m, %.2e rad, %d iterations", name, pos_err, rot_err, total_it)
            return result
        if best is None or pos_err + rot_err < best.position_error_m + best.orientation_error_rad:
            best = result
    assert best is not None
    p = T_world_target.translation
    raise UnreachableTarget(
        name,
        f"{best.status.value} after {config.restarts + 1} attempts for tcp at "
        f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m",
        best.position_error_m,
        best.orientation_error_rad,
    )


#: Spacing of the waypoints at which :func:`solve_line` solves and checks a straight tcp move (m).
LINE_STEP_M = 0.01
#: Largest joint change between two waypoints of a straight move (rad): more is a jump to another IK branch
#: (or a pass near a singularity) that the Cartesian controller, which moves continuously, would not make.
LINE_MAX_JUMP_RAD = 0.2


def solve_line(
    robot: Robot,
    T_world_target: pin.SE3,
    q_start: np.ndarray,
    name: str = "target",
    config: IKConfig | None = None,
    is_valid: Callable[[np.ndarray], bool] | None = None,
    finger_m: float = 0.0,
    step_m: float = LINE_STEP_M,
) -> IKResult:
    """Follow a straight tcp move from where ``q_start`` puts it to ``T_world_target``, the way the arm makes it.

    The Cartesian controller moves the tcp along the segment continuously from ``q_start``, so the joints it
    passes through are those that DLS finds from one waypoint to the next (every ``step_m`` along the segment,
    orientation interpolated on SO(3)), each from the previous solution with no restarts: the arm stays on its
    branch. Every waypoint must converge, stay within the joint limits, move no joint more than
    ``LINE_MAX_JUMP_RAD`` from the previous one, and pass ``is_valid``. An IK solve of the end alone (with
    restarts) can land on another branch and hide a collision half way.

    Args:
        robot: The models.
        T_world_target: The tcp's pose at the end of the move.
        q_start: The arm's configuration at its start (6,) (rad).
        name: The target's name, for the result and errors.
        config: Solver settings (its restarts are not used).
        is_valid: Collision check of each waypoint's configuration.
        finger_m: Finger opening for the kinematics (m).
        step_m: Waypoint spacing (m).

    Returns:
        The :class:`IKResult` at the end of the move (``iterations`` summed over the waypoints), with the
        waypoints' configurations in ``path`` (``q_start`` first).

    Raises:
        UnreachableTarget: a waypoint fails; the message says how far along the move (m) and why.
    """
    config = config or IKConfig()
    data = robot.pin.createData()
    q = np.asarray(q_start, dtype=float).copy()
    T0 = frame_pose(robot.pin, data, robot.pin_q(q, finger_m), robot.pin_tcp_frame)
    length = float(np.linalg.norm(T_world_target.translation - T0.translation))
    turn = pin.log3(T0.rotation.T @ T_world_target.rotation)
    n = max(1, int(np.ceil(length / step_m - 0.05)))  # steps up to 5% longer than step_m (IK residuals)
    total_it = 0
    e = np.zeros(6)
    path = [q.copy()]
    for k in range(1, n + 1):
        s = k / n
        T = pin.SE3(T0.rotation @ pin.exp3(s * turn), (1 - s) * T0.translation + s * T_world_target.translation)
        q_new, e, it = dls_iterate(robot, data, T, q, config, finger_m)
        total_it += it
        q_new = _wrap_near(q_new, q, robot.arm_lower, robot.arm_upper)
        why = None
        if np.linalg.norm(e) > config.tolerance:
            why = IKStatus.NOT_CONVERGED.value
        elif np.any(q_new < robot.arm_lower) or np.any(q_new > robot.arm_upper):
            why = IKStatus.JOINT_LIMITS.value
        elif float(np.max(np.abs(q_new - q))) > LINE_MAX_JUMP_RAD:
            why = (f"a joint jumps {float(np.max(np.abs(q_new - q))):.2f} rad in one {length / n * 1e3:.0f} mm step "
                   f"(limit {LINE_MAX_JUMP_RAD} rad: near a singularity)")
        elif is_valid is not None and not is_valid(q_new):
            why = IKStatus.COLLISION.value
        if why is not None:
            p = T.translation
            raise UnreachableTarget(
                name, f"the straight move to it is {why} {s * length:.3f} of {length:.3f} m along, with the tcp at "
                      f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m", float(np.linalg.norm(e[:3])),
                float(np.linalg.norm(e[3:])), q=q_new)
        q = q_new
        path.append(q.copy())
    waypoints = np.array(path)
    waypoints.setflags(write=False)
    return IKResult(name, q, float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:])), total_it, 1,
                    IKStatus.CONVERGED, waypoints)
