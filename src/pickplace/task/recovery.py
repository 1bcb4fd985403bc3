"""What a failed phase can do about it: the recovery table, and the budget of retries.

A failure is recovered only when its cause may be transient and something can be done about it:

====================================  ===============================  ============================================
failure                               in                               recovery
====================================  ===============================  ============================================
collision predicted ahead             a running trajectory             stop, plan again from where the arm stands
the arm touched the world             a running trajectory             back off along the executed path, replan
slip, the pads still squeezing it     EXEC_TRANSPORT, DESCEND_PLACE    stop, take the grip as it now is, plan the
                                                                       transport or aim the set-down again (once;
                                                                       then as below)
slip, lost grip                       CLOSE … DESCEND_PLACE            stop, set it down where the pads still
                                                                       touch it and the way down is free, open,
                                                                       back off, re-observe, regrasp
the held object hit the world         CLOSE … DESCEND_PLACE            the same (the robot itself touched nothing)
the object moved before the grasp     EXEC_APPROACH, DESCEND           wait for it to rest, re-observe, approach
the grasp missed, or hit the object   DESCEND                          back off, re-observe, approach again
no (timed) path to the pregrasp       PLAN_APPROACH                    the next grasp in the ranking (a fallback)
no path (or no place) with the        PLAN_TRANSPORT, at the lift      set it back down where it was picked, let
object as it sits in the hand                                          go, and take the next grasp
====================================  ===============================  ============================================

Everything else fails the episode with its phase and reason. A failure identical (numbers aside) to the one
the last recovery answered is not answered the same way again: recovering changed nothing, so the cause is not
transient (except a fallback to the next grasp, which changes the grasp). A slip in transit is first answered
by carrying on with the grip as it has become (a carried object that crept a few millimetres in the pads while
the hand turned is still held; opening the hand there drops it wherever the arm is, off the table behind the
base as often as not); the same slip again lets go and grasps again.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass

from pickplace.errors import GraspFailed, PickPlaceError, PlanningFailed, TimingFailed, UnreachableTarget
from pickplace.task.monitor import ObjectMoved, UnexpectedContact
from pickplace.task.phases import CollisionPredicted, Phase, PhaseFailed

#: Numbers in a failure message (ignored when comparing two failures).
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: Phases whose grasp failures are recovered by letting go and grasping again.
GRASP_PHASES = (Phase.CLOSE, Phase.LIFT, Phase.PLAN_TRANSPORT, Phase.EXEC_TRANSPORT, Phase.DESCEND_PLACE)
#: Where to go back to when a collision is predicted or met while a trajectory runs.
REPLAN = {Phase.EXEC_APPROACH: Phase.PLAN_APPROACH, Phase.EXEC_TRANSPORT: Phase.PLAN_TRANSPORT,
          Phase.RETRACT: Phase.RETRACT}

_REGRASP = "stop, open, back off, re-observe the object and grasp again"
#: A slip in these phases, the pads still squeezing the object, is answered by carrying on from this phase.
CARRY_ON = {Phase.EXEC_TRANSPORT: (Phase.PLAN_TRANSPORT, "stop, take the grip as it now is and plan the transport "
                                                         "again"),
            Phase.DESCEND_PLACE: (Phase.DESCEND_PLACE, "stop, take the grip as it now is and aim the set-down "
                                                       "again")}


class FirstMove(enum.Enum):
    """What the arm does at once, before the recovery's next phase."""

    NOTHING = "nothing"
    STOP = "stop"  # come to rest at the deceleration limits
    BACK_OFF = "back off"  # retrace the last 0.3 s of the running trajectory
    PUT_BACK = "put back"  # set the held object back down where it was picked (the lift reversed), let go, back off


@dataclass(frozen=True)
class Recovery:
    """How to recover from one failure.

    Attributes:
        action: What is done, in words (for the result's ``recoveries``).
        next_phase: The phase to continue with.
        first: What the arm does at once.
        next_grasp: The grasp in use is dropped: the next phase chooses another.
        regrip: The held object's grip as it is now becomes the reference for slip (before the first move).
    """

    action: str
    next_phase: Phase
    first: FirstMove = FirstMove.NOTHING
    next_grasp: bool = False
    regrip: bool = False


def recovery_for(phase: Phase, exc: PickPlaceError, touches_object: bool, still_held: bool = False,
                 at_lift: bool = False) -> Recovery | None:
    """The recovery from ``exc`` raised in ``phase``, or None if it is not recoverable.

    Args:
        phase: The phase that failed.
        exc: Its failure.
        touches_object: For an :class:`UnexpectedContact`: whether every contact involves the object.
        still_held: For a :class:`GraspFailed`: whether the robot senses the object still squeezed by both pads
            (and carried), and has not carried on after a slip already.
        at_lift: The arm holds the object where the lift left it, straight above where it was picked.
    """
    contact = isinstance(exc, UnexpectedContact)
    if isinstance(exc, GraspFailed) and phase in CARRY_ON and still_held:
        next_phase, action = CARRY_ON[phase]
        return Recovery(action, next_phase, FirstMove.STOP, regrip=True)
    if isinstance(exc, CollisionPredicted) and phase in REPLAN:
        return Recovery("stop and replan", REPLAN[phase], FirstMove.STOP)
    if contact and phase in REPLAN and not touches_object:
        return Recovery("back off along the executed path and replan", REPLAN[phase], FirstMove.BACK_OFF)
    if isinstance(exc, GraspFailed) and phase in GRASP_PHASES:
        return Recovery(_REGRASP, Phase.RECOVER)
    if contact and phase in GRASP_PHASES and touches_object:
        return Recovery(_REGRASP, Phase.RECOVER)  # the held object hit the world: the robot touched nothing
    if isinstance(exc, ObjectMoved) and phase in (Phase.EXEC_APPROACH, Phase.DESCEND):
        return Recovery("stop, wait for the object to rest, observe it again and approach again", Phase.RECOVER)
    if phase is Phase.DESCEND and (isinstance(exc, PhaseFailed) or (contact and touches_object)):
        return Recovery("back off, re-observe the object and approach again", Phase.RECOVER)
    if isinstance(exc, (PlanningFailed, TimingFailed, UnreachableTarget)) and phase is Phase.PLAN_TRANSPORT \
            and at_lift:
        return Recovery("set it back down where it was picked, let go and take the next grasp", Phase.IDLE,
                        FirstMove.PUT_BACK, next_grasp=True)
    if isinstance(exc, (PlanningFailed, TimingFailed)) and phase is Phase.PLAN_APPROACH:
        return Recovery("drop this grasp and take the next one that solves", Phase.IDLE, next_grasp=True)
    return None


class RetryBudget:
    """How many recoveries are left, and whether a failure repeats the one the last recovery answered.

    Args:
        max_retries: Recoveries allowed (0: none).
    """

    def __init__(self, max_retries: int) -> None:
        self.max_retries = max_retries
        self.used = 0
        self.repeated = False  # the last refusal was a repeat of the failure before it
        self._last: tuple[Phase, str, str] | None = None

    def admits(self, phase: Phase, exc: PickPlaceError, may_repeat: bool = False, action: str = "") -> bool:
        """Whether a recovery ``action`` from ``exc`` in ``phase`` may be tried (retries left, and not the answer
        the same failure had last time unless ``may_repeat``: the recovery changes something a repeat does not
        show, e.g. the grasp)."""
        if self.used >= self.max_retries:
            return False
        if not may_repeat and self._signature(phase, exc, action) == self._last:
            self.repeated = True
            return False
        return True

    def spend(self, phase: Phase, exc: PickPlaceError, action: str = "") -> None:
        """Count a recovery ``action`` from ``exc`` in ``phase``."""
        self.used += 1
        self._last = self._signature(phase, exc, action)

    @staticmethod
    def _signature(phase: Phase, exc: PickPlaceError, action: str) -> tuple[Phase, str, str, str]:
        return phase, type(exc).__name__, _NUMBER.sub("#", str(exc)), action


__all__ = ["CARRY_ON", "GRASP_PHASES", "REPLAN", "FirstMove", "Recovery", "RetryBudget", "recovery_for"]
