"""Gymnasium environment benchmark: env steps per second and real-time factor at both action levels, and the
skill level's success over seeded episodes.

Measured in one run (ideal profile unless ``--profile realistic``), wall times on this machine:

* low level (``pickplace/PickPlaceLowLevel-v0`` at ``--rate`` Hz, Cartesian and joint actions): ``--steps`` steps
  of seeded random actions (an episode that ends is reset; resets are timed apart). Steps per second, the
  real-time factor (simulated s per wall s of the steps), and the physics steps per second against a bare
  ``mujoco.mj_step`` loop on the same model in the same run (the controller's and monitor's share of the cost);
* skill level (``pickplace/PickPlace-v0``): ``--episodes`` episodes, reset with seeds 0 … N-1 (the object's start and
  goal drawn around the default scene's), each choosing the best-ranked grasp the mask allows, then the next one
  if a choice cannot start. Success (with its 95 % Wilson interval), env steps per second, the real-time factor
  of the steps (simulated s of the pick and places per wall s), the final place error and each failure.

Usage: ``pickplace bench env [--json] [--episodes N] [--steps N] [--rate HZ] [--profile P] [--seed S]``
(``benchmarks/env.py`` is the same).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np

from pickplace.eval.bench import machine_info


def _bare_step_rate(env: Any, steps: int) -> float:
    """Physics steps per wall second of a bare ``mj_step`` loop on the environment's model (arm torques zero)."""
    import mujoco

    robot = env.unwrapped._robot
    d = robot.make_data()
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(robot.mj, d)
    return steps / (time.perf_counter() - t0)


def low_level(mode: str, steps: int, rate_hz: float, profile: str, seed: int) -> dict[str, Any]:
    """``steps`` random steps of the low-level env in ``mode`` (``cartesian`` or ``joint``): rates and ends."""
    import gymnasium as gym

    import pickplace.envs  # noqa: F401  (registers the ids)

    env = gym.make("pickplace/PickPlaceLowLevel-v0", action_mode=mode, control_rate_hz=rate_hz, profile=profile,
                   max_steps=200)
    env.action_space.seed(seed)
    t0 = time.perf_counter()
    env.reset(seed=seed)
    reset_s = [time.perf_counter() - t0]
    step_s, ends = 0.0, {"truncated": 0}
    for _ in range(steps):
        action = env.action_space.sample()
        t0 = time.perf_counter()
        _, _, terminated, truncated, info = env.step(action)
        step_s += time.perf_counter() - t0
        if terminated or truncated:
            key = "truncated" if truncated else (info["failure_kind"] or "success")
            ends[key] = ends.get(key, 0) + 1
            t0 = time.perf_counter()
            env.reset()
            reset_s.append(time.perf_counter() - t0)
    per_step = env.unwrapped.steps_per_action
    bare = _bare_step_rate(env, 5000)
    env.close()
    sim_s = steps / rate_hz
    return {"mode": mode, "rate_hz": rate_hz, "steps": steps, "steps_per_s": steps / step_s,
            "real_time_factor": sim_s / step_s, "reset_s_mean": float(np.mean(reset_s)), "resets": len(reset_s),
            "physics_steps_per_s": steps * per_step / step_s, "bare_mj_step_per_s": bare,
            "cost_vs_bare_mj_step": bare / (steps * per_step / step_s), "episode_ends": ends}


def skill_level(episodes: int, profile: str) -> dict[str, Any]:
    """``episodes`` seeded episodes of the skill-level env, each trying the mask's grasps in rank order."""
    import gymnasium as gym

    import pickplace.envs  # noqa: F401  (registers the ids)

    env = gym.make("pickplace/PickPlace-v0", profile=profile)
    rows = []
    for seed in range(episodes):
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
        rows.append({"seed": seed, "object": info["object"], "success": bool(info["success"]), "steps": steps,
                     "step_wall_s": step_s, "reset_wall_s": reset_s, "sim_s": info["sim_time_s"] - sim0,
                     "final_place_error_xy_m": info.get("final_place_error_xy_m", math.nan),
                     "failure_phase": info.get("failure_phase"), "failure_kind": info.get("failure_kind"),
                     "failure_reason": info.get("failure_reason") or info.get("invalid_action") or None})
    env.close()
    from pickplace.eval.campaign.summary import wilson_interval

    ok = [r for r in rows if r["success"]]
    lo, hi = wilson_interval(len(ok), len(rows))
    wall = sum(r["step_wall_s"] for r in rows)
    errors = [r["final_place_error_xy_m"] for r in ok]
    return {"episodes": len(rows), "successes": len(ok), "wilson95": [lo, hi],
            "steps_per_s": sum(r["steps"] for r in rows) / wall,
            "real_time_factor": sum(r["sim_s"] for r in rows) / wall,
            "reset_s_mean": float(np.mean([r["reset_wall_s"] for r in rows])),
            "final_place_error_xy_rms_m": float(np.sqrt(np.mean(np.square(errors)))) if errors else math.nan,
            "failures": [r for r in rows if not r["success"]], "rows": rows}


def run(episodes: int = 10, steps: int = 400, rate_hz: float = 20.0, profile: str = "ideal",
        seed: int = 0) -> dict[str, Any]:
    """Both levels, measured in one run."""
    import logging

    logging.disable(logging.WARNING)
    return {"machine": machine_info(), "profile": profile,
            "low_level": [low_level(m, steps, rate_hz, profile, seed) for m in ("cartesian", "joint")],
            "skill_level": skill_level(episodes, profile) if episodes > 0 else None}


def print_table(result: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    t = Table(title=f"Gymnasium environments, {result['profile']} profile (wall times on this machine)")
    for col in ("environment", "env steps/s", "real-time factor", "reset (s)", "physics steps/s",
                "cost / bare mj_step", "success"):
        t.add_column(col, justify="left" if col == "environment" else "right")
    for r in result["low_level"]:
        t.add_row(f"low level, {r['mode']}, {r['rate_hz']:g} Hz",
                  f"{r['steps_per_s']:.0f}", f"{r['real_time_factor']:.2f}", f"{r['reset_s_mean']:.2f}",
                  f"{r['physics_steps_per_s']:.0f}", f"{r['cost_vs_bare_mj_step']:.1f}", "—")
    s = result["skill_level"]
    if s is not None:
        lo, hi = s["wilson95"]
        t.add_row(f"skill level, {s['episodes']} episodes", f"{s['steps_per_s']:.2f}",
                  f"{s['real_time_factor']:.2f}", f"{s['reset_s_mean']:.2f}", "—", "—",
                  f"{s['successes']}/{s['episodes']} ({lo * 100:.0f}–{hi * 100:.0f} %)")
    console.print(t)
    steps = result["low_level"][0]["steps"]
    console.print(f"low level: PickPlaceLowLevel-v0, {steps} seeded random steps per mode; skill level: PickPlace-v0, "
                  "seeds 0 ... N-1, the best-ranked grasp the mask allows", highlight=False)
    if s is not None:
        console.print(f"final place error (successes): {s['final_place_error_xy_rms_m'] * 1e3:.2f} mm RMS",
                      highlight=False)
        for f in s["failures"]:
            console.print(f"seed {f['seed']} ({f['object']}): {f['failure_kind']} in {f['failure_phase']}: "
                          f"{f['failure_reason']}", highlight=False, markup=False)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="pickplace bench env", description=__doc__.split("\n\n")[0])
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--episodes", type=int, default=10, help="skill-level episodes (default 10; 0: none)")
    p.add_argument("--steps", type=int, default=400, help="low-level steps per action mode (default 400)")
    p.add_argument("--rate", type=float, default=20.0, help="low-level control rate (Hz, 20 to 50; default 20)")
    p.add_argument("--profile", default="ideal", choices=["ideal", "realistic"], help="robot profile")
    p.add_argument("--seed", type=int, default=0, help="seed of the low-level random actions")
    a = p.parse_args(argv)
    if a.episodes < 0 or a.steps < 1:
        p.error("--episodes must be >= 0 and --steps >= 1")
    result = run(a.episodes, a.steps, a.rate, a.profile, a.seed)
    if a.json:
        print(json.dumps(result, indent=2, default=float))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
