"""Choose an offscreen OpenGL backend for MuJoCo when there is no display.

MuJoCo and dm_control read `MUJOCO_GL` when they are first imported. Without a
display the default (GLFW) cannot render and warns at every import, so when the
variable is unset on a Linux machine without a display we pick OSMesa (software,
works everywhere it is installed: `apt-get install libosmesa6`) or else EGL.
An explicit `MUJOCO_GL` is always respected.
"""

from __future__ import annotations

import ctypes.util
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
            return backend
    return None
