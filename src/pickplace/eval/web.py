"""Recorded episodes in a web 3D viewer (viser): ``pickplace replay EP.npz --web`` and ``pickplace run --web``.

:class:`EpisodeViewer` serves one :class:`~pickplace.task.episode_file.SavedEpisode` over HTTP and a websocket
(viser, the ``web`` extra); any browser draws it with WebGL, and the machine that serves it needs no display.

- **Geometry from the MuJoCo model itself.** Every geom the MuJoCo viewer shows by default (groups 0-2: the
  UR5e's and the gripper's visual primitives, the table, the objects, the goal marker, a bin, the wall) becomes
  a triangle mesh (boxes, spheres, capsules, cylinders, ellipsoids and mesh geoms; planes become a grid),
  merged per body and colour in the body's frame. Each frame of the replay sets the recorded ``qpos`` and
  mocap poses, runs ``mj_kinematics`` and moves the bodies.
- **Planned paths**: the tcp's polyline along each planned segment, from the moment it was planned.
- **Grasps**: for each approach, the candidates as small gripper glyphs (open fingers, palm, wrist stem; the
  fingers at the pads' width) and the chosen one in green with its frame, from the approach's planning until
  the grip closes.
- **Contact forces**: an arrow per pad ending where its force acts on the object (the force times
  :data:`FORCE_SCALE_M_PER_N`), while it grips.
- **Timeline**: a time slider, play/pause and speed, a button per phase (jumps to its next start), the phase
  and the pad forces at the current time, and a checkbox per layer.

The viewer binds to ``host:port`` (viser takes the next free port if that one is busy: :attr:`EpisodeViewer.url`
says which); :meth:`EpisodeViewer.serve_forever` plays until interrupted and :meth:`EpisodeViewer.close`
stops the server.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import trimesh

from pickplace.errors import ConfigError, PickPlaceError
from pickplace.robot.model import object_body_name
from pickplace.task.episode_file import SavedEpisode

log = logging.getLogger(__name__)

#: Highest geom group drawn: MuJoCo's viewer shows groups 0-2 by default (visual geoms are group 2, the
#: collision primitives group 3, the camera's obstacle columns group 5).
MAX_GROUP = 2
#: Length of a force arrow per newton (m/N): a 20 N squeeze is an 8 cm arrow.
FORCE_SCALE_M_PER_N = 0.004
#: Pad forces below this are not drawn (N).
MIN_FORCE_N = 0.2
#: Times are shown rounded to 0.1 ms (the slider's); a time is looked up this much later (s), so that a rounded
#: time finds the sample (or frame) it was rounded from: a phase that starts at 0.98100000000000004 s is shown
#: at 0.981 s, in that phase.
ROUNDING_S = 5e-5
#: Bodies farther than this from the origin are parked out of the way (the fault's intruder before it
#: appears): not drawn (m).
PARKED_M = 3.0
#: The first view's distance from the robot and the objects, in units of the diagonal of the box around them.
CAMERA_DISTANCE = 0.7
#: Replay ticks per second while playing.
PLAY_RATE_HZ = 30.0

_PATH_COLORS = {"approach": (31, 119, 180), "transport": (255, 127, 14), "return": (110, 110, 110)}
_OTHER_PATH_COLOR = (148, 103, 189)
_CHOSEN_COLOR = (30, 190, 60)
_CANDIDATE_COLOR = (235, 165, 40)
_FORCE_COLOR = (220, 30, 30)
_MUJOCO_DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)


class WebViewerUnavailable(PickPlaceError):
    """The web viewer's library (viser) is not installed."""


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Keep viser's own prints off stdout (a library does not print)."""
    with contextlib.redirect_stdout(io.StringIO()):
        yield


class _ClosedBeforeRequest(logging.Filter):
    """Drops the websocket server's traceback for a connection closed before it sent a request (browsers open
    such speculative connections); every other record passes."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        cause = exc.__cause__ if exc is not None else None
        return not (record.getMessage() == "opening handshake failed" and isinstance(cause, EOFError))


def require_viser() -> Any:
    """The ``viser`` module.

    Raises:
        WebViewerUnavailable: it is not installed (the ``web`` extra).
    """
    try:
        import viser
    except ImportError:
        raise WebViewerUnavailable("the web viewer needs viser: pip install 'pickplace[web]'") from None
    return viser


# --------------------------------------------------------------------------- #
# geometry of the MuJoCo model
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class BodyMesh:
    """The drawn geoms of one body that share a colour, merged into one triangle mesh in the body's frame.

    Attributes:
        body: The MuJoCo body id.
        rgba: Colour and opacity (4,), 0-1.
        vertices: Vertices in the body's frame (V, 3) (m).
        faces: Triangles (F, 3), indices into ``vertices``.
    """

    body: int
    rgba: tuple[float, float, float, float]
    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True)
class GroundPlane:
    """A plane geom (the floor): its height (m) and half size (m; 0: unbounded)."""

    z_m: float
    half_size_m: float
    rgba: tuple[float, float, float, float]


def geom_rgba(m: mujoco.MjModel, g: int) -> tuple[float, float, float, float]:
    """The colour MuJoCo draws geom ``g`` in: its material's unless the geom sets its own (0-1, (4,))."""
    rgba = tuple(float(v) for v in m.geom_rgba[g])
    mat = int(m.geom_matid[g])
    if mat >= 0 and np.allclose(rgba, _MUJOCO_DEFAULT_RGBA):
        rgba = tuple(float(v) for v in m.mat_rgba[mat])
    return rgba  # type: ignore[return-value]


def geom_mesh(m: mujoco.MjModel, g: int) -> trimesh.Trimesh | None:
    """Geom ``g`` as a triangle mesh in its body's frame, or None for a type that is not drawn this way (planes,
    height fields, SDFs)."""
    size, kind = m.geom_size[g], int(m.geom_type[g])
    t = mujoco.mjtGeom
    if kind == t.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2.0 * size)
    elif kind == t.mjGEOM_SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=float(size[0]))
    elif kind == t.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        mesh.apply_scale(size)
    elif kind == t.mjGEOM_CAPSULE:
        mesh = trimesh.creation.capsule(height=2.0 * float(size[1]), radius=float(size[0]), count=[24, 12])
    elif kind == t.mjGEOM_CYLINDER:
        mesh = trimesh.creation.cylinder(radius=float(size[0]), height=2.0 * float(size[1]), sections=32)
    elif kind == t.mjGEOM_MESH:
        k = int(m.geom_dataid[g])
        v0, nv = int(m.mesh_vertadr[k]), int(m.mesh_vertnum[k])
        f0, nf = int(m.mesh_faceadr[k]), int(m.mesh_facenum[k])
        mesh = trimesh.Trimesh(m.mesh_vert[v0:v0 + nv].copy(), m.mesh_face[f0:f0 + nf].copy(), process=False)
    else:
        return None
    T = np.eye(4)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, m.geom_quat[g])
    T[:3, :3], T[:3, 3] = rot.reshape(3, 3), m.geom_pos[g]
    mesh.apply_transform(T)
    return mesh


def scene_geometry(m: mujoco.MjModel, max_group: int = MAX_GROUP) -> tuple[list[BodyMesh], list[GroundPlane]]:
    """The drawn geoms of a MuJoCo model: meshes merged per body and colour, and the ground planes.

    Args:
        m: The model.
        max_group: Highest geom group drawn.
    """
    parts: dict[tuple[int, tuple[float, ...]], list[trimesh.Trimesh]] = {}
    planes: list[GroundPlane] = []
    for g in range(m.ngeom):
        rgba = geom_rgba(m, g)
        if int(m.geom_group[g]) > max_group or rgba[3] <= 0.0:
            continue
        if int(m.geom_type[g]) == mujoco.mjtGeom.mjGEOM_PLANE:
            planes.append(GroundPlane(float(m.geom_pos[g][2]), float(m.geom_size[g][0]), rgba))
            continue
        mesh = geom_mesh(m, g)
        if mesh is None:
            log.info("geom %d (%s) of type %s is not drawn", g, m.geom(g).name, mujoco.mjtGeom(m.geom_type[g]).name)
            continue
        parts.setdefault((int(m.geom_bodyid[g]), rgba), []).append(mesh)
    meshes = []
    for (body, rgba), group in parts.items():
        merged = trimesh.util.concatenate(group) if len(group) > 1 else group[0]
        meshes.append(BodyMesh(body, rgba, np.asarray(merged.vertices, dtype=np.float32),  # type: ignore[arg-type]
                               np.asarray(merged.faces, dtype=np.uint32)))
    return meshes, planes


def body_poses(m: mujoco.MjModel, frame_qpos: np.ndarray, frame_mocap: np.ndarray, bodies: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """Positions (F, B, 3) (m) and quaternions (w, x, y, z) (F, B, 4) of ``bodies`` (B,) at each recorded frame.

    Args:
        m: The model.
        frame_qpos: ``qpos`` per frame (F, nq).
        frame_mocap: Mocap bodies' position and quaternion per frame (F, nmocap, 7); (F, 0, 7) keeps the model's.
        bodies: Body ids.
    """
    d = mujoco.MjData(m)
    n = frame_qpos.shape[0]
    pos, quat = np.zeros((n, bodies.size, 3)), np.zeros((n, bodies.size, 4))
    for f in range(n):
        d.qpos[:] = frame_qpos[f]
        if frame_mocap.shape[1] == m.nmocap and m.nmocap:
            d.mocap_pos[:] = frame_mocap[f, :, :3]
            d.mocap_quat[:] = frame_mocap[f, :, 3:]
        mujoco.mj_kinematics(m, d)
        pos[f], quat[f] = d.xpos[bodies], d.xquat[bodies]
    return pos, quat


def gripper_glyph(width_m: float, depth_m: float = 0.045, stem_m: float = 0.035) -> np.ndarray:
    """Line segments (4, 2, 3) of a parallel-jaw gripper in its tcp frame (z: approach, y: closing axis): the two
    fingers from the pads (``width_m`` apart, m) back to the palm ``depth_m`` behind them, the palm, and the
    wrist's stem."""
    h = width_m / 2 + 0.004
    return np.array([
        [[0.0, h, 0.0], [0.0, h, -depth_m]],
        [[0.0, -h, 0.0], [0.0, -h, -depth_m]],
        [[0.0, -h, -depth_m], [0.0, h, -depth_m]],
        [[0.0, 0.0, -depth_m], [0.0, 0.0, -depth_m - stem_m]],
    ])


def _wxyz(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def _rgb(rgba: tuple[float, ...]) -> tuple[int, int, int]:
    return (round(255 * rgba[0]), round(255 * rgba[1]), round(255 * rgba[2]))


# --------------------------------------------------------------------------- #
# the viewer
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class _Window:
    """A grasp choice's glyphs are shown for ``start_s <= t < end_s``."""

    start_s: float
    end_s: float


class EpisodeViewer:
    """Serves a recorded episode in the browser (viser), with a timeline to scrub through it.

    Args:
        episode: The episode (``load_episode`` or an episode just run).
        host: The address to bind (``0.0.0.0``: every interface).
        port: The port (0: any free one); a busy port is replaced by the next free one.
        t_s: The time shown first (s).

    Attributes:
        layers: The scene node of each layer a checkbox toggles: ``robot``, ``objects``, ``scene``, ``paths``,
            ``grasps``, ``forces``.

    Raises:
        ConfigError: the port is not 0-65535.
        WebViewerUnavailable: viser is not installed.
        EpisodeFileError: the episode's frames do not fit the scene rebuilt from its config.
    """

    def __init__(self, episode: SavedEpisode, host: str = "127.0.0.1", port: int = 8080, t_s: float = 0.0) -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ConfigError("port", port, "must be an integer from 0 to 65535 (0: any free port)")
        viser = require_viser()
        server_log = logging.getLogger("websockets.server")
        if not any(isinstance(f, _ClosedBeforeRequest) for f in server_log.filters):
            server_log.addFilter(_ClosedBeforeRequest())
        self.episode = episode
        self.robot = episode.build_robot()
        tel = episode.telemetry
        self._lock = threading.RLock()
        self._playing = False
        self._t = -1.0
        self.host = host
        with _quiet():  # viser prints its address: the caller says where the viewer is
            self.server = viser.ViserServer(host=host, port=port, label="pickplace", verbose=False)
        try:
            self.server.scene.set_up_direction("+z")
            self._frame_t = np.asarray(tel.frame_t_s, dtype=float) if tel.frame_t_s.size else np.zeros(1)
            self._end_s = max(float(self._frame_t[-1]) if self._frame_t.size else 0.0, episode.duration_s)
            self.layers: dict[str, Any] = {}
            self._build_scene()
            self._build_gui()
            self.show(t_s)
        except BaseException:
            self.close()
            raise
        log.info("serving the %s at %s", episode.kind, self.url)

    # ----------------------------------------------------------------- scene

    def _build_scene(self) -> None:
        m, scene = self.robot.mj, self.server.scene
        tel = self.episode.telemetry
        meshes, planes = scene_geometry(m)
        robot_bodies = set(self.robot.handles.robot_bodies)
        world = self.robot.world_scene
        object_bodies = {m.body(object_body_name(world, o.name)).id for o in world.objects}
        for name in ("robot", "objects", "scene", "paths", "grasps", "forces"):
            self.layers[name] = scene.add_frame(f"/{name}", show_axes=False)
        for i, p in enumerate(planes):
            width = 2 * p.half_size_m if p.half_size_m > 0 else 4.0
            scene.add_grid(f"/scene/plane{i}", width=width, height=width, plane="xy", cell_size=0.1, section_size=0.5,
                           position=(0.0, 0.0, p.z_m), plane_color=_rgb(p.rgba), plane_opacity=0.35)
        drawn = sorted({mesh.body for mesh in meshes})
        self._bodies = np.array(drawn, dtype=int)
        self._body_nodes: list[Any] = []
        for b in drawn:
            layer = "robot" if b in robot_bodies else "objects" if b in object_bodies else "scene"
            self._body_nodes.append(scene.add_frame(f"/{layer}/{m.body(b).name or f'body{b}'}", show_axes=False))
        for k, mesh in enumerate(meshes):
            node = self._body_nodes[drawn.index(mesh.body)]
            opacity = mesh.rgba[3] if mesh.rgba[3] < 1.0 else None
            scene.add_mesh_simple(f"{node.name}/mesh{k}", mesh.vertices, mesh.faces, color=_rgb(mesh.rgba),
                                  opacity=opacity, flat_shading=False, side="double" if opacity else "front")
        if tel.frame_qpos.shape[0]:
            self._pos, self._quat = body_poses(m, tel.frame_qpos, tel.frame_mocap, self._bodies)
        else:  # nothing moved (it failed in IDLE): the scene as it started
            d = self.robot.make_data()
            self._pos, self._quat = body_poses(m, d.qpos[None], np.hstack([d.mocap_pos, d.mocap_quat])[None],
                                               self._bodies)
        self._shown_frame = -1

        self._paths: list[tuple[float, Any]] = []
        for i, plan in enumerate(tel.plans):
            pts = np.stack([plan.tcp_m[:-1], plan.tcp_m[1:]], axis=1)
            color = _PATH_COLORS.get(plan.name, _OTHER_PATH_COLOR)
            node = scene.add_line_segments(f"/paths/{i:02d}_{plan.name}", pts.astype(np.float32), color,
                                           thickness=0.004)
            self._paths.append((plan.t_s, node))

        self._grasps: list[tuple[_Window, Any]] = []
        for i, (choice, window) in enumerate(zip(tel.grasps, self._grasp_windows(), strict=True)):
            root = scene.add_frame(f"/grasps/{i:02d}", show_axes=False)
            for k in range(choice.T_world_tcp.shape[0]):
                if k == choice.chosen:
                    continue
                T = choice.T_world_tcp[k]
                scene.add_line_segments(f"{root.name}/candidate{k:02d}",
                                        gripper_glyph(float(choice.width_m[k])).astype(np.float32), _CANDIDATE_COLOR,
                                        thickness=0.0015, position=T[:3, 3], wxyz=_wxyz(T[:3, :3]))
            T = choice.T_world_chosen
            width = float(choice.width_m[choice.chosen]) if choice.chosen >= 0 else 0.04
            chosen = scene.add_frame(f"{root.name}/chosen", show_axes=True, axes_length=0.05, axes_radius=0.003,
                                     position=T[:3, 3], wxyz=_wxyz(T[:3, :3]))
            scene.add_line_segments(f"{chosen.name}/glyph", gripper_glyph(width).astype(np.float32), _CHOSEN_COLOR,
                                    thickness=0.004)
            self._grasps.append((window, root))

        empty = np.zeros((1, 2, 3), dtype=np.float32)
        self._force_nodes = [scene.add_arrows(f"/forces/{side}", empty, _FORCE_COLOR, shaft_radius=0.004,
                                              head_radius=0.009, head_length=0.018, visible=False)
                             for side in ("left_pad", "right_pad")]
        lo, hi = self._extent([k for k, b in enumerate(drawn) if b in robot_bodies or b in object_bodies])
        centre = (lo + hi) / 2
        view = np.array([1.0, -0.9, 0.6])
        self.server.initial_camera.look_at = tuple(centre)
        self.server.initial_camera.position = tuple(centre + CAMERA_DISTANCE * float(np.linalg.norm(hi - lo))
                                                    * view / np.linalg.norm(view))

    def _extent(self, bodies: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """The box around these drawn bodies' origins at the first frame, those parked away left out (m)."""
        pos = self._pos[0, bodies] if self._pos.shape[0] and bodies else np.zeros((1, 3))
        near = pos[np.linalg.norm(pos, axis=1) < PARKED_M]
        near = near if near.size else np.zeros((1, 3))
        return near.min(axis=0) - 0.1, near.max(axis=0) + 0.1

    def _grasp_windows(self) -> list[_Window]:
        """When each grasp choice is shown: from its approach's planning to the end of the next CLOSE, or to the
        next choice."""
        tel = self.episode.telemetry
        closes = [end for name, _, end in tel.phase_spans() if name == "CLOSE"]
        starts = [g.t_s for g in tel.grasps]
        out = []
        for i, t0 in enumerate(starts):
            nxt = starts[i + 1] if i + 1 < len(starts) else math.inf
            close = next((end for end in closes if end > t0), math.inf)
            out.append(_Window(t0, min(nxt, close, self._end_s + 1.0)))
        return out

    # ----------------------------------------------------------------- GUI

    def _build_gui(self) -> None:
        gui, ep, tel = self.server.gui, self.episode, self.episode.telemetry
        gui.add_markdown(_summary(ep))
        dt = float(np.median(np.diff(self._frame_t))) if self._frame_t.size > 1 else 0.01
        self.time_slider = gui.add_slider("time (s)", min=0.0, max=round(self._end_s, 3), step=round(dt, 4),
                                          initial_value=0.0)
        self.time_slider.on_update(lambda _: self._render(float(self.time_slider.value)))
        self.play_button = gui.add_button("Play")
        self.play_button.on_click(lambda _: self.toggle_play())
        self.speed = gui.add_dropdown("speed", ("0.1x", "0.25x", "0.5x", "1x", "2x"), initial_value="0.5x")
        self.now = gui.add_markdown("")
        phases = list(dict.fromkeys(name for name, _, _ in tel.phase_spans()))
        if phases:
            group = gui.add_button_group("jump to phase", phases)
            group.on_click(lambda event: self.jump_to_phase(str(event.target.value)))
        self._boxes: dict[str, Any] = {}
        with gui.add_folder("layers"):
            for name, label in (("robot", "robot"), ("objects", "objects"), ("scene", "table and scene"),
                                ("paths", "planned paths"), ("grasps", "grasp candidates"),
                                ("forces", "pad forces")):
                box = self._boxes[name] = gui.add_checkbox(label, True)
                box.on_update(lambda event, name=name: setattr(self.layers[name], "visible", bool(event.target.value)))
        gui.add_markdown(
            "planned tcp paths: <span style='color:#1f77b4'>approach</span>, "
            "<span style='color:#ff7f0e'>transport</span>, <span style='color:#6e6e6e'>return</span>; "
            "grasps: <span style='color:#1ebe3c'>chosen</span>, <span style='color:#eba528'>candidates</span>; "
            f"<span style='color:#dc1e1e'>pad forces</span> ({FORCE_SCALE_M_PER_N * 1e3:g} mm/N)")

    # ----------------------------------------------------------------- state

    @property
    def url(self) -> str:
        """The address to open in a browser (``127.0.0.1`` when bound to every interface)."""
        host = self.host if self.host not in ("", "0.0.0.0", "::") else "127.0.0.1"
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.server.get_port()}"

    @property
    def t_s(self) -> float:
        """The time shown (s)."""
        return self._t

    @property
    def end_s(self) -> float:
        """The last recorded time (s)."""
        return self._end_s

    def set_layer_visible(self, name: str, visible: bool) -> None:
        """Show or hide one of :attr:`layers` (as its checkbox does)."""
        self._boxes[name].value = visible

    def show(self, t_s: float) -> None:
        """Draw the episode at time ``t_s`` (s, clipped to the recording), and move the time slider there."""
        t = round(min(max(float(t_s), 0.0), self._end_s), 4)
        with self._lock:
            if float(self.time_slider.value) != t:
                self.time_slider.value = t  # its callback draws
            else:
                self._render(t)

    def _render(self, t: float) -> None:
        """Move every node to how it was at time ``t`` (s)."""
        t = min(max(t, 0.0), self._end_s)
        tel = self.episode.telemetry
        with self._lock, self.server.atomic():
            self._t = t
            t_look = t + ROUNDING_S  # the samples, frames, plans and windows of the time shown (rounded)
            f = max(0, int(np.searchsorted(self._frame_t, t_look, side="right")) - 1) if self._frame_t.size else -1
            if f >= 0 and f != self._shown_frame:
                for k, node in enumerate(self._body_nodes):
                    p = self._pos[f, k]
                    node.position, node.wxyz = p, self._quat[f, k]
                    _set_visible(node, bool(np.linalg.norm(p) <= PARKED_M))
                self._shown_frame = f
            for t_plan, node in self._paths:
                _set_visible(node, t_plan <= t_look)
            for window, node in self._grasps:
                _set_visible(node, window.start_s <= t_look < window.end_s)
            for pad, node in enumerate(self._force_nodes):
                force = tel.frame_pad_force_n[f, pad] if 0 <= f < tel.frame_pad_force_n.shape[0] else np.zeros(3)
                on = float(np.linalg.norm(force)) >= MIN_FORCE_N
                if on:
                    point = tel.frame_pad_point_m[f, pad]
                    node.points = np.array([[point - FORCE_SCALE_M_PER_N * force, point]], dtype=np.float32)
                _set_visible(node, on)
            self.now.content = _now(tel, t)

    def jump_to_phase(self, phase: str) -> None:
        """Show the next start of ``phase`` after the current time (the first one after the last)."""
        starts = [start for name, start, _ in self.episode.telemetry.phase_spans() if name == phase]
        if starts:
            later = [s for s in starts if s > self._t + 1e-6]
            self.show(later[0] if later else starts[0])

    def toggle_play(self) -> None:
        """Play from the current time (from the start at the end), or pause."""
        with self._lock:
            self._playing = not self._playing
            if self._playing and self._t >= self._end_s - 1e-6:
                self.show(0.0)
            self.play_button.label = "Pause" if self._playing else "Play"

    def tick(self, dt_s: float) -> None:
        """Advance a playing replay by ``dt_s`` of wall time (s) at the chosen speed; stop at the end."""
        with self._lock:
            if not self._playing:
                return
            speed = float(str(self.speed.value).rstrip("x"))
            t = self._t + dt_s * speed
            if t >= self._end_s:
                t = self._end_s
                self._playing = False
                self.play_button.label = "Play"
            self.show(t)

    def serve_forever(self, stop: threading.Event | None = None) -> None:
        """Serve and play until ``stop`` is set (or Ctrl-C, which propagates)."""
        stop = stop if stop is not None else threading.Event()
        period = 1.0 / PLAY_RATE_HZ
        while not stop.wait(period):
            self.tick(period)

    def close(self) -> None:
        """Stop the server (and its threads)."""
        with _quiet():
            self.server.stop()

    def __enter__(self) -> EpisodeViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _set_visible(node: Any, visible: bool) -> None:
    """Show or hide a scene node, sending nothing when it already is."""
    if node.visible != visible:
        node.visible = visible


def _summary(ep: SavedEpisode) -> str:
    """The GUI's header: what ran and how it ended."""
    r = ep.result
    what = f"{r.get('kind', '')} task" if ep.kind == "task" else "pick and place"
    if ep.success:
        status = "<span style='color:#1a8f2e'>**success**</span>"
    else:
        phase = r.get("failure_phase") or "?"
        status = f"<span style='color:#c0392b'>**failed in {phase}**</span>: {r.get('failure_reason') or ''}"
    lines = [f"**{what}**, seed {ep.seed}, {ep.config.profile.name} profile: {status}"]
    if ep.kind == "task":
        lines.append(f"{len(r.get('picks', []))} picks, {r.get('total_time_s', 0.0):.2f} s simulated")
    else:
        err = r.get("place_error_xy_m")
        lines.append(f"object `{ep.config.scene.object.name}`, cycle {r.get('cycle_time_s', 0.0):.2f} s"
                     + (f", place error {err * 1e3:.2f} mm" if isinstance(err, float) else ""))
    return "  \n".join(lines)


def _now(tel: Any, t: float) -> str:
    """The phase and the pad forces at time ``t`` (s)."""
    if tel.t_s.size == 0:
        return f"t = {t:.3f} s"
    i = min(max(0, int(np.searchsorted(tel.t_s, t + ROUNDING_S, side="right")) - 1), tel.t_s.size - 1)
    phase = tel.phase_names[int(tel.phase[i])]
    left, right = (float(v) for v in tel.pad_force_n[i])
    return f"t = {t:.3f} s · **{phase}** · pad forces {left:.1f} / {right:.1f} N"


__all__ = ["FORCE_SCALE_M_PER_N", "MAX_GROUP", "BodyMesh", "EpisodeViewer", "GroundPlane", "WebViewerUnavailable",
           "body_poses", "geom_mesh", "geom_rgba", "gripper_glyph", "require_viser", "scene_geometry"]
