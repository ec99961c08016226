"""Keeping a simulated Qube in step with the wall clock, for people watching it.

    pacer = RealTimePacer()
    pacer.restart(physics.time())
    while ...:
        physics.step()
        pacer.wait(physics.time())        # sleeps until the wall clock has caught up

A loop slower than real time (software rendering, a paused window) is not slowed
further, and it does not race to catch up afterwards: a lag of more than
`max_lag` is forgiven.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class RealTimePacer:
    """Sleeps so that simulated time passes at `speed` times the wall clock.

    Args:
        speed: simulated seconds per wall-clock second (1: real time; 0.5: half speed).
        max_lag: the most the simulation may fall behind (s, wall clock) before the pacer stops
            trying to make it up.
        clock, sleep: the wall clock (s) and how to wait (for tests).
    """

    def __init__(self, speed: float = 1.0, max_lag: float = 0.1,
                 clock: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep):
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        self._speed, self.max_lag = float(speed), float(max_lag)
        self._clock, self._sleep = clock, sleep
        self._wall_start, self._sim_start = clock(), 0.0

    @property
    def speed(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self._speed

    def set_speed(self, speed: float, sim_time: float) -> None:
        """Go on at `speed` from simulated time `sim_time` (s), now."""
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        self._speed = float(speed)
        self.restart(sim_time)

    def restart(self, sim_time: float = 0.0) -> None:
        """Count from now, at simulated time `sim_time` (s): after a reset, a pause or a jump."""
        self._wall_start, self._sim_start = self._clock(), float(sim_time)

    def wait(self, sim_time: float) -> None:
        """Sleep until the wall clock reaches simulated time `sim_time` (s)."""
        due = self._wall_start + (sim_time - self._sim_start) / self._speed
        delay = due - self._clock()
        if delay > 0:
            self._sleep(delay)
        elif delay < -self.max_lag:
            self.restart(sim_time)
