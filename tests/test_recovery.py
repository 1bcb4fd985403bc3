"""The recovery table and the retry budget (pickplace.task.recovery), and the grasp fallback in an episode."""

from __future__ import annotations

from pickplace.errors import GraspFailed, PlanningFailed
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
    r = recovery_for(Phase.DESCEND, ObjectMoved("moved"), touches_object=False)
    assert r is not None and r.next_phase is Phase.RECOVER
    assert recovery_for(Phase.DESCEND, hit, touches_object=False) is None  # the arm hit the wall: not transient
    r = recovery_for(Phase.PLAN_APPROACH, PlanningFailed("no path"), touches_object=False)
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


def test_no_path_to_a_grasp_falls_back_to_the_next_one_before_the_arm_moves() -> None:
    """A planner that gives up at once (1 iteration, no retry) finds no path around the wall to the cube beside
    it: the episode drops each grasp in turn for the next that solves, up to the retry budget, without moving."""
    config = EpisodeConfig(planner=PlannerConfig(iterations=1, retries=0)).with_scene(
        obstacle=True, obstacle_xy_m=(0.42, 0.0), start_xy_m=(0.35, 0.08))
    r = run_episode(config)
    assert not r.success
    assert r.failure_phase == "PLAN_APPROACH" and r.failure_kind == "SearchExhausted"  # a PlanningFailed
    assert len(r.recoveries) == config.machine.max_retries
    assert all("drop this grasp and take the next one" in note for note in r.recoveries)
    assert "same failure as before" not in r.failure_reason  # each fallback changed the grasp
    assert [p for p, *_ in r.phase_timeline].count("IDLE") == config.machine.max_retries + 1
    assert r.cycle_time_s == 0.0  # planning only: the arm never moved
