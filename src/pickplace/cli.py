"""The ``pickplace`` command line: ``inspect`` and ``bench``.

The library logs and never prints; this module prints (rich tables) and turns every
:class:`~pickplace.errors.PickPlaceError` into one clear line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console
from rich.table import Table

from pickplace import __version__
from pickplace.config import SceneConfig
from pickplace.errors import PickPlaceError

EXIT_FAILURE = 1
EXIT_USAGE = 2


def _scene_from_args(args: argparse.Namespace) -> SceneConfig:
    kwargs: dict[str, object] = {}
    if getattr(args, "obstacle", False):
        kwargs["obstacle"] = True
    return SceneConfig(**kwargs)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- #
# inspect
# --------------------------------------------------------------------------- #


def inspect_data(scene: SceneConfig) -> dict[str, object]:
    """Everything ``pickplace inspect`` reports, as JSON-ready data."""
    from pickplace import model
    from pickplace.configurations import solve_grasp_configurations
    from pickplace.gripper import GripperGeometry, hold_margin

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
            "cube_half_width_m": scene.cube_size_m / 2,
            "open_width_m": geom.open_width_m,
            "tcp_offset_m": geom.tcp_offset_m,
            "closed_target_past_contact_m": scene.cube_size_m / 2 - geom.closed_inner_face_y_m,
        },
        "ik": [
            {"name": r.name, "position_error_m": r.position_error_m,
             "orientation_error_rad": r.orientation_error_rad, "iterations": r.iterations,
             "q_rad": [float(v) for v in r.q]}
            for r in configs.results()
        ],
        "hold": {
            "cube_mass_kg": nominal.cube_mass_kg,
            "held": nominal.held,
            "slip_m": nominal.slip_m,
            "slip_rad": nominal.slip_rad,
            "grip_force_n": nominal.grip_force_n,
            "min_grip_force_n": nominal.min_grip_force_n,
            "peak_acceleration_m_s2": nominal.peak_acceleration_m_s2,
            "safety_factor": margin.safety_factor,
            "trials": [{"cube_mass_kg": r.cube_mass_kg, "held": r.held, "slip_m": r.slip_m,
                        "grip_force_n": r.grip_force_n} for r in margin.results],
        },
    }


def _cmd_inspect(args: argparse.Namespace, console: Console) -> int:
    scene = _scene_from_args(args)
    if args.export_xml:
        from pickplace import model

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
        f"±{g['closed_inner_face_y_m'] * 1e3:.1f} mm, cube half-width {g['cube_half_width_m'] * 1e3:.1f} mm "
        f"(the closed target lies {g['cube_half_width_m'] * 1e3 - g['closed_inner_face_y_m'] * 1e3:.1f} mm "
        f"inside the cube), open width {g['open_width_m'] * 1e3:.1f} mm, tcp {g['tcp_offset_m'] * 1e3:.1f} mm "
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
    for col in ("cube mass (kg)", "held", "slip (mm)", "grip force / pad (N)"):
        t.add_column(col, justify="right")
    for r in h["trials"]:
        t.add_row(f"{r['cube_mass_kg']:.3f}", "yes" if r["held"] else "NO", f"{r['slip_m'] * 1e3:.3f}",
                  f"{r['grip_force_n']:.1f}")
    console.print(t)
    console.print(
        f"nominal cube: slip {h['slip_m'] * 1e3:.3f} mm, grip force {h['grip_force_n']:.1f} N per pad, "
        f"peak acceleration {h['peak_acceleration_m_s2']:.2f} m/s², safety factor ≥ {h['safety_factor']:g} "
        "(heaviest cube held / cube mass)"
    )
    return 0


# --------------------------------------------------------------------------- #
# entry point
# --------------------------------------------------------------------------- #


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pickplace``."""
    parser = argparse.ArgumentParser(prog="pickplace", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"pickplace {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="log more (-v info, -vv debug)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("inspect", help="model summary, gripper geometry, IK of the targets, hold test")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--export-xml", metavar="PATH", help="write the compiled scene MJCF to PATH")
    p.add_argument("--obstacle", action="store_true", help="put the wall between start and goal")
    p.set_defaults(func=_cmd_inspect)

    p = sub.add_parser("bench", help="benchmarks (planning: pickplace RRT* vs OMPL)")
    p.add_argument("name", choices=["planning"], help="which benchmark")
    p.add_argument("bench_args", nargs=argparse.REMAINDER,
                   help="options of the benchmark (e.g. --json, --quick, --queries N, --budget S, --no-ompl)")
    p.set_defaults(func=_cmd_bench)
    return parser


def _cmd_bench(args: argparse.Namespace, console: Console) -> int:
    from pickplace.bench import planning

    return int(planning.main(list(args.bench_args)))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    console = Console()
    err = Console(stderr=True)
    try:
        return int(args.func(args, console))
    except PickPlaceError as exc:
        err.print(f"[bold red]error:[/] {type(exc).__name__}: {exc}", highlight=False)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
