"""Fixtures for tests against the wall-clock double of `quanser.hardware` (tests/doubles).

`wall_clock_board`: a board process (`board_server.BoardServer`) and the double on
`sys.path` for this test only, so that `board="qube_servo2_usb"` / `"qube_servo3_usb"`
drives it through the real-board code path. `busy_core`: a process spinning on
the other core while the test runs.

The board process runs with real-time scheduling where allowed (a real board's
clock does not wait for the host's scheduler); the test process, the control loop
under test, runs at normal priority and bears every delay of the host. (Raising
it to real-time scheduling is not safe here: a real-time thread that spins while
waiting for a normal-priority worker, as OpenBLAS does, starves that worker.) On a
host loaded far beyond its cores, the loop can miss samples for reasons outside
the package, and these tests can then fail with `MissedSamplesError` or
`WatchdogExpiredError`: the safety stops doing their job.
"""

from __future__ import annotations

import gc
import os
import subprocess
import sys
from pathlib import Path

import pytest

DOUBLES = str(Path(__file__).parent / "doubles")


@pytest.fixture(name="wall_clock_board")
def wall_clock_board_fixture(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(DOUBLES)
    for name in [n for n in sys.modules if n == "quanser" or n.startswith("quanser.")]:
        monkeypatch.delitem(sys.modules, name)
    from board_server import BoardServer

    server = BoardServer(str(tmp_path))
    for key, value in server.environment().items():
        monkeypatch.setenv(key, value)
    gc.collect()  # from a collected heap, as a paced board's episode starts: earlier tests' garbage would
    yield server  # make a full collection (0.1 s) due during a test that calls the board directly
    server.stop()
    for name in [n for n in sys.modules if n == "quanser" or n.startswith("quanser.")]:
        del sys.modules[name]



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
