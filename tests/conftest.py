"""Test setup: offscreen rendering chosen before MuJoCo or dm_control are imported."""

import ctypes.util
import os

import pytest

OFFSCREEN_GL = ctypes.util.find_library("OSMesa") is not None
if OFFSCREEN_GL:
    os.environ["MUJOCO_GL"] = "osmesa"
    os.environ["PYOPENGL_PLATFORM"] = "osmesa"

requires_offscreen_gl = pytest.mark.skipif(
    not OFFSCREEN_GL, reason="offscreen rendering needs OSMesa (apt-get install libosmesa6)")


@pytest.fixture
def physics():
    """A nominal simulated Qube at 250 Hz."""
    from qube_suite.domains import qube

    return qube.make_physics()
