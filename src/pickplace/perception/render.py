"""Offscreen rendering with MuJoCo on whatever OpenGL backend works here (EGL without a display).

MuJoCo's Python bindings choose their OpenGL backend once, when ``mujoco`` is imported, from ``MUJOCO_GL``
(``glfw`` when unset, which needs a display). Setting the variable after ``import mujoco`` has no effect.
pickplace imports mujoco early, so :func:`make_renderer` handles the common headless case itself: when the
bindings picked GLFW on Linux and there is no display (neither ``DISPLAY`` nor ``WAYLAND_DISPLAY``), it
creates the renderer on an EGL context (Mesa's libEGL renders on the CPU) and sets ``MUJOCO_GL=egl`` for
child processes. Any other failure to get a context raises :class:`RenderError` saying what to set. Setting
``MUJOCO_GL=egl`` before starting Python remains the most predictable choice.

Used by the depth camera (:mod:`pickplace.perception.camera`) and the environments' images
(:mod:`pickplace.envs.common`), each through an :class:`OffscreenScene` on the thread's shared context
(:func:`shared_gl_context`), and by the episode video (:mod:`pickplace.eval.report`, :func:`make_renderer`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import platform
import threading
from collections.abc import Iterator
from typing import Any

import mujoco
import numpy as np

from pickplace.errors import PickPlaceError

log = logging.getLogger(__name__)

#: What to do when no OpenGL context can be created.
GL_HINT = (
    "set MUJOCO_GL=egl before starting Python and install Mesa's libEGL (Debian/Ubuntu: apt-get install "
    "libegl1 libgl1; or MUJOCO_GL=osmesa with libosmesa6), or run with a display (MUJOCO_GL=glfw)"
)
# Serialises the short window in which the bindings' GLContext class is swapped for EGL (see _gl_backend).
_GL_SWAP_LOCK = threading.Lock()


class RenderError(PickPlaceError):
    """An image, a video or a plot could not be produced: no OpenGL context, a missing optional package, bad
    input.

    The message says what to do (the environment variable to set, or the package to install).
    """


def _has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@contextlib.contextmanager
def _gl_backend() -> Iterator[str]:
    """Make ``mujoco.Renderer`` create a context on a backend that works here; yields the backend's name.

    The bindings resolve ``mujoco.rendering.classic.gl_context.GLContext`` at ``import mujoco`` (from
    ``MUJOCO_GL``) and ``mujoco.Renderer.__init__`` instantiates that class. When it is GLFW on Linux and there
    is no display (``MUJOCO_GL`` unset at import), GLFW cannot make a context; the class is then replaced by
    ``mujoco.egl.GLContext`` for the duration of the block only, under a lock (the renderer keeps the context
    it created). There is no retry on EGL after GLFW *fails* with a display set: MuJoCo's context set-up is
    left half-initialised by that failure and a second attempt aborts the process (measured with
    ``DISPLAY=:99`` and no X server), so that case raises :class:`RenderError` instead.
    """
    try:
        from mujoco.rendering.classic import gl_context
    except ImportError as exc:  # pragma: no cover - depends on the mujoco build
        raise RenderError(f"this mujoco build has no OpenGL rendering module ({exc}); {GL_HINT}") from exc
    active = getattr(gl_context, "GLContext", None)
    if active is None:
        raise RenderError(f"MuJoCo's OpenGL rendering is disabled (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}); "
                          f"{GL_HINT}")
    name = getattr(active, "__module__", "unknown").rsplit(".", 1)[-1]
    if not (name == "glfw" and platform.system() == "Linux" and not _has_display()):
        yield name
        return
    try:
        from mujoco.egl import GLContext as EGLContext
    except (ImportError, OSError, AttributeError) as exc:
        raise RenderError(f"there is no display for GLFW and MuJoCo's EGL backend cannot be loaded ({exc}); "
                          f"{GL_HINT}") from exc
    os.environ.setdefault("MUJOCO_GL", "egl")
    log.info("no display and mujoco was imported with MUJOCO_GL unset (GLFW): rendering on EGL instead")
    with _GL_SWAP_LOCK:
        gl_context.GLContext = EGLContext
        try:
            yield "egl"
        finally:
            gl_context.GLContext = active


def check_size(m: mujoco.MjModel, width: int, height: int) -> None:
    """Raise :class:`RenderError` if ``width`` x ``height`` px exceeds the model's offscreen buffer."""
    if width > m.vis.global_.offwidth or height > m.vis.global_.offheight:
        raise RenderError(f"{width}x{height} px exceeds the model's offscreen buffer "
                          f"{m.vis.global_.offwidth}x{m.vis.global_.offheight} px (<visual><global offwidth "
                          f"offheight> in scene.xml); render smaller")


_THREAD = threading.local()
#: Size of the shared contexts' own framebuffer (px; a hidden window with GLFW, a buffer with OSMesa, none with EGL):
#: nothing is drawn into it, the cameras render into their MuJoCo render contexts' offscreen buffers.
_SHARED_SIZE_PX = 64


def shared_gl_context() -> tuple[Any, str]:
    """This thread's OpenGL context for offscreen rendering, made on the first call in the thread and kept for the
    thread's life, and its backend's name (a backend that works here, as for :func:`make_renderer`).

    A camera makes only its MuJoCo render context (``mujoco.MjrContext``) on it and renders into that context's
    offscreen buffer. A new OpenGL context is what made a renderer costly on a software OpenGL: a
    ``mujoco.Renderer`` took 140-280 ms to make, its render context 12 ms of that on a context already in use (Mesa
    llvmpipe), and an episode of the realistic profile made two. Contexts are per thread (an OpenGL context is
    current in one thread at a time) and per process (a child forked after the context was made makes its own).

    Raises:
        RenderError: no OpenGL context can be made.
    """
    made = getattr(_THREAD, "context", None)
    if made is None or _THREAD.pid != os.getpid():  # (a process forked from one that had made it: not usable here)
        from mujoco.rendering.classic import gl_context  # (_gl_backend checked that it imports)

        with _gl_backend() as backend:
            try:
                context = gl_context.GLContext(_SHARED_SIZE_PX, _SHARED_SIZE_PX)
                context.make_current()
            except Exception as exc:  # GLFW/EGL/OSMesa failures come as ImportError, FatalError, GLError, ...
                raise RenderError(f"cannot create an OpenGL context with the {backend} backend "
                                  f"({type(exc).__name__}: {exc}); {GL_HINT}") from exc
        made = _THREAD.context = (context, backend)
        _THREAD.pid = os.getpid()
    return made


#: Room in a scene beyond one entry per geom of the model, for what MuJoCo adds to it (frames, contacts, ...).
DECOR_GEOMS = 1000


class OffscreenScene:
    """What a ``mujoco.Renderer`` holds, a model's MuJoCo scene (``MjvScene``) and render context (``MjrContext``,
    with its offscreen buffer), on the thread's shared OpenGL context (:func:`shared_gl_context`) instead of one of
    its own: the same images, for a tenth of the cost to make on a software OpenGL. No text is drawn (the smallest
    font).

    Args:
        m: The model.
        width, height: The largest image it renders (px), within the model's offscreen buffer.
        decor_geoms: Room in the scene beyond one entry per geom of the model (see :data:`DECOR_GEOMS`).

    Raises:
        RenderError: no OpenGL context, or an image larger than the model's offscreen buffer.
    """

    def __init__(self, m: mujoco.MjModel, width: int, height: int, decor_geoms: int = DECOR_GEOMS) -> None:
        check_size(m, width, height)
        self.model, self.width, self.height = m, width, height
        self.gl, self.backend = shared_gl_context()
        self.scene = mujoco.MjvScene(m, maxgeom=m.ngeom + decor_geoms)
        self._default_option = mujoco.MjvOption()  # MuJoCo's visualisation defaults
        self.gl.make_current()
        try:
            self.context: mujoco.MjrContext | None = mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_50)
        except Exception as exc:  # an OpenGL error
            raise RenderError(f"cannot make MuJoCo's render context on the {self.backend} backend "
                              f"({type(exc).__name__}: {exc}); {GL_HINT}") from exc
        self.context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # (the mapping metric_depth undoes)

    def update(self, data: mujoco.MjData, camera: mujoco.MjvCamera | str,
               option: mujoco.MjvOption | None = None) -> mujoco.MjvScene:
        """Update the scene from ``data`` as seen by ``camera`` (a free camera, or a model camera's name), with the
        visualisation ``option`` (default: MuJoCo's); returns the scene."""
        if isinstance(camera, str):
            cam_id = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
            if cam_id < 0:
                raise RenderError(f"the model has no camera named {camera!r}")
            camera = mujoco.MjvCamera()
            camera.type, camera.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, cam_id
        mujoco.mjv_updateScene(self.model, data, option if option is not None else self._default_option, None,
                               camera, mujoco.mjtCatBit.mjCAT_ALL, self.scene)
        return self.scene

    def draw(self, width: int, height: int, segment: bool = False,
             rgb: np.ndarray | None = None, depth: np.ndarray | None = None) -> None:
        """Render the scene (as last updated) into the bottom-left ``width`` x ``height`` px of the offscreen
        buffer, with MuJoCo's segmentation colours if ``segment`` (which also gives the depth of its depth mode: no
        lighting, no transparency), and read its colours into ``rgb`` (height, width, 3) uint8 and its depth buffer
        into ``depth`` (height, width) float32, either or both, as OpenGL's rows come (bottom first)."""
        ctx = self.context
        if ctx is None:
            raise RuntimeError("render cannot be called after close")
        rect = mujoco.MjrRect(0, 0, width, height)
        self.gl.make_current()
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, ctx)  # (this context's, on the shared one)
        flags = self.scene.flags.copy()
        if segment:
            self.scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = True
            self.scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = True
        try:
            mujoco.mjr_render(rect, self.scene, ctx)
            mujoco.mjr_readPixels(rgb, depth, rect, ctx)
        finally:
            np.copyto(self.scene.flags, flags)

    def metric_depth(self, zbuf: np.ndarray) -> np.ndarray:
        """MuJoCo's (reversed-Z, perspective) depth buffer (H, W) as metric depth along the optical axis (m),
        float32, computed as ``mujoco.Renderer.render`` computes it."""
        m = self.model
        zfar = np.float32(m.vis.map.zfar * m.stat.extent)
        znear = np.float32(m.vis.map.znear * m.stat.extent)
        c_coef = -(zfar + znear) / (zfar - znear)
        d_coef = -(np.float32(2) * zfar * znear) / (zfar - znear)
        c_coef = np.float32(-0.5) * c_coef - np.float32(0.5)
        d_coef = np.float32(-0.5) * d_coef
        return (d_coef / (zbuf.astype(np.float64) + c_coef)).astype(np.float32)

    def rgb(self, data: mujoco.MjData, camera: mujoco.MjvCamera | str) -> np.ndarray:
        """The image (height, width, 3) uint8 of ``camera``, lit as the viewer lights it (``Renderer.render``)."""
        self.update(data, camera)
        out = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self.draw(self.width, self.height, rgb=out)
        return np.flipud(out).copy()

    def depth(self, data: mujoco.MjData, camera: mujoco.MjvCamera | str) -> np.ndarray:
        """The metric depth (height, width) float32 (m) of ``camera``'s pixels (``Renderer.render``'s depth mode)."""
        self.update(data, camera)
        zbuf = np.empty((self.height, self.width), dtype=np.float32)
        self.draw(self.width, self.height, segment=True, depth=zbuf)
        return np.flipud(self.metric_depth(zbuf)).copy()

    def close(self) -> None:
        """Release the render context (its buffers on the shared OpenGL context); idempotent."""
        if self.context is not None:
            self.gl.make_current()
            self.context.free()
            self.context = None


def make_renderer(m: mujoco.MjModel, width: int, height: int) -> tuple[mujoco.Renderer, str]:
    """A ``mujoco.Renderer`` of ``width`` x ``height`` px on a working OpenGL backend, and the backend's name.

    Raises:
        RenderError: the size exceeds the model's offscreen buffer, or no OpenGL context can be made.
    """
    check_size(m, width, height)
    with _gl_backend() as backend:
        try:
            return mujoco.Renderer(m, height=height, width=width), backend
        except Exception as exc:  # GLFW/EGL/OSMesa failures come as ImportError, FatalError, GLError, ...
            raise RenderError(f"cannot create an OpenGL context with the {backend} backend "
                              f"({type(exc).__name__}: {exc}); {GL_HINT}") from exc


__all__ = ["DECOR_GEOMS", "GL_HINT", "OffscreenScene", "RenderError", "check_size", "make_renderer",
           "shared_gl_context"]
