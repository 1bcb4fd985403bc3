"""Perception benchmark: how well the depth camera and the pose fit locate each library object.

For each object, ``--trials`` scenes: the object resting at a random place around the default start (±5 cm)
and a random yaw, seen by the default camera (Intel RealSense D435 model, :class:`CameraConfig`) whose real
pose carries a calibration error drawn per trial (:meth:`CameraConfig.drawn`). Two looks per scene, as the
realistic episode takes them (each fits ``SensingConfig.views_per_look`` frames together):

* **from the table** (before a pick, :meth:`~pickplace.perception.view.TableCamera.locate`): the depth image
  rendered from the real pose with the sensor's noise, back-projected with the *calibrated* pose, the robot's
  own links left out, the object segmented on the table as it sees it and its resting pose fitted
  (:mod:`pickplace.perception.pose`);
* **from the hand** (the look at the pregrasp): the arm holds the tcp 10 cm above the object's top, pointing
  down; the same fit, its points measured against the hand (``from_hand``), which cancels the calibration
  error to first order, started from the first look's estimate.

Reported per object and look, against the simulator's truth (which the fit never sees): median and p95 of the
position error (horizontal) and of the yaw error (modulo the object's symmetry), the fit's RMS residual, the
looks where the object was not seen, and the wall time per estimate (rendering included).

Usage: ``pickplace bench perception [--json] [--trials N] [--objects NAME ...] [--seed S] [--workers W]``.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.eval.bench import machine_info
from pickplace.grasping.targets import yaw_error
from pickplace.perception.camera import CameraConfig
from pickplace.perception.pose import ObjectNotSeen
from pickplace.perception.view import TableCamera
from pickplace.robot.ik import IKConfig, solve_ik
from pickplace.robot.kinematics import rot_z
from pickplace.robot.model import build
from pickplace.task.observe import SensingConfig
from pickplace.world.config import SceneConfig
from pickplace.world.objects import LIBRARY

#: Height of the tcp above the object's top for the look from the hand (m): about where the pregrasp holds it.
HAND_ABOVE_M = 0.10

#: The looks of a scene, in the order taken.
LOOKS = ("table", "hand")


def _stats(v: list[float]) -> dict[str, float]:
    return {"median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "max": float(np.max(v))} if v \
        else {"median": float("nan"), "p95": float("nan"), "max": float("nan")}


def run_object(name: str, trials: int, seed: int, camera: CameraConfig | None = None) -> dict[str, Any]:
    """The benchmark for one library object (see the module's docstring)."""
    cfg = camera if camera is not None else CameraConfig()
    views = SensingConfig().views_per_look
    scene = SceneConfig(object=LIBRARY[name])
    robot = build(scene)
    d = robot.make_data()
    h = robot.handles
    rng = np.random.default_rng(seed)
    view = TableCamera(robot, cfg, rng)
    a = h.object_qpos
    top_m = float(scene.object.geometry().vertices[:, 2].max())
    errors: dict[str, dict[str, list[float]]] = {k: {"pos": [], "yaw": [], "res": [], "wall": []} for k in LOOKS}
    not_seen = dict.fromkeys(LOOKS, 0)
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
            first = None
            for look in LOOKS:
                if look == "hand":  # the tcp above the object, pointing down, as at a pregrasp
                    above = pin.SE3(np.diag([1.0, -1.0, -1.0]) @ R,
                                    np.array([xy[0], xy[1], scene.rest_z_m + top_m + HAND_ABOVE_M]))
                    d.qpos[h.arm_qpos] = solve_ik(robot, above, robot.home_q, "look", IKConfig()).q
                    mujoco.mj_forward(robot.mj, d)
                t0 = time.perf_counter()
                try:
                    if look == "table":
                        est = view.locate(d, views=views)
                        first = est.T_world_object
                    else:
                        near = first if first is not None else pin.SE3(R, np.array([*xy, scene.rest_z_m]))
                        est = view.locate(d, near=near, start=near, from_hand=True, views=views)
                except ObjectNotSeen:
                    not_seen[look] += 1
                    continue
                e = errors[look]
                e["wall"].append(time.perf_counter() - t0)
                T = est.T_world_object
                e["pos"].append(float(np.hypot(*(T.translation[:2] - xy))))
                e["yaw"].append(abs(yaw_error(T.rotation, R, scene.object.yaw_period_rad)))
                e["res"].append(est.residual_m)
    finally:
        view.close()
    return {"object": name, "trials": trials, "yaw_defined": scene.object.yaw_period_rad > 0,
            "looks": {look: {"not_seen": not_seen[look], "position_error_m": _stats(e["pos"]),
                             "yaw_error_rad": _stats(e["yaw"]), "residual_rms_m": _stats(e["res"]),
                             "wall_s_per_estimate": float(np.mean(e["wall"])) if e["wall"] else float("nan")}
                      for look, e in errors.items()}}


def run(trials: int, objects: list[str], seed: int, workers: int = 1) -> dict[str, Any]:
    """The benchmark for several objects (``workers`` processes, one object each at a time), with the
    conditions."""
    cfg = CameraConfig()
    jobs = [(name, trials, seed + i, cfg) for i, name in enumerate(objects)]
    if workers > 1:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            results = list(pool.map(run_object, *zip(*jobs, strict=True)))
    else:
        results = [run_object(*job) for job in jobs]
    return {"machine": machine_info(), "camera": {k: getattr(cfg, k) for k in (
        "position_m", "look_at_m", "width_px", "height_px", "vertical_fov_rad", "baseline_m", "subpixel_px",
        "depth_unit_m", "calibration_position_sigma_m", "calibration_angle_sigma_rad")},
        "views_per_look": SensingConfig().views_per_look, "hand_above_m": HAND_ABOVE_M,
        "conditions": "object resting within 5 cm of the default start, any yaw; ideal render + D435 noise model; "
                      "calibration error drawn per trial; 'table': the look before the pick, 'hand': the look "
                      f"with the tcp {HAND_ABOVE_M * 100:.0f} cm above the object, measured against the hand; "
                      f"{SensingConfig().views_per_look} frames per look; errors against the simulator's truth",
        "seed": seed, "workers": workers, "objects": results}


def print_table(result: dict[str, Any]) -> None:
    """Print the result as a rich table."""
    from rich.console import Console
    from rich.table import Table

    t = Table(title="Object pose from the depth camera vs the truth (median / p95)")
    for col in ("object", "look", "trials", "not seen", "position (mm)", "yaw (deg)", "residual (mm)",
                "s / estimate"):
        t.add_column(col, justify="left" if col in ("object", "look") else "right")
    for r in result["objects"]:
        for look, x in r["looks"].items():
            p, y, res = x["position_error_m"], x["yaw_error_rad"], x["residual_rms_m"]
            yaw = f"{np.degrees(y['median']):.2f} / {np.degrees(y['p95']):.2f}" if r["yaw_defined"] else "(free)"
            t.add_row(r["object"], look, str(r["trials"]), str(x["not_seen"]),
                      f"{p['median'] * 1e3:.2f} / {p['p95'] * 1e3:.2f}", yaw,
                      f"{res['median'] * 1e3:.2f} / {res['p95'] * 1e3:.2f}", f"{x['wall_s_per_estimate']:.2f}")
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
    parser.add_argument("--workers", type=int, default=1, help="processes (one object each at a time)")
    args = parser.parse_args(argv)
    if args.trials < 1:
        parser.error(f"--trials must be >= 1, got {args.trials}")
    if args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
    result = run(args.trials, args.objects, args.seed, args.workers)
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
