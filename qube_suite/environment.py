"""The dm_env environment that runs a Qube task on a Qube domain."""

from __future__ import annotations

import collections
import math

import dm_env
import numpy as np
from dm_control.rl import control
from dm_env import specs

from qube_suite import randomization as randomization_
from qube_suite.arguments import is_number
from qube_suite.capabilities import Closable
from qube_suite.domains.interface import SeededSubstitute
from qube_suite.episode_rules import judge_step
from qube_suite.tasks.base import voltage_from_action

_MID, _LAST = dm_env.StepType.MID, dm_env.StepType.LAST  # looked up once: an enum member costs ~0.3 us

DEFAULT_CONTROL_FREQUENCY = 250.0
"""Control steps per second (Hz)."""

DEFAULT_TIME_LIMIT = 8.192
"""Episode length (s): 2048 steps at 250 Hz."""


def episode_steps(time_limit: float, control_frequency: float) -> int:
    """Control steps in an episode of `time_limit` seconds at `control_frequency` (Hz); at least 1.

    Raises ValueError unless `time_limit` is a positive finite number.
    """
    if not (is_number(time_limit) and 0.0 < time_limit < math.inf):
        raise ValueError(f"time_limit must be a positive number of seconds, got {time_limit!r}")
    return max(1, round(time_limit * control_frequency))


def reward_colour(reward: float) -> tuple[float, float, float]:
    """LED colour for a reward in [0, 1]: red at 0, green at 1."""
    reward = 0.0 if reward < 0.0 else 1.0 if reward > 1.0 else reward  # builtin min/max cost 4x this
    return 1.0 - reward, reward, 0.0


class Environment(control.Environment):
    """A Qube task on a Qube domain, as a `dm_env.Environment`.

    Like dm_control's `control.Environment` (and an instance of it, so tools made
    for dm_control accept it), with the Qube's episode rules (`qube_suite.episode_rules`, shared
    with the vector environment):

    * `step(action)` validates the action before anything moves: a bad action
      raises ValueError and leaves the environment as it was;
    * the episode terminates (discount 0) when the task's safe set is left, and is
      truncated (discount 1) after `time_limit` seconds of control steps;
    * a step in which the simulation diverges ends the episode too (reward 0,
      discount 0, the observation of the state before that step), and
      `physics_error` says why; a step or reset that raises (e.g. a hardware
      safety stop) ends the episode, so the next `step` resets;
    * the LED shows each step's reward (green high, red low);
    * with a randomization, every reset first draws the episode's parameters and
      effects from the task's random state (`randomization_sample`);
    * `reset(seed=s)` reseeds the task's random state first (same seed, same
      episode), as Gymnasium's `reset(seed=...)` does;
    * a refused action on hardware first writes 0 V (the next valid action drives again; without
      one, the board's watchdog disables the amplifier), and any other exception in a step or a
      reset stops the motor (0 V, amplifier off) before it propagates;
    * after `close()` both domains refuse to run (RuntimeError): a closed hardware environment has
      released its board for good, a closed simulation its model; neither can be pickled (TypeError);
    * objects in `observers` are told of every episode start and step (e.g. a
      `qube_suite.recording.Recorder`): `episode_started(environment)` and
      `step_done(environment, action, reward, discount)`, discount None while the
      episode goes on.

    Args:
        physics: a Qube domain (`qube_suite.domains.interface.QubePhysics`) whose
            timestep divides the control period.
        task: a `qube_suite.tasks.QubeTask`.
        control_frequency: control steps per second (Hz).
        time_limit: episode length (s).
        randomization: None, or a preset name, config mapping, YAML file path or
            `qube_suite.randomization.Randomization`.
        flat_observation: as in dm_control's `control.Environment`: observations are an
            OrderedDict with the single key "observations", every entry concatenated in order.
    """

    def __init__(self, physics, task, control_frequency: float = DEFAULT_CONTROL_FREQUENCY,
                 time_limit: float = DEFAULT_TIME_LIMIT, randomization=None, flat_observation: bool = False):
        steps = episode_steps(time_limit, control_frequency)
        if not isinstance(flat_observation, bool):
            raise ValueError(f"flat_observation must be True or False, got {flat_observation!r}")
        super().__init__(physics, task, control_timestep=1.0 / control_frequency, legacy_step=False,
                         flat_observation=flat_observation)
        self._control_frequency = float(control_frequency)
        self._episode_steps = steps
        self._randomizer = None if randomization is None else randomization_.Randomizer(
            randomization_.load(randomization), physics, 1.0 / self._control_frequency)
        self._randomization_sample = None
        self._episode_seed: int | None = None
        self._seeded_random = task.random  # a different object later: reseeded from outside (shimmy)
        self.observers: list = []
    @property
    def control_frequency(self) -> float:
        """Control steps per second (Hz)."""
        return self._control_frequency

    @property
    def episode_steps(self) -> int:
        """Control steps in a full-length episode."""
        return self._episode_steps

    @property
    def step_count(self) -> int:
        """Control steps taken in the current episode."""
        return self._step_count

    @property
    def needs_reset(self) -> bool:
        """True before the first reset, after an episode's last step, and after a step or reset
        that raised: the next `step` starts a new episode."""
        return self._reset_next_step

    @property
    def physics_error(self) -> str | None:
        """Why the last step ended the episode because the simulation diverged, else None."""
        return self._physics.physics_error

    @property
    def episode_seed(self) -> int | None:
        """The seed the current episode's reset was given, or None (the task's random state went on)."""
        return self._episode_seed

    @property
    def randomization(self) -> randomization_.Randomization | None:
        """The randomization drawn from at every reset, or None."""
        return None if self._randomizer is None else self._randomizer.config

    @property
    def randomization_sample(self) -> randomization_.Sample | None:
        """What the randomization drew for the current episode (parameters, effect settings),
        or None without randomization."""
        return self._randomization_sample

    def reset(self, seed: int | None = None) -> dm_env.TimeStep:
        """Start a new episode and return its first `TimeStep`; `seed` reseeds the task first."""
        self.start_episode(seed)
        return dm_env.restart(self._observation())

    def start_episode(self, seed: int | None = None) -> None:
        """Start a new episode without building a `TimeStep`: the core that `reset` and the
        Gymnasium view share. `seed`: reseed the task's random state first."""
        self._reset_next_step = True  # until the episode has started
        self._step_count = 0
        if seed is not None:
            self._task.random.seed(seed)
        self._episode_seed = seed
        reseeded = seed is not None or self._task.random is not self._seeded_random
        self._seeded_random = self._task.random
        if reseeded and isinstance(self._physics, SeededSubstitute):
            self._physics.seed_substitute(int(self._task.random.randint(2**31)))
        if self._randomizer is not None:
            self._randomization_sample = self._randomizer.draw(self._task.random)
        with self._physics.reset_context():
            self._task.initialize_episode(self._physics)
        self._show(self._task.get_reward(self._physics))
        self._reset_next_step = False
        for observer in self.observers:
            observer.episode_started(self)

    def step(self, action) -> dm_env.TimeStep:
        """Apply `action` for one control period and return the resulting `TimeStep`.

        After an episode's last step this starts the next episode, as dm_env does, but only for a
        valid action: a bad one raises ValueError first and nothing moves."""
        if self._reset_next_step:
            voltage_from_action(action, self._task.voltage_limit, shape=self._task.action_shape)
            return self.reset()
        reward, discount = self.advance(action)
        try:
            observation = self._observation()
        except BaseException:
            self.stop_episode()
            raise
        if discount is None:
            return dm_env.TimeStep(_MID, reward, 1.0, observation)
        return dm_env.TimeStep(_LAST, reward, discount, observation)

    def advance(self, action) -> tuple[float, float | None]:
        """One control period without building a `TimeStep`: the core that `step` and the
        Gymnasium view share.

        Returns the reward and the discount: None while the episode goes on, 0.0 when it
        terminates (or the simulation diverged: reward 0), 1.0 when it is truncated; after
        either, the next `step` resets. A bad action raises ValueError and changes nothing.
        """
        physics, task = self._physics, self._task
        try:
            task.before_step(action, physics)
        except ValueError:
            physics.stop_motor()  # on hardware: the last voltage does not stay on while the error rises
            raise
        except BaseException:
            self.stop_episode()
            raise
        try:
            physics.step(self._n_sub_steps)
            return self._finish_step(action)
        except BaseException:
            # Anything that fails here (reward, observation, an observer such as a recorder with a
            # full disk, Ctrl-C) ends the episode and stops the motor before it propagates.
            self.stop_episode()
            raise

    def stop_episode(self) -> None:
        """End the current episode now (the next `step` resets); on hardware the motor stops (0 V,
        amplifier off). What a step that fails after moving the Qube does before it raises."""
        self._reset_next_step = True
        self._physics.end_episode()

    def _show(self, reward: float) -> None:
        """The reward on the LED, and with the task's `visualize_reward` in dm_control's colours."""
        self._physics.set_led(reward_colour(reward))
        if self._task.visualize_reward:
            self._physics.show_reward(reward)

    def _finish_step(self, action) -> tuple[float, float | None]:
        physics = self._physics
        self._step_count += 1
        reward, terminated, truncated = judge_step(self._task, physics, physics.physics_error is not None,
                                                   self._step_count, self._episode_steps)
        self._show(reward)
        discount = 0.0 if terminated else 1.0 if truncated else None
        if discount is not None:
            self._reset_next_step = True
            physics.end_episode()
        for observer in self.observers:
            observer.step_done(self, action, reward, discount)
        return reward, discount

    def observation_spec(self):
        """The task's observation spec; flattened like the observations with `flat_observation`."""
        spec = self._task.observation_spec(self._physics)
        if not self._flat_observation:
            return spec
        size = sum(int(np.prod(array.shape)) for array in spec.values())
        key = control.FLAT_OBSERVATION_KEY
        return collections.OrderedDict([(key, specs.Array((size,), np.float64, name=key))])

    def _observation(self):
        observation = self._task.get_observation(self._physics)
        return control.flatten_observation(observation) if self._flat_observation else observation

    def close(self) -> None:
        """Release the domain for good: on hardware, stop the motor and close the board; a closed
        environment refuses to reset or step (RuntimeError)."""
        self._reset_next_step = True
        self._physics.close()

    @property
    def closed(self) -> bool:
        """Whether the domain was closed for good (the simulated Qube after `close()`)."""
        return isinstance(self._physics, Closable) and self._physics.closed
