"""Applying a randomization to a Qube domain at the start of every episode."""

from __future__ import annotations

import numpy as np

from qube_suite.randomization import catalog
from qube_suite.randomization.base import Chain
from qube_suite.randomization.config import Randomization
from qube_suite.randomization.sampling import Sample, sample

HOOKS = {"state": "set_sensor_model", "voltage": "set_actuator_model", "duration": "set_step_duration_model"}
"""Signal -> the domain method that installs effects on it."""


class Randomizer:
    """Draws each episode's parameters and effects and applies them to a Qube domain.

    The domain (`physics`) needs `set_parameters` for physical parameters and the
    hooks in HOOKS for the effects it is asked to apply; a missing one is a
    ValueError here, before any episode. Hooks the config does not use are left
    alone, so a domain without randomization keeps its plain step path.

    Args:
        config: what to draw.
        physics: a Qube domain.
        control_period: seconds per control step (delays in seconds, velocity filter).
    """

    def __init__(self, config: Randomization, physics, control_period: float):
        self.config = config
        self._physics = physics
        self._control_period = control_period
        if config.parameters:
            if not hasattr(physics, "set_parameters"):
                raise ValueError(f"{type(physics).__name__} cannot change physical parameters; "
                                 f"randomize only effects on this domain")
            unmodelled = [name for name in config.parameters
                          if name in getattr(physics, "UNMODELLED_PARAMETERS", ())]
            if unmodelled:
                raise ValueError(f"{type(physics).__name__} does not model {', '.join(unmodelled)}: "
                                 f"randomizing it would change nothing")
        self._signals = {catalog.EFFECTS[name].signal for name in config.effects}
        for signal in self._signals:
            if not hasattr(physics, HOOKS[signal]):
                names = [name for name in config.effects if catalog.EFFECTS[name].signal == signal]
                raise ValueError(f"{type(physics).__name__} cannot apply {', '.join(names)} "
                                 f"(it has no {HOOKS[signal]})")

    def start_episode(self, random: np.random.RandomState) -> Sample:
        """Draw the next episode's values from `random` and apply them; returns what was drawn.

        Call before the episode's initial state is set: the effects start afresh
        from it when it is.
        """
        drawn = sample(self.config, random)
        if self.config.parameters:
            self._physics.set_parameters(drawn.parameters)
        rng = None if drawn.seed is None else np.random.default_rng(drawn.seed)
        effects = catalog.build(drawn.effects, self._control_period, rng)
        for signal in self._signals:
            getattr(self._physics, HOOKS[signal])(Chain(effects[signal]))
        return drawn
