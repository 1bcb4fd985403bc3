"""The closed-loop benchmark's replay (pickplace.eval.bench.loop): a bare mj_step replay of an episode's own
controls visits exactly its states, so closed loop / replay is the cost of the Python around the physics."""

from __future__ import annotations

import numpy as np
import pytest

from pickplace.eval.bench.loop import CASES, case_config, loop_timer, replay, run, taped
from pickplace.motion.control import ControlConfig
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


def test_the_cases_are_the_four_benchmarked() -> None:
    assert CASES == ("default", "obstacle", "realistic", "stack")
    stack = case_config("stack")
    assert stack.task is not None and stack.task.kind == "stack" and len(stack.scene.objects) == 3
    assert case_config("obstacle").scene.obstacle and case_config("realistic").profile.realistic


def test_the_joint_servos_gains_are_on_the_tape() -> None:
    """The arm's actuators switch between torque motors and joint servos (every joint loop of the default episode
    runs on the servos); the replay sets them as the episode had them (it would not end in the episode's state
    otherwise) and leaves the model as it found it."""
    with taped() as tape:
        result = run_episode(case_config("default"))
    assert result.success and tape.model is not None
    first = tape.changes[0][3]  # the actuators' gains before the first step
    np.testing.assert_array_equal(first[:6, 0], ControlConfig().joint_kp)
    np.testing.assert_array_equal(tape.model.actuator_gainprm[:6, 0], 1.0)  # torque motors again after it
    before = tape.model.actuator_gainprm.copy()
    replay(tape)
    np.testing.assert_array_equal(tape.model.actuator_gainprm, before)


@pytest.mark.slow
def test_the_realistic_case_counts_its_camera_apart() -> None:
    """The realistic profile's camera works inside the loops (its re-checks of the resting object): the benchmark
    reports that time apart, part of the closed loop, and of it the renders."""
    out = run(("realistic",), repeats=1, clock="cpu")["cases"]["realistic"]
    assert out["replay_identical"] and out["all_succeeded"]
    assert 0.0 < out["render_s"] < out["camera_s"] < out["closed_loop_s"]
    assert out["ratio_without_camera"] < out["ratio"] and out["ratio_renders_as_simulation"] < out["ratio"]
