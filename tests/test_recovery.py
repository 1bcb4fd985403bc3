"""The recovery table and the retry budget (pickplace.task.recovery), and the grasp fallback in an episode."""

from __future__ import annotations

import numpy as np
import pytest

from pickplace.errors import GraspFailed, PlanningFailed, TimingFailed
from pickplace.motion.planning import PlannerConfig
from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.task.monitor import ObjectMoved, UnexpectedContact
from pickplace.task.phases import CollisionPredicted, Phase
from pickplace.task.recovery import FirstMove, RetryBudget, recovery_for


def test_the_table() -> None:
    hit = UnexpectedContact([("forearm_collision", "obstacle")], 1.0)
    r = recovery_for(Phase.EXEC_APPROACH, CollisionPredicted([("a", "b")], 1.0, 0.2), touches_object=False)
    assert r is not None and r.next_phase is Phase.PLAN_APPROACH and r.first is FirstMove.STOP
    r = recovery_for(Phase.EXEC_TRANSPORT, hit, touches_object=False)
    assert r is not None and r.next_phase is Phase.PLAN_TRANSPORT and r.first is FirstMove.BACK_OFF
    for phase in (Phase.CLOSE, Phase.LIFT, Phase.EXEC_TRANSPORT, Phase.DESCEND_PLACE):
        r = recovery_for(phase, GraspFailed("slipped"), touches_object=False)
        assert r is not None and r.next_phase is Phase.RECOVER
    assert recovery_for(Phase.RELEASE, GraspFailed("x"), touches_object=False) is None
    # a slip in transit while the pads still squeeze the object: carry on with the grip as it is (no drop)
    r = recovery_for(Phase.EXEC_TRANSPORT, GraspFailed("slipped"), touches_object=False, still_held=True)
    assert r is not None and r.regrip and r.next_phase is Phase.PLAN_TRANSPORT and r.first is FirstMove.STOP
    r = recovery_for(Phase.DESCEND_PLACE, GraspFailed("slipped"), touches_object=False, still_held=True)
    assert r is not None and r.regrip and r.next_phase is Phase.DESCEND_PLACE and r.first is FirstMove.STOP
    for phase in (Phase.CLOSE, Phase.LIFT):  # only once carried: before, it is let go and grasped again
        r = recovery_for(phase, GraspFailed("slipped"), touches_object=False, still_held=True)
        assert r is not None and not r.regrip and r.next_phase is Phase.RECOVER
    r = recovery_for(Phase.DESCEND, ObjectMoved("moved"), touches_object=False)
    assert r is not None and r.next_phase is Phase.RECOVER
    assert recovery_for(Phase.DESCEND, hit, touches_object=False) is None  # the arm hit the wall: not transient
    r = recovery_for(Phase.PLAN_APPROACH, PlanningFailed("no path"), touches_object=False)
    assert r is not None and r.next_grasp and r.next_phase is Phase.IDLE
    r = recovery_for(Phase.PLAN_APPROACH, TimingFailed("spline rejected"), touches_object=False)
    assert r is not None and r.next_grasp and r.next_phase is Phase.IDLE
    assert recovery_for(Phase.PLAN_TRANSPORT, PlanningFailed("no path"), touches_object=False) is None


def test_the_budget_refuses_repeats_and_counts() -> None:
    budget = RetryBudget(2)
    slip = GraspFailed("the cube slipped 3.01 mm")
    assert budget.admits(Phase.LIFT, slip)
    budget.spend(Phase.LIFT, slip)
    assert not budget.admits(Phase.LIFT, GraspFailed("the cube slipped 3.20 mm"))  # the same, numbers aside
    assert budget.repeated
    assert budget.admits(Phase.LIFT, GraspFailed("the cube slipped 3.20 mm"), may_repeat=True)
    assert budget.admits(Phase.EXEC_TRANSPORT, slip)  # another phase: another failure
    budget.spend(Phase.EXEC_TRANSPORT, slip)
    assert not budget.admits(Phase.CLOSE, GraspFailed("other"), may_repeat=True)  # none left


def test_the_same_failure_may_be_answered_once_more_another_way() -> None:
    """A failure answered by one recovery is refused the same answer again, not another one: a slip in transit
    carried on with, then the same slip again, is let go and grasped again; a third time it is refused."""
    budget = RetryBudget(3)
    slip = GraspFailed("the cube slipped 3.00 mm")
    carry = recovery_for(Phase.EXEC_TRANSPORT, slip, touches_object=False, still_held=True)
    regrasp = recovery_for(Phase.EXEC_TRANSPORT, slip, touches_object=False, still_held=False)
    assert carry is not None and regrasp is not None and carry.action != regrasp.action
    assert budget.admits(Phase.EXEC_TRANSPORT, slip, action=carry.action)
    budget.spend(Phase.EXEC_TRANSPORT, slip, carry.action)
    assert not budget.admits(Phase.EXEC_TRANSPORT, slip, action=carry.action)
    assert budget.admits(Phase.EXEC_TRANSPORT, slip, action=regrasp.action)
    budget.spend(Phase.EXEC_TRANSPORT, slip, regrasp.action)
    assert not budget.admits(Phase.EXEC_TRANSPORT, GraspFailed("the cube slipped 3.10 mm"), action=regrasp.action)


def test_no_path_to_a_grasp_falls_back_to_the_next_one_before_the_arm_moves() -> None:
    """A planner that gives up at once (RRT*, 1 iteration, no retry) finds no path around the wall to the cube beside
    it: the episode drops each grasp in turn for the next that solves, up to the retry budget, without moving."""
    config = EpisodeConfig(planner=PlannerConfig(search="rrtstar", iterations=1, retries=0)).with_scene(
        obstacle=True, obstacle_xy_m=(0.42, 0.0), start_xy_m=(0.35, 0.08))
    r = run_episode(config)
    assert not r.success
    assert r.failure_phase == "PLAN_APPROACH" and r.failure_kind == "SearchExhausted"  # a PlanningFailed
    assert len(r.recoveries) == config.machine.max_retries
    assert all("drop this grasp and take the next one" in note for note in r.recoveries)
    assert "same failure as before" not in r.failure_reason  # each fallback changed the grasp
    assert [p for p, *_ in r.phase_timeline].count("IDLE") == config.machine.max_retries + 1
    assert r.cycle_time_s == 0.0  # planning only: the arm never moved


def test_a_transport_that_cannot_be_planned_puts_the_object_back_and_takes_the_next_grasp() -> None:
    """A planner that gives up at once finds no path around the wall with the cube in the hand: each time, the
    cube is set back down where it was picked (not dropped from the lift), and the next grasp is tried, up to the
    retry budget; the last failure names PLAN_TRANSPORT."""
    config = EpisodeConfig(planner=PlannerConfig(search="rrtstar", iterations=1, retries=0)).with_scene(obstacle=True)
    r = run_episode(config, record=True)
    assert not r.success and r.failure_phase == "PLAN_TRANSPORT" and r.failure_kind == "SearchExhausted"
    assert len(r.recoveries) == config.machine.max_retries
    assert all("set it back down where it was picked" in note for note in r.recoveries)
    tel = r.telemetry
    assert tel is not None
    approaches = [t0 for phase, t0, _ in tel.phase_spans() if phase == "EXEC_APPROACH"][1:]  # after each put-back
    assert len(approaches) == config.machine.max_retries
    start = config.scene.start_pos_m
    for t0 in approaches:
        p = tel.object_pos_m[int(np.searchsorted(tel.t_s, t0))]
        assert np.hypot(*(p[:2] - start[:2])) < 0.003 and abs(p[2] - start[2]) < 0.001  # resting where it was


@pytest.mark.slow
def test_a_slip_while_the_hand_turns_over_is_carried_on_with() -> None:
    """A ball far out on +y goes to the table's far corner on -y, which the arm reaches only on another IK branch:
    the hand turns over on the way and the ball creeps 3 mm in the pads. It is still squeezed by both: the arm
    stops, takes the grip as it now is and plans the transport again, instead of opening the hand in the air
    (which dropped such objects behind the base), and the ball is placed."""
    from pickplace.world.config import SceneConfig
    from pickplace.world.objects import library_object

    scene = SceneConfig(object=library_object("tennis_ball"), start_xy_m=(0.60, 0.35), goal_xy_m=(0.56, -0.36))
    r = run_episode(EpisodeConfig(scene=scene))
    assert r.success, r.failure_reason
    assert any("take the grip as it now is and plan the transport again" in note for note in r.recoveries)
    assert not any("open" in note for note in r.recoveries)
    assert r.place_error_xy_m < EpisodeConfig().machine.place_tolerance_xy_m
