"""Perception benchmark: how well the depth camera and the pose fit locate each library object.

For each object, ``--trials`` scenes: the object resting at a random place around the default start (±5 cm)
and a random yaw, seen by the default camera (Intel RealSense D435 model, :class:`CameraConfig`) whose real
pose carries a calibration error drawn per trial (:meth:`CameraConfig.drawn`). The robot locates the object as
it does before a pick (:meth:`~pickplace.perception.view.TableCamera.locate`): the depth image rendered from the
real pose with the sensor's noise, back-projected with the *calibrated* pose, its own links left out, the
object segmented on the table as it sees it and its resting pose fitted (:mod:`pickplace.perception.pose`).
Reported per object, against the simulator's truth (which the fit never sees): median and p95 of the position
error (horizontal) and of the yaw error (modulo the object's symmetry), the fit's RMS residual, the trials
where the object was not seen, and the wall time per estimate (rendering included).

Usage: ``pickplace bench perception [--json] [--trials N] [--objects NAME ...] [--seed S]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

import mujoco
import numpy as np

from pickplace.eval.bench import machine_info
from pickplace.grasping.targets import yaw_error
from pickplace.perception.camera import CameraConfig
from pickplace.perception.pose import ObjectNotSeen
from pickplace.perception.view import TableCamera
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import build
from pickplace.world.config import SceneConfig
from pickplace.world.objects import LIBRARY


def run_object(name: str, trials: int, seed: int, camera: CameraConfig | None = None) -> dict[str, Any]:
    """The benchmark for one library object (see the module's docstring)."""
    cfg = camera if camera is not None else CameraConfig()
    scene = SceneConfig(object=LIBRARY[name])
    robot = build(scene)
    d = robot.make_data()
    rng = np.random.default_rng(seed)
    view = TableCamera(robot, cfg, rng)
    a = robot.handles.object_qpos
    pos_err, yaw_err, residual, wall = [], [], [], []
    not_seen = 0
    try:
        for _ in range(trials):
            xy = np.asarray(scene.start_xy_m) + rng.uniform(-0.05, 0.05, 2)
            R = rot_z(float(rng.uniform(-np.pi, np.pi)))
            mujoco.mj_resetDataKeyframe(robot.mj, d, 0)
            d.qpos[a:a + 3] = [xy[0], xy[1], scene.rest_z_m]
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, R.ravel())
            d.qpos[a + 3:a + 7] = quat
            mujoco.mj_forward(robot.mj, d)
            view.draw_calibration()  # a calibration error per trial
            t0 = time.perf_counter()
            try:
                est = view.locate(d)
            except ObjectNotSeen:
                not_seen += 1
                continue
            wall.append(time.perf_counter() - t0)
            T = est.T_world_object
            pos_err.append(float(np.hypot(*(T.translation[:2] - xy))))
            yaw_err.append(abs(yaw_error(T.rotation, R, scene.object.yaw_period_rad)))
            residual.append(est.residual_m)
    finally:
        view.close()

    def stats(v: list[float]) -> dict[str, float]:
        return {"median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "max": float(np.max(v))} if v \
            else {"median": float("nan"), "p95": float("nan"), "max": float("nan")}

    return {"object": name, "trials": trials, "not_seen": not_seen, "position_error_m": stats(pos_err),
            "yaw_error_rad": stats(yaw_err), "residual_rms_m": stats(residual),
            "wall_s_per_estimate": float(np.mean(wall)) if wall else float("nan"),
            "yaw_defined": scene.object.yaw_period_rad > 0}


def run(trials: int, objects: list[str], seed: int) -> dict[str, Any]:
    """The benchmark for several objects, with the conditions."""
    cfg = CameraConfig()
    return {"machine": machine_info(), "camera": {k: getattr(cfg, k) for k in (
        "position_m", "look_at_m", "width_px", "height_px", "vertical_fov_rad", "baseline_m", "subpixel_px",
        "depth_unit_m", "calibration_position_sigma_m", "calibration_angle_sigma_rad")},
        "conditions": "object resting within 5 cm of the default start, any yaw; ideal render + D435 noise model; "
                      "calibration error drawn per trial; errors against the simulator's truth",
        "seed": seed, "objects": [run_object(name, trials, seed + i, cfg) for i, name in enumerate(objects)]}


def print_table(result: dict[str, Any]) -> None:
    """Print the result as a rich table."""
    from rich.console import Console
    from rich.table import Table

    t = Table(title="Object pose from the depth camera vs the truth (median / p95)")
    for col in ("object", "trials", "not seen", "position (mm)", "yaw (deg)", "residual (mm)", "s / estimate"):
        t.add_column(col, justify="left" if col == "object" else "right")
    for r in result["objects"]:
        p, y, res = r["position_error_m"], r["yaw_error_rad"], r["residual_rms_m"]
        yaw = f"{np.degrees(y['median']):.2f} / {np.degrees(y['p95']):.2f}" if r["yaw_defined"] else "(free)"
        t.add_row(r["object"], str(r["trials"]), str(r["not_seen"]), f"{p['median'] * 1e3:.2f} / {p['p95'] * 1e3:.2f}",
                  yaw, f"{res['median'] * 1e3:.2f} / {res['p95'] * 1e3:.2f}", f"{r['wall_s_per_estimate']:.2f}")
    console = Console()
    console.print(t)
    console.print(result["conditions"])


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a table, or one JSON object with ``--json``. Returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--trials", type=int, default=20, help="scenes per object")
    parser.add_argument("--objects", nargs="+", default=list(LIBRARY), choices=list(LIBRARY), metavar="NAME",
                        help="library objects (default: all)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the poses, noise and calibration errors")
    args = parser.parse_args(argv)
    if args.trials < 1:
        parser.error("--trials must be >= 1")
    result = run(args.trials, args.objects, args.seed)
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
