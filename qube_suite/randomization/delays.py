"""Delays of the measurements and of the motor commands, in whole control steps."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.randomization.base import Effect, Field

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
        self.steps = np.asarray(steps, dtype=np.intp)
        if self.steps.ndim == 0:
            smallest = largest = int(self.steps)
        else:
            smallest, largest = int(self.steps.min()), int(self.steps.max())
        if smallest < 0:
            raise ValueError(f"{self.name}: steps must be >= 0, got {steps}")
        self._length = largest + 1

    def set_rows(self, rows: np.ndarray, fresh: Delay) -> None:
        super().set_rows(rows, fresh)
        length = int(self.steps.max()) + 1
        if length > self._length and hasattr(self, "_line"):  # lengthen: newest entries kept, oldest repeated
            oldest_first = np.roll(self._line, -(self._head + 1), axis=0)
            padding = np.repeat(oldest_first[:1], length - self._length, axis=0)
            self._line = np.concatenate([padding, oldest_first])
            self._head = length - 1
        self._length = max(self._length, length)

    def reset(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        if rows is None:
            self._line = np.repeat(np.asarray(x)[None], self._length, axis=0)
            self._head = 0
            self._envs = None if self.steps.ndim == 0 else np.arange(self.steps.shape[0])
        else:
            self._line[:, rows] = x
        return x

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self._head = (self._head + 1) % self._length
        self._line[self._head] = x
        if self._envs is None:
            return self._line[(self._head - int(self.steps)) % self._length].copy()
        return self._line[(self._head - self.steps) % self._length, self._envs]


class ObservationDelay(Delay):
    """The measured state of `steps` control steps before (the first measurement until then)."""

    name = "observation_delay"
    signal = "state"


class ActionDelay(Delay):
    """The motor receives the voltage commanded `steps` control steps before (0 V until then)."""

    name = "action_delay"
    signal = "voltage"
