"""Rendering without a display works whatever was imported before qube_suite, with MUJOCO_GL unset."""

import ctypes.util
import os
import subprocess
import sys

import pytest

pytestmark = [pytest.mark.render, pytest.mark.skipif(
    sys.platform != "linux" or not (ctypes.util.find_library("OSMesa") or ctypes.util.find_library("EGL")),
    reason="needs an offscreen OpenGL library (libosmesa6 or EGL) on Linux")]

RENDER_BOTH_WAYS = """
import gymnasium, qube_suite
from qube_suite import suite
env = gymnasium.make("QubeSuite/Balance-v0", render_mode="rgb_array", width=64, height=48)
env.reset(seed=0)
assert env.render().std() > 10                                     # MuJoCo's renderer
assert suite.load("qube", "balance").physics.render(48, 64).std() > 10   # dm_control's
print("rendered")
"""


@pytest.mark.parametrize("first", ["import shimmy", "from dm_control import suite", "import mujoco"])
def test_rendering_works_whatever_was_imported_first(first):
    environment = {key: value for key, value in os.environ.items()
                   if key not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run([sys.executable, "-c", f"{first}\n{RENDER_BOTH_WAYS}"], env=environment,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0 and "rendered" in result.stdout, result.stderr[-2000:]
