"""What every controller shares: observation in, motor voltage out."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np


def split_observation(observation: Any) -> tuple[np.ndarray, float]:
    """([theta, alpha, dtheta, dalpha], theta_target) from any Qube observation.

    Accepts a dm_env observation (mapping with `state` and maybe `target`) or a
    flat Gymnasium vector: 4 values (state), 5 (state, target), 6 (trig state) or
    7 (trig state, target). The target is 0 when absent.
    """
    if isinstance(observation, Mapping):
        flat = np.concatenate([np.ravel(observation["state"]), np.ravel(observation.get("target", ()))])
    else:
        flat = np.ravel(np.asarray(observation, dtype=np.float64))
    if flat.size in (6, 7):  # trig layout
        flat = np.concatenate([[math.atan2(flat[1], flat[0]), math.atan2(flat[3], flat[2])], flat[4:]])
    if flat.size not in (4, 5):
        raise ValueError(f"not a Qube observation: {flat.size} values")
    return flat[:4].astype(np.float64), float(flat[4]) if flat.size == 5 else 0.0


class Controller:
    """A controller for the Qube: `voltage = controller(observation)`.

    Subclasses set `name` and `tasks` (the suite tasks it is meant for) and
    implement `__call__`; `reset` is called at the start of each episode.
    """

    name: ClassVar[str]
    tasks: ClassVar[tuple[str, ...]]

    def reset(self) -> None:
        """Forget everything about the previous episode."""

    def __call__(self, observation: Any) -> float:
        """Motor voltage (V) for `observation`."""
        raise NotImplementedError

    def close(self) -> None:
        """Release threads or other resources."""
