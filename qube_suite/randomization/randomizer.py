"""Applying a randomization to a Qube domain, or to each Qube of a batch, at the start of every episode."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.capabilities import ActuatorEffects, Batch, Randomizable, SensorEffects, StepDurationEffects
from qube_suite.randomization.base import Chain, Streams
from qube_suite.randomization.catalog import EFFECTS
from qube_suite.randomization.config import Randomization
from qube_suite.randomization.distributions import Distribution
from qube_suite.randomization.sampling import Sample, sample, sample_effects

HOOKS = {"state": "set_sensor_model", "voltage": "set_actuator_model", "duration": "set_step_duration_model"}
"""Signal -> the domain method that installs effects on it."""

CAPABILITIES = {"state": SensorEffects, "voltage": ActuatorEffects, "duration": StepDurationEffects}
"""Signal -> the capability (`qube_suite.capabilities`) of a domain that takes effects on it."""


class Randomizer:
    """Draws each episode's parameters and effects and applies them to a Qube domain: one Qube, or
    each Qube ("world") of a batch when it starts an episode.

    The domain needs to be `Randomizable` for physical parameters and to have the
    capabilities in CAPABILITIES for the effects it is asked to apply; a missing one is
    a ValueError here, before any episode. Hooks the config does not use are left
    alone, so a domain without randomization keeps its plain step path. A `Batch`
    (`qube_suite.devices.qube.batch.QubeBatch`) takes effects on arrays with one row
    per world; a one-Qube domain is a batch of one (`OneQube`) whose effects hold
    numbers and run on its floats.

    World i draws from the random state it is given, and its noise and jitter come from
    a generator of its own (`Streams`) seeded by that draw, so world i of a batch
    replays the episodes of a single Qube randomized from the same random state. The
    effects have per-world settings and memory, installed once; a world's start gives
    it its settings (`Effect.set_rows`), and the domain restarts its memory when the
    world's initial state is set. Until a world's first episode its settings are a
    placeholder draw.

    Args:
        config: what to draw.
        domain: a Qube domain, or a batch of them.
        control_period: seconds per control step (delays in seconds, velocity filter).
    """

    def __init__(self, config: Randomization, domain, control_period: float):
        check_domain(config, domain)
        self.config = config
        self._one = not isinstance(domain, Batch)
        batch = OneQube(domain) if self._one else domain
        self._batch = batch
        self._control_period = control_period
        self._generators = [np.random.RandomState() for _ in range(batch.num_worlds)]  # reseeded per episode
        placeholder = sample_effects(config, np.random.RandomState(0))
        rng = self._generators[0] if self._one else Streams(self._generators)
        self._effects = {name: EFFECTS[name].from_settings(self._settings(settings, batch.num_worlds),
                                                           control_period, rng)
                         for name, settings in placeholder.items()}
        self._redrawn = [name for name, settings in config.effects.items()
                         if any(isinstance(value, Distribution) for value in settings.values())]
        """Effects with settings drawn per episode (the others have the same settings in every world)."""
        for signal in {EFFECTS[name].signal for name in self._effects}:
            chain = [effect for name, effect in self._effects.items() if EFFECTS[name].signal == signal]
            getattr(batch, HOOKS[signal])(Chain(chain))

    def draw(self, random: np.random.RandomState, world: int = 0) -> Sample:
        """Draw `world`'s next episode from `random` and apply it; returns what was drawn.

        Call before the episode's initial state is set: the domain restarts the world's
        effects from it.
        """
        drawn = sample(self.config, random)
        if self.config.parameters:
            self._batch.set_parameters(world, drawn.parameters)
        rows = np.array([world])
        for name in self._redrawn:
            settings = self._settings(drawn.effects[name], 1)
            fresh = EFFECTS[name].from_settings(settings, self._control_period, None)
            self._effects[name].set_rows(rows, fresh)
        if drawn.seed is not None:
            self._generators[world].seed(drawn.seed)
        return drawn

    def _settings(self, settings: Mapping, count: int) -> Mapping:
        """An effect's settings for `count` worlds of the batch (arrays, one entry per world), or as
        they are for one Qube."""
        if self._one:
            return settings
        return {key: np.repeat(np.asarray(value)[None], count, axis=0) for key, value in settings.items()}


class OneQube:
    """A one-Qube domain as a batch of one world, as `Randomizer` drives it: its parameters set for
    world 0, its hooks given each `Chain`."""

    num_worlds = 1

    def __init__(self, physics):
        self.physics = physics

    def set_parameters(self, world: int, parameters: Mapping[str, float]) -> None:
        self.physics.set_parameters(parameters)

    def set_sensor_model(self, chain: Chain) -> None:
        self.physics.set_sensor_model(chain)

    def set_actuator_model(self, chain: Chain) -> None:
        self.physics.set_actuator_model(chain)

    def set_step_duration_model(self, chain: Chain) -> None:
        self.physics.set_step_duration_model(chain)


def check_domain(config: Randomization, physics) -> None:
    """Raise ValueError unless the domain `physics` (one Qube or a batch) can apply everything
    `config` randomizes: it is `Randomizable` for parameters it models, and has the capabilities in
    CAPABILITIES for the effects."""
    if config.parameters:
        if not isinstance(physics, Randomizable):
            raise ValueError(f"{type(physics).__name__} cannot change physical parameters; "
                             f"randomize only effects on this domain")
        unmodelled = [name for name in config.parameters if name in physics.UNMODELLED_PARAMETERS]
        if unmodelled:
            raise ValueError(f"{type(physics).__name__} does not model {', '.join(unmodelled)}: "
                             f"randomizing it would change nothing")
    for signal in {EFFECTS[name].signal for name in config.effects}:
        if not isinstance(physics, CAPABILITIES[signal]):
            names = [name for name in config.effects if EFFECTS[name].signal == signal]
            raise ValueError(f"{type(physics).__name__} cannot apply {', '.join(names)} "
                             f"(it has no {HOOKS[signal]})")
