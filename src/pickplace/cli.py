"""The ``pickplace`` command line: ``run``, ``replay``, ``eval``, ``report``, ``dataset``, ``inspect`` and ``bench``.

The library logs and never prints; this module prints (rich tables) and turns every
:class:`~pickplace.errors.PickPlaceError` into one clear line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from pickplace import __version__
from pickplace.errors import ConfigError, PickPlaceError
from pickplace.world.config import SceneConfig

if TYPE_CHECKING:
    from pickplace.eval.campaign import CampaignConfig, CampaignRun
    from pickplace.eval.dataset import RecordConfig
    from pickplace.robot.model import Robot
    from pickplace.task.episode import EpisodeConfig, EpisodeResult
    from pickplace.task.episode_file import SavedEpisode
    from pickplace.task.faults import FaultConfig
    from pickplace.task.task_episode import TaskResult
    from pickplace.task.tasks import TaskConfig
    from pickplace.task.telemetry import Telemetry

EXIT_FAILURE = 1
EXIT_USAGE = 2


def _scene_from_args(args: argparse.Namespace) -> SceneConfig:
    """The scene of ``pickplace inspect``: the default one, with ``--obstacle`` and ``--object``."""
    obj = {"library": args.object} if getattr(args, "object", None) else None
    return SceneConfig.from_mapping({"obstacle": True} if getattr(args, "obstacle", False) else {}, object_data=obj)


# --------------------------------------------------------------------------- #
# inspect
# --------------------------------------------------------------------------- #


def inspect_data(scene: SceneConfig) -> dict[str, object]:
    """Everything ``pickplace inspect`` reports, as JSON-ready data."""
    from pickplace.eval.campaign import RandomizationSpec
    from pickplace.grasping.configurations import solve_grasp_configurations
    from pickplace.grasping.hold import hold_margin
    from pickplace.robot import model
    from pickplace.robot.gripper import GripperGeometry

    robot = model.build(scene)
    m = robot.mj
    geom = GripperGeometry.measure(robot)
    joints = [
        {"name": name, "lower_rad": float(lo), "upper_rad": float(hi), "torque_limit_nm": float(t),
         "home_rad": float(q)}
        for name, lo, hi, t, q in zip(model.ARM_JOINTS, robot.arm_lower, robot.arm_upper,
                                      robot.torque_limits_nm, robot.home_q, strict=True)
    ]
    bodies = [m.body(b).name for b in sorted(robot.handles.robot_bodies)]
    masses = {name: float(m.body_mass[m.body(name).id]) for name in bodies}
    configs = solve_grasp_configurations(robot)
    margin = hold_margin(scene)
    nominal = margin.nominal
    lowest = RandomizationSpec().object_friction[0]  # the lowest friction of the default randomization
    margins = [margin] if lowest == scene.object.friction else [
        hold_margin(scene.with_object(friction=lowest)), margin]
    half = configs.targets.width_m / 2
    return {
        "version": __version__,
        "model": {
            "nq": int(m.nq), "nv": int(m.nv), "nu": int(m.nu), "timestep_s": float(m.opt.timestep),
            "joints": joints, "masses_kg": masses, "robot_mass_kg": float(sum(masses.values())),
            "pinocchio_joints": list(robot.pin.names)[1:],
        },
        "gripper": {
            "open_inner_face_y_m": geom.open_inner_face_y_m,
            "closed_inner_face_y_m": geom.closed_inner_face_y_m,
            "object_half_width_m": half,
            "open_width_m": geom.open_width_m,
            "tcp_offset_m": geom.tcp_offset_m,
            "closed_target_past_contact_m": half - geom.closed_inner_face_y_m,
        },
        "ik": [
            {"name": r.name, "position_error_m": r.position_error_m,
             "orientation_error_rad": r.orientation_error_rad, "iterations": r.iterations,
             "q_rad": [float(v) for v in r.q]}
            for r in configs.results()
        ],
        "hold": {
            "object": scene.object.name,
            "mass_kg": nominal.mass_kg,
            "held": nominal.held,
            "slip_m": nominal.slip_m,
            "slip_rad": nominal.slip_rad,
            "grip_force_n": nominal.grip_force_n,
            "min_grip_force_n": nominal.min_grip_force_n,
            "peak_acceleration_m_s2": nominal.peak_acceleration_m_s2,
            "safety_factor": margin.safety_factor,
            "trials": [{"mass_kg": r.mass_kg, "held": r.held, "slip_m": r.slip_m,
                        "grip_force_n": r.grip_force_n} for r in margin.results],
            "by_friction": [
                {"friction": m.friction, "safety_factor": m.safety_factor,
                 "heaviest_held_kg": m.safety_factor * scene.object.mass_kg, "coulomb_limit_kg": m.coulomb_limit_kg,
                 "trials": [{"mass_kg": r.mass_kg, "held": r.held, "slip_m": r.slip_m}
                            for r in m.results]}
                for m in margins
            ],
        },
    }


def _cmd_inspect(args: argparse.Namespace, console: Console) -> int:
    scene = _scene_from_args(args)
    if args.export_xml:
        from pickplace.robot import model

        path = Path(args.export_xml)
        path.write_text(model.scene_xml(scene))
        console.print(f"wrote the compiled scene MJCF to {path}")
        if not args.json:
            return 0
    data = inspect_data(scene)
    if args.json:
        print(json.dumps(data, indent=2))
        return 0

    mdl = data["model"]
    t = Table(title=f"UR5e + gripper  (nq={mdl['nq']}, nu={mdl['nu']}, dt={mdl['timestep_s'] * 1e3:g} ms)")
    for col in ("joint", "lower (rad)", "upper (rad)", "torque limit (N·m)", "home (rad)"):
        t.add_column(col, justify="right" if col != "joint" else "left")
    for j in mdl["joints"]:
        t.add_row(j["name"], f"{j['lower_rad']:+.4f}", f"{j['upper_rad']:+.4f}", f"{j['torque_limit_nm']:.0f}",
                  f"{j['home_rad']:+.4f}")
    console.print(t)
    console.print("masses (kg): " + ", ".join(f"{k} {v:.3f}" for k, v in mdl["masses_kg"].items()))

    g = data["gripper"]
    console.print(
        f"gripper: pad inner face open ±{g['open_inner_face_y_m'] * 1e3:.1f} mm, closed target "
        f"±{g['closed_inner_face_y_m'] * 1e3:.1f} mm, object half-width {g['object_half_width_m'] * 1e3:.1f} mm "
        f"(the closed target lies {g['object_half_width_m'] * 1e3 - g['closed_inner_face_y_m'] * 1e3:.1f} mm "
        f"inside the object), open width {g['open_width_m'] * 1e3:.1f} mm, tcp {g['tcp_offset_m'] * 1e3:.1f} mm "
        "from tool0"
    )
    t = Table(title="IK (DLS) for the four tcp targets")
    for col in ("target", "position error (mm)", "orientation error (rad)", "iterations"):
        t.add_column(col, justify="right" if col != "target" else "left")
    for r in data["ik"]:
        t.add_row(r["name"], f"{r['position_error_m'] * 1e3:.4f}", f"{r['orientation_error_rad']:.2e}",
                  str(r["iterations"]))
    console.print(t)
    h = data["hold"]
    t = Table(title="Hold test: close, lift 0.15 m, carry 0.40 m sideways")
    for col in ("mass (kg)", "held", "slip (mm)", "grip force / pad (N)"):
        t.add_column(col, justify="right")
    for r in h["trials"]:
        t.add_row(f"{r['mass_kg']:.3f}", "yes" if r["held"] else "NO", f"{r['slip_m'] * 1e3:.3f}",
                  f"{r['grip_force_n']:.1f}")
    console.print(t)
    console.print(
        f"nominal {h['object']}: slip {h['slip_m'] * 1e3:.3f} mm, grip force {h['grip_force_n']:.1f} N per pad, "
        f"peak acceleration {h['peak_acceleration_m_s2']:.2f} m/s²"
    )
    for m in h["by_friction"]:
        console.print(
            f"friction μ {m['friction']:g}: safety factor ≥ {m['safety_factor']:g} (heaviest held "
            f"{m['heaviest_held_kg']:.2f} kg / its mass; Coulomb limit 2μF/(g + a) = {m['coulomb_limit_kg']:.2f} "
            "kg)", highlight=False)
    return 0


# --------------------------------------------------------------------------- #
# run
# --------------------------------------------------------------------------- #

#: The reference design's reported figures, shown next to ours.
DESIGN_NOTE = {
    "place_error": "1.4 mm RMS",
    "cycle_time": "8.2 s",
    "tracking": "< 5 mrad",
    "grip_force": "≈ m·g",
    "saturation": "none",
}


def episode_config_from_args(args: argparse.Namespace, base: EpisodeConfig | None = None) -> EpisodeConfig:
    """The episode config of ``pickplace run``/``eval``: ``--config`` TOML (or ``base``), then the flags on top."""
    from pickplace.task.episode import EpisodeConfig

    if base is None:
        base = EpisodeConfig.from_toml(args.config) if args.config else EpisodeConfig()
    config = base
    if args.fault:
        config = dataclasses.replace(config, faults=_faults_from_args(args.fault, config.faults))
    if args.profile is not None and args.profile != config.profile.name:
        config = config.with_profile(args.profile)
    scene: dict[str, object] = {}
    obj: dict[str, object] = {}
    if args.object is not None:
        obj["library"] = args.object
    if args.object_mesh is not None:
        if args.object_mass is None:
            raise CliError("--object-mesh needs --object-mass KG (the mass of the object)")
        stem = "".join(c if c.isalnum() else "_" for c in Path(args.object_mesh).stem).strip("_") or "mesh"
        obj.update(name=stem if stem[0].isalpha() else f"mesh_{stem}", kind="mesh", mesh_path=args.object_mesh)
    if args.object_mass is not None:
        obj["mass_kg"] = args.object_mass
    for flag, key in (("start", "start_xy_m"), ("cube_start", "cube_start_xy_m"), ("goal", "goal_xy_m")):
        if getattr(args, flag) is not None:
            scene[key] = tuple(getattr(args, flag))
    for flag, key in (("start_yaw", "start_yaw_rad"), ("cube_yaw", "cube_yaw_rad"), ("goal_yaw", "goal_yaw_rad"),
                      ("cube_mass", "cube_mass_kg"), ("cube_size", "cube_size_m"), ("friction", "cube_friction")):
        if getattr(args, flag) is not None:
            scene[key] = getattr(args, flag)
    if args.obstacle:
        scene["obstacle"] = True
    if not scene and not obj:
        return config
    from pickplace.world.config import SceneConfig

    return dataclasses.replace(config, scene=SceneConfig.from_mapping(scene, config.scene, obj or None))


def _faults_from_args(items: list[str], base: FaultConfig) -> FaultConfig:
    """``--fault KEY=VALUE`` options (VALUE in TOML syntax: ``0.5``, ``true``, ``[0, 0, -40]``) over ``base``."""
    import tomllib

    from pickplace.task.faults import LEGACY_FAULT_KEYS, FaultConfig
    from pickplace.world.config import from_mapping

    values: dict[str, object] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError("--fault", item, "must be KEY=VALUE, e.g. --fault pad_friction_scale=0.5")
        try:
            values[key] = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            raise ConfigError(f"faults.{key}", raw, "must be a number, true/false or a list like [0, 0, -40]") from None
    return from_mapping(FaultConfig, values, "faults", base, LEGACY_FAULT_KEYS)


def _mm(value: float | None) -> str:
    return "—" if value is None or value != value else f"{value * 1e3:.3f} mm"


#: The conditions every figure of ``pickplace run`` holds under, by profile.
CONDITIONS = {
    "ideal": ("Ideal robot: the object's pose is read from the simulator (exact, no delay), the controller's "
              "dynamics model is the simulated arm's own, control runs at the 1 kHz physics rate without "
              "delay. Tracking errors: every control loop of every phase; --json has them per phase."),
    "realistic": ("Realistic robot: the object's pose from a simulated D435 depth camera (noise, missing edge "
                  "pixels, a calibration error drawn per episode), slip from the fingers and the wrist "
                  "force/torque sensor, the weight from the wrist; control at 500 Hz with 2 ms latency on "
                  "quantized, noisy encoders, a dynamics model off by up to 10 % per link, joint friction the "
                  "controller does not know, a gripper closing at 0.15 m/s. Errors are measured against the "
                  "simulator's truth, which the robot never used. Tracking errors: every control loop of every "
                  "phase."),
}


def _worst(result: EpisodeResult, figure: str) -> str:
    """`` (worst: PHASE)`` for the phase with the largest ``figure`` of ``result.tracking_by_phase``."""
    values = {p: getattr(t, figure) for p, t in result.tracking_by_phase.items()
              if getattr(t, figure) == getattr(t, figure)}  # not NaN
    return f" (worst: {max(values, key=values.__getitem__)})" if values else ""


def print_episode(result: EpisodeResult, console: Console) -> None:
    """The phase timeline and the results table of one episode."""
    t = Table(title=f"Phase timeline (seed {result.seed})")
    for col in ("phase", "start (s)", "duration (s)", ""):
        t.add_column(col, justify="left" if col in ("phase", "") else "right")
    style = {"ok": "[green]ok[/]", "recovered": "[yellow]failed → recovery[/]", "failed": "[red]FAILED[/]"}
    for phase, start, dur, outcome in result.phase_timeline:
        status = style[outcome]
        t.add_row(phase, f"{start:.3f}", f"{dur:.3f}", status)
    console.print(t)

    t = Table(title=f"Results ({result.config.profile.name} profile)",
              caption=CONDITIONS[result.config.profile.name])
    t.add_column("measure")
    t.add_column("design note", justify="right")
    t.add_column("pickplace", justify="right")
    sc = result.config.scene
    mg = sc.object.mass_kg * 9.81
    t.add_row("success", "50/50 picks", "[green]yes[/]" if result.success else "[red]no[/]")
    t.add_row("place error xy (at rest)", DESIGN_NOTE["place_error"], _mm(result.place_error_xy_m))
    t.add_row("place error xy 1 s after release", "—", _mm(result.final_place_error_xy_m))
    t.add_row("place error z / yaw", "—", f"{_mm(result.place_error_z_m)} / {result.place_error_yaw_rad:.2e} rad")
    t.add_row("cycle time (simulated)", DESIGN_NOTE["cycle_time"], f"{result.cycle_time_s:.3f} s")
    t.add_row("joint tracking error max / rms (trajectories and holds)", DESIGN_NOTE["tracking"],
              f"{result.tracking_error_max_rad * 1e3:.3f} / {result.tracking_error_rms_rad * 1e3:.3f} mrad"
              f"{_worst(result, 'joint_error_max_rad')}")
    t.add_row("tcp tracking error max (Cartesian moves)", "—",
              f"{_mm(result.tcp_tracking_error_max_m)} / {result.tcp_orientation_error_max_rad * 1e3:.3f} mrad"
              f"{_worst(result, 'tcp_position_error_max_m')}")
    t.add_row("grip: pad normal force during lift", "—", f"{result.lift_grip_force_n:.1f} N")
    t.add_row("grip: load carried by the pads (m·g)", DESIGN_NOTE["grip_force"],
              f"{result.lift_load_n:.2f} N ({mg:.2f} N)")
    t.add_row("force closure (margin)", "—", f"{'yes' if result.force_closure else 'no'} ({result.grasp_margin:.3f})")
    t.add_row("slip in the grip (max)", "—", _mm(result.slip_max_m))
    t.add_row("torque saturation", DESIGN_NOTE["saturation"], f"{result.torque_saturation_events} steps")
    t.add_row("joint limits, every 1 ms step of the motions: steps over / peak speed, acceleration, torque", "—",
              f"{result.limit_violations} / {result.joint_speed_ratio_max:.3f}, "
              f"{result.joint_acceleration_ratio_max:.3f}, {result.torque_ratio_max:.3f} of the limits")
    t.add_row("joint limits while the arm holds still (contacts jolting it): steps over", "—",
              f"{result.hold_limit_violations}" + (f" (worst: {result.hold_limit_worst})"
                                                   if result.hold_limit_violations else ""))
    t.add_row("tcp off its straight line: final approach / set-down (max)", "—",
              f"{_mm(result.approach_line_deviation_max_m)} / {_mm(result.place_line_deviation_max_m)}")
    t.add_row("IK residual (max)", "—",
              f"{_mm(result.ik_position_error_m)} / {result.ik_orientation_error_rad:.1e} rad")
    plan = ", ".join(f"{k} {v * 1e3:.1f} ms ({result.waypoints_raw[k]}→{result.waypoints_shortcut[k]} wp)"
                     for k, v in result.plan_time_s.items())
    t.add_row("planning (per segment)", "200–600 ms", plan or "—")
    for what in ("resting", "in hand"):
        errs = [(pos, yaw) for _, w, pos, yaw in result.pose_estimates if w == what]
        if errs:
            worst = max(errs)
            t.add_row(f"object pose estimate, {what} (worst of {len(errs)})", "—",
                      f"{_mm(worst[0])} / {math.degrees(abs(worst[1])):.2f}°")
    t.add_row("wall time / real-time factor", "—", f"{result.wall_time_s:.2f} s / {result.real_time_factor:.1f}×")
    t.add_row("recoveries", "—", str(result.retries))
    console.print(t)
    for line in result.recoveries:
        console.print(f"recovery: {escape(line)}", highlight=False)


def add_web_options(p: argparse.ArgumentParser) -> None:
    """The web viewer's options (``run`` and ``replay``)."""
    p.add_argument("--web", action="store_true",
                   help="serve the episode in a web 3D viewer until Ctrl-C: robot, objects, planned paths, grasps, "
                        "pad forces and a timeline (needs pip install 'pickplace[web]'; no display needed)")
    p.add_argument("--host", default="127.0.0.1", metavar="HOST",
                   help="with --web: the address to serve on (default 127.0.0.1; 0.0.0.0 for every interface)")
    p.add_argument("--port", type=int, default=8080, metavar="PORT",
                   help="with --web: the port (default 8080; the next free one if it is busy; 0: any free one)")


def add_task_options(p: argparse.ArgumentParser) -> None:
    """The task options of ``run`` (several objects)."""
    p.add_argument("--task", choices=("place", "stack", "clear"),
                   help="a task with several objects: each to its goal, a tower, or everything into the bin")
    p.add_argument("--objects", type=int, metavar="N",
                   help="with --task: N objects drawn at random from the library (default 3, or the config's "
                        "[[objects]]); drawn from the seed")
    p.add_argument("--order", choices=("planned", "listed"),
                   help="with --task: the task planner's order (default) or the objects' listed order")


def task_config_from_args(args: argparse.Namespace, config: EpisodeConfig) -> EpisodeConfig:
    """The config of ``run --task``: the config's [task] and [[objects]], or random objects, with the flags on top."""
    import numpy as np

    from pickplace.task.tasks import random_task_scene

    task = _task_from_flags(args, config)
    if args.objects is not None or (config.task is None and not config.scene.others):  # else: its [[objects]]
        n = args.objects if args.objects is not None else 3
        scene = random_task_scene(task.kind, n, np.random.default_rng([args.seed, 7]), base=config.scene)
    else:
        scene = _with_bin(task, config.scene)
    return dataclasses.replace(config, scene=scene, task=task)


def _task_from_flags(args: argparse.Namespace, config: EpisodeConfig) -> TaskConfig:
    """The config's [task], or a new one of kind ``--task``, changed by ``--task`` and ``--order``."""
    from pickplace.task.tasks import TaskConfig

    task = config.task if config.task is not None else TaskConfig(kind=args.task)
    return dataclasses.replace(task, **{k: v for k, v in (("kind", args.task), ("order", args.order))
                                        if v is not None})


def _with_bin(task: TaskConfig, scene: SceneConfig) -> SceneConfig:
    """The scene, with the default bin for a clear task if it has none."""
    from pickplace.world.config import BinConfig

    return dataclasses.replace(scene, bin=BinConfig()) if task.kind == "clear" and scene.bin is None else scene


def print_task(result: TaskResult, console: Console) -> None:
    """The picks and the objects of one task."""
    t = Table(title=f"{result.kind} task, {result.order_policy} order (seed {result.seed})",
              caption="Ideal robot. Times are simulated: each pick and place from its IDLE to the end of the "
                      "settling after its release (1 s after it by default), the return home included.")
    for col in ("#", "object", "to", "start (s)", "time (s)", "place error", "outcome"):
        t.add_column(col, justify="right" if col in ("#", "start (s)", "time (s)", "place error") else "left")
    rows = zip(result.order, result.picks, result.pick_spans_s, strict=True)
    for i, ((name, label), pick, (start, span)) in enumerate(rows, start=1):
        outcome = "[green]ok[/]" if pick.success else f"[red]{pick.failure_phase}[/]"
        if pick.retries:
            outcome += f" ({pick.retries} recover{'y' if pick.retries == 1 else 'ies'})"
        t.add_row(str(i), name, label, f"{start:.2f}", f"{span:.2f}", _mm(pick.place_error_xy_m), outcome)
    console.print(t)
    t = Table(title="Objects at the end (1 s after the last release, the simulator's truth)")
    for col in ("object", "xy error", "yaw error", "z error", ""):
        t.add_column(col, justify="left" if col in ("object", "") else "right")
    for o in result.objects:
        yaw = "—" if o.yaw_error_rad != o.yaw_error_rad else f"{math.degrees(o.yaw_error_rad):.2f}°"
        t.add_row(o.name, _mm(o.xy_error_m), yaw, _mm(o.z_error_m), "[green]ok[/]" if o.ok else f"[red]{o.note}[/]")
    console.print(t)
    console.print(f"task time {result.total_time_s:.2f} s simulated ({result.time_per_pick_s:.2f} s per object), "
                  f"wall {result.wall_time_s:.2f} s ({result.real_time_factor:.1f}× real time)", highlight=False)
    for line in result.skipped:
        console.print(f"put back: {escape(line)}", highlight=False)
    for k in result.knocked:
        console.print(f"knocked: the {k.name} moved {k.shift_m * 1e3:.1f} mm while the {k.by} was handled"
                      f"{' (placed again)' if k.repaired else ''}", highlight=False)


def _cmd_task(args: argparse.Namespace, console: Console, config: EpisodeConfig) -> int:
    from pickplace.task.task_episode import run_task

    config = task_config_from_args(args, config)
    if args.viewer and not _has_display():
        raise CliError("--viewer needs a display (none found: DISPLAY and WAYLAND_DISPLAY are unset); "
                       "use --video PATH.mp4 to render offscreen instead")
    _check_web(args)
    result = run_task(config, args.seed, record=_wants_recording(args))
    if args.json:
        print(json.dumps(result.to_dict(), indent=2))
    else:
        print_task(result, console)
    _write_media(args, config, result.telemetry, console)
    _save_episode(args, result, console)
    code = 0
    if not result.success:
        Console(stderr=True, soft_wrap=True).print(
            f"[bold red]error:[/] {result.failure_kind}: task failed: {escape(result.failure_reason or '')}",
            highlight=False)
        code = EXIT_FAILURE
    if args.web:
        from pickplace.task.episode_file import episode_of

        _serve_web(args, episode_of(result), console)
    return code


def _wants_recording(args: argparse.Namespace) -> bool:
    """Whether ``run`` must record the episode's telemetry (for media, the episode file or the web viewer)."""
    return bool(args.video or args.plots or args.viewer or args.save or args.web)


def _check_web(args: argparse.Namespace) -> None:
    """Fail before anything runs if ``--web`` cannot be served (viser missing)."""
    if args.web:
        from pickplace.eval.web import require_viser

        require_viser()


def _save_episode(args: argparse.Namespace, result: EpisodeResult | TaskResult, console: Console) -> None:
    """``run --save EP.npz``: the episode file that ``pickplace replay`` reads."""
    if args.save:
        from pickplace.task.episode_file import save_episode

        path = save_episode(args.save, result)
        (Console(stderr=True) if args.json else console).print(escape(f"wrote {path}"), highlight=False)


def _serve_web(args: argparse.Namespace, episode: SavedEpisode, console: Console) -> None:
    """Serve ``episode`` in the web viewer at ``--host``/``--port`` until Ctrl-C or SIGTERM.

    Both signals get a handler of their own: a process started in the background by a non-interactive shell
    inherits SIGINT ignored, and Python then raises no KeyboardInterrupt for it.
    """
    import signal
    import threading

    from pickplace.eval.web import EpisodeViewer

    out = Console(stderr=True, soft_wrap=True) if getattr(args, "json", False) else console
    viewer = EpisodeViewer(episode, host=args.host, port=args.port, t_s=getattr(args, "at", None) or 0.0)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        if viewer.server.get_port() != args.port and args.port != 0:
            out.print(f"port {args.port} is busy: using {viewer.server.get_port()}", highlight=False)
        out.print(escape(f"web viewer: {viewer.url}  (serving until Ctrl-C)"), highlight=False, soft_wrap=True)
        out.file.flush()
        viewer.serve_forever(stop)
        out.print("web viewer stopped", highlight=False)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        viewer.close()


def _write_media(args: argparse.Namespace, config: EpisodeConfig, telemetry: Telemetry | None,
                 console: Console) -> None:
    """The plots, the video and the viewer's replay of a recorded episode or task."""
    if telemetry is None:
        return
    from pickplace.eval import report
    from pickplace.robot import model

    written = report.save_plots(telemetry, Path(args.plots)) if args.plots else []
    robot = model.build(config.scene) if args.video or args.viewer else None  # the scene the frames show
    if args.video:
        written.append(report.render_video(robot, telemetry, Path(args.video)))
    if not args.json:
        for path in written:
            console.print(f"wrote {path}", highlight=False)
    if args.viewer:
        _replay_in_viewer(robot, telemetry)


def _cmd_run(args: argparse.Namespace, console: Console) -> int:
    from pickplace.task.episode import run_episode
    from pickplace.task.machine import Phase

    config = episode_config_from_args(args)
    if args.task is not None or config.task is not None:
        return _cmd_task(args, console, config)
    if args.objects is not None or args.order is not None:
        raise CliError("--objects and --order go with --task place|stack|clear")
    if args.viewer and not _has_display():
        raise CliError("--viewer needs a display (none found: DISPLAY and WAYLAND_DISPLAY are unset); "
                       "use --video PATH.mp4 to render offscreen instead")
    _check_web(args)
    result = run_episode(config, args.seed, record=_wants_recording(args))
    moved = result.failure_phase != Phase.IDLE.value  # IDLE fails before the arm moves: one line is enough
    if args.json:
        print(json.dumps(result.to_dict(), indent=2))
    elif moved:
        print_episode(result, console)
    _write_media(args, config, result.telemetry, console)
    _save_episode(args, result, console)
    code = 0
    if not result.success:
        err = Console(stderr=True, soft_wrap=True)
        where = f"episode failed in {result.failure_phase}" if moved else "nothing moved"
        err.print(f"[bold red]error:[/] {result.failure_kind}: {where}: {escape(result.failure_reason or '')}",
                  highlight=False)
        code = EXIT_FAILURE
    if args.web:
        from pickplace.task.episode_file import episode_of

        _serve_web(args, episode_of(result), console)
    return code


def _cmd_replay(args: argparse.Namespace, console: Console) -> int:
    """``pickplace replay EP.npz``: what the file holds; with --web, --video, --plots or --viewer, shown."""
    from pickplace.task.episode_file import load_episode

    if args.viewer and not _has_display():
        raise CliError("--viewer needs a display (none found: DISPLAY and WAYLAND_DISPLAY are unset); "
                       "use --web to replay it in a browser instead")
    _check_web(args)
    ep = load_episode(args.episode)
    tel, r = ep.telemetry, ep.result
    what = f"{r.get('kind')} task" if ep.kind == "task" else f"pick and place of the {ep.config.scene.object.name}"
    if ep.success:
        outcome = "[green]success[/]"
    else:
        outcome = f"[red]failed in {escape(str(r.get('failure_phase')))}[/]: {escape(str(r.get('failure_reason')))}"
    console.print(f"{escape(what)}, seed {ep.seed}, {ep.config.profile.name} profile: {outcome}", highlight=False)
    console.print(f"{ep.duration_s:.2f} s simulated, {tel.frame_t_s.size} frames, planned paths: {len(tel.plans)}, "
                  f"grasp choices: {len(tel.grasps)} (written by pickplace {escape(ep.written_by)})", highlight=False)
    if not (args.web or args.video or args.plots or args.viewer):
        console.print("show it with --web (in a browser), --video PATH.mp4, --plots DIR or --viewer", highlight=False)
        return 0
    _write_media(args, ep.config, tel, console)
    if args.web:
        _serve_web(args, ep, console)
    return 0


def _has_display() -> bool:
    import os

    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform in ("darwin", "win32")


def _replay_in_viewer(robot: Robot, tel: Telemetry) -> None:
    """Replay a recorded episode in MuJoCo's passive viewer, in real time."""
    import time

    import mujoco
    import mujoco.viewer

    d = robot.make_data()
    with mujoco.viewer.launch_passive(robot.mj, d) as viewer:
        t0 = time.perf_counter()
        for t, qpos in zip(tel.frame_t_s, tel.frame_qpos, strict=True):
            if not viewer.is_running():
                break
            d.qpos[:] = qpos
            mujoco.mj_forward(robot.mj, d)
            viewer.sync()
            time.sleep(max(0.0, t - (time.perf_counter() - t0)))


class CliError(PickPlaceError):
    """A command-line request that cannot be carried out (e.g. ``--viewer`` without a display)."""


# --------------------------------------------------------------------------- #
# entry point
# --------------------------------------------------------------------------- #


def add_episode_options(p: argparse.ArgumentParser) -> None:
    """The options that define an episode's config (shared by ``run`` and ``eval``)."""
    p.add_argument("--config", metavar="FILE.toml", help="episode config ([scene], [planner], ... tables)")
    p.add_argument("--object", metavar="NAME", help="a library object (see `pickplace objects`); default: the cube")
    p.add_argument("--object-mesh", metavar="FILE", help="your own object: an OBJ or STL file (m), watertight")
    p.add_argument("--object-mass", type=float, metavar="KG", help="the object's mass (kg)")
    p.add_argument("--start", nargs=2, type=float, metavar=("X", "Y"), help="where the object starts (m)")
    p.add_argument("--start-yaw", type=float, metavar="RAD", help="the object's yaw at the start (rad)")
    p.add_argument("--goal", nargs=2, type=float, metavar=("X", "Y"), help="where the object goes (m)")
    p.add_argument("--goal-yaw", type=float, metavar="RAD", help="the object's yaw at the goal (rad)")
    p.add_argument("--friction", type=float, metavar="MU", help="the object's friction coefficient")
    p.add_argument("--cube-start", nargs=2, type=float, metavar=("X", "Y"), help="same as --start")
    p.add_argument("--cube-yaw", type=float, metavar="RAD", help="same as --start-yaw")
    p.add_argument("--cube-mass", type=float, metavar="KG", help="same as --object-mass")
    p.add_argument("--cube-size", type=float, metavar="M", help="the cube's edge length (m) (a box object only)")
    p.add_argument("--obstacle", action="store_true", help="put a wall between start and goal")
    p.add_argument("--profile", choices=("ideal", "realistic"),
                   help="how the robot knows the world: ideal (the simulator's truth; the default) or realistic "
                        "(a depth camera, the gripper's and the wrist's sensors); [profile] in the TOML")
    p.add_argument("--fault", action="append", metavar="KEY=VALUE", default=[],
                   help="inject a fault (repeatable), e.g. pad_friction_scale=0.5, 'transport_push_n=[0,0,-40]', "
                        "transport_push_s=0.05, intruder=true, true_mass_scale=3, joint_noise_rad=1e-4")


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (exit 2), like every other error."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"error: {self.prog}: {message} (see '{self.prog} --help')\n")
        raise SystemExit(EXIT_USAGE)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pickplace``."""
    parser = _Parser(prog="pickplace", description="A simulated UR5e picks an object at A and places it at B, in "
                     "closed loop, and measures every step: one episode (run), campaigns (eval, report), the model and "
                     "its IK (inspect), benchmarks (bench).")
    parser.add_argument("--version", action="version", version=f"pickplace {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="log more (-v info, -vv debug)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="one pick and place in simulation, with its timeline and measured results; or a "
                                   "task with several objects (--task)")
    add_episode_options(p)
    p.add_argument("--seed", type=int, default=0, help="episode seed (the planner's random stream); default 0")
    p.add_argument("--json", action="store_true", help="print the EpisodeResult as one JSON object")
    p.add_argument("--viewer", action="store_true", help="replay the episode in MuJoCo's viewer (needs a display)")
    p.add_argument("--video", metavar="PATH.mp4", help="render the episode offscreen to a video (MUJOCO_GL=egl)")
    p.add_argument("--plots", metavar="DIR", help="write joint tracking, tcp height, grip force and timeline PNGs")
    p.add_argument("--save", metavar="EP.npz", help="write the recorded episode (or task) for `pickplace replay`")
    add_web_options(p)
    add_task_options(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("replay", help="a recorded episode (pickplace run --save EP.npz): in the browser (--web), as a "
                                      "video, plots, or in MuJoCo's viewer")
    p.add_argument("episode", metavar="EP.npz", help="the episode file (pickplace run --save)")
    add_web_options(p)
    p.add_argument("--at", type=float, metavar="S", help="with --web: the time shown first (s)")
    p.add_argument("--viewer", action="store_true", help="replay it in MuJoCo's viewer (needs a display)")
    p.add_argument("--video", metavar="PATH.mp4", help="render it offscreen to a video (MUJOCO_GL=egl)")
    p.add_argument("--plots", metavar="DIR", help="write joint tracking, tcp height, grip force and timeline PNGs")
    p.set_defaults(func=_cmd_replay, json=False)

    p = sub.add_parser("inspect", help="model summary, gripper geometry, IK of the targets, hold test")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--export-xml", metavar="PATH", help="write the compiled scene MJCF to PATH")
    p.add_argument("--obstacle", action="store_true", help="put the wall between start and goal")
    p.add_argument("--object", metavar="NAME", help="a library object (see `pickplace objects`); default: the cube")
    p.set_defaults(func=_cmd_inspect)

    p = sub.add_parser("bench", help="benchmarks: planning (vs OMPL), control (vs bare mj_step), loop (whole episodes "
                                     "vs a bare mj_step replay of their torques), campaign (scaling; --memory: "
                                     "workers' memory), perception (camera pose error), sensing (success and place "
                                     "error vs camera noise and calibration), env (the Gymnasium environments' speed "
                                     "and success)")
    p.add_argument("name", choices=["planning", "control", "loop", "campaign", "perception", "sensing", "tasks", "env"],
                   help="which benchmark")
    p.add_argument("bench_args", nargs=argparse.REMAINDER,
                   help="options of the benchmark (e.g. --json; planning: --quick, --queries N, --budget S, "
                        "--no-ompl; sensing: --quick, --trials N, --workers W, --plot PATH.png)")
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("eval", help="a campaign of randomized episodes on local processes or Ray, persisted and "
                       "resumable, with its summary")
    add_episode_options(p)
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (campaign.json, results.jsonl, summary.json, trials/)")
    p.add_argument("--trials", type=int, metavar="N",
                   help="number of trials (default 100; with --resume: the recorded campaign's)")
    p.add_argument("--workers", type=int, metavar="W",
                   help="trials at once (default: every core; with --ray ADDRESS: the cluster's CPUs)")
    p.add_argument("--seed", type=int, metavar="S", help="campaign seed (default 0; with --resume: the recorded one)")
    p.add_argument("--resume", action="store_true",
                   help="complete the campaign in --out: run only the trials not recorded yet")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="run on Ray: a local instance (no ADDRESS), 'auto' (the cluster started on this machine) or "
                        "the cluster at HOST:PORT, with or without token auth (needs pip install 'pickplace[ray]')")
    p.add_argument("--timeout", type=float, default=60.0, metavar="S",
                   help="per-trial wall-clock limit, counted from when a worker that is up starts the trial; a "
                        "trial over it is recorded as failed (default 60 s)")
    p.add_argument("--no-randomize", action="store_true",
                   help="run the base config in every trial (only the episode seed varies)")
    p.add_argument("--json", action="store_true", help="print summary.json instead of the tables")
    p.add_argument("--record", metavar="DIR",
                   help="the trials acted by the expert through pickplace/PickPlaceLowLevel-v0 (joint mode) and "
                        "written as one Minari dataset in DIR/<id> (needs pip install 'pickplace[dataset]')")
    p.add_argument("--record-failures", choices=("keep", "drop"), default=None,
                   help="with --record: keep the failed episodes, labelled with phase, kind and reason (default), "
                        "or leave them out")
    p.add_argument("--record-id", metavar="ID", default=None,
                   help="with --record: the dataset's id, namespace/name-vN (default pickplace/expert-v0)")
    p.add_argument("--record-rate", type=float, metavar="HZ", default=None,
                   help="with --record: the environment's control rate, 20, 25, 40 or 50 Hz (default 20)")
    add_task_options(p)
    p.set_defaults(func=_cmd_eval)

    p = sub.add_parser("dataset", help="the figures of a recorded dataset (pickplace eval --record), and replays "
                       "of its episodes through the environment")
    p.add_argument("dir", metavar="DIR", help="the datasets' directory (pickplace eval --record DIR)")
    p.add_argument("--id", default=None, metavar="ID", help="the dataset's id (default pickplace/expert-v0)")
    p.add_argument("--replay", type=int, default=0, metavar="N",
                   help="replay the first N episodes from their seeds with their actions and compare every step "
                        "and the outcome")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_dataset)

    p = sub.add_parser("objects", help="the object library: sizes, masses, friction and how many grasps each offers")
    p.add_argument("names", nargs="*", metavar="NAME", help="only these library objects (default: all)")
    p.add_argument("--json", action="store_true", help="print a JSON list of objects (each with its name)")
    p.set_defaults(func=_cmd_objects)

    p = sub.add_parser("report", help="plots and report.md of a campaign's output directory")
    p.add_argument("out", metavar="OUT", help="the campaign's output directory (pickplace eval --out)")
    p.set_defaults(func=_cmd_report)
    return parser


def _cmd_bench(args: argparse.Namespace, console: Console) -> int:
    import importlib

    bench = importlib.import_module(f"pickplace.eval.bench.{args.name}")
    return int(bench.main(list(args.bench_args)))


# --------------------------------------------------------------------------- #
# eval and report (campaigns)
# --------------------------------------------------------------------------- #


def _episode_options_given(args: argparse.Namespace) -> bool:
    """Whether any option of :func:`add_episode_options` differs from its default."""
    probe = argparse.ArgumentParser(add_help=False)
    add_episode_options(probe)
    return any(getattr(args, dest) != default for dest, default in vars(probe.parse_args([])).items())


def campaign_from_args(args: argparse.Namespace) -> CampaignConfig:
    """The campaign of ``pickplace eval``.

    The base config is built exactly as ``pickplace run`` builds its config (``--config`` TOML, then the scene
    flags on top); the TOML may also hold a ``[randomization]`` table. With ``--resume`` and no episode
    option, ``--seed`` or ``--no-randomize``, the campaign recorded in ``OUT/campaign.json`` is resumed.
    """
    from pickplace.eval.campaign import (
        CAMPAIGN_FILE,
        CampaignConfig,
        RandomizationSpec,
        load_campaign,
        load_campaign_toml,
    )

    if (args.resume and (Path(args.out) / CAMPAIGN_FILE).exists() and not _episode_options_given(args)
            and args.seed is None and not args.no_randomize):
        return load_campaign(args.out, workers=args.workers, timeout_s=args.timeout, trials=args.trials)
    spec = RandomizationSpec()
    if args.config:
        base_file, spec = load_campaign_toml(args.config)
        base = episode_config_from_args(args, base_file)
    else:
        base = episode_config_from_args(args)
    if args.no_randomize:
        spec = RandomizationSpec.off()
    if args.task is not None or base.task is not None:
        task = _task_from_flags(args, base)
        base = dataclasses.replace(base, scene=_with_bin(task, base.scene), task=task)
        if args.objects is not None:
            spec = dataclasses.replace(spec, task_objects=(args.objects, args.objects))
    elif args.objects is not None or args.order is not None:
        raise CliError("--objects and --order go with --task place|stack|clear")
    return CampaignConfig(base, spec, args.trials if args.trials is not None else 100,
                          args.seed if args.seed is not None else 0, args.workers, args.timeout)


def print_campaign(run: CampaignRun, console: Console, max_commands: int = 20) -> None:
    """The summary table, the failures grouped by phase and reason, and the reproduce commands."""
    from rich.markup import escape

    from pickplace.eval.campaign_report import summary_rows

    s = run.summary
    t = Table(title=escape(f"Campaign {run.out_dir}"))
    t.add_column("measure")
    t.add_column("value", justify="right")
    for measure, value in summary_rows(s):
        t.add_row(measure, value)
    rate = f"{run.trials_run / run.elapsed_s:.2f} trials/s" if run.trials_run and run.elapsed_s > 0 else "—"
    t.add_row("this run: trials / wall time", f"{run.trials_run} in {run.elapsed_s:.1f} s ({rate})")
    console.print(t)
    if s.failures:
        t = Table(title="Failures by phase and reason (numbers as #)")
        for col in ("phase", "kind", "trials", "reason"):
            t.add_column(col, justify="right" if col == "trials" else "left")
        for g in s.failures:
            t.add_row(escape(g.phase), escape(g.kind), str(g.count), escape(g.reason))
        console.print(t)
        console.print("reproduce a failed trial:", highlight=False)
        for f in s.failed_trials[:max_commands]:
            console.print(escape(f"  {f.command}    # trial {f.trial}: {f.phase}"), highlight=False, soft_wrap=True)
        if len(s.failed_trials) > max_commands:
            console.print(escape(f"  ... {len(s.failed_trials) - max_commands} more in {run.out_dir / 'summary.json'}"),
                          highlight=False)


def _cmd_eval(args: argparse.Namespace, console: Console) -> int:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from pickplace.eval.campaign import CampaignProgress, run_campaign

    record = _record_from_args(args)
    campaign = campaign_from_args(args)
    progress = Progress(TextColumn("[bold]eval"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[ok]}"),
                        TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                        console=Console(stderr=True), transient=False)
    task = progress.add_task("eval", total=campaign.trials, ok="")

    def on_progress(p: CampaignProgress) -> None:
        rate = f" ({p.successes / p.done:.1%})" if p.done else ""
        if p.last is None:  # the start, once the output directory is checked; after a resume, the trials
            progress.start()  # already done must not count in the ETA's speed
            progress.reset(task, completed=p.done, ok=f"{p.successes} ok{rate}")
        else:
            progress.update(task, completed=p.done, ok=f"{p.successes} ok{rate}")

    backend = "ray" if args.ray is not None else "local"
    written = None
    try:
        if record is None:
            run = run_campaign(campaign, args.out, resume=args.resume, backend=backend, ray_address=args.ray or None,
                               on_progress=on_progress)
        else:
            from pickplace.eval.dataset import record_campaign

            recorded = record_campaign(campaign, args.out, record, resume=args.resume, backend=backend,
                                       ray_address=args.ray or None, on_progress=on_progress)
            run, written = recorded.run, recorded.dataset
    finally:
        progress.stop()
    if args.json:
        data = run.summary.to_dict()
        if written is not None:
            data["dataset"] = {"path": str(written.path), "id": written.dataset_id, "episodes": written.episodes,
                               "steps": written.steps, "successes": written.successes,
                               "dropped": list(written.dropped), "missing": list(written.missing)}
        print(json.dumps(data, indent=2))
    else:
        print_campaign(run, console)
        if written is not None:
            console.print(escape(f"dataset {written.dataset_id}: {written.episodes} episodes ({written.steps} steps, "
                                 f"{written.successes} successes) in {written.path}; {len(written.dropped)} failed "
                                 f"episodes dropped, {len(written.missing)} trials not recorded"), highlight=False)
    return 0


def _record_from_args(args: argparse.Namespace) -> RecordConfig | None:
    """The :class:`~pickplace.eval.dataset.RecordConfig` of ``eval --record``, or None without it."""
    extra = [flag for flag, value in (("--record-failures", args.record_failures), ("--record-id", args.record_id),
                                      ("--record-rate", args.record_rate)) if value is not None]
    if args.record is None:
        if extra:
            raise CliError(f"{' and '.join(extra)} {'goes' if len(extra) == 1 else 'go'} with --record DIR")
        return None
    from pickplace.eval.dataset import DATASET_ID, RecordConfig

    return RecordConfig(Path(args.record), args.record_id or DATASET_ID, args.record_failures or "keep",
                        args.record_rate if args.record_rate is not None else 20.0)


def _cmd_dataset(args: argparse.Namespace, console: Console) -> int:
    from pickplace.eval.dataset import DATASET_ID, load, replay_episode, summarize_dataset

    dataset = load(args.dir, args.id or DATASET_ID)
    s = summarize_dataset(dataset)
    if args.replay < 0:
        raise ConfigError("replay", args.replay, "must be >= 0 episodes")
    checks = [replay_episode(dataset, i) for i in range(min(args.replay, s.episodes))]
    if args.json:
        data = s.to_dict()
        data["replays"] = [{**dataclasses.asdict(c), "reproduced": c.reproduced} for c in checks]
        print(json.dumps(data, indent=2))
        return 0 if all(c.reproduced for c in checks) else EXIT_FAILURE
    t = Table(title=escape(f"Dataset {s.dataset_id} ({s.path})"))
    t.add_column("measure")
    t.add_column("value", justify="right")
    t.add_row("episodes / steps", f"{s.episodes} / {s.steps} ({s.mean_steps:.1f} steps per episode)")
    t.add_row("successes", f"{s.successes}/{s.episodes}")
    t.add_row("environment", escape(", ".join(f"{k}={v}" for k, v in s.env_kwargs.items())))
    t.add_row("failed trials dropped / trials not recorded", f"{len(s.dropped)} / {len(s.missing)}")
    for phase, kind, count in s.failures:
        t.add_row(escape(f"failed: {kind} in {phase}"), str(count))
    console.print(t)
    for c in checks:
        verdict = "reproduced" if c.reproduced else "DIFFERS"
        console.print(escape(f"replay of episode {c.index}: {verdict}: {c.steps[1]}/{c.steps[0]} steps, observations "
                             f"{'identical' if c.identical_observations else f'differ by {c.max_difference:.3g}'}, "
                             f"success {c.success_stored} -> {c.success_replayed}"), highlight=False)
    return 0 if all(c.reproduced for c in checks) else EXIT_FAILURE


def _cmd_objects(args: argparse.Namespace, console: Console) -> int:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from pickplace.grasping.library import summarize_object
    from pickplace.world.objects import LIBRARY

    names = args.names or list(LIBRARY)
    for name in names:
        if name not in LIBRARY:
            raise ConfigError("objects", name, f"must be one of {', '.join(LIBRARY)}")
    rows = []
    with Progress(TextColumn("[bold]grasps"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.description}"),
                  console=Console(stderr=True), transient=True, disable=args.json) as progress:
        task = progress.add_task("", total=len(names))
        for name in names:
            progress.update(task, description=name)
            rows.append(summarize_object(LIBRARY[name]))
            progress.advance(task)
    if args.json:
        print(json.dumps([r.to_dict() for r in rows], indent=2))
        return 0
    t = Table(title="Object library (grasps: synthesized / clear of the table / reachable at the default pose)")
    for col in ("object", "kind", "size x × y × z (mm)", "mass (kg)", "μ", "grasps", "feasible: top / tilted / side"):
        t.add_column(col, justify="left" if col in ("object", "kind") else "right")
    for r in rows:
        by = r.feasible_by_approach
        t.add_row(r.name, r.kind, " × ".join(f"{v * 1e3:.0f}" for v in r.extent_m), f"{r.mass_kg:.3f}",
                  f"{r.friction:g}", f"{r.grasps} / {r.grasps_at_default_pose} / {r.feasible}",
                  f"{by.get('top', 0)} / {by.get('tilted', 0)} / {by.get('side', 0)}")
    console.print(t)
    console.print("Sources of the numbers: pickplace objects --json (field source). Default pose: the default "
                  "scene's start; feasible = pregrasp and the straight approach to the grasp collision free.")
    return 0


def _cmd_report(args: argparse.Namespace, console: Console) -> int:
    from rich.markup import escape

    from pickplace.eval.campaign_report import write_report

    for path in write_report(args.out):
        console.print(escape(f"wrote {path}"), highlight=False)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    console = Console()
    err = Console(stderr=True, soft_wrap=True)
    try:
        return int(args.func(args, console))
    except PickPlaceError as exc:
        err.print(f"[bold red]error:[/] {type(exc).__name__}: {escape(str(exc))}", highlight=False)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
