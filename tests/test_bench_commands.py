"""benchmarks/bench_commands.py leaves nothing running when it is stopped."""

from __future__ import annotations

import pathlib
import signal
import subprocess
import sys
import time

import pytest

BENCH = pathlib.Path(__file__).resolve().parent.parent / "benchmarks" / "bench_commands.py"


def children(pid: int) -> set[int]:
    """The process ids of `pid`'s children (Linux /proc)."""
    found = set()
    for tasks in pathlib.Path(f"/proc/{pid}/task").glob("*/children"):
        found.update(int(child) for child in tasks.read_text().split())
    return found


def alive(pid: int) -> bool:
    """True if `pid` runs (exists and is not a zombie)."""
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.mark.slow
@pytest.mark.skipif(not pathlib.Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_sigterm_stops_the_spinner_and_the_board_server():
    bench = subprocess.Popen([sys.executable, str(BENCH), "--runs", "1"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        started = set()
        while time.monotonic() < deadline and len(started) < 3:   # spinner, board server, a command
            started |= children(bench.pid)
            time.sleep(0.05)
        assert len(started) >= 2, "the benchmark did not start its helpers"
        bench.send_signal(signal.SIGTERM)
        bench.wait(timeout=30)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(alive(pid) for pid in started):
            time.sleep(0.05)
        assert not [pid for pid in started if alive(pid)]
    finally:
        if bench.poll() is None:
            bench.kill()
            bench.wait()
