"""Speed of the substitute board behind QubeServo2: fast-mode throughput and real-time jitter.

Fast mode (realtime=False): `QubeServo2.action` in a loop with a 1 Hz, 2 V sine,
reported as a multiple of real time at the control frequency (goal: >= 100x at
250 Hz; all safety checks run, the arm limit is off because the open-loop sine
turns the arm far), next to the bare board's `task_read` and `write_analog` (the
plant's integration, at >= 10 kHz, with the least Python around it).
Through the environment: `env.step` of `suite.load("qube_hardware", "swingup")` (250 Hz)
with a constant 0.1 V, the step that calibration, training and the held-out studies
run, episode resets excluded, in wall and CPU time; next to it the same step with the
wrapper's compiled samples (`_hil_sim.ClearSamples`) turned off, every sample going
through the board calls and checks one by one, as on a real board.
Whole episodes: the same steps over whole 8 s episodes, each episode's last step (which
ends the episode) included and the resets left out, in CPU time; next to it the same
with Python's full garbage collections held off during each episode and run at its end,
as on a board paced by the wall clock (the fast substitute does not hold them off).
Real-time mode: the period between successive `action` returns at 250 Hz for 5 s,
as median, 99th percentile and maximum, with the samples the board counted as
missed.

    python benchmarks/hardware_substitute.py
"""

from __future__ import annotations

import math
import time

import numpy as np

from qube_suite import suite
from qube_suite.devices.qube.hardware import FULL_COLLECTIONS
from qube_suite.hardware import QubeServo2, _hil_sim

FAST_SECONDS = 60.0      # simulated time per fast-mode measurement
REALTIME_SECONDS = 5.0


def fast_action(frequency: float) -> float:
    """Simulated seconds per wall-clock second through QubeServo2.action."""
    steps = int(FAST_SECONDS * frequency)
    with QubeServo2(frequency, arm_limit=None) as qube:
        start = time.perf_counter()
        for k in range(steps):
            qube.action(2.0 * math.sin(2 * math.pi * k / frequency))
        elapsed = time.perf_counter() - start
    return FAST_SECONDS / elapsed


def fast_board(frequency: float) -> float:
    """Simulated seconds per wall-clock second of the bare board (task_read + write_analog)."""
    steps = int(FAST_SECONDS * frequency)
    board = _hil_sim.HIL("qube_servo2_usb", "0")
    motor, encoders = np.array([0], np.uint32), np.array([0, 1], np.uint32)
    board.write_digital(motor, 1, np.array([1], np.int8))
    task = board.task_create_encoder_reader(1, encoders, 2)
    board.task_start(task, _hil_sim.Clock.HARDWARE_CLOCK_0, frequency, _hil_sim.HIL.INFINITE)
    counts, volts = np.zeros(2, np.int32), np.zeros(1)
    start = time.perf_counter()
    for k in range(steps):
        board.task_read_encoder(task, 1, counts)
        volts[0] = 2.0 * math.sin(2 * math.pi * k / frequency)
        board.write_analog(motor, 1, volts)
    elapsed = time.perf_counter() - start
    board.close()
    return FAST_SECONDS / elapsed


def fast_env_step(steps: int = 5000, compiled: bool = True) -> tuple[float, float]:
    """Seconds per dm_env step of qube_hardware swingup, resets excluded, in wall time and in the
    process's CPU time (which other processes on a busy machine do not inflate), each the best of
    5 runs; with `compiled` False, without the wrapper's compiled samples."""
    env = suite.load("qube_hardware", "swingup")
    action = np.array([0.1])
    wall = cpu = math.inf
    try:
        for _ in range(6):                                # the first run warms up
            env.reset()
            if not compiled:
                env.physics.qube._clear_samples = None    # the board calls and checks one by one
            taken, start, start_cpu = 0, time.perf_counter(), time.process_time()
            while taken < steps // 5 and not env.step(action).last():
                taken += 1
            wall = min(wall, (time.perf_counter() - start) / max(taken, 1))
            cpu = min(cpu, (time.process_time() - start_cpu) / max(taken, 1))
    finally:
        env.close()
    return wall, cpu


def episode_step(episodes: int = 4, held: bool = False) -> float:
    """CPU seconds per dm_env step of qube_hardware swingup over whole episodes (the step that ends
    each included, resets excluded); with `held`, full collections held off during each episode as
    on a paced board."""
    env = suite.load("qube_hardware", "swingup")
    action = np.array([0.1])
    cpu, steps = 0.0, 0
    try:
        for _ in range(episodes):
            env.reset()
            if held:
                FULL_COLLECTIONS.hold(env.physics)    # released when the episode ends
            start = time.process_time()
            while True:
                steps += 1
                if env.step(action).last():
                    break
            cpu += time.process_time() - start
    finally:
        env.close()
    return cpu / steps


def realtime_periods(frequency: float) -> tuple[np.ndarray, int]:
    """Periods (s) between action returns in real-time mode, and the missed samples."""
    steps = int(REALTIME_SECONDS * frequency)
    returns = np.empty(steps)
    with QubeServo2(frequency, realtime=True) as qube:
        qube.action(0.0)
        for k in range(steps):
            qube.action(0.5 * math.sin(2 * math.pi * k / frequency))
            returns[k] = time.perf_counter()
    return np.diff(returns), qube.missed_samples


def main() -> None:
    print("Fast mode (realtime=False): multiple of real time")
    print(f"{'frequency (Hz)':>15s} {'QubeServo2.action':>18s} {'bare board':>11s} {'us/action':>10s}")
    for frequency in (250.0, 500.0, 1000.0):
        wrapped, bare = fast_action(frequency), fast_board(frequency)
        print(f"{frequency:15.0f} {wrapped:17.0f}x {bare:10.0f}x {1e6 / (wrapped * frequency):10.1f}")
    print("\nThrough the environment (qube_hardware swingup, 250 Hz): time per step, multiple of real time")
    print(f"{'':>22s} {'wall':>16s} {'CPU':>16s}")
    for label, compiled in (("compiled samples", True), ("board calls one by one", False)):
        times = fast_env_step(compiled=compiled)
        print(f"{label:>22s}" + "".join(f" {1e6 * t:8.1f} us {1 / (t * 250.0):4.0f}x" for t in times))
    print("\nWhole episodes, CPU time per step (each episode's end included, resets excluded)")
    for label, held in (("as the substitute runs", False), ("collections held, then run", True)):
        t = episode_step(held=held)
        print(f"{label:>27s} {1e6 * t:8.1f} us {1 / (t * 250.0):4.0f}x")
    print()
    periods, missed = realtime_periods(250.0)
    ms = 1e3 * periods
    print(f"Real-time mode (realtime=True) at 250 Hz for {REALTIME_SECONDS:g} s: period between actions (ms)")
    print(f"{'nominal':>8s} {'median':>8s} {'p99':>8s} {'max':>8s} {'missed samples':>15s}")
    print(f"{4.0:8.3f} {np.median(ms):8.3f} {np.percentile(ms, 99):8.3f} {ms.max():8.3f} {missed:15d}")


if __name__ == "__main__":
    main()
