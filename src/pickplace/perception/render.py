"""Offscreen rendering with MuJoCo on whatever OpenGL backend works here (EGL without a display).

MuJoCo's Python bindings choose their OpenGL backend once, when ``mujoco`` is imported, from ``MUJOCO_GL``
(``glfw`` when unset, which needs a display). Setting the variable after ``import mujoco`` has no effect.
pickplace imports mujoco early, so :func:`make_renderer` handles the common headless case itself: when the
bindings picked GLFW on Linux and there is no display (neither ``DISPLAY`` nor ``WAYLAND_DISPLAY``), it
creates the renderer on an EGL context (Mesa's libEGL renders on the CPU) and sets ``MUJOCO_GL=egl`` for
child processes. Any other failure to get a context raises :class:`RenderError` saying what to set. Setting
``MUJOCO_GL=egl`` before starting Python remains the most predictable choice.

Used by the depth camera (:mod:`pickplace.perception.camera`, on the thread's shared context:
:func:`shared_gl_context`) and the episode video (:mod:`pickplace.eval.report`, :func:`make_renderer`).
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


__all__ = ["GL_HINT", "RenderError", "check_size", "make_renderer", "shared_gl_context"]
