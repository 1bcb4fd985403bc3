"""Control benchmark: tracking accuracy and the wall-clock cost of a control step against a bare ``mj_step``.

Measured in one run, on the default scene:

* accuracy: the TOPP-RA trajectory home -> pregrasp (``TimingConfig.ur5e()``) tracked with joint impedance
  (with and without inverse-dynamics feedforward), and a 0.15 m Cartesian descent from pregrasp;
* cost per step (µs) of the two loops, each against a bare ``mujoco.mj_step`` baseline that replays the
  torques the loop applied from the same start state (MuJoCo is deterministic, so the replay visits the same
  states, contacts and solver work): :func:`control.track` (joint impedance, home -> pregrasp) and
  :func:`control.move_vertical` (Cartesian impedance, 0.15 m descent), whose per-step cost includes the
  law, clipping, logging and ``mj_step``; plus the two control laws alone in a tight loop. Every cost is the
  best of ``--repeats`` interleaved rounds (the machines are shared and noisy).

Usage: ``python benchmarks/control.py [--json] [--calls N] [--repeats R]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from pickplace.eval.bench import machine_info
from pickplace.grasping.configurations import solve_grasp_configurations
from pickplace.motion import control
from pickplace.motion.control import ControlConfig
from pickplace.motion.timing import TimingConfig, retime
from pickplace.robot.model import Robot, build


def _data_at(robot: Robot, q: np.ndarray) -> mujoco.MjData:
    d = robot.make_data()
    d.qpos[robot.handles.arm_qpos] = q
    mujoco.mj_forward(robot.mj, d)
    return d


def _replay_us(robot: Robot, q_start: np.ndarray, tau: np.ndarray) -> float:
    """µs per bare ``mj_step`` replaying the torques (steps, 6) a loop applied, from the same start state.

    MuJoCo is deterministic, so the replay visits exactly the states of the loop (same contacts, same solver
    work): the difference to the loop's cost is the controller's, nothing else.
    """
    d = _data_at(robot, q_start)
    ctrl, act = d.ctrl, robot.handles.arm_actuators
    t0 = time.perf_counter()
    for u in tau:
        ctrl[act] = u
        mujoco.mj_step(robot.mj, d)
    return (time.perf_counter() - t0) / len(tau) * 1e6


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _law_us(robot: Robot, config: ControlConfig, calls: int) -> tuple[float, float]:
    """µs per call of :func:`control.joint_impedance` and :func:`control.cartesian_impedance` at home."""
    arm = control.arm_model(robot)
    q, z3, z6 = robot.home_q, np.zeros(3), np.zeros(6)
    qd = np.full(6, 0.1)
    kp, kd = config.joint_kp, config.joint_kd
    t0 = time.perf_counter()
    for _ in range(calls):
        control.joint_impedance(arm, q, qd, q, z6, z6, kp, kd)
    joint = (time.perf_counter() - t0) / calls * 1e6
    R, K = np.eye(3), config.cartesian_stiffness
    t0 = time.perf_counter()
    for _ in range(calls):
        control.cartesian_impedance(arm, q, qd, z3, z3, z3, R, K, 1.0, q, 10.0, 6.0)
    cart = (time.perf_counter() - t0) / calls * 1e6
    return joint, cart


def run(calls: int = 3000, repeats: int = 5) -> dict[str, Any]:
    """Run the benchmark; returns one JSON-serialisable dict."""
    robot = build()
    configs = solve_grasp_configurations(robot)
    cfg = ControlConfig()
    traj = retime(np.array([robot.home_q, configs.pregrasp.q]), TimingConfig.ur5e())
    pre = configs.pregrasp.q

    def track(c: ControlConfig) -> control.TrackingRecord:
        return control.track(robot, _data_at(robot, robot.home_q), traj, c)

    def descend() -> control.CartesianRecord:
        d = _data_at(robot, pre)
        return control.move_vertical(robot, d, d.site_xpos[robot.handles.tcp_site, 2] - 0.15, cfg)

    tracking = {}
    for name, c in (("feedforward", cfg), ("gravity_only", ControlConfig(feedforward=False))):
        rec = track(c)
        tracking[name] = {"max_error_rad": rec.max_error_rad, "rms_error_rad": rec.rms_error_rad,
                          "final_error_rad": rec.final_error_rad, "saturation_events": rec.saturation_events,
                          "steps": rec.steps, "sim_duration_s": rec.duration_s}
    cart = descend()
    cartesian = {"final_height_error_m": cart.final_height_error_m, "lateral_drift_max_m": cart.lateral_drift_max_m,
                 "orientation_error_max_rad": cart.orientation_error_max_rad,
                 "saturation_events": cart.saturation_events, "steps": cart.steps, "sim_duration_s": cart.duration_s}

    keys = ("joint_loop", "joint_replay", "cartesian_loop", "cartesian_replay", "joint_law", "cartesian_law")
    rounds: dict[str, list[float]] = {k: [] for k in keys}
    for _ in range(repeats):  # interleaved rounds, best of
        rec, wall = _timed(lambda: track(cfg))
        rounds["joint_loop"].append(wall / rec.steps * 1e6)
        rounds["joint_replay"].append(_replay_us(robot, robot.home_q, rec.tau))
        crec, wall = _timed(descend)
        rounds["cartesian_loop"].append(wall / crec.steps * 1e6)
        rounds["cartesian_replay"].append(_replay_us(robot, pre, crec.tau))
        joint, cart_law = _law_us(robot, cfg, calls)
        rounds["joint_law"].append(joint)
        rounds["cartesian_law"].append(cart_law)
    best = {k: min(v) for k, v in rounds.items()}
    return {
        "trajectory": {"segment": "home->pregrasp", "duration_s": traj.duration_s, "timing": "TimingConfig.ur5e()"},
        "tracking": tracking,
        "cartesian_descent_0.15m": cartesian,
        "step_cost_us": best,
        "ratio_to_bare_mj_step": {"joint_loop": best["joint_loop"] / best["joint_replay"],
                                  "cartesian_loop": best["cartesian_loop"] / best["cartesian_replay"]},
        "law_calls": calls,
        "repeats": repeats,
        "timestep_s": robot.mj.opt.timestep,
        "machine": machine_info(),
    }


def print_table(result: dict[str, Any]) -> None:
    """Render the result as two rich tables."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    traj = result["trajectory"]
    acc = Table(title=f"Tracking {traj['segment']} ({traj['duration_s']:.3f} s, {traj['timing']}) + 0.1 s settle")
    for col in ("controller", "max error (mrad)", "rms (mrad)", "final (mrad)", "saturated steps"):
        acc.add_column(col, justify="right" if col != "controller" else "left")
    for name, row in result["tracking"].items():
        acc.add_row(name, f"{row['max_error_rad'] * 1e3:.3g}", f"{row['rms_error_rad'] * 1e3:.3g}",
                    f"{row['final_error_rad'] * 1e3:.3g}", str(row["saturation_events"]))
    console.print(acc)
    c = result["cartesian_descent_0.15m"]
    console.print(f"Cartesian 0.15 m descent: final height error {c['final_height_error_m'] * 1e3:.3g} mm, "
                  f"lateral drift {c['lateral_drift_max_m'] * 1e3:.3g} mm, orientation "
                  f"{c['orientation_error_max_rad']:.3g} rad, {c['saturation_events']} saturated steps")
    cost = Table(title=f"Cost per control step, µs (best of {result['repeats']} interleaved rounds)")
    for col in ("loop", "control loop (law + mj_step)", "bare mj_step (same torques replayed)", "ratio",
                "law alone"):
        cost.add_column(col, justify="left" if col == "loop" else "right")
    us, ratio = result["step_cost_us"], result["ratio_to_bare_mj_step"]
    for name, label in (("joint", "joint impedance (track)"), ("cartesian", "Cartesian impedance (move_vertical)")):
        cost.add_row(label, f"{us[name + '_loop']:.1f}", f"{us[name + '_replay']:.1f}",
                     f"{ratio[name + '_loop']:.2f}", f"{us[name + '_law']:.1f}")
    console.print(cost)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print rich tables, or one JSON object with ``--json``. Returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    parser.add_argument("--calls", type=int, default=3000, help="calls per law-alone cost measurement")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds; the best is reported")
    args = parser.parse_args(argv)
    if args.calls < 100 or args.repeats < 1:
        parser.error("--calls must be >= 100 and --repeats >= 1")
    result = run(args.calls, args.repeats)
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
