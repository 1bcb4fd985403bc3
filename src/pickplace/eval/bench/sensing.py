"""Sensing benchmark: how good the depth camera must be, measured on whole realistic pick and places.

Two sweeps of the realistic profile's camera (:class:`~pickplace.perception.camera.CameraConfig`, an Intel
RealSense D435 model), each point run on the same ``--trials`` randomized episodes:

* depth noise: the stereo disparity error ``subpixel_px`` (default grid 0.04, 0.08, 0.16, 0.32, 0.64 px; the
  D435's datasheet value is 0.08 px), at the default calibration error. The depth error RMS is
  ``sigma_z = z^2 subpixel / (f baseline)``; the table reports it at the distance from the camera to the point
  it looks at (0.81 m: 2.4 mm at 0.08 px);
* calibration error: a scale on both extrinsic calibration sigmas (default grid 0, 1, 2, 4; 0 is a perfectly
  calibrated camera, 1 the default 2 mm per axis and 0.2 degrees per axis), at the default depth noise. The
  error is drawn once per episode from its seed, so every point of the sweep moves the camera along the same
  direction, farther.

The point both sweeps share (the defaults, 0.08 px at scale 1) is run once and reported in both.

The episodes: the realistic profile (:meth:`EpisodeConfig.with_profile`: camera, gripper and wrist sensors, a
500 Hz loop with latency and encoder noise, model error), randomized as the campaigns randomize by default
(:class:`~pickplace.eval.campaign.RandomizationSpec`, drawn and applied by
:func:`~pickplace.eval.campaign.make_trial`: start and goal within 5 cm, start yaw within 45 degrees, the cube's
mass, size and friction). Trial ``i`` has the same scene and the same episode seed at every grid point (a
paired comparison: only the camera differs). Measured per point, against the simulator's truth (which the robot
never reads):

* the success rate, with its 95 % Wilson score interval;
* the horizontal place error (``EpisodeResult.place_error_xy_m``) over the successes: RMS, p95, max;
* the robot's estimates of the object's pose (``EpisodeResult.pose_estimates``), by what was estimated:
  ``resting`` (the object on the table: the first look before the grasp and the check after the release) and
  ``in hand`` (the held object against the gripper, before the place): position error median, p95, RMS and the
  yaw error's median and p95 (absolute, modulo the object's symmetry), over every estimate of every trial;
* the failures by phase and kind.

Episodes run in ``--workers`` spawned worker processes (the campaigns' local backend,
:func:`~pickplace.eval.campaign.backends.run_local`: a per-trial timeout, a crashed or hung worker recorded as
a failed trial of phase ``WORKER``); this process never renders. A realistic episode takes 5-15 s of wall time,
so the default run (8 distinct grid points x 10 trials = 80 episodes) takes about 5-15 minutes on 2 cores
(measured: ~5 s per episode on an idle core, twice that on a loaded machine); ``--quick`` (2 points x 2 trials)
under a minute.

Usage: ``pickplace bench sensing [--trials N] [--workers W] [--seed S] [--subpixel-px V ...]
[--calibration-scale S ...] [--timeout S] [--json] [--plot PATH.png] [--quick]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pickplace.errors import ConfigError
from pickplace.eval.bench import machine_info
from pickplace.eval.campaign import CampaignConfig, RandomizationSpec, Trial, make_trial, wilson_interval
from pickplace.eval.campaign.backends import run_local
from pickplace.eval.campaign.store import json_ready
from pickplace.perception.camera import CameraConfig
from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.world.config import check_int, check_range

log = logging.getLogger(__name__)

#: The default grid of the depth-noise sweep: disparity error RMS (px); the D435's datasheet value is 0.08.
DEFAULT_SUBPIXEL_PX = (0.04, 0.08, 0.16, 0.32, 0.64)
#: The default grid of the calibration sweep: scale on both calibration sigmas (1: 2 mm and 0.2 deg per axis).
DEFAULT_CALIBRATION_SCALES = (0.0, 1.0, 2.0, 4.0)
#: The grid of ``--quick``: 2 distinct points (the shared default and one noisier camera).
QUICK_SUBPIXEL_PX = (0.08, 0.32)
QUICK_CALIBRATION_SCALES = (1.0,)
#: Trials per grid point by default, and with ``--quick``.
DEFAULT_TRIALS, QUICK_TRIALS = 10, 2
#: Largest calibration scale accepted (x 2 mm is 4 cm; CameraConfig allows 5 cm and 0.1 rad).
MAX_CALIBRATION_SCALE = 20.0
#: What the robot estimates: ``EpisodeResult.pose_estimates``' ``what``.
ESTIMATE_KINDS = ("resting", "in hand")
#: The sweeps, in the order they are reported.
SWEEPS = ("depth_noise", "calibration")
#: Command-line option of each config field (to name it in errors).
OPTIONS = {"subpixel_px": "--subpixel-px", "calibration_scales": "--calibration-scale", "trials": "--trials",
           "workers": "--workers", "seed": "--seed", "timeout_s": "--timeout"}


@dataclass(frozen=True)
class SensingBenchConfig:
    """What the sensing benchmark runs.

    Attributes:
        subpixel_px: Grid of the depth-noise sweep: the camera's ``subpixel_px`` (px), each in [0, 2]; sorted,
            duplicates dropped.
        calibration_scales: Grid of the calibration sweep: the scale on both of the camera's calibration sigmas,
            each in [0, ``MAX_CALIBRATION_SCALE``]; sorted, duplicates dropped.
        trials: Randomized episodes per grid point (the same ones at every point).
        workers: Worker processes running episodes at once.
        seed: Campaign seed of the trials (their scenes and episode seeds).
        timeout_s: Wall-clock limit per episode (s); an episode over it is a failed trial of phase ``WORKER``.
        camera: The camera whose noise and calibration error are swept (default: the D435 model); the calibration
            sweep runs at its ``subpixel_px``, the noise sweep at its calibration sigmas.
        randomization: How the trials are drawn (default: the campaigns' default randomization).
    """

    subpixel_px: tuple[float, ...] = DEFAULT_SUBPIXEL_PX
    calibration_scales: tuple[float, ...] = DEFAULT_CALIBRATION_SCALES
    trials: int = DEFAULT_TRIALS
    workers: int = 2
    seed: int = 0
    timeout_s: float = 180.0
    camera: CameraConfig = field(default_factory=CameraConfig)
    randomization: RandomizationSpec = field(default_factory=RandomizationSpec)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "subpixel_px", _grid("sensing.subpixel_px", self.subpixel_px, 0.0, 2.0, "px"))
        set_(self, "calibration_scales",
             _grid("sensing.calibration_scales", self.calibration_scales, 0.0, MAX_CALIBRATION_SCALE, ""))
        set_(self, "trials", check_int("sensing.trials", self.trials, 1, 100_000))
        set_(self, "workers", check_int("sensing.workers", self.workers, 1, 1024))
        set_(self, "seed", check_int("sensing.seed", self.seed, 0, 2**63 - 1))
        set_(self, "timeout_s", check_range("sensing.timeout_s", self.timeout_s, 0.0, 86400.0, lo_open=True,
                                            unit="s"))
        if not isinstance(self.camera, CameraConfig):
            raise ConfigError("sensing.camera", self.camera, "must be a CameraConfig")
        if not isinstance(self.randomization, RandomizationSpec):
            raise ConfigError("sensing.randomization", self.randomization, "must be a RandomizationSpec")

    def points(self) -> dict[str, tuple[tuple[float, float], ...]]:
        """The grid: per sweep, its ``(subpixel_px, calibration_scale)`` points in order."""
        return {"depth_noise": tuple((v, 1.0) for v in self.subpixel_px),
                "calibration": tuple((self.camera.subpixel_px, s) for s in self.calibration_scales)}

    def distinct_points(self) -> tuple[tuple[float, float], ...]:
        """Every distinct point of the grid, each run once (the sweeps share the default one)."""
        return tuple(dict.fromkeys(p for pts in self.points().values() for p in pts))

    def camera_at(self, subpixel_px: float, calibration_scale: float) -> CameraConfig:
        """The camera of a grid point."""
        c = self.camera
        return dataclasses.replace(c, subpixel_px=subpixel_px,
                                   calibration_position_sigma_m=c.calibration_position_sigma_m * calibration_scale,
                                   calibration_angle_sigma_rad=c.calibration_angle_sigma_rad * calibration_scale)


def _grid(name: str, values: Iterable[float], lo: float, hi: float, unit: str) -> tuple[float, ...]:
    try:
        items = list(values)
    except TypeError:
        raise ConfigError(name, values, "must be a list of numbers") from None
    if not items:
        raise ConfigError(name, items, "must have at least one value")
    return tuple(sorted({check_range(f"{name}[{k}]", v, lo, hi, unit=unit) for k, v in enumerate(items)}))


# --------------------------------------------------------------------------- #
# results
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of a set of errors (NaN when it is empty).

    Attributes:
        n: How many values.
        median, p95, rms, max: Of the values (their unit: the field's name says it).
    """

    n: int
    median: float
    p95: float
    rms: float
    max: float

    @classmethod
    def of(cls, values: Sequence[float]) -> ErrorStats:
        """The statistics of ``values`` (finite values only)."""
        v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
        if v.size == 0:
            return cls(0, math.nan, math.nan, math.nan, math.nan)
        return cls(int(v.size), float(np.median(v)), float(np.percentile(v, 95)), float(np.sqrt(np.mean(v**2))),
                   float(np.max(v)))


@dataclass(frozen=True)
class PointResult:
    """One grid point, measured over its trials (lengths in m, angles in rad).

    Attributes:
        subpixel_px: The camera's disparity error RMS (px).
        calibration_scale: The scale on the calibration sigmas.
        calibration_position_sigma_m: The calibration's position error RMS per axis (m).
        calibration_angle_sigma_rad: The calibration's orientation error RMS per axis (rad).
        depth_sigma_m: Depth error RMS at the distance from the camera to its look-at point (m).
        trials: Trials run.
        successes: Successful episodes.
        success_rate: ``successes / trials``.
        success_rate_ci95: 95 % Wilson score interval of the success rate.
        place_error_xy_m: Horizontal place error over the successes (the truth).
        estimate_position_error_m: Position error of the robot's pose estimates, by what was estimated
            (``resting``, ``in hand``), over every estimate of every trial.
        estimate_yaw_error_rad: Absolute yaw error of those estimates (modulo the object's symmetry).
        failures: Failed trials by ``"PHASE: Kind"``.
        failure_examples: One failure reason (with its numbers and trial index) per key of ``failures``.
        worker_failures: Trials whose worker raised, crashed or timed out (among the failures).
        wall_time_mean_s: Mean wall time of an episode (s).
    """

    subpixel_px: float
    calibration_scale: float
    calibration_position_sigma_m: float
    calibration_angle_sigma_rad: float
    depth_sigma_m: float
    trials: int
    successes: int
    success_rate: float
    success_rate_ci95: tuple[float, float]
    place_error_xy_m: ErrorStats
    estimate_position_error_m: dict[str, ErrorStats]
    estimate_yaw_error_rad: dict[str, ErrorStats]
    failures: dict[str, int]
    failure_examples: dict[str, str]
    worker_failures: int
    wall_time_mean_s: float


def summarize_point(lines: Sequence[Mapping[str, Any]], camera: CameraConfig, calibration_scale: float,
                    look_distance_m: float) -> PointResult:
    """Measure one grid point from its trials' results lines (:func:`~pickplace.eval.campaign.execute_trial`).

    Args:
        lines: One results line per trial (``EpisodeResult.to_dict()`` plus ``trial`` and ``params``; a worker
            failure has ``None`` figures).
        camera: The point's camera.
        calibration_scale: The point's scale on the calibration sigmas.
        look_distance_m: Distance at which ``depth_sigma_m`` is given (m).
    """
    n = len(lines)
    ok = [ln for ln in lines if ln.get("success")]
    pos: dict[str, list[float]] = {k: [] for k in ESTIMATE_KINDS}
    yaw: dict[str, list[float]] = {k: [] for k in ESTIMATE_KINDS}
    for ln in lines:
        for _phase, what, p, y in ln.get("pose_estimates") or ():
            pos.setdefault(what, []).append(p if p is not None else math.nan)
            yaw.setdefault(what, []).append(abs(y) if y is not None else math.nan)
    failed = Counter(f"{ln.get('failure_phase')}: {ln.get('failure_kind')}" for ln in lines if not ln.get("success"))
    examples: dict[str, str] = {}
    for ln in lines:
        if not ln.get("success"):
            examples.setdefault(f"{ln.get('failure_phase')}: {ln.get('failure_kind')}",
                                f"trial {ln.get('trial')}: {ln.get('failure_reason')}")
    walls = [ln["wall_time_s"] for ln in lines if ln.get("wall_time_s") is not None]
    return PointResult(
        subpixel_px=camera.subpixel_px, calibration_scale=calibration_scale,
        calibration_position_sigma_m=camera.calibration_position_sigma_m,
        calibration_angle_sigma_rad=camera.calibration_angle_sigma_rad,
        depth_sigma_m=float(camera.depth_sigma_m(look_distance_m)),
        trials=n, successes=len(ok), success_rate=len(ok) / n if n else math.nan,
        success_rate_ci95=wilson_interval(len(ok), n),
        place_error_xy_m=ErrorStats.of([ln.get("place_error_xy_m") for ln in ok]),
        estimate_position_error_m={k: ErrorStats.of(v) for k, v in pos.items()},
        estimate_yaw_error_rad={k: ErrorStats.of(v) for k, v in yaw.items()},
        failures=dict(failed.most_common()), failure_examples={k: examples[k] for k, _ in failed.most_common()},
        worker_failures=sum(1 for ln in lines if ln.get("failure_phase") == "WORKER"),
        wall_time_mean_s=float(np.mean(walls)) if walls else math.nan)


@dataclass(frozen=True)
class SensingBenchResult:
    """The benchmark's result, with its conditions.

    Attributes:
        config: What ran.
        sweeps: Per sweep (``depth_noise``, ``calibration``), its points in grid order.
        look_distance_m: Distance from the camera to its look-at point, where ``depth_sigma_m`` is given (m).
        episodes: Episodes run (distinct points x trials).
        wall_s: Wall time of the whole run (s).
        machine: Where it ran (:func:`~pickplace.eval.bench.machine_info`).
    """

    config: SensingBenchConfig
    sweeps: dict[str, tuple[PointResult, ...]]
    look_distance_m: float
    episodes: int
    wall_s: float
    machine: dict[str, Any]

    def conditions(self) -> str:
        """One line saying what every figure was measured under."""
        c, cam = self.config, self.config.camera
        active = _randomization_text(self.config.randomization)
        return (f"realistic profile (D435-model depth camera, 500 Hz loop with latency, encoder noise, model "
                f"error); {c.trials} randomized episodes per grid point, the same trials at every point (campaign "
                f"seed {c.seed}), randomized as the campaigns' default: {active}; depth noise swept at calibration "
                f"x1 ({cam.calibration_position_sigma_m * 1e3:g} mm, "
                f"{math.degrees(cam.calibration_angle_sigma_rad):g} deg per axis), calibration swept at "
                f"{cam.subpixel_px:g} px; errors against the simulator's truth; place error over successes only")

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (NaN becomes None), with the conditions."""
        cam = self.config.camera
        return json_ready({
            "benchmark": "sensing",
            "conditions": self.conditions(),
            "profile": "realistic",
            "camera_defaults": dataclasses.asdict(cam),
            "look_distance_m": self.look_distance_m,
            "grid": {"subpixel_px": list(self.config.subpixel_px),
                     "calibration_scales": list(self.config.calibration_scales),
                     "distinct_points": [list(p) for p in self.config.distinct_points()]},
            "trials_per_point": self.config.trials, "seed": self.config.seed, "workers": self.config.workers,
            "timeout_s": self.config.timeout_s,
            "randomization": self.config.randomization.to_dict(),
            "episodes": self.episodes, "wall_s": self.wall_s, "machine": self.machine,
            "sweeps": {name: [dataclasses.asdict(p) for p in pts] for name, pts in self.sweeps.items()},
        })


def _randomization_text(spec: RandomizationSpec) -> str:
    """The randomized ranges, e.g. ``start_dx_m [-0.05, 0.05]`` (fixed ones left out)."""
    parts = [f"{name} [{r[0]:.3g}, {r[1]:.3g}]" for name in spec.active()
             if (r := getattr(spec, name))[0] != r[1]]
    if spec.objects is not None:
        parts.append(f"object one of {', '.join(spec.objects)}")
    return ", ".join(parts) or "nothing"


# --------------------------------------------------------------------------- #
# the run
# --------------------------------------------------------------------------- #


def with_camera(config: EpisodeConfig, camera: CameraConfig) -> EpisodeConfig:
    """``config`` with its profile's camera replaced."""
    return dataclasses.replace(config, profile=dataclasses.replace(config.profile, camera=camera))


def make_trials(config: SensingBenchConfig) -> tuple[list[Trial], dict[int, tuple[float, float]]]:
    """Every episode of the benchmark, and the grid point of each (by trial index).

    Trial ``i`` of every point is the campaign's trial ``i`` (:func:`~pickplace.eval.campaign.make_trial` on the
    realistic profile with the config's randomization and seed) with the point's camera; its index here is
    ``point * trials + i``.
    """
    campaign = CampaignConfig(base=EpisodeConfig().with_profile("realistic"), randomization=config.randomization,
                              trials=config.trials, seed=config.seed, workers=config.workers,
                              timeout_s=config.timeout_s)
    base_trials = [make_trial(campaign, i) for i in range(config.trials)]
    trials, where = [], {}
    for k, point in enumerate(config.distinct_points()):
        camera = config.camera_at(*point)
        for t in base_trials:
            index = k * config.trials + t.index
            trials.append(Trial(index, t.seed, {**t.params, "subpixel_px": point[0], "calibration_scale": point[1]},
                                with_camera(t.config, camera)))
            where[index] = point
    # interleave the points, so that a run cut short has measured every point alike
    trials.sort(key=lambda t: (t.index % config.trials, t.index // config.trials))
    return trials, where


def run(config: SensingBenchConfig | None = None,
        on_result: Callable[[dict[str, Any]], None] | None = None) -> SensingBenchResult:
    """Run the benchmark (see the module's docstring).

    Args:
        config: What to run (default: the default grid, 10 trials per point, 2 workers).
        on_result: Called in this process with each finished trial's results line (e.g. for a progress bar).

    Raises:
        ConfigError: a bad config (nothing has run).
    """
    config = config if config is not None else SensingBenchConfig()
    if not isinstance(config, SensingBenchConfig):
        raise ConfigError("config", config, "must be a SensingBenchConfig")
    trials, where = make_trials(config)
    lines: dict[tuple[float, float], list[dict[str, Any]]] = {p: [] for p in config.distinct_points()}

    def done(line: dict[str, Any]) -> None:
        lines[where[line["trial"]]].append(line)
        log.info("sensing trial %d (subpixel %.3g px, calibration x%g): %s", line["trial"], *where[line["trial"]],
                 "success" if line.get("success") else f"failed in {line.get('failure_phase')}")
        if on_result is not None:
            on_result(line)

    t0 = time.perf_counter()
    run_local(trials, run_episode, config.workers, config.timeout_s, done,
              lambda: log.info("sensing: %d workers up", config.workers))
    wall = time.perf_counter() - t0
    look = float(np.linalg.norm(np.subtract(config.camera.look_at_m, config.camera.position_m)))
    measured = {p: summarize_point(sorted(ls, key=lambda ln: ln["trial"]), config.camera_at(*p), p[1], look)
                for p, ls in lines.items()}
    sweeps = {name: tuple(measured[p] for p in pts) for name, pts in config.points().items()}
    return SensingBenchResult(config, sweeps, look, len(trials), wall, machine_info())


# --------------------------------------------------------------------------- #
# table and plot
# --------------------------------------------------------------------------- #


def _mm(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v * 1e3:.1f}"


def _short(text: str, limit: int = 160) -> str:
    return text if len(text) <= limit else text[:limit - 1] + "…"


def print_table(result: SensingBenchResult) -> None:
    """Print one rich table per sweep (its failures under it), and the conditions."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if not console.is_terminal:  # a log or a pipe: do not squeeze the table into 80 columns
        console = Console(width=150)
    titles = {"depth_noise": "Depth noise sweep (calibration error x1)",
              "calibration": f"Calibration error sweep (depth noise {result.config.camera.subpixel_px:g} px)"}
    for name in SWEEPS:
        t = Table(title=f"{titles[name]}: {result.config.trials} realistic episodes per point")
        for col in ("subpixel px", f"σz@{result.look_distance_m:.2f}m mm", "calib. mm / °", "success", "95% CI",
                    "place RMS / p95 mm", "resting est. med / p95 mm", "resting yaw p95 °",
                    "in-hand est. med / p95 mm"):
            t.add_column(col, justify="right")
        failures = []
        for p in result.sweeps[name]:
            rest, hand = p.estimate_position_error_m["resting"], p.estimate_position_error_m["in hand"]
            yaw = p.estimate_yaw_error_rad["resting"].p95
            lo, hi = p.success_rate_ci95
            t.add_row(f"{p.subpixel_px:g}", _mm(p.depth_sigma_m),
                      f"x{p.calibration_scale:g}: {p.calibration_position_sigma_m * 1e3:g} / "
                      f"{math.degrees(p.calibration_angle_sigma_rad):.2g}",
                      f"{p.successes}/{p.trials}", f"{lo:.2f}-{hi:.2f}",
                      f"{_mm(p.place_error_xy_m.rms)} / {_mm(p.place_error_xy_m.p95)}",
                      f"{_mm(rest.median)} / {_mm(rest.p95)}",
                      "-" if not math.isfinite(yaw) else f"{math.degrees(yaw):.2f}",
                      f"{_mm(hand.median)} / {_mm(hand.p95)}")
            if p.failures:
                failures.append(f"  {p.subpixel_px:g} px, calibration x{p.calibration_scale:g}: "
                                + ", ".join(f"{k} x{v}" for k, v in p.failures.items()))
                failures += [f"    e.g. {k}, {_short(ex)}" for k, ex in p.failure_examples.items()]
        console.print(t)
        console.print("failures (phase: kind x count):" + ("\n" + "\n".join(failures) if failures else " none"),
                      highlight=False)
    m = result.machine
    console.print(f"Conditions: {result.conditions()}.", highlight=False)
    console.print(f"{result.episodes} episodes on {result.config.workers} workers in {result.wall_s:.0f} s wall; "
                  f"{m['cpu_count']} cores, 1-min load average {m['load_average_1min']:.2f}, Python {m['python']}, "
                  f"MuJoCo {m['mujoco']}, {m['platform']}", highlight=False)


def write_plot(result: SensingBenchResult, path: str | Path) -> Path:
    """Write the plot: per sweep, the success rate (with its 95 % interval) and the place error RMS and p95
    against the swept parameter, each panel titled with its conditions. Returns the path."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    out = Path(path)
    fig = Figure(figsize=(13.0, 9.0), dpi=100, layout="constrained")  # its own Agg canvas: no pyplot, no GUI
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2)
    cam, n = result.config.camera, result.config.trials
    cal = (f"calibration x1 ({cam.calibration_position_sigma_m * 1e3:g} mm, "
           f"{math.degrees(cam.calibration_angle_sigma_rad):g}°)")
    sweep_cond = {"depth_noise": cal, "calibration": f"depth noise {cam.subpixel_px:g} px"}
    for row, name in enumerate(SWEEPS):
        pts = result.sweeps[name]
        if name == "depth_noise":
            x = [p.subpixel_px for p in pts]
            ticks = [f"{p.subpixel_px:g}\n({p.depth_sigma_m * 1e3:.1f} mm)" for p in pts]
            xlabel = f"disparity noise subpixel_px (px)  (σz at {result.look_distance_m:.2f} m)"
        else:
            x = [p.calibration_scale for p in pts]
            ticks = [f"×{p.calibration_scale:g}\n({p.calibration_position_sigma_m * 1e3:g} mm, "
                     f"{math.degrees(p.calibration_angle_sigma_rad):.2g}°)" for p in pts]
            xlabel = "calibration error scale (position, angle RMS per axis)"
        rate = np.array([p.success_rate for p in pts])
        lo = np.array([p.success_rate_ci95[0] for p in pts])
        hi = np.array([p.success_rate_ci95[1] for p in pts])
        ax = axes[row, 0]
        ax.errorbar(x, rate, yerr=[rate - lo, hi - rate], fmt="o-", capsize=4, label="success rate (95% Wilson)")
        ax.set_ylim(-0.02, 1.02)
        ax.set_ylabel("success rate")
        ax.set_title(f"Success, {n} realistic episodes/point, {sweep_cond[name]}", fontsize=9)
        ax = axes[row, 1]
        ax.plot(x, [p.place_error_xy_m.rms * 1e3 for p in pts], "o-", label="place error RMS")
        ax.plot(x, [p.place_error_xy_m.p95 * 1e3 for p in pts], "s--", label="place error p95")
        ax.plot(x, [p.estimate_position_error_m["resting"].p95 * 1e3 for p in pts], "^:",
                label="resting pose estimate p95 (3-D, all trials)")
        ax.set_ylabel("error (mm); place error horizontal")
        ax.set_ylim(bottom=0)
        ax.set_title(f"Place error over successes vs truth, {n} episodes/point, {sweep_cond[name]}", fontsize=9)
        ax.legend(fontsize=8)
        for ax in axes[row]:
            if name == "depth_noise" and min(x) > 0:
                ax.set_xscale("log", base=2)
            ax.set_xticks(x, ticks, fontsize=7)
            ax.minorticks_off()
            ax.set_xlabel(xlabel, fontsize=8)
            ax.grid(alpha=0.3)
    fig.suptitle("pickplace bench sensing: realistic profile, campaign default randomization, same trials at "
                 f"every point (seed {result.config.seed}); {result.machine['cpu_count']} cores", fontsize=10)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    return out


# --------------------------------------------------------------------------- #
# command line
# --------------------------------------------------------------------------- #


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print rich tables, or one JSON object with ``--json``. Returns the exit code."""
    parser = argparse.ArgumentParser(prog="pickplace bench sensing", description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, metavar="N",
                        help=f"randomized episodes per grid point (default {DEFAULT_TRIALS}; --quick: {QUICK_TRIALS})")
    parser.add_argument("--workers", type=int, default=2, metavar="W", help="worker processes (default 2)")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="campaign seed of the trials (default 0)")
    parser.add_argument("--subpixel-px", type=float, nargs="+", metavar="V",
                        help="depth-noise grid, disparity RMS in px (default: "
                             f"{' '.join(f'{v:g}' for v in DEFAULT_SUBPIXEL_PX)})")
    parser.add_argument("--calibration-scale", type=float, nargs="+", metavar="S",
                        help="calibration grid, scale on the 2 mm / 0.2 deg sigmas (default: "
                             f"{' '.join(f'{v:g}' for v in DEFAULT_CALIBRATION_SCALES)})")
    parser.add_argument("--timeout", type=float, default=180.0, metavar="S",
                        help="wall-clock limit per episode in s (default 180)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the tables")
    parser.add_argument("--plot", metavar="PATH.png", help="write the success and place-error plot there")
    parser.add_argument("--quick", action="store_true",
                        help=f"a tiny grid ({len(QUICK_SUBPIXEL_PX)} points, {QUICK_TRIALS} trials each)")
    args = parser.parse_args(argv)
    if args.trials is not None and args.trials < 1:
        parser.error(f"--trials must be >= 1 (got {args.trials})")
    if args.workers < 1:
        parser.error(f"--workers must be >= 1 (got {args.workers})")
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        parser.error(f"--plot must be a .png path (got {args.plot})")
    trials = args.trials if args.trials is not None else (QUICK_TRIALS if args.quick else DEFAULT_TRIALS)
    subpixel = args.subpixel_px or (QUICK_SUBPIXEL_PX if args.quick else DEFAULT_SUBPIXEL_PX)
    scales = args.calibration_scale or (QUICK_CALIBRATION_SCALES if args.quick else DEFAULT_CALIBRATION_SCALES)
    try:
        config = SensingBenchConfig(subpixel_px=tuple(subpixel), calibration_scales=tuple(scales), trials=trials,
                                    workers=args.workers, seed=args.seed, timeout_s=args.timeout)
    except ConfigError as exc:
        option = OPTIONS.get(exc.field.removeprefix("sensing.").split("[")[0], exc.field)
        parser.error(f"{option}: {exc}")

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    total = len(config.distinct_points()) * config.trials
    with Progress(TextColumn("sensing episodes"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=Console(stderr=True), transient=True) as progress:
        task = progress.add_task("episodes", total=total)
        result = run(config, on_result=lambda _line: progress.advance(task))
    if args.json:
        print(json.dumps(result.to_dict()))
    else:
        print_table(result)
    if args.plot is not None:
        out = write_plot(result, args.plot)
        if not args.json:
            print(f"plot written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
