"""Closed-loop benchmark: whole episodes against a bare ``mj_step`` replay of their own torques, in one run.

For each case (``default``: the default scene; ``obstacle``: the wall between start and goal; ``realistic``: the
realistic profile, :mod:`pickplace.task.profile`; ``stack``: a three-object stack as ``pickplace run --task stack
--objects 3`` draws it), all with seed 0:

1. the episode runs once with a tape on ``mujoco.mj_step`` (:mod:`pickplace.motion.loop` is the only place an
   episode steps the physics): the MuJoCo data before its first step, and before every step the controls and,
   where they changed, the applied forces and the mocap bodies' poses;
2. then, ``--repeats`` interleaved rounds of: the episode again, untaped, timing its control loops
   (:meth:`ControlLoop.run <pickplace.motion.loop.ControlLoop.run>`: law, monitor, telemetry and physics: the
   *closed loop*) and the whole run; and a bare replay: from a copy of that first state, every step's controls
   written and ``mujoco.mj_step`` called, nothing else. MuJoCo is deterministic, so the replay visits the
   episode's states (same contacts, same solver work; checked: its final state must equal the episode's), and
   ``closed loop / replay`` is the cost of everything Python does around the physics, as a ratio measured side by
   side (the machines are shared and noisy).

Reported per case, best of the rounds: closed-loop and replay wall time, their ratio, the simulated time and
the real-time factor of the whole episode, planning included (the figure ``pickplace run`` reports: simulated
time over the wall time from the first phase to the end; ``end_to_end`` also counts building the model). The
realistic profile's cameras work inside its loops: their time (``camera_s``: rendering and the robot's image
processing) and, of it, the renders alone (``render_s``: what a simulator spends on a camera, the images being
part of what it simulates) are reported too, with the ratio without the cameras and the ratio against the replay
plus those renders (``ratio_renders_as_simulation``).

Usage: ``python benchmarks/loop.py [--json] [--repeats R] [--cases default,obstacle,realistic,stack]``.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import json
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from pickplace.eval.bench import machine_info
from pickplace.motion import control as control_module
from pickplace.motion import loop as loop_module
from pickplace.motion.loop import ControlLoop
from pickplace.perception.camera import DepthCamera
from pickplace.perception.obstacles import ObstacleCamera
from pickplace.task.episode import EpisodeConfig, EpisodeResult, run_episode
from pickplace.task.observe import SensorObserver
from pickplace.task.profile import ProfileConfig
from pickplace.task.task_episode import TaskResult, run_task
from pickplace.task.tasks import TaskConfig, random_task_scene
from pickplace.world.config import SceneConfig

#: The cases, in the order they run.
CASES = ("default", "obstacle", "realistic", "stack")


def case_config(name: str, seed: int = 0) -> EpisodeConfig:
    """The episode config of a case (:data:`CASES`)."""
    if name == "default":
        return EpisodeConfig()
    if name == "obstacle":
        return EpisodeConfig(scene=SceneConfig(obstacle=True))
    if name == "realistic":
        return EpisodeConfig(profile=ProfileConfig.named("realistic"))
    if name == "stack":  # as `pickplace run --task stack --objects 3 --seed SEED` draws it
        scene = random_task_scene("stack", 3, np.random.default_rng([seed, 7]), base=SceneConfig())
        return EpisodeConfig(scene=scene, task=TaskConfig(kind="stack"))
    raise ValueError(f"unknown case {name!r}; cases: {', '.join(CASES)}")


def _run(config: EpisodeConfig, seed: int) -> EpisodeResult | TaskResult:
    return run_task(config, seed) if config.task is not None else run_episode(config, seed)


def _sim_time(result: EpisodeResult | TaskResult) -> float:
    return result.total_time_s if isinstance(result, TaskResult) else result.cycle_time_s


# --------------------------------------------------------------------------- #
# the tape and the replay
# --------------------------------------------------------------------------- #


@dataclass
class Tape:
    """What an episode applied at each physics step.

    Attributes:
        model: The model stepped.
        start: A copy of the data before the first step.
        ctrl: The controls of every step (steps, nu).
        changes: ``{step: (xfrc_applied, mocap_pos, mocap_quat, actuator_gainprm, actuator_biasprm)}`` at the steps
            where one of them changed (the gains: the arm's actuators switched between torque motors and joint
            servos, :class:`~pickplace.motion.loop.ServoGains`).
        final_qpos: ``qpos`` after the last step.
        final_qvel: ``qvel`` after the last step.
        other_models: Steps taken on another model than ``model`` (the replay cannot reproduce them).
    """

    model: mujoco.MjModel | None = None
    start: mujoco.MjData | None = None
    ctrl: list[np.ndarray] = field(default_factory=list)
    changes: dict[int, tuple[np.ndarray, ...]] = field(default_factory=dict)
    final_qpos: np.ndarray | None = None
    final_qvel: np.ndarray | None = None
    other_models: int = 0
    _last: tuple[np.ndarray, ...] | None = None

    def step(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Record what step ``len(self.ctrl)`` applies, then take it."""
        if self.model is None:
            self.model, self.start = m, copy.copy(d)
        elif m is not self.model:
            self.other_models += 1
        now = (d.xfrc_applied, d.mocap_pos, d.mocap_quat, m.actuator_gainprm, m.actuator_biasprm)
        if self._last is None or any(not np.array_equal(a, b) for a, b in zip(now, self._last, strict=True)):
            self._last = tuple(a.copy() for a in now)
            self.changes[len(self.ctrl)] = self._last
        self.ctrl.append(d.ctrl.copy())
        mujoco.mj_step(m, d)
        self.final_qpos, self.final_qvel = d.qpos.copy(), d.qvel.copy()


class _Stepper:
    """Stands in for the ``mujoco`` module in :mod:`pickplace.motion.loop`: ``mj_step`` goes through the tape."""

    def __init__(self, tape: Tape) -> None:
        self._tape = tape

    def __getattr__(self, name: str) -> Any:
        return getattr(mujoco, name)

    def mj_step(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        self._tape.step(m, d)


@contextlib.contextmanager
def taped() -> Iterator[Tape]:
    """Within the block, every physics step of an episode is recorded on the tape yielded."""
    tape = Tape()
    saved = loop_module.mujoco
    loop_module.mujoco = _Stepper(tape)  # type: ignore[assignment]
    try:
        yield tape
    finally:
        loop_module.mujoco = saved


@contextlib.contextmanager
def loop_timer(clock: Callable[[], float] = time.perf_counter) -> Iterator[list[float]]:
    """Within the block, the time (s, by ``clock``) spent in the control loops adds up in the first element of the
    list yielded: in :meth:`ControlLoop.run` and :meth:`ControlLoop.run_servo` (law, monitor, telemetry and physics)
    and in :func:`~pickplace.motion.control.servo_setpoints` (the joint servos' setpoints: the law's work done
    ahead). The second element adds up the part of it spent in the realistic profile's cameras: the table camera's
    re-checks of the resting object (rendering and pose fitting, :class:`~pickplace.task.observe.SensorObserver`) and
    the obstacle camera's looks for the trajectory predictor's believed world
    (:class:`~pickplace.perception.obstacles.ObstacleCamera`); the third, the part of that spent rendering the
    images (OpenGL: :meth:`DepthCamera._render <pickplace.perception.camera.DepthCamera._render>`, which a
    simulator would spend on its camera however the robot's software used the images)."""
    total = [0.0, 0.0, 0.0]
    depth = [0]
    wrapped = {0: [(ControlLoop, "run"), (ControlLoop, "run_servo"), (control_module, "servo_setpoints")],
               1: [(SensorObserver, "_recheck"), (ObstacleCamera, "columns")],
               2: [(DepthCamera, "_render")]}
    originals = {(owner, name): getattr(owner, name) for places in wrapped.values() for owner, name in places}

    def timed(f: Callable[..., Any], slot: int) -> Callable[..., Any]:
        """``f``, its time added to ``total[slot]``: always for the loops (slot 0, which counts its depth), inside a
        loop only for the others."""
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            t0 = clock()
            inside = depth[0] > 0
            if slot == 0:
                depth[0] += 1
            try:
                return f(*args, **kwargs)
            finally:
                if slot == 0:
                    depth[0] -= 1
                if slot == 0 or inside:
                    total[slot] += clock() - t0

        return wrapper

    for slot, places in wrapped.items():
        for owner, name in places:
            setattr(owner, name, timed(originals[owner, name], slot))
    try:
        yield total
    finally:
        for (owner, name), f in originals.items():
            setattr(owner, name, f)


def replay(tape: Tape, clock: Callable[[], float] = time.perf_counter) -> tuple[float, mujoco.MjData]:
    """Step a copy of the tape's first state with its controls by bare ``mujoco.mj_step``; returns the time (s, by
    ``clock``) and the data at the end."""
    assert tape.model is not None and tape.start is not None
    m, d = tape.model, copy.copy(tape.start)
    ctrl, changes, step = d.ctrl, tape.changes, mujoco.mj_step
    gains = m.actuator_gainprm.copy(), m.actuator_biasprm.copy()
    t0 = clock()
    for k, u in enumerate(tape.ctrl):
        if k in changes:
            xfrc, mocap_pos, mocap_quat, gain, bias = changes[k]
            d.xfrc_applied[:], d.mocap_pos[:], d.mocap_quat[:] = xfrc, mocap_pos, mocap_quat
            m.actuator_gainprm[:], m.actuator_biasprm[:] = gain, bias
        ctrl[:] = u
        step(m, d)
    spent = clock() - t0
    m.actuator_gainprm[:], m.actuator_biasprm[:] = gains
    return spent, d


# --------------------------------------------------------------------------- #
# the benchmark
# --------------------------------------------------------------------------- #


#: The clocks the loops can be timed by: ``wall`` (the episode as a user waits for it) and
#: ``cpu`` (the thread's processor time: what the loop itself costs, less disturbed by other work on a shared
#: machine).
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.thread_time}


def _one_round(config: EpisodeConfig, seed: int, tape: Tape, clock: str = "wall") -> dict[str, float]:
    with loop_timer(CLOCKS[clock]) as closed:
        t0 = time.perf_counter()
        result = _run(config, seed)
        wall = time.perf_counter() - t0
    replay_s, _ = replay(tape, CLOCKS[clock])
    sim = _sim_time(result)
    return {"closed_loop_s": closed[0], "camera_s": closed[1], "render_s": closed[2], "replay_s": replay_s,
            "ratio": closed[0] / replay_s,
            "episode_wall_s": result.wall_time_s, "real_time_factor": result.real_time_factor,
            "real_time_factor_end_to_end": sim / wall, "success": bool(result.success)}


def run(cases: tuple[str, ...] = CASES, repeats: int = 5, seed: int = 0,
        progress: Callable[[str], None] | None = None, clock: str = "wall") -> dict[str, Any]:
    """Run the benchmark (times by ``clock``, :data:`CLOCKS`); returns one JSON-serialisable dict."""
    if clock not in CLOCKS:
        raise ValueError(f"unknown clock {clock!r}; clocks: {', '.join(CLOCKS)}")
    configs = {c: case_config(c, seed) for c in cases}
    tapes: dict[str, Tape] = {}
    facts: dict[str, dict[str, Any]] = {}
    for c in cases:  # the taped runs (also the warm-up)
        with taped() as tape:
            result = _run(configs[c], seed)
        _, end = replay(tape)
        assert tape.final_qpos is not None and tape.final_qvel is not None
        deviation = max(float(np.max(np.abs(end.qpos - tape.final_qpos))),
                        float(np.max(np.abs(end.qvel - tape.final_qvel))))
        tapes[c] = tape
        facts[c] = {"steps": len(tape.ctrl), "simulated_s": _sim_time(result), "success": bool(result.success),
                    "replay_identical": deviation == 0.0 and tape.other_models == 0,
                    "replay_max_deviation": deviation}
        if progress is not None:
            progress(f"{c}: taped {len(tape.ctrl)} steps, replay identical: {facts[c]['replay_identical']}")
    rounds: dict[str, list[dict[str, float]]] = {c: [] for c in cases}
    for r in range(repeats):  # interleaved rounds
        for c in cases:
            rounds[c].append(_one_round(configs[c], seed, tapes[c], clock))
            if progress is not None:
                row = rounds[c][-1]
                progress(f"round {r + 1}/{repeats} {c}: closed loop {row['closed_loop_s']:.3f} s, replay "
                         f"{row['replay_s']:.3f} s ({row['ratio']:.2f}x), real-time factor "
                         f"{row['real_time_factor']:.2f}")
    out: dict[str, Any] = {}
    for c in cases:
        rs = rounds[c]
        closed, rep = min(x["closed_loop_s"] for x in rs), min(x["replay_s"] for x in rs)
        best = min(rs, key=lambda x: x["closed_loop_s"])
        steps = facts[c]["steps"]
        out[c] = {
            **facts[c],
            "closed_loop_s": closed, "replay_s": rep, "ratio": closed / rep,
            "camera_s": best["camera_s"], "ratio_without_camera": (closed - best["camera_s"]) / rep,
            "render_s": best["render_s"], "ratio_renders_as_simulation": closed / (rep + best["render_s"]),
            "ratio_best_round": min(x["ratio"] for x in rs),
            "closed_loop_us_per_step": closed / steps * 1e6, "replay_us_per_step": rep / steps * 1e6,
            "python_us_per_step": (closed - rep) / steps * 1e6,
            "episode_wall_s": min(x["episode_wall_s"] for x in rs),
            "real_time_factor": max(x["real_time_factor"] for x in rs),
            "real_time_factor_end_to_end": max(x["real_time_factor_end_to_end"] for x in rs),
            "all_succeeded": all(x["success"] for x in rs),
        }
    return {"cases": out, "repeats": repeats, "seed": seed, "clock": clock, "machine": machine_info()}


def print_table(result: dict[str, Any]) -> None:
    """Render the result as a rich table."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    t = Table(title=f"Closed loop against a bare mj_step replay of the same controls (best of {result['repeats']} "
                    f"interleaved rounds, {result['clock']} clock)")
    for col in ("case", "steps", "closed loop (s)", "of it camera (s)", "of that rendering (s)", "replay (s)", "ratio",
                "ratio w/o camera", "ratio, renders as simulation", "Python µs/step", "simulated (s)",
                "episode wall (s)", "real-time factor", "replay identical"):
        t.add_column(col, justify="left" if col == "case" else "right")
    for name, c in result["cases"].items():
        t.add_row(name, str(c["steps"]), f"{c['closed_loop_s']:.3f}", f"{c['camera_s']:.3f}", f"{c['render_s']:.3f}",
                  f"{c['replay_s']:.3f}", f"{c['ratio']:.2f}×", f"{c['ratio_without_camera']:.2f}×",
                  f"{c['ratio_renders_as_simulation']:.2f}×", f"{c['python_us_per_step']:.1f}",
                  f"{c['simulated_s']:.2f}", f"{c['episode_wall_s']:.3f}", f"{c['real_time_factor']:.1f}×",
                  "yes" if c["replay_identical"] else "NO")
    console.print(t)
    m = result["machine"]
    console.print(f"1-min load average {m['load_average_1min']:.2f} on {m['cpu_count']} cores; real-time factor: "
                  "simulated time over the episode's wall time from its first phase (planning included)",
                  highlight=False)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a rich table, or one JSON object with ``--json``. Returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds; the best is reported (default 5)")
    parser.add_argument("--cases", default=",".join(CASES),
                        help=f"comma-separated cases among {', '.join(CASES)} (default: all)")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    parser.add_argument("--clock", choices=tuple(CLOCKS), default="wall",
                        help="time the loops and the replay by the wall clock (default) or by the thread's processor "
                             "time (less disturbed by other work on a shared machine)")
    args = parser.parse_args(argv)
    cases = tuple(c.strip() for c in args.cases.split(",") if c.strip())
    unknown = [c for c in cases if c not in CASES]
    if unknown or not cases:
        parser.error(f"--cases must name some of {', '.join(CASES)} (got {args.cases!r})")
    if args.repeats < 1 or args.seed < 0:
        parser.error("--repeats must be >= 1 and --seed >= 0")
    echo = None if args.json else (lambda line: print(line, file=sys.stderr, flush=True))
    result = run(cases, args.repeats, args.seed, echo, args.clock)
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 0


__all__ = ["CASES", "CLOCKS", "Tape", "case_config", "loop_timer", "main", "replay", "run", "taped"]

if __name__ == "__main__":
    sys.exit(main())
