"""The episode file (``pickplace run --save``) and the web viewer (``pickplace replay EP --web``).

The viewer's test opens the page in a real headless Chromium (Debian's ``chromium``, which ``.ci/run`` installs;
without it the test is skipped and says why), driven over the DevTools protocol: it waits until the scene is
drawn, takes screenshots and checks the pixels. The robot is drawn (its blue joint covers appear, and vanish with
the robot's layer), the object is drawn (hiding its layer changes a small, compact patch of light grey pixels),
and the canvas is not blank. ``PICKPLACE_WEB_SCREENSHOT=PATH`` keeps the first screenshot (the README's).
"""

from __future__ import annotations

import base64
import io
import json
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import mujoco
import numpy as np
import pytest

from pickplace.cli import main
from pickplace.task.episode import EpisodeResult, run_episode
from pickplace.task.episode_file import (
    EPISODE_VERSION,
    EpisodeFileError,
    load_episode,
    save_episode,
)

CHROMIUM = "/usr/bin/chromium"
#: The browser's viewport (px); the GUI panel takes the right-hand ``GUI_WIDTH`` px of it.
WIDTH, HEIGHT, GUI_WIDTH = 1200, 800, 360


@pytest.fixture(scope="module")
def recorded() -> EpisodeResult:
    """The default episode, recorded."""
    result = run_episode(record=True)
    assert result.success
    return result


@pytest.fixture(scope="module")
def episode_path(recorded: EpisodeResult, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return save_episode(tmp_path_factory.mktemp("episode") / "default.npz", recorded)


# --------------------------------------------------------------------------- #
# the episode file
# --------------------------------------------------------------------------- #


def test_recording_records_paths_grasps_and_forces(recorded: EpisodeResult) -> None:
    """What the viewer draws besides the bodies: each planned segment's tcp path (from the tcp where it was
    planned to where it ends), the chosen grasp among its candidates, and the pads' forces while gripping."""
    tel = recorded.telemetry
    assert tel is not None
    assert [p.name for p in tel.plans] == ["approach", "transport", "return"]
    for plan in tel.plans:
        k = int(np.searchsorted(tel.t_s, plan.t_s))
        assert np.linalg.norm(plan.tcp_m[0] - tel.tcp_pos_m[k]) < 2e-3, plan.name  # starts where the tcp is
    home = tel.tcp_pos_m[0]
    assert np.linalg.norm(tel.plans[-1].tcp_m[-1] - home) < 2e-3  # the return ends at home
    (choice,) = tel.grasps
    assert choice.object_name == "cube" and choice.chosen == 0  # the best ranked grasp works here
    assert len(choice.approach) == choice.T_world_tcp.shape[0] > 1
    assert np.allclose(choice.T_world_tcp[0], choice.T_world_chosen, atol=1e-4)
    # the tcp when the grip has closed is at the chosen grasp (within the pads' push, a few mm)
    close_end = next(end for name, _, end in tel.phase_spans() if name == "CLOSE")
    k = int(np.searchsorted(tel.t_s, close_end)) - 1
    assert np.linalg.norm(tel.tcp_pos_m[k] - choice.T_world_chosen[:3, 3]) < 5e-3
    # while lifting, the pads squeeze the object from both sides and carry its weight and its vertical inertia (the
    # lift runs on into the transport: it accelerates the object up all the way), m (g + a_z), a_z from the object's
    # recorded height (central differences over 10 ms)
    start, end = next((s, e) for name, s, e in tel.phase_spans() if name == "LIFT")
    f = (tel.frame_t_s > start + 0.1) & (tel.frame_t_s < end - 0.1)
    force, point = tel.frame_pad_force_n[f], tel.frame_pad_point_m[f]
    assert force.shape[0] > 3
    assert np.all(np.einsum("ij,ij->i", force[:, 0], force[:, 1]) < 0)  # opposite squeezes
    tf, z, h = tel.frame_t_s[f], tel.object_pos_m[:, 2], 0.01
    a_z = (np.interp(tf + h, tel.t_s, z) - 2 * np.interp(tf, tel.t_s, z) + np.interp(tf - h, tel.t_s, z)) / h**2
    carried = recorded.config.scene.object.mass_kg * (9.81 + a_z)
    assert np.median(force[:, :, 2].sum(axis=1) / carried) == pytest.approx(1.0, rel=0.15)
    centre = tel.object_pos_m[np.searchsorted(tel.t_s, tel.frame_t_s[f])]
    assert np.all(np.linalg.norm(point - centre[:, None], axis=2) < 0.03)  # on the 40 mm cube's faces


def test_recording_does_not_change_the_episode(recorded: EpisodeResult) -> None:
    """The same episode without recording gives the same figures (wall-clock times aside)."""
    plain = run_episode(record=False)
    wall = {"wall_time_s", "real_time_factor", "plan_time_s", "retime_time_s"}
    a = {k: v for k, v in recorded.to_dict().items() if k not in wall}
    b = {k: v for k, v in plain.to_dict().items() if k not in wall}
    assert a == b


def test_episode_file_round_trip(recorded: EpisodeResult, episode_path: Path) -> None:
    saved = load_episode(episode_path)
    tel, back = recorded.telemetry, saved.telemetry
    assert tel is not None
    assert (saved.kind, saved.seed, saved.success) == ("episode", 0, True)
    assert saved.config == recorded.config
    assert saved.result["cycle_time_s"] == recorded.cycle_time_s
    assert back.phase_names == tel.phase_names
    for name in ("t_s", "phase", "q", "frame_qpos", "frame_mocap", "frame_pad_force_n", "frame_pad_point_m"):
        assert np.array_equal(getattr(back, name), getattr(tel, name)), name
    assert [(p.name, p.t_s) for p in back.plans] == [(p.name, p.t_s) for p in tel.plans]
    assert all(np.array_equal(a.tcp_m, b.tcp_m) for a, b in zip(back.plans, tel.plans, strict=True))
    assert back.grasps[0].approach == tel.grasps[0].approach
    assert np.array_equal(back.grasps[0].T_world_tcp, tel.grasps[0].T_world_tcp)
    assert [s.phase for s in back.joint_segments] == [s.phase for s in tel.joint_segments]
    assert back.phase_spans() == tel.phase_spans()
    assert saved.build_robot().mj.nq == back.frame_qpos.shape[1]


def test_episode_file_errors(episode_path: Path, tmp_path: Path) -> None:
    """A wrong or old file is refused with one clear line naming the file and what it is."""
    json_file = tmp_path / "result.json"
    json_file.write_text(json.dumps({"success": True}))
    other = tmp_path / "other.npz"
    np.savez(other, a=np.zeros(3))
    with np.load(episode_path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["meta"][()]))
    old, newer = tmp_path / "old.npz", tmp_path / "newer.npz"
    np.savez(old, **{**arrays, "meta": np.array(json.dumps({**meta, "version": 0}))})
    np.savez(newer, **{**arrays, "meta": np.array(json.dumps({**meta, "version": EPISODE_VERSION + 1}))})
    cases = {tmp_path / "missing.npz": "no such file", json_file: "not an .npz file",
             other: "an .npz of something else", old: "an older episode format (version 0",
             newer: "written by a newer pickplace"}
    for path, says in cases.items():
        with pytest.raises(EpisodeFileError, match="episode file") as err:
            load_episode(path)
        assert says in str(err.value) and str(path) in str(err.value)
        assert "pickplace run --save" in str(err.value)
    assert main(["replay", str(json_file)]) == 1


def test_cli_run_save_and_replay(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "ep.npz"
    assert main(["run", "--save", str(path)]) == 0
    assert f"wrote {path}" in capsys.readouterr().out
    assert main(["replay", str(path)]) == 0
    out = capsys.readouterr().out
    assert "pick and place" in out and "success" in out and "--web" in out


# --------------------------------------------------------------------------- #
# the scene's geometry
# --------------------------------------------------------------------------- #


def test_scene_geometry_comes_from_the_model(recorded: EpisodeResult) -> None:
    """Every geom the MuJoCo viewer shows by default becomes a mesh of its body, at its place and size: the
    meshes' bounds match MuJoCo's own axis-aligned boxes of the geoms in the home pose."""
    web = pytest.importorskip("pickplace.eval.web")
    from pickplace.robot.model import build

    robot = build(recorded.config.scene)
    m = robot.mj
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    meshes, planes = web.scene_geometry(m)
    assert len(planes) == 1 and planes[0].z_m == 0.0  # the floor
    drawn = [g for g in range(m.ngeom) if m.geom_group[g] <= web.MAX_GROUP and web.geom_rgba(m, g)[3] > 0
             and m.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE]
    assert all(len(mesh.faces) > 0 for mesh in meshes)
    bodies = {mesh.body for mesh in meshes}
    assert bodies == {int(m.geom_bodyid[g]) for g in drawn}
    assert robot.handles.object_body in bodies
    assert len(bodies & set(robot.handles.robot_bodies)) == 10  # base to wrist 3, the gripper and its fingers
    for body in bodies:  # the merged meshes of a body span what its drawn geoms span
        R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
        verts = np.vstack([mesh.vertices @ R.T + p for mesh in meshes if mesh.body == body])
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for g in drawn:
            if m.geom_bodyid[g] == body:
                mesh = web.geom_mesh(m, g)
                v = np.asarray(mesh.vertices) @ R.T + p
                lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
                # MuJoCo's own bounding box of the geom (aabb: centre and half sizes in the geom frame)
                c, half = m.geom_aabb[g][:3], m.geom_aabb[g][3:]
                Rg, pg = d.geom_xmat[g].reshape(3, 3), d.geom_xpos[g]
                corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half + c
                world = corners @ Rg.T + pg
                assert np.all(v.min(axis=0) >= world.min(axis=0) - 1e-4) and np.all(
                    v.max(axis=0) <= world.max(axis=0) + 1e-4), m.geom(g).name
                if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:  # a box's corners are its vertices
                    assert np.allclose(np.sort(v, axis=0), np.sort(world, axis=0), atol=1e-6), m.geom(g).name
        assert np.allclose(verts.min(axis=0), lo, atol=1e-6) and np.allclose(verts.max(axis=0), hi, atol=1e-6)
    colours = {m.body(mesh.body).name: mesh.rgba for mesh in meshes}
    assert colours["object"] == pytest.approx(tuple(m.mat_rgba[m.material("object").id]))


def test_viewer_timeline(episode_path: Path) -> None:
    """The timeline in-process (no browser): scrubbing moves the bodies to the recorded frame, a phase button jumps
    to the phase's next start, play advances at the chosen speed and stops at the end; paths and grasps appear when
    they were planned, the force arrows while the pads grip."""
    pytest.importorskip("viser", reason="the web viewer needs the web extra (viser)")
    from pickplace.eval.web import EpisodeViewer

    saved = load_episode(episode_path)
    tel = saved.telemetry
    with EpisodeViewer(saved, port=0) as viewer:
        spans = tel.phase_spans()
        lift = next(start for name, start, _ in spans if name == "LIFT")
        viewer.jump_to_phase("LIFT")
        assert viewer.t_s == pytest.approx(lift, abs=1e-4)
        assert float(viewer.time_slider.value) == pytest.approx(lift, abs=1e-4)
        assert "LIFT" in viewer.now.content
        k = list(viewer._bodies).index(viewer.robot.handles.object_body)
        f = int(np.searchsorted(tel.frame_t_s, lift, side="right")) - 1
        assert np.allclose(viewer._body_nodes[k].position, viewer._pos[f, k])
        step = np.searchsorted(tel.t_s, tel.frame_t_s[f])  # its xpos is from before the step's integration
        assert np.linalg.norm(viewer._pos[f, k] - tel.object_pos_m[step]) < 1e-4
        assert all(node.visible for node in viewer._force_nodes)  # gripping
        # the lift, the transport and the set-down are planned as one motion as LIFT starts; the return is not yet
        assert [node.visible for _, node in viewer._paths] == [True, True, False]
        assert not viewer._grasps[0][1].visible  # the grip has closed
        viewer.show(0.2)
        assert viewer._grasps[0][1].visible and not any(node.visible for node in viewer._force_nodes)
        viewer.speed.value = "1x"
        viewer.toggle_play()
        viewer.tick(0.5)
        assert viewer.t_s == pytest.approx(0.7, abs=1e-3)
        viewer.tick(100.0)
        assert viewer.t_s == pytest.approx(viewer.end_s) and viewer.play_button.label == "Play"
        assert all(node.visible for _, node in viewer._paths)
        viewer.set_layer_visible("robot", False)
        assert not viewer.layers["robot"].visible


# --------------------------------------------------------------------------- #
# the viewer in a real browser
# --------------------------------------------------------------------------- #


class _Chromium:
    """Headless Chromium with software WebGL showing ``url``, driven over the DevTools protocol (websockets)."""

    def __init__(self, profile: Path, url: str) -> None:
        from websockets.sync.client import connect

        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--enable-unsafe-swiftshader", "--use-angle=swiftshader", f"--user-data-dir={profile}",
             f"--window-size={WIDTH},{HEIGHT}", "--remote-debugging-port=0", url],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            port_file = profile / "DevToolsActivePort"
            deadline = time.monotonic() + 30
            while not (port_file.exists() and port_file.read_text().strip()):
                if time.monotonic() > deadline or self.proc.poll() is not None:
                    raise RuntimeError(f"chromium did not start (exit code {self.proc.poll()})")
                time.sleep(0.1)
            port = int(port_file.read_text().split()[0])
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
                page = next(t for t in json.load(r) if t["type"] == "page")
            self.ws = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=10)
            self._id = 0
            self.call("Emulation.setDeviceMetricsOverride", width=WIDTH, height=HEIGHT, deviceScaleFactor=1,
                      mobile=False)
        except BaseException:
            self.close()
            raise

    def call(self, method: str, **params: object) -> dict:
        self._id += 1
        self.ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=60))
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def screenshot(self) -> np.ndarray:
        """The page as RGB pixels (HEIGHT, WIDTH, 3)."""
        from PIL import Image

        png = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))

    def close(self) -> None:
        ws = getattr(self, "ws", None)
        if ws is not None:
            ws.close()
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)


def _scene(img: np.ndarray) -> np.ndarray:
    """The 3D canvas's pixels left of the GUI panel, below the corner where a notification may sit."""
    out = img[:, : WIDTH - GUI_WIDTH].astype(float) / 255.0
    out[:170, :330] = np.nan
    return out


def _hsv(img: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    v = np.max(img, axis=-1)
    c = v - np.min(img, axis=-1)
    s = np.where(v > 0, c / np.where(v > 0, v, 1), 0.0)
    safe = np.where(c > 0, c, 1)
    h = np.where(v == r, ((g - b) / safe) % 6, np.where(v == g, (b - r) / safe + 2, (r - g) / safe + 4)) * 60
    return np.where(c > 0, h, 0.0), s, v


def _ur_blue(img: np.ndarray) -> np.ndarray:
    """Pixels of the UR5e's blue joint covers (material ``ur_blue``, RGB 0.22 0.47 0.72: hue 210°), lit."""
    h, s, v = _hsv(np.nan_to_num(img))
    return (h > 195) & (h < 225) & (s > 0.4) & (v > 0.25)


def _changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pixels that differ between two renders of the canvas, in patches: a pixel counts only if its 3 x 3
    neighbourhood changed too (software rendering redraws the edges of lines and silhouettes a little differently
    from one frame to the next)."""
    diff = np.any(np.abs(np.nan_to_num(a) - np.nan_to_num(b)) > 0.1, axis=-1)
    out = diff.copy()
    h, w = diff.shape
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = np.zeros_like(diff)
            shifted[max(0, dy):h + min(0, dy), max(0, dx):w + min(0, dx)] = \
                diff[max(0, -dy):h - max(0, dy), max(0, -dx):w - max(0, dx)]
            out &= shifted
    return out


def _wait_for(browser: _Chromium, done, what: str, timeout_s: float = 60.0) -> np.ndarray:
    """Screenshots until ``done(img)``, then one more that must agree (the scene has settled)."""
    deadline = time.monotonic() + timeout_s
    img = browser.screenshot()
    while not done(img):
        if time.monotonic() > deadline:
            pytest.fail(f"the browser did not show {what} within {timeout_s:.0f} s")
        time.sleep(0.5)
        img = browser.screenshot()
    time.sleep(0.5)
    again = browser.screenshot()
    return again if done(again) else img


def test_viewer_draws_the_robot_and_the_object(episode_path: Path, tmp_path: Path) -> None:
    pytest.importorskip("viser", reason="the web viewer needs the web extra (viser)")
    pytest.importorskip("PIL", reason="reading screenshots needs pillow")
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no browser: {CHROMIUM} is missing (apt-get install chromium; .ci/run installs it)")
    from pickplace.eval.web import EpisodeViewer

    saved = load_episode(episode_path)
    close_end = next(end for name, _, end in saved.telemetry.phase_spans() if name == "CLOSE")
    t0 = time.monotonic()
    viewer = EpisodeViewer(saved, port=0, t_s=close_end - 0.01)  # gripping: forces, the grasps, the approach
    browser = None
    try:
        assert viewer.url.startswith("http://127.0.0.1:")
        browser = _Chromium(tmp_path / "profile", viewer.url)
        _wait_for(browser, lambda img: _ur_blue(_scene(img)).sum() > 800, "the robot")
        close_notices = "document.querySelectorAll('.mantine-Notification-closeButton').forEach(b => b.click())"
        browser.call("Runtime.evaluate", expression=close_notices)  # the notice that WebGL runs in software
        time.sleep(1.0)
        full = _wait_for(browser, lambda img: _ur_blue(_scene(img)).sum() > 800, "the robot")
        if os.environ.get("PICKPLACE_WEB_SCREENSHOT"):
            from PIL import Image

            Image.fromarray(full).save(os.environ["PICKPLACE_WEB_SCREENSHOT"])
        scene = _scene(full)
        assert np.nanstd(scene) > 0.05, "a uniform canvas"
        quantized = np.unique((np.nan_to_num(scene) * 15).astype(int).reshape(-1, 3), axis=0)
        assert len(quantized) > 50, f"only {len(quantized)} colours on the canvas"
        blue = _ur_blue(scene)

        viewer.set_layer_visible("robot", False)
        no_robot = _scene(_wait_for(browser, lambda img: _ur_blue(_scene(img)).sum() < 0.2 * blue.sum(),
                                    "the scene without the robot"))
        changed = _changed(no_robot, scene)
        assert changed.sum() > 3000, f"hiding the robot changed only {changed.sum()} pixels"
        assert blue[changed].mean() > 0.1  # much of what vanished was the robot's blue

        viewer.set_layer_visible("robot", True)
        _wait_for(browser, lambda img: _ur_blue(_scene(img)).sum() > 0.8 * blue.sum(), "the robot again")
        viewer.set_layer_visible("objects", False)

        no_object = _scene(_wait_for(browser, lambda img: _changed(_scene(img), scene).sum() > 30,
                                     "the scene without the object"))
        changed = _changed(no_object, scene)
        if os.environ.get("PICKPLACE_WEB_DEBUG"):
            from PIL import Image

            Image.fromarray((changed * 255).astype(np.uint8)).save(os.environ["PICKPLACE_WEB_DEBUG"])
        rows, cols = np.nonzero(changed)
        height, width = rows.max() - rows.min() + 1, cols.max() - cols.min() + 1
        print(f"\nweb viewer: {blue.sum()} robot-blue pixels, the object {changed.sum()} pixels in a {width} x "
              f"{height} px box, {time.monotonic() - t0:.1f} s")
        assert 30 < changed.sum() < 20000
        assert width < 150 and height < 150, "the object's pixels are not one compact patch"
        _, s, v = _hsv(scene[changed])
        assert np.median(s) < 0.3 and np.median(v) > 0.35, "the object is not its light grey"
    finally:
        if browser is not None:
            browser.close()
        viewer.close()


def test_cli_replay_web_serves_until_interrupted(episode_path: Path) -> None:
    """``pickplace replay EP --web --port 0`` prints its URL, serves the page, and stops cleanly on Ctrl-C."""
    pytest.importorskip("viser", reason="the web viewer needs the web extra (viser)")
    proc = subprocess.Popen([sys.executable, "-m", "pickplace", "replay", str(episode_path), "--web", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "COLUMNS": "200"})
    try:
        assert proc.stdout is not None
        line = ""
        deadline = time.monotonic() + 60
        while "http://" not in line and time.monotonic() < deadline and proc.poll() is None:
            line = proc.stdout.readline()
        url = line[line.index("http://"):].split()[0]
        with urllib.request.urlopen(url, timeout=10) as r:
            assert r.status == 200 and b"<title>Viser</title>" in r.read()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
