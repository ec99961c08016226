"""Fixtures for tests against the wall-clock double of `quanser.hardware` (tests/doubles).

`wall_clock_board`: a board process (`board_server.BoardServer`) and the double on
`sys.path` for this test only, so that `board="qube_servo2_usb"` / `"qube_servo3_usb"`
drives it through the real-board code path. `busy_core`: a process spinning on
the other core while the test runs.

The test process (the control loop under test, and the children it starts) runs
with real-time scheduling where the system allows it, below the board's, as a lab
runs a control loop (`chrt -f 10 qube-suite run ...`): the tests then measure what
the package's own code does within a sample, not how busy the rest of the machine
is (this machine is shared). Work inside the loop that takes longer than a sample
still misses samples at any priority.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

DOUBLES = str(Path(__file__).parent / "doubles")


LOOP_PRIORITY = 10
"""SCHED_FIFO priority of the control loop under test (the board process runs at 20)."""


@pytest.fixture(name="wall_clock_board")
def wall_clock_board_fixture(tmp_path, monkeypatch):
    previous = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(LOOP_PRIORITY))
    except (AttributeError, PermissionError, OSError):
        previous = None
    monkeypatch.syspath_prepend(DOUBLES)
    for name in [n for n in sys.modules if n == "quanser" or n.startswith("quanser.")]:
        monkeypatch.delitem(sys.modules, name)
    from board_server import BoardServer

    server = BoardServer(str(tmp_path))
    for key, value in server.environment().items():
        monkeypatch.setenv(key, value)
    yield server
    server.stop()
    for name in [n for n in sys.modules if n == "quanser" or n.startswith("quanser.")]:
        del sys.modules[name]
    if previous is not None:
        os.sched_setscheduler(0, *previous)


@pytest.fixture(name="busy_core")
def busy_core_fixture():
    """Keep another core busy (a process spinning on the last core) for the duration of the test."""
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    cores = sorted(os.sched_getaffinity(0))
    if len(cores) > 1:
        os.sched_setaffinity(spinner.pid, {cores[-1]})
    yield spinner
    spinner.kill()
    spinner.wait()


def child_environment(server) -> dict[str, str]:
    """Environment for a child process that drives the double's board."""
    path = os.pathsep.join([DOUBLES, os.environ.get("PYTHONPATH", "")])
    return {**os.environ, **server.environment(), "PYTHONPATH": path}
