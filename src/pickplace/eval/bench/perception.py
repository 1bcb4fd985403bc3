"""Perception benchmark: how well the depth camera and the pose fit locate each library object.

For each object, ``--trials`` scenes: the object resting at a random place around the default start (±5 cm)
and a random yaw, seen by the default camera (Intel RealSense D435 model, :class:`CameraConfig`) whose real
pose carries a calibration error drawn per trial (:meth:`CameraConfig.drawn`). The depth image is rendered
from the real pose with the sensor's noise; the robot back-projects it with the *calibrated* pose, leaves out
its own links (rendered from the calibrated pose too, widened by ``MASK_MARGIN_PX``), segments the object
(no higher than 1.5 times its largest extent) on the table as it sees it (its heights measured from the
observed table top) and fits its resting pose
(:mod:`pickplace.perception.pose`). Reported per object, against the simulator's truth (which the fit never
sees): median and p95 of the position error (horizontal) and of the yaw error (modulo the object's
symmetry), the fit's RMS residual, the trials where the object was not seen, and the wall time per estimate.

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
from scipy import ndimage

from pickplace.eval.bench import machine_info
from pickplace.grasping.targets import object_yaw
from pickplace.perception.camera import CameraConfig, DepthCamera, point_cloud, sensor_depth
from pickplace.perception.pose import ObjectNotSeen, fit_resting_pose, observed_table_height, segment
from pickplace.perception.view import MASK_MARGIN_PX
from pickplace.robot.kinematics import rot_z, wrap_to_pi
from pickplace.robot.model import build
from pickplace.world.config import SceneConfig
from pickplace.world.objects import LIBRARY


def _yaw_error(est: float, true: float, period: float) -> float:
    if period <= 0.0:
        return 0.0
    k = 2 * np.pi / period
    return float(wrap_to_pi(k * (est - true))) / k


def run_object(name: str, trials: int, seed: int, camera: CameraConfig | None = None) -> dict[str, Any]:
    """The benchmark for one library object (see the module's docstring)."""
    cfg = camera if camera is not None else CameraConfig()
    scene = SceneConfig(object=LIBRARY[name])
    robot = build(scene)
    d = robot.make_data()
    own = frozenset(robot.handles.robot_bodies) | frozenset(robot.handles.gripper_bodies)
    centre, half = np.asarray(scene.table_center_xy_m), np.asarray(scene.table_size_xy_m) / 2
    clearance = 4 * float(cfg.depth_sigma_m(1.0))
    tallest = 1.5 * float(np.max(scene.object.geometry().extent_m))
    believed = DepthCamera(robot, cfg)
    rng = np.random.default_rng(seed)
    a = robot.handles.object_qpos
    pos_err, yaw_err, residual, wall = [], [], [], []
    not_seen = 0
    try:
        for _ in range(trials):
            xy = np.asarray(scene.start_xy_m) + rng.uniform(-0.05, 0.05, 2)
            yaw = float(rng.uniform(-np.pi, np.pi))
            mujoco.mj_resetDataKeyframe(robot.mj, d, 0)
            d.qpos[a:a + 3] = [xy[0], xy[1], scene.rest_z_m]
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, rot_z(yaw).ravel())
            d.qpos[a + 3:a + 7] = quat
            mujoco.mj_forward(robot.mj, d)
            exact = believed.render_depth(d, seen_from=cfg.drawn(rng))  # from where the camera really is
            t0 = time.perf_counter()
            depth = sensor_depth(exact, cfg, rng)
            # the robot's own links, rendered where it believes the camera is, widened by a few pixels for the
            # calibration error
            mask = ndimage.binary_dilation(believed.render_mask(d, own), iterations=MASK_MARGIN_PX)
            cloud = point_cloud(depth, cfg, ~mask)
            box = (centre - half, centre + half)
            try:
                table = observed_table_height(cloud, scene.table_height_m, box)
                est = fit_resting_pose(segment(cloud, table, box, clearance, tallest), scene.object, table, rng)
            except ObjectNotSeen:
                not_seen += 1
                continue
            wall.append(time.perf_counter() - t0)
            T = est.T_world_object
            pos_err.append(float(np.hypot(*(T.translation[:2] - xy))))
            yaw_err.append(abs(_yaw_error(object_yaw(T.rotation), yaw, scene.object.yaw_period_rad)))
            residual.append(est.residual_m)
    finally:
        believed.close()

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
