"""Test setup: offscreen rendering chosen before MuJoCo or dm_control are imported, and the test tiers.

Tiers (markers, declared in pyproject.toml): `slow` tests (seconds each: training, long
episodes, real-time runs) are left out of a plain `pytest` and run with `pytest -m slow`;
`hardware` marks the tests of the hardware path (every module `test_hardware_*.py` and
`test_baselines_hardware.py`), `render` the tests that draw frames (skipped without OSMesa).
`pytest -m "not hardware and not render"` runs the simulation alone.
"""

import ctypes.util
import os

import pytest

OFFSCREEN_GL = ctypes.util.find_library("OSMesa") is not None
if OFFSCREEN_GL:
    os.environ["MUJOCO_GL"] = "osmesa"
    os.environ["PYOPENGL_PLATFORM"] = "osmesa"

requires_offscreen_gl = pytest.mark.render
"""Mark of a test that renders frames: skipped where no offscreen OpenGL library is found."""

HARDWARE_MODULES = ("test_hardware_", "test_baselines_hardware")
JAX_MODULES = ("test_mjx",)
"""Modules that start JAX's thread pools: they run after every other test, so that no test that times
signals and samples by the wall clock shares its process with them."""


def pytest_collection_modifyitems(config, items):
    skip_render = pytest.mark.skip(reason="offscreen rendering needs OSMesa (apt-get install libosmesa6)")
    for item in items:
        if item.module.__name__.startswith(HARDWARE_MODULES):
            item.add_marker(pytest.mark.hardware)
        if item.get_closest_marker("render") is not None and not OFFSCREEN_GL:
            item.add_marker(skip_render)
    items.sort(key=lambda item: item.module.__name__.startswith(JAX_MODULES))  # stable: order kept otherwise


@pytest.fixture
def physics():
    """A nominal simulated Qube at 250 Hz."""
    from qube_suite.devices.qube import simulation as qube

    return qube.make_physics()


@pytest.fixture
def forget_new_tasks():
    """Tasks a test registers (and their Gymnasium ids) are forgotten when it ends, so that the
    tests after it see the suite's own tasks only."""
    import gymnasium

    from qube_suite.tasks import SUITE

    tasks, ids = set(SUITE), set(gymnasium.registry)
    yield
    for name in set(SUITE) - tasks:
        SUITE._tasks.pop(name)
        for tagged in SUITE._tags.values():
            tagged.pop(name, None)
    for env_id in set(gymnasium.registry) - ids:
        gymnasium.registry.pop(env_id)
