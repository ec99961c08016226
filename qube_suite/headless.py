"""Choose an offscreen OpenGL backend for MuJoCo when there is no display.

MuJoCo and dm_control read `MUJOCO_GL` when they are first imported. Without a
display the default (GLFW) cannot render and warns at every import, so when the
variable is unset on a Linux machine without a display we pick OSMesa (software,
works everywhere it is installed: `apt-get install libosmesa6`) or else EGL.
An explicit `MUJOCO_GL` is always respected.

If MuJoCo or dm_control was imported before qube_suite (by shimmy, say) with the
variable unset, it has already settled on GLFW; `choose_backend` then points the
backend each of them renders with (MuJoCo's `GLContext`, dm_control's `Renderer`)
at the offscreen one, so rendering works whatever was imported first.
"""

from __future__ import annotations

import ctypes.util
import importlib
import os
import sys

_BACKENDS = (("osmesa", "OSMesa"), ("egl", "EGL"))


def choose_backend() -> str | None:
    """Set `MUJOCO_GL` (and `PYOPENGL_PLATFORM`) if unset and headless; return the backend in use."""
    if os.environ.get("MUJOCO_GL") or sys.platform != "linux":
        return os.environ.get("MUJOCO_GL")
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return None
    for backend, library in _BACKENDS:
        if ctypes.util.find_library(library):
            os.environ["MUJOCO_GL"] = backend
            os.environ.setdefault("PYOPENGL_PLATFORM", backend)
            _switch_imported_renderers(backend)
            return backend
    return None


def _switch_imported_renderers(backend: str) -> None:
    """Make MuJoCo and dm_control, if already imported (having read no `MUJOCO_GL`), render with
    `backend` ("osmesa" or "egl") instead of the GLFW they fell back to."""
    gl_context = sys.modules.get("mujoco.rendering.classic.gl_context")
    if gl_context is not None:
        context = importlib.import_module(f"mujoco.{backend}").GLContext
        gl_context.GLContext = context
        legacy = sys.modules.get("mujoco.gl_context")  # the older import path re-exports it
        if legacy is not None:
            legacy.GLContext = context
    render = sys.modules.get("dm_control._render")
    if render is not None and backend != render.BACKEND:
        render.Renderer = {"osmesa": render._import_osmesa, "egl": render._import_egl}[backend]()
        render.BACKEND = backend
        render.USING_GPU = backend == "egl"
