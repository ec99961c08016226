"""Per-episode draws as pure functions of (config, random state), for one environment or each of n."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from qube_suite.devices.qube.parameters import NOMINAL
from qube_suite.randomization.config import Randomization
from qube_suite.randomization.distributions import Distribution


@dataclasses.dataclass(frozen=True)
class Sample:
    """What one episode drew.

    `parameters`: name -> value of each randomized physical parameter (the others
    are nominal). `effects`: effect name -> its settings for the episode. `seed`
    (in [0, 2**32)): of the generator the stochastic effects (noise, jitter) draw
    from at every step; None when no such effect is on.
    """

    parameters: dict[str, float]
    effects: dict[str, dict[str, Any]]
    seed: int | None


def sample_parameters(config: Randomization, random: np.random.RandomState) -> dict[str, float]:
    """Parameter name -> value for one episode, drawn from `random` in the parameter table's order."""
    return {name: distribution.sample(random, NOMINAL[name])
            for name, distribution in config.parameters.items()}


def sample_effects(config: Randomization, random: np.random.RandomState) -> dict[str, dict[str, Any]]:
    """Effect name -> settings for one episode; settings given as distributions are drawn from `random`."""
    return {name: {key: value.sample(random) if isinstance(value, Distribution) else value
                   for key, value in settings.items()}
            for name, settings in config.effects.items()}


def sample(config: Randomization, random: np.random.RandomState) -> Sample:
    """One episode's `Sample`: parameters, then effect settings, then (if needed) the per-step seed.

    Draws nothing when `config` randomizes nothing, so the `none` preset leaves a
    seeded task's own draws (its initial states) exactly as without randomization.
    """
    parameters = sample_parameters(config, random)
    effects = sample_effects(config, random)
    seed = int(random.random_sample() * 2.0**32) if config.stochastic else None
    return Sample(parameters, effects, seed)
