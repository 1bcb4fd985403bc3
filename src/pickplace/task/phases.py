"""The vocabulary of a pick and place: its phases, the errors a phase raises, its settings and its record.

``IDLE → PLAN_APPROACH → EXEC_APPROACH → DESCEND → CLOSE → LIFT → PLAN_TRANSPORT → EXEC_TRANSPORT →
DESCEND_PLACE → RELEASE → RETRACT → DONE`` (or ``FAILED``, with the phase and a specific reason; ``RECOVER``
only after a failure that can be recovered).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

from pickplace.errors import PickPlaceError
from pickplace.motion import control
from pickplace.motion.limits import LimitReport
from pickplace.world.config import check_int, check_range


class Phase(enum.Enum):
    """The phases of a pick and place, in order (FAILED is terminal)."""

    IDLE = "IDLE"
    PLAN_APPROACH = "PLAN_APPROACH"
    EXEC_APPROACH = "EXEC_APPROACH"
    DESCEND = "DESCEND"
    CLOSE = "CLOSE"
    LIFT = "LIFT"
    PLAN_TRANSPORT = "PLAN_TRANSPORT"
    EXEC_TRANSPORT = "EXEC_TRANSPORT"
    DESCEND_PLACE = "DESCEND_PLACE"
    RELEASE = "RELEASE"
    RETRACT = "RETRACT"
    RECOVER = "RECOVER"  # only after a recoverable failure: stop, open, back off, re-observe the object
    DONE = "DONE"
    FAILED = "FAILED"


class PhaseFailed(PickPlaceError):
    """A phase's own success check failed.

    Attributes:
        phase: The phase that failed.
        reason: What was measured and what was required.
    """

    def __init__(self, phase: Phase, reason: str) -> None:
        self.phase = phase
        self.reason = reason
        super().__init__(f"{phase.value}: {reason}")


class CollisionPredicted(PickPlaceError):
    """The rest of the running trajectory would collide with the world as it is now (it changed).

    Attributes:
        pairs: The geom pairs that would collide first.
    """

    def __init__(self, pairs: list[tuple[str, str]], t_s: float, ahead_s: float) -> None:
        self.pairs = pairs
        names = ", ".join(f"{a} <-> {b}" for a, b in pairs) or "unknown geoms"
        super().__init__(f"collision predicted at t = {t_s:.3f} s, {ahead_s:.2f} s ahead: {names}")


@dataclass(frozen=True)
class MachineConfig:
    """Tolerances, timeouts and motion choices of the state machine (SI units).

    Attributes:
        planning_margin_m: Clearance the planner keeps from the table, floor and obstacles (m).
        close_timeout_s: Time allowed for the gripper to close and settle on the object (s).
        min_pad_force_n: Normal force each pad must press with for the grip to count (N).
        finger_settle_speed_m_s: Fingers slower than this count as settled (m/s).
        slip_tolerance_m: Largest allowed motion of the object in the tcp frame while it is held (m).
        release_timeout_s: Time allowed for the pads to open and clear the object (s).
        release_clearance_m: Gap between each pad and the object needed before retracting (m).
        object_rest_speed_m_s: The released object counts as resting below this speed (m/s).
        place_tolerance_xy_m: Largest horizontal distance of the placed object from the goal (m).
        place_tolerance_z_m: Largest height error of the placed object (m).
        place_tolerance_yaw_rad: Largest yaw error of the placed object (rad, modulo its symmetry).
        retract_height_m: Vertical retreat after the release, before returning home (m).
        settle_s: Hold at the end of each trajectory before the next phase (s).
        poll_s: Step of the loops that wait for the gripper (s).
        stable_after_release_s: After DONE, the simulation continues until this long after the release; the
            object must then still lie within ``place_tolerance_xy_m`` of the goal, or the episode fails (s).
        max_retries: Recoveries allowed per episode (regrasp, re-pick, replan); 0 turns recovery off. A
            failure identical (numbers aside) to the one the last recovery answered is not retried again.
        predict_period_s: While a trajectory runs, the rest of it is checked against the world as it is now
            this often (s); a predicted collision stops the arm and replans.
        object_settle_timeout_s: During a recovery, time allowed for the released object to come to rest (s).
        grip_safety_factor: Margin of the grip: the friction the object needs (its weight, and its inertia in a
            motion) times this must stay within what the pads give; an object whose weight alone needs more is
            rejected before the arm moves, and motions that carry it are slowed down until it holds.
    """

    planning_margin_m: float = 0.01
    close_timeout_s: float = 1.0
    min_pad_force_n: float = 2.0
    finger_settle_speed_m_s: float = 2e-3
    slip_tolerance_m: float = 0.003
    release_timeout_s: float = 1.0
    release_clearance_m: float = 0.002
    object_rest_speed_m_s: float = 0.002
    place_tolerance_xy_m: float = 0.003
    place_tolerance_z_m: float = 0.003
    place_tolerance_yaw_rad: float = 0.05
    retract_height_m: float = 0.06
    settle_s: float = 0.02
    poll_s: float = 0.01
    stable_after_release_s: float = 1.0
    max_retries: int = 3
    predict_period_s: float = 0.05
    object_settle_timeout_s: float = 2.0
    grip_safety_factor: float = 1.25

    def __post_init__(self) -> None:
        limits = {
            "planning_margin_m": (0.0, 0.1, "m"), "close_timeout_s": (0.01, 10.0, "s"),
            "min_pad_force_n": (0.0, 100.0, "N"), "finger_settle_speed_m_s": (1e-5, 1.0, "m/s"),
            "slip_tolerance_m": (1e-4, 0.05, "m"), "release_timeout_s": (0.01, 10.0, "s"),
            "release_clearance_m": (0.0, 0.03, "m"), "object_rest_speed_m_s": (1e-5, 1.0, "m/s"),
            "place_tolerance_xy_m": (1e-4, 0.1, "m"),
            "place_tolerance_z_m": (1e-4, 0.1, "m"), "place_tolerance_yaw_rad": (1e-4, math.pi / 4, "rad"),
            "retract_height_m": (0.0, 0.5, "m"), "settle_s": (0.0, 5.0, "s"), "poll_s": (0.001, 0.1, "s"),
            "stable_after_release_s": (0.0, 10.0, "s"), "predict_period_s": (0.001, 1.0, "s"),
            "object_settle_timeout_s": (0.01, 10.0, "s"), "grip_safety_factor": (1.0, 10.0, ""),
        }
        for name, (lo, hi, unit) in limits.items():
            object.__setattr__(self, name, check_range(f"machine.{name}", getattr(self, name), lo, hi, unit=unit))
        object.__setattr__(self, "max_retries", check_int("machine.max_retries", self.max_retries, 0, 20))


@dataclass(frozen=True)
class SegmentPlan:
    """How one joint-space segment was planned and timed.

    Attributes:
        name: ``"approach"``, ``"transport"`` or ``"return"``.
        plan_time_s: Wall time of planning (search + shortcut) (s).
        retime_time_s: Wall time of TOPP-RA (s).
        waypoints_raw: Waypoints of the tree path.
        waypoints_shortcut: Waypoints after shortcutting.
        cost_rad: Joint-space length after shortcutting (rad).
        duration_s: Duration of the timed trajectory (s).
        status: The planner's status (``direct``, ``solved``, ``refined``).
        slowdown: How many times slower than time-optimal it was run so that the grip holds (1: not slowed).
    """

    name: str
    plan_time_s: float
    retime_time_s: float
    waypoints_raw: int
    waypoints_shortcut: int
    cost_rad: float
    duration_s: float
    status: str
    slowdown: float = 1.0


@dataclass
class MachineOutcome:
    """Everything one run of the machine measured (filled in as the phases run).

    Attributes:
        phase: The final phase (DONE or FAILED).
        failure_phase: The phase that failed, or None.
        failure_reason: Why, with the numbers, or None.
        failure_kind: The exception class behind the failure (e.g. ``"UnreachableTarget"``), or None.
        phase_durations_s: Simulated time spent in each phase (s), in order.
        cycle_time_s: Simulated time from IDLE to DONE (s).
        segments: The planned segments.
        ik_position_error_m: Largest tcp position residual of the IK solutions (m).
        ik_orientation_error_rad: Largest tcp orientation residual of the IK solutions (rad).
        tracking: Tracking errors per phase, of every control loop that ran in it (trajectories, holds,
            Cartesian moves).
        tracking_total: The same over the whole episode.
        torque_saturation_events: Control steps with a clipped torque, all phases.
        grip_force_n: Sum of the pads' normal forces when the grip settled (N).
        lift_grip_force_n: Mean sum of the pads' normal forces while the object is lifted off the table (N).
        lift_load_n: Weight of the object as the pads measure it while lifting (N): ``g * sum(F_z) / sum(g + a_z)``
            over the airborne steps, with F_z the pads' vertical force on the object and a_z its measured
            acceleration. It equals m g when the pads alone hold the object.
        force_closure: Whether the settled grip was force closure (6D wrench test on the actual contacts).
        grasp_margin: Ferrari–Canny margin of that grip (normalized wrench units).
        grasp_approach: How the grasp that was executed last approaches the object (``top``, ``tilted``,
            ``side``; in the object's resting frame), or "" before one is chosen.
        grasp_tilt_rad: Its approach's angle from straight down (rad).
        grasp_width_m: The object's width between its pads (m).
        grasps_tried: Candidates tried (IK and collisions) before it was found, last time a grasp was chosen.
        slip_max_m: Largest motion of the object in the tcp frame while it was held (m).
        place_error_xy_m, place_error_z_m, place_error_yaw_rad: The object at rest after the release,
            relative to the goal (m, m, rad modulo 90 degrees).
        final_place_error_xy_m: Horizontal error ``stable_after_release_s`` after the release (m).
        unexpected_contacts: Geom pairs of unexpected contacts seen (empty on success).
        wall_plan_time_s: Wall time spent planning, IK and retiming (s).
        recoveries: One line per recovery: the failure that was caught and what was done about it.
        timeline: ``(phase, start_s, duration_s, outcome)`` of every phase run, in order; outcome is ``ok``,
            ``recovered`` (it failed and a recovery followed) or ``failed``. Phases repeat after a recovery.
        estimates: ``(phase, what, position_error_m, yaw_error_rad)`` of every estimate of the object's pose the
            robot took (``resting`` or ``in hand``), against the truth (which the robot never used).
        limits: Every physics step of the arm against its joint speed, acceleration and torque limits.
        approach_line_deviation_max_m: Largest distance of the tcp from the straight line of its final approach
            to the grasp (pregrasp to grasp), over every step of every DESCEND (m); NaN if none ran.
        place_line_deviation_max_m: The same for the set-down (preplace to place, as aimed), over every
            DESCEND_PLACE (m); NaN if none ran.
    """

    phase: Phase = Phase.IDLE
    failure_phase: Phase | None = None
    failure_reason: str | None = None
    failure_kind: str | None = None
    phase_durations_s: dict[str, float] = field(default_factory=dict)
    cycle_time_s: float = 0.0
    segments: list[SegmentPlan] = field(default_factory=list)
    ik_position_error_m: float = 0.0
    ik_orientation_error_rad: float = 0.0
    tracking: dict[str, control.PhaseTracking] = field(default_factory=dict)
    tracking_total: control.PhaseTracking = field(default_factory=control.PhaseTracking)
    torque_saturation_events: int = 0
    grip_force_n: float = 0.0
    lift_grip_force_n: float = 0.0
    lift_load_n: float = 0.0
    force_closure: bool = False
    grasp_margin: float = 0.0
    grasp_approach: str = ""
    grasp_tilt_rad: float = math.nan
    grasp_width_m: float = math.nan
    grasps_tried: int = 0
    slip_max_m: float = 0.0
    place_error_xy_m: float = math.nan
    place_error_z_m: float = math.nan
    place_error_yaw_rad: float = math.nan
    final_place_error_xy_m: float = math.nan
    unexpected_contacts: list[tuple[str, str]] = field(default_factory=list)
    wall_plan_time_s: float = 0.0
    recoveries: list[str] = field(default_factory=list)
    timeline: list[tuple[str, float, float, str]] = field(default_factory=list)
    estimates: list[tuple[str, str, float, float]] = field(default_factory=list)
    limits: LimitReport = field(default_factory=LimitReport)
    approach_line_deviation_max_m: float = math.nan
    place_line_deviation_max_m: float = math.nan


__all__ = ["CollisionPredicted", "MachineConfig", "MachineOutcome", "Phase", "PhaseFailed", "SegmentPlan"]
