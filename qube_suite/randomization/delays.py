"""Delays of the measurements and of the motor commands, in whole control steps."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.randomization.base import Effect, Field, components, number_or_array, with_rows

MAX_DELAY_SECONDS = 1.0
"""Longest delay (s) a config may give: 100 times the Qube's real loop latency, an eighth of an episode."""

MAX_DELAY_STEPS = 2000
"""Longest delay in control steps: MAX_DELAY_SECONDS at the highest control frequency (2000 Hz)."""


class Delay(Effect):
    """Outputs its input of `steps` control steps before, from a delay line that
    `reset` fills with the reset signal. Given in `seconds`, a delay is rounded to
    whole control periods."""

    fields = {
        "steps": Field("control steps", "delay (default 1 step)", optional=True, minimum=0,
                       maximum=MAX_DELAY_STEPS, integer=True),
        "seconds": Field("s", "delay, rounded to whole control steps", optional=True, minimum=0.0,
                         maximum=MAX_DELAY_SECONDS),
    }
    per_env_settings = ("steps",)

    @classmethod
    def complete(cls, settings: dict) -> dict:
        if "steps" in settings and "seconds" in settings:
            raise ValueError(f"effects.{cls.name}: give 'steps' or 'seconds', not both")
        return settings or {"steps": 1}

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> Delay:
        if "seconds" in settings:
            return cls(np.rint(np.asarray(settings["seconds"]) / control_period).astype(np.intp))
        return cls(settings["steps"])

    def __init__(self, steps: int | np.ndarray):
        self.steps = number_or_array(steps, dtype=np.intp)
        smallest, largest = int(np.min(self.steps)), int(np.max(self.steps))
        if smallest < 0:
            raise ValueError(f"{self.name}: steps must be >= 0, got {steps}")
        self._length = largest + 1

    def set_rows(self, rows: np.ndarray, fresh: Delay) -> None:
        super().set_rows(rows, fresh)
        length = int(np.max(self.steps)) + 1
        if length > self._length and hasattr(self, "_line"):  # lengthen: newest entries kept, oldest repeated
            oldest_first = [(self._head + 1 + k) % self._length for k in range(self._length)]
            oldest_first = [oldest_first[0]] * (length - self._length) + oldest_first
            self._line = self._line[oldest_first] if self._per_env else [self._line[k] for k in oldest_first]
            self._head = length - 1
        self._length = max(self._length, length)

    def start(self, x, rows: np.ndarray | None):
        if rows is None:
            self._head = 0
            self._per_env = type(self.steps) is np.ndarray
            if self._per_env:  # the entries of each environment's delay, gathered from one array
                self._line = np.repeat(np.asarray(x, dtype=np.float64)[None], self._length, axis=0)
                self._envs = np.arange(self.steps.shape[0])
            else:
                self._line = [x] * self._length
        elif self._per_env:
            self._line[..., rows] = x
        elif self.signal == "state":
            self._line = [[with_rows(kept, rows, new) for kept, new in zip(entry, x, strict=True)]
                          for entry in self._line]
        else:
            self._line = [with_rows(entry, rows, x) for entry in self._line]
        return x

    def advance(self, x):
        self._head = head = (self._head + 1) % self._length
        self._line[head] = x
        if not self._per_env:
            return self._line[(head - self.steps) % self._length]
        delayed = self._line[(head - self.steps) % self._length, ..., self._envs]  # (n, 4) or (n,)
        return components(delayed) if self.signal == "state" else delayed


class ObservationDelay(Delay):
    """The measured state of `steps` control steps before (the first measurement until then)."""

    name = "observation_delay"
    signal = "state"


class ActionDelay(Delay):
    """The motor receives the voltage commanded `steps` control steps before (0 V until then)."""

    name = "action_delay"
    signal = "voltage"
