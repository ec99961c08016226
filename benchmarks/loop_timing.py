"""Where a hardware control loop's time goes: its own Python work per step, and the sample periods.

The loop is `qube-suite run`'s: the balance task on `qube_hardware` with the balance
controller, on the real-board code path (`board="qube_servo2_usb"`) against the
wall-clock stand-in of `quanser.hardware` (tests/doubles; its board runs in a process of
its own at real-time priority where allowed, as a real board is separate hardware). In
each condition a fresh loop process runs for `--seconds` and records, at every sample:

* its own Python work: from the return of one blocking `task_read` to the call of the next
  (the wrapper's checks, the estimator, the task, the controller), less the time spent in the
  other board calls of that step (`watchdog_reload`, `task_get_buffer_overflows`,
  `write_analog`: each a round trip to the board process, about 0.15 ms on this stand-in,
  which a real board's USB link replaces): median, 99th percentile and maximum, and the
  median of those board calls;
* the sample period: between two `task_read` returns (4 ms at 250 Hz; the missed-sample
  stop trips beyond 44 ms, the watchdog at 100 ms): median, 99th percentile, maximum;
* each gap over 20 ms, and whether the hypervisor took the CPU from this virtual machine
  meanwhile (steal time in /proc/stat, read every 2 ms by a separate process, in jiffies of
  10 ms, within 10 ms of the gap): "stolen" counts those gaps.

Conditions, in one run: `quiet` (nothing else of the benchmark's running), `hog` (one
CPU-bound process at nice 10 per core, the loop at normal priority), `hog, chrt -f 10`
(the same, with the loop at real-time priority; needs the privilege, else left out).

    python benchmarks/loop_timing.py               # 20 s per condition
    python benchmarks/loop_timing.py --seconds 5
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOUBLES = ROOT / "tests" / "doubles"

LOOP = """
import json, sys, time
import numpy as np
from qube_suite import baselines, suite

seconds = float(sys.argv[1])
env = suite.load("qube_hardware", "balance", task_kwargs={"random": 0},
                 environment_kwargs={"time_limit": seconds}, domain_kwargs={"board": "qube_servo2_usb"})
controller = baselines.for_environment("balance", env)
marks = []                                 # (read called, read returned, board calls since the last read)
timestep = env.reset()
board = env.physics.qube.board
read, call = board.task_read, board._call
in_calls = [0.0]

def timed_read(*args):
    called = time.perf_counter()
    result = read(*args)
    marks.append((called, time.perf_counter(), in_calls[0]))
    in_calls[0] = 0.0
    return result

def timed_call(method, *args):
    if method == "task_read_values":
        return call(method, *args)
    start = time.perf_counter()
    try:
        return call(method, *args)
    finally:
        in_calls[0] += time.perf_counter() - start

board.task_read, board._call = timed_read, timed_call
controller.reset()
while not timestep.last():
    timestep = env.step(controller(timestep.observation))
env.close()
json.dump({"marks": marks}, sys.stdout)
"""

STEAL = """
import sys, time
period = 0.002
with open(sys.argv[1], "w") as out:
    while True:
        with open("/proc/stat") as stat:
            steal = int(stat.readline().split()[8])
        out.write(f"{time.perf_counter()} {steal}\\n")
        out.flush()
        time.sleep(period)
"""

GAP = 0.020
"""Sample periods longer than this (s) are counted and checked against steal time."""


def run_loop(seconds: float, environment: dict[str, str], prefix: list[str]) -> np.ndarray:
    """(read called, read returned) perf_counter times of one loop process."""
    result = subprocess.run([*prefix, sys.executable, "-c", LOOP, str(seconds)], env=environment,
                            capture_output=True, text=True, check=True)
    return np.array(json.loads(result.stdout)["marks"])


def stolen(gaps: list[tuple[float, float]], steal_file: str) -> int:
    """How many gaps (start, end) saw steal time grow within 10 ms of them."""
    rows = np.loadtxt(steal_file, ndmin=2)
    if len(rows) < 2:
        return 0
    times, steal = rows[:, 0], rows[:, 1]
    count = 0
    for start, end in gaps:
        before = np.searchsorted(times, start - 0.010) - 1
        after = np.searchsorted(times, end + 0.010)
        if steal[min(after, len(steal) - 1)] > steal[max(before, 0)]:
            count += 1
    return count


def summary(name: str, marks: np.ndarray, steal_file: str) -> str:
    called, returned, calls = marks[:, 0], marks[:, 1], marks[:, 2]
    work = (called[1:] - returned[:-1] - calls[1:]) * 1e3
    periods = np.diff(returned) * 1e3
    starts = np.flatnonzero(periods > GAP * 1e3)
    gaps = [(returned[k], returned[k + 1]) for k in starts]
    return (f"{name:18s} {len(periods):6d} {np.median(work):7.2f} {np.percentile(work, 99):7.2f} "
            f"{work.max():7.2f} {np.median(calls[1:]) * 1e3:7.2f} {np.median(periods):7.2f} "
            f"{np.percentile(periods, 99):7.2f} "
            f"{periods.max():7.1f} {len(gaps):5d} {stolen(gaps, steal_file):7d}")


def realtime_allowed() -> bool:
    return subprocess.run(["chrt", "-f", "10", "true"], capture_output=True).returncode == 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="loop time per condition (s)")
    args = parser.parse_args()
    sys.path.insert(0, str(DOUBLES))
    from board_server import BoardServer

    single_threaded = {name: "1" for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    conditions = [("quiet", False, []), ("hog", True, [])]
    if realtime_allowed():
        conditions.append(("hog, chrt -f 10", True, ["chrt", "-f", "10"]))
    print(f"{os.cpu_count()} CPUs; the loop at 250 Hz for {args.seconds:g} s per condition; times in ms")
    print(f"{'condition':18s} {'steps':>6s} {'work median':>7s} {'p99':>7s} {'max':>7s} {'calls':>7s} "
          f"{'period median':>7s} {'p99':>7s} {'max':>7s} {'gaps>20ms':>5s} {'stolen':>7s}")
    with tempfile.TemporaryDirectory() as directory:
        server = BoardServer(directory)
        python_path = os.pathsep.join([str(DOUBLES), str(ROOT), os.environ.get("PYTHONPATH", "")])
        environment = {**os.environ, **server.environment(), **single_threaded, "PYTHONPATH": python_path}
        try:
            for name, hog, prefix in conditions:
                hogs = [subprocess.Popen(["nice", "-n", "10", sys.executable, "-c", "while True: pass"])
                        for _ in range(os.cpu_count() if hog else 0)]
                steal_file = os.path.join(directory, "steal.txt")
                sampler = subprocess.Popen([sys.executable, "-c", STEAL, steal_file])
                try:
                    time.sleep(0.5)
                    marks = run_loop(args.seconds, environment, prefix)
                finally:
                    for process in [sampler, *hogs]:
                        process.kill()
                        process.wait()
                print(summary(name, marks, steal_file), flush=True)
        finally:
            server.stop()


if __name__ == "__main__":
    main()
