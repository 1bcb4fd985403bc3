"""Gymnasium environment benchmark: env steps per second and real-time factor at both action levels, next to
robosuite's Lift measured in the same run, and the skill level's success over seeded episodes.

Measured in one run (ideal profile unless ``--profile realistic``), wall times on this machine, in ``--rounds``
rounds whose blocks alternate pickplace then robosuite, robosuite then pickplace (A B B A ...), so that a drift of
the shared machine's load falls on both sides:

* low level (``pickplace/PickPlaceLowLevel-v0``, Cartesian and joint actions, at each ``--rate``): seeded random
  actions (uniform in the action box), ``--steps`` steps at 20 Hz and the same simulated time at the other rates
  (``steps x rate / 20``). Episodes last 10 simulated s (``max_steps = 10 x rate``) unless a forbidden contact ends
  them earlier; an ended episode is reset. Steps per second and the real-time factor (simulated s per wall s) of
  ``env.step`` alone: the first reset, 10 warm-up steps and every reset are timed apart. Also the physics steps
  per second and their cost against a bare ``mujoco.mj_step`` loop on the same model (the controller's, the
  monitor's and the observation's share);
* skill level (``pickplace/PickPlace-v0``, its defaults: the default task, the object's start and goal drawn
  around the default scene's): ``--episodes`` episodes reset with seeds 0 ... N-1, each choosing the best-ranked
  grasp the mask allows, then the next one if a choice cannot start. Success (with its 95 % Wilson interval),
  env steps per second, the real-time factor of the steps (simulated s of the pick and places, planning included,
  per wall s of ``env.step``; the reset, which ranks and checks the grasps, is timed apart), the final place error
  and each failure with its phase, kind and reason;
* robosuite (``--robosuite [PYTHON]``): ``Lift`` with a Panda and its default composite controller (an OSC_POSE
  arm, delta actions, kp 150), no renderer, no offscreen renderer, no camera observations, at each
  ``--robosuite-rates`` control rate (its physics: 500 Hz), random actions uniform in its action spec, episodes of
  10 simulated s, timed the same way (its simulated time = steps / control_freq). It runs in robosuite's own
  Python (a separate venv: ``make bench-env`` creates ``.bench-venv/robosuite``; robosuite pins its own mujoco,
  numba and numpy, so it is no dependency of pickplace) as a subprocess that stays up for the whole run and
  answers one block at a time. Without it, or if it cannot start, the comparison is skipped and the reason
  printed; pickplace's figures are measured all the same.

Ratios are pickplace / robosuite: at the same control rate, of the steps per second (= of the real-time factors);
for the skill level, of the real-time factors against robosuite at 20 Hz. Each low-level ratio (of the pooled
steps and times) also comes with the median, lowest and highest of the rounds' own ratios: a load that came and
went during the run shows there. An engine cross-check times a bare ``mj_step`` loop on robosuite's Lift
model under both MuJoCo versions (robosuite's and pickplace's), which the ratios otherwise mix in.

Usage: ``pickplace bench env [--json] [--episodes N] [--steps N] [--rate HZ ...] [--rounds R] [--profile P]
[--seed S] [--robosuite [PYTHON]] [--robosuite-rates HZ ...]`` (``benchmarks/env.py`` is the same).
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import math
import os
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from pickplace.eval.bench import machine_info

#: Where ``make bench-env`` puts robosuite's venv (relative to the repository root); ``--robosuite`` without a
#: value uses it.
DEFAULT_ROBOSUITE_PYTHON = ".bench-venv/robosuite/bin/python"
#: Simulated length of a low-level episode on both sides (s): ``max_steps`` / robosuite's ``horizon``.
EPISODE_S = 10.0
#: Untimed steps after the first reset (robosuite compiles its numba functions in its first steps).
WARMUP_STEPS = 10
#: Steps of the bare ``mj_step`` loops.
BARE_STEPS = 5000
#: Longest wait for robosuite's worker to answer one request (s).
WORKER_TIMEOUT_S = 900.0


class RobosuiteUnavailable(Exception):
    """robosuite's side cannot be measured; the message says why."""


# --------------------------------------------------------------------------- pickplace's side
def _bare_step_rate(mj_model: Any, steps: int = BARE_STEPS) -> float:
    """Physics steps per wall second of a bare ``mj_step`` loop on a model (actuators at zero)."""
    import mujoco

    d = mujoco.MjData(mj_model)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(mj_model, d)
    return steps / (time.perf_counter() - t0)


def _block_steps(total: int, rounds: int, r: int) -> int:
    """Steps of round ``r``'s block when ``total`` steps are split over ``rounds`` blocks."""
    return total * (r + 1) // rounds - total * r // rounds


class _LowLevel:
    """One low-level configuration (action mode, rate) kept alive over the rounds: its episodes go on between
    blocks."""

    def __init__(self, mode: str, rate_hz: float, steps: int, profile: str, seed: int) -> None:
        import gymnasium as gym

        import pickplace.envs  # noqa: F401  (registers the ids)

        self.mode, self.rate_hz, self.total = mode, rate_hz, steps
        self.env = gym.make("pickplace/PickPlaceLowLevel-v0", action_mode=mode, control_rate_hz=rate_hz,
                            profile=profile, max_steps=max(2, round(EPISODE_S * rate_hz)))
        self.env.action_space.seed(seed)
        self.reset_s: list[float] = []
        self.ends: dict[str, int] = {}
        self.block_steps: list[int] = []
        self.block_s: list[float] = []
        self._reset(seed)
        for _ in range(WARMUP_STEPS):
            self._step()

    def _reset(self, seed: int | None = None) -> None:
        t0 = time.perf_counter()
        self.env.reset(seed=seed)
        self.reset_s.append(time.perf_counter() - t0)

    def _step(self) -> float:
        """One step of a random action; the wall time of ``env.step`` (an ended episode is reset, untimed)."""
        action = self.env.action_space.sample()
        t0 = time.perf_counter()
        _, _, terminated, truncated, info = self.env.step(action)
        dt = time.perf_counter() - t0
        if terminated or truncated:
            key = "truncated" if truncated else (info["failure_kind"] or "success")
            self.ends[key] = self.ends.get(key, 0) + 1
            self._reset()
        return dt

    def block(self, steps: int) -> None:
        self.block_steps.append(steps)
        self.block_s.append(sum(self._step() for _ in range(steps)))

    def result(self) -> dict[str, Any]:
        per_step = self.env.unwrapped.steps_per_action
        bare = _bare_step_rate(self.env.unwrapped.robot.mj)
        self.env.close()
        steps, step_s = sum(self.block_steps), sum(self.block_s)
        return {"mode": self.mode, "rate_hz": self.rate_hz, "steps": steps, "step_wall_s": step_s,
                "steps_per_s": steps / step_s, "real_time_factor": steps / self.rate_hz / step_s,
                "reset_s_mean": float(np.mean(self.reset_s)), "resets": len(self.reset_s),
                "physics_steps_per_step": per_step, "physics_steps_per_s": steps * per_step / step_s,
                "bare_mj_step_per_s": bare, "cost_vs_bare_mj_step": bare / (steps * per_step / step_s),
                "episode_ends": self.ends, "rounds_steps_per_s": [n / s for n, s in zip(self.block_steps,
                                                                                        self.block_s, strict=True)]}


class _Skill:
    """The skill-level env kept alive over the rounds; each block runs the next seeds."""

    def __init__(self, profile: str) -> None:
        import gymnasium as gym

        import pickplace.envs  # noqa: F401  (registers the ids)

        self.env = gym.make("pickplace/PickPlace-v0", profile=profile)
        self.rows: list[dict[str, Any]] = []

    def block(self, seeds: range) -> None:
        env = self.env
        for seed in seeds:
            t0 = time.perf_counter()
            _, info = env.reset(seed=seed)
            reset_s = time.perf_counter() - t0
            tried: set[int] = set()
            steps, step_s, sim0 = 0, 0.0, info["sim_time_s"]
            while True:
                valid = [int(i) for i in np.flatnonzero(info["action_mask"]) if int(i) not in tried]
                choice = valid[0] if valid else int(np.flatnonzero(info["action_mask"] == 0)[0])
                tried.add(choice)
                t0 = time.perf_counter()
                _, _, terminated, truncated, info = env.step(choice)
                step_s += time.perf_counter() - t0
                steps += 1
                if terminated or truncated:
                    break
            self.rows.append({"seed": seed, "object": info["object"], "success": bool(info["success"]),
                              "steps": steps, "step_wall_s": step_s, "reset_wall_s": reset_s,
                              "sim_s": info["sim_time_s"] - sim0,
                              "final_place_error_xy_m": info.get("final_place_error_xy_m", math.nan),
                              "grasp_index": info.get("grasp_index"), "grasp_approach": info.get("grasp_approach"),
                              "started": info.get("started"), "failure_phase": info.get("failure_phase"),
                              "failure_kind": info.get("failure_kind"),
                              "failure_reason": info.get("failure_reason") or info.get("invalid_action") or None})

    def result(self) -> dict[str, Any]:
        from pickplace.eval.campaign.summary import wilson_interval

        self.env.close()
        rows = self.rows
        ok = [r for r in rows if r["success"]]
        lo, hi = wilson_interval(len(ok), len(rows))
        wall = sum(r["step_wall_s"] for r in rows)
        errors = [r["final_place_error_xy_m"] for r in ok]
        return {"episodes": len(rows), "seeds": [rows[0]["seed"], rows[-1]["seed"]], "successes": len(ok),
                "success_rate": len(ok) / len(rows), "wilson95": [lo, hi],
                "steps": sum(r["steps"] for r in rows), "step_wall_s": wall, "sim_s": sum(r["sim_s"] for r in rows),
                "steps_per_s": sum(r["steps"] for r in rows) / wall,
                "real_time_factor": sum(r["sim_s"] for r in rows) / wall,
                "reset_s_mean": float(np.mean([r["reset_wall_s"] for r in rows])),
                "final_place_error_xy_rms_m": float(np.sqrt(np.mean(np.square(errors)))) if errors else math.nan,
                "failures": [r for r in rows if not r["success"]], "rows": rows}


# --------------------------------------------------------------------------- robosuite's side
def _robosuite_worker() -> None:  # pragma: no cover - runs in robosuite's Python, not pickplace's
    """robosuite's side of the benchmark, run as ``PYTHON -c SOURCE SETTINGS_JSON`` in robosuite's own venv (so it
    imports nothing from pickplace). Requests are JSON lines on stdin, each answered by one JSON line on the
    original stdout (whatever robosuite prints goes to stderr):

    * ``{"op": "block", "rate": HZ, "steps": N}``: N random steps of Lift at that control rate (the env is made,
      reset and warmed up at its first block, untimed): ``{"steps", "step_s", "resets", "reset_s" (the resets
      since the last block's answer, the first included), "make_s", "physics_steps_per_step", ...}``;
    * ``{"op": "bare", "rate": HZ, "steps": N}``: a bare ``mj_step`` loop on that env's model;
    * ``{"op": "xml", "rate": HZ, "path": P}``: the env's model saved as MJCF to P (for the engine cross-check);
    * ``{"op": "quit"}``.
    """
    import json
    import os
    import platform
    import sys
    import time
    import traceback

    out = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr

    def reply(obj: dict) -> None:
        out.write(json.dumps(obj) + "\n")
        out.flush()

    settings = json.loads(sys.argv[1])
    try:
        import mujoco
        import numpy as np
        import robosuite
        from robosuite import load_composite_controller_config
    except Exception as exc:  # the reason goes back to the parent
        reply({"error": f"importing robosuite failed: {type(exc).__name__}: {exc}"})
        return
    versions = {"robosuite": robosuite.__version__, "mujoco": mujoco.__version__, "numpy": np.__version__,
                "python": platform.python_version()}
    try:
        import numba

        versions["numba"] = numba.__version__
    except ImportError:
        pass
    try:
        controller = load_composite_controller_config(controller=settings["controller"], robot=settings["robot"])
        arm = controller["body_parts"]["right"]
    except Exception as exc:
        reply({"error": f"loading robosuite's controller config failed: {type(exc).__name__}: {exc}"})
        return
    reply({"hello": versions, "controller": {"composite": controller.get("type"), "arm": arm.get("type"),
                                             "kp": arm.get("kp"), "damping_ratio": arm.get("damping_ratio"),
                                             "input_type": arm.get("input_type")}})
    envs: dict = {}

    def make(rate: float) -> dict:
        t0 = time.perf_counter()
        env = robosuite.make(settings["env"], robots=settings["robot"], controller_configs=controller,
                             has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False,
                             control_freq=rate, horizon=max(2, round(settings["episode_s"] * rate)),
                             seed=settings["seed"])
        make_s = time.perf_counter() - t0
        rng = np.random.default_rng(settings["seed"])
        low, high = env.action_spec
        state = {"env": env, "rng": rng, "low": low, "high": high, "make_s": make_s, "reset_s": [], "resets": 0,
                 "reported": 0}

        def reset() -> None:
            t = time.perf_counter()
            env.reset()
            state["reset_s"].append(time.perf_counter() - t)
            state["resets"] += 1

        def step() -> float:
            action = rng.uniform(low, high)
            t = time.perf_counter()
            _, _, done, _ = env.step(action)
            dt = time.perf_counter() - t
            if done:
                reset()
            return dt

        state["step"] = step
        reset()
        for _ in range(settings["warmup_steps"]):
            step()
        state["physics_steps_per_step"] = round(env.control_timestep / env.model_timestep)
        state["model_timestep_s"] = env.model_timestep
        state["action_dim"] = len(low)
        return state

    for line in sys.stdin:
        try:
            req = json.loads(line)
            if req["op"] == "quit":
                reply({"bye": True})
                return
            rate = float(req["rate"])
            if rate not in envs:
                envs[rate] = make(rate)
            s = envs[rate]
            if req["op"] == "block":
                step_s = sum(s["step"]() for _ in range(int(req["steps"])))
                reset_s, s["reported"] = s["reset_s"][s["reported"]:], len(s["reset_s"])
                reply({"steps": int(req["steps"]), "step_s": step_s, "resets": len(reset_s),
                       "reset_s": reset_s, "make_s": s["make_s"],
                       "physics_steps_per_step": s["physics_steps_per_step"],
                       "model_timestep_s": s["model_timestep_s"], "action_dim": s["action_dim"]})
            elif req["op"] == "bare":
                m = s["env"].sim.model._model
                d = mujoco.MjData(m)
                n = int(req["steps"])
                t = time.perf_counter()
                for _ in range(n):
                    mujoco.mj_step(m, d)
                reply({"bare_mj_step_per_s": n / (time.perf_counter() - t)})
            elif req["op"] == "xml":
                with open(req["path"], "w") as f:
                    f.write(s["env"].sim.model.get_xml())
                reply({"path": req["path"]})
            else:
                reply({"error": f"unknown op {req['op']!r}"})
        except Exception as exc:
            reply({"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()[-2000:]})


class _Robosuite:
    """robosuite's worker process (:func:`_robosuite_worker`) in its own Python, kept up for the whole run."""

    SETTINGS: ClassVar[dict[str, Any]] = {"env": "Lift", "robot": "Panda", "controller": "BASIC",
                                          "episode_s": EPISODE_S, "warmup_steps": WARMUP_STEPS}

    def __init__(self, python: str, seed: int) -> None:
        if not Path(python).is_file():
            raise RobosuiteUnavailable(
                f"robosuite's Python {python!r} does not exist: `make bench-env` creates "
                f"{DEFAULT_ROBOSUITE_PYTHON} (a venv with robosuite 1.5.2, apart from pickplace's)")
        self.python = python
        self.settings = {**self.SETTINGS, "seed": seed}
        source = inspect.getsource(_robosuite_worker) + "\n_robosuite_worker()\n"
        self._stderr = tempfile.TemporaryFile(mode="w+")  # noqa: SIM115  (the worker's stderr; closed in close())
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHONPATH", "VIRTUAL_ENV"))}
        try:
            self.proc = subprocess.Popen([python, "-c", source, json.dumps(self.settings)], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=self._stderr, text=True, env=env)
        except OSError as exc:
            raise RobosuiteUnavailable(f"cannot start {python}: {exc}") from None
        hello = self._read(120.0)
        self.versions, self.controller = hello["hello"], hello["controller"]
        if self.controller.get("arm") != "OSC_POSE":
            self.close()
            raise RobosuiteUnavailable(f"robosuite's default Panda controller drives the arm with "
                                       f"{self.controller.get('arm')!r}, not OSC_POSE")
        self.blocks: dict[float, list[dict[str, Any]]] = {}

    def _stderr_tail(self) -> str:
        self._stderr.seek(0)
        lines = [ln for ln in self._stderr.read().splitlines() if ln.strip() and "WARNING" not in ln]
        return " | ".join(lines[-3:])

    def _read(self, timeout_s: float) -> dict[str, Any]:
        assert self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout_s)
        line = self.proc.stdout.readline() if ready else ""
        if not line:
            why = "did not answer in time" if not ready else "exited"
            tail = self._stderr_tail()
            self.close()
            raise RobosuiteUnavailable(f"robosuite's worker ({self.python}) {why}: {tail}")
        msg = json.loads(line)
        if "error" in msg:
            self.close()
            raise RobosuiteUnavailable(msg["error"])
        return msg

    def request(self, **req: Any) -> dict[str, Any]:
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(json.dumps(req) + "\n")
            self.proc.stdin.flush()
        except OSError as exc:
            tail = self._stderr_tail()
            self.close()
            raise RobosuiteUnavailable(f"robosuite's worker is gone: {exc}: {tail}") from None
        return self._read(WORKER_TIMEOUT_S)

    def block(self, rate_hz: float, steps: int) -> None:
        self.blocks.setdefault(rate_hz, []).append(self.request(op="block", rate=rate_hz, steps=steps))

    def result(self, rate_hz: float) -> dict[str, Any]:
        blocks = self.blocks[rate_hz]
        steps, step_s = sum(b["steps"] for b in blocks), sum(b["step_s"] for b in blocks)
        per_step = blocks[-1]["physics_steps_per_step"]
        bare = self.request(op="bare", rate=rate_hz, steps=BARE_STEPS)["bare_mj_step_per_s"]
        resets = [s for b in blocks for s in b["reset_s"]]
        return {"rate_hz": rate_hz, "steps": steps, "step_wall_s": step_s, "steps_per_s": steps / step_s,
                "real_time_factor": steps / rate_hz / step_s, "resets": sum(b["resets"] for b in blocks),
                "reset_s_mean": float(np.mean(resets)) if resets else math.nan, "make_s": blocks[0]["make_s"],
                "physics_steps_per_step": per_step, "physics_steps_per_s": steps * per_step / step_s,
                "bare_mj_step_per_s": bare, "cost_vs_bare_mj_step": bare / (steps * per_step / step_s),
                "model_timestep_s": blocks[0]["model_timestep_s"], "action_dim": blocks[0]["action_dim"],
                "rounds_steps_per_s": [b["steps"] / b["step_s"] for b in blocks]}

    def engine_cross_check(self, rate_hz: float) -> dict[str, Any]:
        """A bare ``mj_step`` loop on robosuite's Lift model under robosuite's MuJoCo and under pickplace's,
        alternated twice."""
        import mujoco

        with tempfile.TemporaryDirectory() as tmp:
            path = str(Path(tmp) / "lift.xml")
            self.request(op="xml", rate=rate_hz, path=path)
            model = mujoco.MjModel.from_xml_path(path)
        theirs, ours = [], []
        for _ in range(2):
            theirs.append(self.request(op="bare", rate=rate_hz, steps=BARE_STEPS)["bare_mj_step_per_s"])
            ours.append(_bare_step_rate(model))
        return {"model": "robosuite Lift (Panda), saved by robosuite and loaded by each MuJoCo",
                "robosuite_mujoco": self.versions["mujoco"], "pickplace_mujoco": mujoco.__version__,
                "bare_mj_step_per_s_robosuite_mujoco": float(np.mean(theirs)),
                "bare_mj_step_per_s_pickplace_mujoco": float(np.mean(ours)),
                "pickplace_mujoco_over_robosuite_mujoco": float(np.mean(ours) / np.mean(theirs))}

    def close(self) -> None:
        proc = getattr(self, "proc", None)
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(OSError, ValueError):
                assert proc.stdin is not None
                proc.stdin.write(json.dumps({"op": "quit"}) + "\n")
                proc.stdin.flush()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        stderr = getattr(self, "_stderr", None)
        if stderr is not None and proc is not None and proc.poll() is not None:
            stderr.close()


# --------------------------------------------------------------------------- the run
def _commit() -> str | None:
    """The repository's commit (``+dirty`` with uncommitted changes), or None outside a git work tree."""
    root = Path(__file__).resolve().parents[4]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


def _ratio(a: dict[str, Any], b: dict[str, Any], key: str) -> float:
    return float(a[key] / b[key])


def run(episodes: int = 10, steps: int = 400, rates_hz: tuple[float, ...] = (20.0, 50.0), profile: str = "ideal",
        seed: int = 0, rounds: int = 4, robosuite: str | None = None,
        robosuite_rates_hz: tuple[float, ...] = (20.0, 50.0, 500.0)) -> dict[str, Any]:
    """Both levels, and robosuite's Lift when ``robosuite`` names its Python, measured in one run.

    Args:
        episodes: Skill-level episodes (seeds 0 ... episodes - 1); 0: none.
        steps: Low-level steps per action mode at 20 Hz (the same simulated time at the other rates).
        rates_hz: The low-level env's control rates (Hz).
        profile: ``ideal`` or ``realistic``.
        seed: Seed of the random actions (and of robosuite's env).
        rounds: Blocks each configuration's steps (and the episodes) are split into, alternating the two sides.
        robosuite: robosuite's Python (None: no comparison).
        robosuite_rates_hz: robosuite's control rates (Hz).
    """
    import logging

    logging.disable(logging.WARNING)
    result: dict[str, Any] = {"machine": {**machine_info(), "commit": _commit()}, "profile": profile,
                              "rounds": rounds, "episode_s": EPISODE_S, "warmup_steps": WARMUP_STEPS}
    rs: _Robosuite | None = None
    skipped = None
    if robosuite is None:
        skipped = "no robosuite Python given (--robosuite [PYTHON]; `make bench-env` creates one)"
    else:
        try:
            rs = _Robosuite(robosuite, seed)
        except RobosuiteUnavailable as exc:
            skipped = f"robosuite could not be measured: {exc}"
    lows = [_LowLevel(mode, rate, max(rounds, round(steps * rate / 20.0)), profile, seed)
            for rate in rates_hz for mode in ("cartesian", "joint")]
    skill = _Skill(profile) if episodes > 0 else None

    def ours(r: int) -> None:
        for low in lows:
            low.block(_block_steps(low.total, rounds, r))
        if skill is not None:
            skill.block(range(episodes * r // rounds, episodes * (r + 1) // rounds))

    def theirs(r: int) -> None:
        nonlocal rs, skipped
        if rs is None:
            return
        try:
            for rate in robosuite_rates_hz:
                rs.block(rate, _block_steps(max(rounds, round(steps * rate / 20.0)), rounds, r))
        except RobosuiteUnavailable as exc:
            skipped, rs = f"robosuite failed during the run: {exc}", None

    try:
        for r in range(rounds):
            for side in ((ours, theirs) if r % 2 == 0 else (theirs, ours)):
                side(r)
        result["low_level"] = [low.result() for low in lows]
        result["skill_level"] = skill.result() if skill is not None else None
        result["robosuite"] = None
        if rs is not None:
            try:
                result["robosuite"] = {
                    "python": rs.python, "versions": rs.versions, "controller": rs.controller,
                    "env": {"name": "Lift", "robots": "Panda", "has_renderer": False, "has_offscreen_renderer": False,
                            "use_camera_obs": False, "horizon_s": EPISODE_S},
                    "rates": [rs.result(rate) for rate in robosuite_rates_hz],
                    "engine_cross_check": rs.engine_cross_check(robosuite_rates_hz[0])}
            except RobosuiteUnavailable as exc:
                skipped, result["robosuite"] = f"robosuite failed during the run: {exc}", None
    finally:
        if rs is not None:
            rs.close()
    result["comparison"] = _comparison(result, skipped)
    return result


def _comparison(result: dict[str, Any], skipped: str | None) -> dict[str, Any]:
    """pickplace / robosuite: each low-level row against robosuite at the same rate (with the spread over the
    rounds), the skill level's real-time factor against robosuite at 20 Hz."""
    if result["robosuite"] is None:
        return {"skipped": skipped or "robosuite was not measured", "ratios": []}
    theirs = {r["rate_hz"]: r for r in result["robosuite"]["rates"]}
    ratios = []
    for low in result["low_level"]:
        other = theirs.get(low["rate_hz"])
        if other is None:
            continue
        per_round = [a / b for a, b in zip(low["rounds_steps_per_s"], other["rounds_steps_per_s"], strict=True)]
        ratios.append({"pickplace": f"low level, {low['mode']}, {low['rate_hz']:g} Hz",
                       "robosuite_rate_hz": other["rate_hz"], "steps_per_s_ratio": _ratio(low, other, "steps_per_s"),
                       "real_time_factor_ratio": _ratio(low, other, "real_time_factor"),
                       "rounds_median": float(np.median(per_round)), "rounds_min": min(per_round),
                       "rounds_max": max(per_round)})
    skill = result["skill_level"]
    if skill is not None and 20.0 in theirs:
        other = theirs[20.0]
        per_round = []
        rounds, episodes = len(other["rounds_steps_per_s"]), skill["episodes"]
        for r, steps_per_s in enumerate(other["rounds_steps_per_s"]):  # round r ran seeds [N r / R, N (r + 1) / R)
            rows = skill["rows"][episodes * r // rounds: episodes * (r + 1) // rounds]
            if rows:
                rtf = sum(x["sim_s"] for x in rows) / sum(x["step_wall_s"] for x in rows)
                per_round.append(rtf / (steps_per_s / other["rate_hz"]))
        ratios.append({"pickplace": "skill level", "robosuite_rate_hz": 20.0, "steps_per_s_ratio": None,
                       "real_time_factor_ratio": _ratio(skill, other, "real_time_factor"),
                       "rounds_median": float(np.median(per_round)) if per_round else None,
                       "rounds_min": min(per_round, default=None), "rounds_max": max(per_round, default=None)})
    return {"skipped": None, "ratios": ratios}


# --------------------------------------------------------------------------- output
def print_table(result: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(Console().width, 150))
    m = result["machine"]
    t = Table(title=f"Gymnasium environments, {result['profile']} profile, next to robosuite's Lift "
                    f"({m['cpu_count']} cores, load {m['load_average_1min']:.1f}, commit {m['commit']})")
    for col in ("environment", "env steps/s", "real-time factor", "reset (s)", "physics steps/s",
                "cost / bare mj_step", "x robosuite", "success"):
        t.add_column(col, justify="left" if col == "environment" else "right",
                     no_wrap=col in ("environment", "x robosuite"))
    ratios = {r["pickplace"]: r for r in result["comparison"]["ratios"]}

    def ratio(name: str) -> str:
        r = ratios.get(name)
        if r is None:
            return "—"
        pooled = r["steps_per_s_ratio"] if r["steps_per_s_ratio"] is not None else r["real_time_factor_ratio"]
        if r["rounds_median"] is None:
            return f"{pooled:.2f}"
        return f"{pooled:.2f} ({r['rounds_median']:.2f}; {r['rounds_min']:.2f}–{r['rounds_max']:.2f})"

    for r in result["low_level"]:
        name = f"low level, {r['mode']}, {r['rate_hz']:g} Hz"
        t.add_row(f"pickplace {r['mode']} {r['rate_hz']:g} Hz", f"{r['steps_per_s']:.0f}",
                  f"{r['real_time_factor']:.2f}", f"{r['reset_s_mean']:.2f}", f"{r['physics_steps_per_s']:.0f}",
                  f"{r['cost_vs_bare_mj_step']:.1f}", ratio(name), "—")
    s = result["skill_level"]
    if s is not None:
        lo, hi = s["wilson95"]
        t.add_row(f"pickplace skill level ({s['episodes']} episodes)", f"{s['steps_per_s']:.2f}",
                  f"{s['real_time_factor']:.2f}", f"{s['reset_s_mean']:.2f}", "—", "—", ratio("skill level"),
                  f"{s['successes']}/{s['episodes']} ({lo * 100:.1f}–{hi * 100:.1f} %)")
    rs = result["robosuite"]
    if rs is not None:
        for r in rs["rates"]:
            t.add_row(f"robosuite Lift {r['rate_hz']:g} Hz", f"{r['steps_per_s']:.0f}",
                      f"{r['real_time_factor']:.2f}", f"{r['reset_s_mean']:.2f}", f"{r['physics_steps_per_s']:.0f}",
                      f"{r['cost_vs_bare_mj_step']:.1f}", "1", "—")
    console.print(t)
    low0 = result["low_level"][0]
    console.print(f"low level: PickPlaceLowLevel-v0, {low0['steps']} seeded random steps per mode at "
                  f"{low0['rate_hz']:g} Hz (the same simulated time at the other rates), episodes of "
                  f"{result['episode_s']:g} s; only env.step is timed (resets and {result['warmup_steps']} warm-up "
                  f"steps apart); {result['rounds']} rounds, pickplace and robosuite alternating", highlight=False)
    if s is not None:
        console.print(f"skill level: PickPlace-v0 (default task), seeds {s['seeds'][0]} ... {s['seeds'][1]}, the "
                      f"best-ranked grasp the mask allows; final place error (successes) "
                      f"{s['final_place_error_xy_rms_m'] * 1e3:.2f} mm RMS", highlight=False)
        for f in s["failures"]:
            console.print(f"seed {f['seed']} ({f['object']}): {f['failure_kind']} in {f['failure_phase']}: "
                          f"{f['failure_reason']}", highlight=False, markup=False)
    if rs is not None:
        console.print("x robosuite: pickplace / robosuite at the same control rate, of the pooled steps per second "
                      "(the rounds' median; lowest–highest); skill level: of the real-time factors against robosuite "
                      "at 20 Hz", highlight=False)
        v, c = rs["versions"], rs["controller"]
        console.print(f"robosuite {v['robosuite']} (mujoco {v['mujoco']}, numba {v.get('numba', '?')}, numpy "
                      f"{v['numpy']}) in {rs['python']}: Lift, Panda, {c['composite']} with an {c['arm']} arm "
                      f"(kp {c['kp']}), no renderer, no camera observations; pickplace: mujoco {m['mujoco']}",
                      highlight=False, markup=False)
        e = rs["engine_cross_check"]
        console.print(f"engine cross-check, bare mj_step on robosuite's Lift model: mujoco {e['pickplace_mujoco']} "
                      f"{e['bare_mj_step_per_s_pickplace_mujoco']:.0f}/s, mujoco {e['robosuite_mujoco']} "
                      f"{e['bare_mj_step_per_s_robosuite_mujoco']:.0f}/s "
                      f"(x{e['pickplace_mujoco_over_robosuite_mujoco']:.2f})", highlight=False)
    else:
        console.print(f"comparison skipped: {result['comparison']['skipped']}", highlight=False, markup=False)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="pickplace bench env", description=__doc__.split("\n\n")[0])
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--episodes", type=int, default=10,
                   help="skill-level episodes, seeds 0 ... N-1 (default 10; 0: none)")
    p.add_argument("--steps", type=int, default=400,
                   help="low-level steps per action mode at 20 Hz; the same simulated time at other rates "
                        "(default 400)")
    p.add_argument("--rate", type=float, nargs="+", default=[20.0, 50.0], metavar="HZ",
                   help="low-level control rates (Hz, 20 to 50; default 20 50)")
    p.add_argument("--rounds", type=int, default=4,
                   help="blocks per configuration, alternating pickplace and robosuite (default 4)")
    p.add_argument("--profile", default="ideal", choices=["ideal", "realistic"], help="robot profile")
    p.add_argument("--seed", type=int, default=0, help="seed of the random actions")
    p.add_argument("--robosuite", nargs="?", const=DEFAULT_ROBOSUITE_PYTHON, default=None, metavar="PYTHON",
                   help=f"measure robosuite's Lift with this Python (default {DEFAULT_ROBOSUITE_PYTHON}, which "
                        "`make bench-env` creates); without it the comparison is skipped")
    p.add_argument("--robosuite-rates", type=float, nargs="+", default=[20.0, 50.0, 500.0], metavar="HZ",
                   help="robosuite's control rates (Hz; default 20 50 500)")
    a = p.parse_args(argv)
    if a.episodes < 0 or a.steps < 1 or a.rounds < 1:
        p.error("--episodes must be >= 0, --steps >= 1 and --rounds >= 1")
    if any(r <= 0 for r in a.robosuite_rates):
        p.error("--robosuite-rates must be > 0")
    result = run(a.episodes, a.steps, tuple(a.rate), a.profile, a.seed, a.rounds, a.robosuite,
                 tuple(a.robosuite_rates))
    if a.json:
        print(json.dumps(result, indent=2, default=float))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
