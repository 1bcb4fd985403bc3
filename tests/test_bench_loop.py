"""The closed-loop benchmark's replay (pickplace.eval.bench.loop): a bare mj_step replay of an episode's own
controls visits exactly its states, so closed loop / replay is the cost of the Python around the physics."""

from __future__ import annotations

import numpy as np

from pickplace.eval.bench.loop import CASES, case_config, loop_timer, replay, taped
from pickplace.task.episode import run_episode


def test_the_replay_of_an_episode_ends_in_its_final_state() -> None:
    with taped() as tape, loop_timer() as closed:
        result = run_episode(case_config("default"))
    assert result.success
    steps = len(tape.ctrl)
    assert steps * 0.001 >= result.cycle_time_s - 1e-9  # every physics step of the episode went on the tape
    wall, d = replay(tape)
    print(f"\n{steps} steps: closed loop {closed[0]:.3f} s, bare replay {wall:.3f} s ({closed[0] / wall:.2f}x)")
    assert tape.other_models == 0
    assert np.array_equal(d.qpos, tape.final_qpos) and np.array_equal(d.qvel, tape.final_qvel)
    assert wall > 0.0 and 0.0 < closed[0] <= result.wall_time_s


def test_the_cases_are_the_ones_the_issue_names() -> None:
    assert CASES == ("default", "obstacle", "realistic", "stack")
    stack = case_config("stack")
    assert stack.task is not None and stack.task.kind == "stack" and len(stack.scene.objects) == 3
    assert case_config("obstacle").scene.obstacle and case_config("realistic").profile.realistic
