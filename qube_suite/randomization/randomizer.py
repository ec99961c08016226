"""Applying a randomization to a Qube domain, or to each Qube of a batch, at the start of every episode."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.randomization.base import BatchChain, Chain, Effect, Streams
from qube_suite.randomization.catalog import EFFECTS
from qube_suite.randomization.config import Randomization
from qube_suite.randomization.distributions import Distribution
from qube_suite.randomization.sampling import Sample, sample, sample_effects

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
        check_domain(config, physics)
        self.config = config
        self._physics = physics
        self._control_period = control_period
        self._rng = np.random.RandomState()  # reseeded at every episode
        self._effects: dict[str, tuple[dict, Effect]] = {}  # name -> (settings, effect) of the last episode

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


class BatchRandomizer:
    """Draws each world's parameters and effects when it starts an episode and applies them to a
    batch of Qubes (`qube_suite.domains.qube_batch.QubeBatch`), as `Randomizer` does for one.

    A world draws from the random state it is given, exactly what `Randomizer` draws
    from it, and its noise and jitter come from a generator of its own (`Streams`)
    seeded as `Randomizer` seeds its one: world i replays the episodes of a single
    Qube randomized from the same random state. The effects run on arrays with
    per-world settings and memory, installed once; a world's start gives it its
    settings (`Effect.set_rows`), and the batch restarts its memory (`reset_world`).
    Until a world's first episode its settings are a placeholder draw.

    Args:
        config: what to draw.
        batch: the Qubes.
        control_period: seconds per control step (delays in seconds, velocity filter).
    """

    def __init__(self, config: Randomization, batch, control_period: float):
        check_domain(config, batch)
        self.config = config
        self._batch = batch
        self._control_period = control_period
        self._generators = [np.random.RandomState() for _ in range(batch.num_worlds)]  # reseeded per episode
        placeholder = sample_effects(config, np.random.RandomState(0))
        streams = Streams(self._generators)
        self._effects = {name: EFFECTS[name].from_settings(_repeated(settings, batch.num_worlds),
                                                           control_period, streams)
                         for name, settings in placeholder.items()}
        self._redrawn = [name for name, settings in config.effects.items()
                         if any(isinstance(value, Distribution) for value in settings.values())]
        """Effects with settings drawn per episode (the others have the same settings in every world)."""
        for signal in {EFFECTS[name].signal for name in self._effects}:
            chain = [effect for name, effect in self._effects.items() if EFFECTS[name].signal == signal]
            getattr(batch, HOOKS[signal])(BatchChain(chain))

    def start_world(self, world: int, random: np.random.RandomState) -> Sample:
        """Draw `world`'s next episode from `random` and apply it; returns what was drawn.

        Call before the world's initial state is set (`reset_world` restarts its effects).
        """
        drawn = sample(self.config, random)
        if self.config.parameters:
            self._batch.set_parameters(world, drawn.parameters)
        rows = np.array([world])
        for name in self._redrawn:
            fresh = EFFECTS[name].from_settings(_repeated(drawn.effects[name], 1), self._control_period, None)
            self._effects[name].set_rows(rows, fresh)
        if drawn.seed is not None:
            self._generators[world].seed(drawn.seed)
        return drawn


def check_domain(config: Randomization, physics) -> None:
    """Raise ValueError unless the domain `physics` (one Qube or a batch) can apply everything
    `config` randomizes: `set_parameters` for parameters it models, the hooks in HOOKS for effects."""
    if config.parameters:
        if not hasattr(physics, "set_parameters"):
            raise ValueError(f"{type(physics).__name__} cannot change physical parameters; "
                             f"randomize only effects on this domain")
        unmodelled = [name for name in config.parameters
                      if name in getattr(physics, "UNMODELLED_PARAMETERS", ())]
        if unmodelled:
            raise ValueError(f"{type(physics).__name__} does not model {', '.join(unmodelled)}: "
                             f"randomizing it would change nothing")
    for signal in {EFFECTS[name].signal for name in config.effects}:
        if not hasattr(physics, HOOKS[signal]):
            names = [name for name in config.effects if EFFECTS[name].signal == signal]
            raise ValueError(f"{type(physics).__name__} cannot apply {', '.join(names)} "
                             f"(it has no {HOOKS[signal]})")


def _repeated(settings: Mapping, count: int) -> dict[str, np.ndarray]:
    """Effect settings for `count` environments: each value repeated along a new first axis."""
    return {key: np.repeat(np.asarray(value)[None], count, axis=0) for key, value in settings.items()}
