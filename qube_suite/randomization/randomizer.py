"""Applying a randomization to a Qube domain at the start of every episode."""

from __future__ import annotations

import numpy as np

from qube_suite.randomization.base import Chain, Effect
from qube_suite.randomization.catalog import EFFECTS
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
        self._rng = np.random.RandomState()  # reseeded at every episode
        self._effects: dict[str, tuple[dict, Effect]] = {}  # name -> (settings, effect) of the last episode
        for signal in {EFFECTS[name].signal for name in config.effects}:
            if not hasattr(physics, HOOKS[signal]):
                names = [name for name in config.effects if EFFECTS[name].signal == signal]
                raise ValueError(f"{type(physics).__name__} cannot apply {', '.join(names)} "
                                 f"(it has no {HOOKS[signal]})")

    def start_episode(self, random: np.random.RandomState) -> Sample:
        """Draw the next episode's values from `random` and apply them; returns what was drawn.

        Call before the episode's initial state is set: the effects start afresh
        from it when it is. Effects whose settings did not change since the last
        episode are kept (the domain restarts them), the others built anew; either
        way the noise and jitter of the episode are the draws that follow its seed.
        """
        drawn = sample(self.config, random)
        if self.config.parameters:
            self._physics.set_parameters(drawn.parameters)
        changed = set()
        for name, settings in drawn.effects.items():
            kept = self._effects.get(name)
            if kept is None or kept[0] != settings:
                cls = EFFECTS[name]
                self._effects[name] = settings, cls.from_settings(settings, self._control_period, self._rng)
                changed.add(cls.signal)
        for signal in changed:
            chain = [effect for name, (_, effect) in self._effects.items() if EFFECTS[name].signal == signal]
            getattr(self._physics, HOOKS[signal])(Chain(chain))
        if drawn.seed is not None:  # after installing, which measures: the stream starts with the episode
            self._rng.seed(drawn.seed)
        return drawn
