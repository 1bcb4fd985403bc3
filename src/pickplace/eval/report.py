"""Episode video and plots from a :class:`~pickplace.task.telemetry.Telemetry`.

:func:`render_video` replays the recorded ``qpos`` frames offscreen through MuJoCo's renderer and writes an
MP4 (H.264) or a GIF; :func:`save_plots` writes PNG plots of joint tracking, tcp and object heights, pad forces
and the phase timeline. Both need the ``video`` extra (``pip install 'pickplace[video]'``: imageio,
imageio-ffmpeg, matplotlib); those packages are imported inside the functions, so ``import pickplace.eval.report``
works without them.

The OpenGL context (EGL without a display) comes from :func:`pickplace.perception.render.make_renderer`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from pickplace.perception.render import RenderError, make_renderer
from pickplace.robot.model import ARM_JOINTS, Robot
from pickplace.task.telemetry import Telemetry

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

log = logging.getLogger(__name__)

#: The pip command that installs the optional packages this module needs.
VIDEO_EXTRA_HINT = "pip install 'pickplace[video]'"
#: Frame rate used when the telemetry has fewer than two frames (frames per second).
DEFAULT_FPS = 30.0

# --------------------------------------------------------------------------- #
# optional dependencies
# --------------------------------------------------------------------------- #


def _import_optional(module: str) -> Any:
    """Import ``module`` from the ``video`` extra, or raise :class:`RenderError` with the pip command."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise RenderError(f"{module} is not installed ({exc}); install the video extra: {VIDEO_EXTRA_HINT}") from exc


# --------------------------------------------------------------------------- #
# video
# --------------------------------------------------------------------------- #


def _frame_fps(telemetry: Telemetry) -> float:
    """1 / median interval of the frame times (frames per second), or :data:`DEFAULT_FPS`."""
    dt = np.diff(telemetry.frame_t_s)
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if dt.size else DEFAULT_FPS


def _frame_phases(telemetry: Telemetry) -> list[str]:
    """Name of the phase running at each video frame."""
    if telemetry.t_s.size == 0:
        return [""] * telemetry.frame_t_s.size
    idx = np.searchsorted(telemetry.t_s, telemetry.frame_t_s, side="right") - 1
    idx = np.clip(idx, 0, telemetry.t_s.size - 1)
    return [telemetry.phase_names[int(telemetry.phase[i])] for i in idx]


def _overlay_font(height: int) -> Any:
    """Pillow's built-in font at about 1/28 of the frame height (px), or None if Pillow is missing."""
    try:
        from PIL import ImageFont
    except ImportError:  # pragma: no cover - Pillow comes with matplotlib
        return None
    return ImageFont.load_default(size=max(10, height // 28))


def _overlay(frame: np.ndarray, text: str, font: Any) -> np.ndarray:
    """``frame`` (H, W, 3) uint8 with ``text`` drawn top-left in white on a black box."""
    from PIL import Image, ImageDraw

    img = Image.fromarray(frame)
    draw = ImageDraw.Draw(img)
    pad = 3
    left, top, right, bottom = draw.textbbox((2 * pad, 2 * pad), text, font=font)
    draw.rectangle((left - pad, top - pad, right + pad, bottom + pad), fill=(0, 0, 0))
    draw.text((2 * pad, 2 * pad), text, fill=(255, 255, 255), font=font)
    return np.asarray(img)


class _VideoWriter:
    """Streams RGB frames to an MP4 (H.264, yuv420p, via imageio-ffmpeg) or collects them for a GIF."""

    def __init__(self, path: Path, width: int, height: int, fps: float) -> None:
        self.path, self.fps = path, fps
        self._gif = path.suffix.lower() == ".gif"
        self._frames: list[np.ndarray] = []
        self._writer: Any = None
        if self._gif:
            _import_optional("imageio")
            return
        imageio_ffmpeg = _import_optional("imageio_ffmpeg")
        self._writer = imageio_ffmpeg.write_frames(
            str(path), (width, height), fps=fps, codec="libx264", pix_fmt_in="rgb24", pix_fmt_out="yuv420p",
            quality=7, macro_block_size=2, ffmpeg_log_level="error")
        self._writer.send(None)  # start ffmpeg

    def write(self, frame: np.ndarray) -> None:
        if self._gif:
            self._frames.append(frame.copy())
        else:
            self._writer.send(np.ascontiguousarray(frame))

    def close(self) -> None:
        if self._gif:
            iio = _import_optional("imageio.v3")
            iio.imwrite(self.path, np.stack(self._frames), extension=".gif", duration=1000.0 / self.fps, loop=0)
        else:
            self._writer.close()


def render_video(
    robot: Robot,
    telemetry: Telemetry,
    path: str | Path,
    *,
    width: int = 640,
    height: int = 480,
    fps: float | None = None,
    camera: str = "overview",
    overlay: bool = True,
    shadows: bool = True,
) -> Path:
    """Render the episode's recorded frames offscreen to an MP4 (H.264) or, if ``path`` ends in .gif, a GIF.

    Each frame sets the full ``qpos`` recorded in ``telemetry.frame_qpos`` on a private ``MjData``, computes
    the kinematics and camera poses (``mj_kinematics`` + ``mj_camlight``) and renders from ``camera``.

    Args:
        robot: The models the telemetry was recorded on (``robot.mj.nq`` must match the frames' width).
        telemetry: The episode; its ``frame_t_s`` (F,) (s) and ``frame_qpos`` (F, nq) are rendered.
        path: Output file; ``.gif`` writes a GIF, anything else an H.264 MP4. Parent folders are created.
        width: Frame width (px); even for MP4, at most the model's offscreen width.
        height: Frame height (px); even for MP4, at most the model's offscreen height.
        fps: Playback frame rate (frames per second); default 1 / median interval of ``frame_t_s``, which
            plays the episode in real time.
        camera: Name of a camera of the model.
        overlay: Draw the running phase's name and the time (s) in the top-left corner.
        shadows: Render shadows. On a CPU renderer (Mesa llvmpipe) they cost more than half the render time
            with the scene's 4096 px shadow map: 640x480 renders at ~15 frames/s with, ~35 without (2 cores).

    Returns:
        The path written.

    Raises:
        RenderError: no OpenGL context can be created, imageio / imageio-ffmpeg is missing, the camera does
            not exist, the telemetry has no frames or frames of another model, or the encoder fails.
    """
    path = Path(path)
    m = robot.mj
    frames = telemetry.frame_qpos
    if frames.shape[0] == 0:
        raise RenderError("the telemetry has no video frames (recorded with frame_rate_hz=0?)")
    if frames.ndim != 2 or frames.shape[1] != m.nq:
        raise RenderError(f"frame_qpos has shape {frames.shape}, expected (F, {m.nq}) for this model")
    if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
        names = [m.camera(i).name for i in range(m.ncam)]
        raise RenderError(f"the model has no camera named {camera!r}; cameras: {names}")
    if fps is None:
        fps = _frame_fps(telemetry)
    if not fps > 0:
        raise RenderError(f"fps = {fps} is invalid: must be > 0 frames per second")
    if path.suffix.lower() != ".gif" and (width % 2 or height % 2):
        raise RenderError(f"an H.264 MP4 (yuv420p) needs an even frame size, got {width}x{height} px")
    _import_optional("imageio.v3" if path.suffix.lower() == ".gif" else "imageio_ffmpeg")  # fail before rendering
    labels = _frame_phases(telemetry)
    font = _overlay_font(height) if overlay else None

    path.parent.mkdir(parents=True, exist_ok=True)
    renderer, backend = make_renderer(m, width, height)
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
    d = mujoco.MjData(m)
    t0 = time.perf_counter()
    try:
        writer = _VideoWriter(path, width, height, fps)
        try:
            for i, qpos in enumerate(frames):
                d.qpos[:] = qpos
                mujoco.mj_kinematics(m, d)
                mujoco.mj_camlight(m, d)
                renderer.update_scene(d, camera=camera)
                frame = renderer.render()
                if font is not None:
                    frame = _overlay(frame, f"{labels[i]}  t = {telemetry.frame_t_s[i]:.2f} s", font)
                writer.write(frame)
        finally:
            writer.close()
    except (OSError, RuntimeError) as exc:
        raise RenderError(f"could not write {path}: {exc}") from exc
    finally:
        renderer.close()
    elapsed = time.perf_counter() - t0
    log.info("wrote %s: %d frames %dx%d px at %.3g fps (%s backend, %.1f frames/s rendered+encoded)",
             path, frames.shape[0], width, height, fps, backend, frames.shape[0] / max(elapsed, 1e-9))
    return path


# --------------------------------------------------------------------------- #
# plots
# --------------------------------------------------------------------------- #


def _figure(width_in: float, height_in: float) -> Figure:
    """A matplotlib Figure with its own Agg canvas: no pyplot, no global figure registry."""
    _import_optional("matplotlib")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _phase_colors(names: Sequence[str]) -> dict[str, tuple[float, ...]]:
    """One colour per phase name (matplotlib's tab20 colours, in order of first entry)."""
    from matplotlib import colormaps

    cmap = colormaps["tab20"]
    return {name: tuple(cmap(i % cmap.N)) for i, name in enumerate(names)}


def _shade_phases(ax: Axes, telemetry: Telemetry, colors: dict[str, tuple[float, ...]]) -> None:
    """Shade each phase span of ``ax`` in its colour, with a boundary line and the name at the top."""
    spans = telemetry.phase_spans()
    if not spans:
        return
    total = max(spans[-1][2] - spans[0][1], 1e-9)
    for name, t0, t1 in spans:
        ax.axvspan(t0, t1, color=colors[name], alpha=0.15, linewidth=0)
        ax.axvline(t0, color="0.5", linewidth=0.5)
        if (t1 - t0) / total > 0.03:
            ax.text((t0 + t1) / 2, 0.99, name, transform=ax.get_xaxis_transform(), ha="center", va="top",
                    rotation=0 if (t1 - t0) / total > 0.12 else 90, fontsize=7, color="0.25", clip_on=True)


def _plot_joint_tracking(telemetry: Telemetry, path: Path) -> None:
    segments = telemetry.joint_segments
    rows = max(len(segments), 1)
    fig = _figure(11.0, 2.6 * rows + 0.6)
    axes = fig.subplots(rows, 2, squeeze=False)
    if not segments:
        for ax in axes[0]:
            ax.text(0.5, 0.5, "no tracked trajectory", transform=ax.transAxes, ha="center", va="center")
            ax.set_axis_off()
    short = [n.removesuffix("_joint") for n in ARM_JOINTS]
    for (ax_q, ax_e), seg in zip(axes, segments, strict=False):
        t, q, q_ref = np.asarray(seg.t_s), np.asarray(seg.q), np.asarray(seg.q_ref)
        for j in range(q.shape[1]):
            color = f"C{j}"
            ax_q.plot(t, q[:, j], color=color, linewidth=1.2, label=short[j] if j < len(short) else f"q{j}")
            ax_q.plot(t, q_ref[:, j], color=color, linewidth=1.0, linestyle="--")
            ax_e.plot(t, (q[:, j] - q_ref[:, j]) * 1e3, color=color, linewidth=1.0)
        ax_q.set_title(f"{seg.phase}: q (solid) and q_ref (dashed)", fontsize=9)
        ax_q.set_ylabel("joint angle (rad)")
        ax_e.set_title(f"{seg.phase}: tracking error q - q_ref", fontsize=9)
        ax_e.set_ylabel("error (mrad)")
        ax_e.axhline(0.0, color="0.5", linewidth=0.5)
        for ax in (ax_q, ax_e):
            ax.set_xlabel("time (s)")
            ax.grid(True, alpha=0.3)
    if segments:
        axes[0][0].legend(fontsize=7, ncols=2, loc="best")
    fig.savefig(path, dpi=110)


def _plot_tcp_height(telemetry: Telemetry, path: Path, colors: dict[str, tuple[float, ...]]) -> None:
    fig = _figure(10.0, 4.0)
    ax = fig.subplots()
    _shade_phases(ax, telemetry, colors)
    ax.plot(telemetry.t_s, telemetry.tcp_pos_m[:, 2], label="tcp z", color="C0")
    ax.plot(telemetry.t_s, telemetry.object_pos_m[:, 2], label="object origin z", color="C3")
    if telemetry.goal_pos_m.size == 3:
        ax.axhline(float(telemetry.goal_pos_m[2]), color="C2", linestyle=":", label="goal centre z")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("height above the floor (m)")
    ax.set_title("tcp and object height")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.savefig(path, dpi=110)


def _plot_grip_force(telemetry: Telemetry, path: Path, colors: dict[str, tuple[float, ...]]) -> None:
    fig = _figure(10.0, 4.0)
    ax = fig.subplots()
    _shade_phases(ax, telemetry, colors)
    f = telemetry.pad_force_n
    ax.plot(telemetry.t_s, f[:, 0], label="left pad", color="C0")
    ax.plot(telemetry.t_s, f[:, 1], label="right pad", color="C1")
    ax.plot(telemetry.t_s, f.sum(axis=1), label="sum", color="k", linewidth=1.0, linestyle="--")
    ax.set_ylim(bottom=min(0.0, float(f.min(initial=0.0))), top=max(1.0, 1.1 * float(f.sum(axis=1).max(initial=0.0))))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("pad normal force (N)")
    ax.set_title("grip force (normal force of the object on each pad)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.savefig(path, dpi=110)


def _plot_phase_timeline(telemetry: Telemetry, path: Path, colors: dict[str, tuple[float, ...]]) -> None:
    names = list(telemetry.phase_names)
    fig = _figure(10.0, 0.45 * max(len(names), 1) + 1.2)
    ax = fig.subplots()
    spans = telemetry.phase_spans()
    if not spans:
        ax.text(0.5, 0.5, "no phases recorded", transform=ax.transAxes, ha="center", va="center")
        ax.set_axis_off()
    total = max(spans[-1][2] - spans[0][1], 1e-9) if spans else 1.0
    for name, t0, t1 in spans:
        row = names.index(name)
        ax.barh(row, t1 - t0, left=t0, height=0.6, color=colors[name], edgecolor="k", linewidth=0.5)
        label = f"{t1 - t0:.2f} s"
        if (t1 - t0) / total > 0.08:
            ax.text((t0 + t1) / 2, row, label, ha="center", va="center", fontsize=7)
        else:
            ax.text(t1, row, " " + label, ha="left", va="center", fontsize=7)
    if spans:
        ax.set_yticks(range(len(names)), names, fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel("time (s)")
        ax.set_title("phase timeline")
        ax.grid(True, axis="x", alpha=0.3)
    fig.savefig(path, dpi=110)


def save_plots(telemetry: Telemetry, out_dir: str | Path) -> list[Path]:
    """Write the episode's plots as PNG files into ``out_dir`` (created if missing).

    Files:
        ``joint_tracking.png``: per tracked trajectory (one row each), q and q_ref (rad) and the tracking
        error q - q_ref (mrad) of the six arm joints against time (s).
        ``tcp_height.png``: tcp and object origin heights (m) and the goal height against time, phases shaded.
        ``grip_force.png``: left and right pad normal forces and their sum (N) against time, phases shaded.
        ``phase_timeline.png``: one horizontal bar per phase span (s), one row per phase.

    Matplotlib is used through ``matplotlib.figure.Figure`` with its own Agg canvas; pyplot's global state
    is never touched.

    Args:
        telemetry: The episode.
        out_dir: Folder to write into.

    Returns:
        The paths written, in the order above.

    Raises:
        RenderError: matplotlib is not installed.
    """
    _import_optional("matplotlib")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    colors = _phase_colors(telemetry.phase_names)
    paths = [out / name for name in ("joint_tracking.png", "tcp_height.png", "grip_force.png",
                                     "phase_timeline.png")]
    t0 = time.perf_counter()
    _plot_joint_tracking(telemetry, paths[0])
    _plot_tcp_height(telemetry, paths[1], colors)
    _plot_grip_force(telemetry, paths[2], colors)
    _plot_phase_timeline(telemetry, paths[3], colors)
    log.info("wrote %d plots to %s in %.2f s", len(paths), out, time.perf_counter() - t0)
    return paths


__all__ = ["RenderError", "render_video", "save_plots"]
