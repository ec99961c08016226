"""A native Gymnasium vector environment: N simulated Qubes of one task stepped in one call."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from qube_suite import randomization as randomization_
from qube_suite import suite
from qube_suite.arguments import check_keywords, keywords_of
from qube_suite.devices.qube.batch import QubeBatch
from qube_suite.environment import DEFAULT_CONTROL_FREQUENCY, DEFAULT_TIME_LIMIT, episode_steps
from qube_suite.episode_rules import judge_step
from qube_suite.wrappers.gym_env import action_space, observation_space

ResetHook = Callable[[QubeBatch, int, np.random.RandomState], None]
"""`hook(batch, world, random)`, called when `world` starts an episode, before the task draws its start."""


class QubeVectorEnv(gymnasium.vector.VectorEnv):
    """`num_envs` Qubes running one task, with Gymnasium's vector API.

    Obtain one with `gymnasium.make_vec("QubeSuite/<Task>-v0", num_envs=N)`. All
    worlds advance in one call to MuJoCo's rollout on a thread pool
    (`qube_suite.devices.qube.batch.QubeBatch`); rewards, terminations, observations
    and resets come from the same task definitions as the single environments,
    evaluated on arrays (a task made with `worlds=N`), under the same episode rules
    (`qube_suite.episode_rules`): this class adds only the batching, Gymnasium's
    autoreset and the info. World i reset with seed s replays exactly the episode of
    a single environment reset with seed s under the same actions.

    ## Spaces
    Batched versions of the single environment's: actions (N, 1) float32 volts;
    observations (N, 4), (N, 5) in follow tasks, (N, 6) or
    (N, 7) with `observation="trig"`, float32. Actions beyond the voltage limit are
    clipped; NaN/inf, a wrong shape or a non-number raise ValueError before any
    world moves.

    ## Reward, start and episode end
    Each world's are the task's, as in the single environment (the task classes'
    docstrings, e.g. `help(qube_suite.devices.qube.tasks.Swingup)`, and the table in docs/tasks.md).

    ## Seeding
    `reset(seed=s)` seeds world i with s + i (like `SyncVectorEnv`); `seed=[s_0,
    ...]` seeds each world (None: not reseeded). The task keyword `random=s` seeds
    the worlds at construction the same way.

    ## Autoreset
    `autoreset_mode` (also in `metadata["autoreset_mode"]`):
    * NEXT_STEP (default): the step after a world's last step resets it, ignoring
      its action, and returns its first observation with reward 0 and terminated
      and truncated False;
    * SAME_STEP: a world is reset in the step that ends its episode; the returned
      observation is the new episode's, the last one is in `info["final_obs"]` and
      its info in `info["final_info"]`;
    * DISABLED: reset ended worlds with `reset(options={"reset_mask": mask})`;
      stepping an ended world raises RuntimeError.

    ## Randomization
    `randomization=` takes what a single environment takes (preset name, config
    mapping, YAML path, `Randomization`). A world starting an episode draws its
    physical parameters and effect settings from its task random state, exactly as a
    single environment does, into its own model and its rows of the effects, which
    run on all worlds at once with per-world memory and noise. Control-period jitter
    gives each world its own timestep (see `QubeBatch`). World i seeded s still plays
    exactly the episodes of `gymnasium.make(id, randomization=...)` seeded s.

    ## Info
    `time` (s) and `voltage` (V, as commanded after clipping) of each world, `target`
    (rad) in follow tasks, each with Gymnasium's `_key` mask. With a randomization,
    the worlds that started an episode in the call (all at `reset`, the restarted ones
    at `step`) add what they drew, as their single environment's reset info does:
    `parameters` (name -> array over worlds) and `effects` (effect name -> setting ->
    array), nested in Gymnasium's vector-info convention (what `SyncVectorEnv` gives)
    with masks `_parameters`, `_effects` and inner ones marking those worlds. In a
    step where the simulation of some worlds diverged, `physics_error` (bool per
    world) marks them: each such world terminates with reward 0 and the observation
    of its state before that step.

    Args:
        task: suite task name, e.g. "swingup".
        num_envs: number of Qubes.
        autoreset_mode: an `AutoresetMode` or its value.
        control_frequency: control steps per second (Hz).
        time_limit: episode length (s).
        threads: rollout threads; default: the CPU count (small batches use none).
        reset_hook: called as `hook(batch, world, random)` when a world starts an
            episode, after any randomization's draws and before the task draws its
            start, e.g. to set that world's physical parameters with
            `batch.set_parameters(world, ...)` (which replaces drawn ones).
        randomization: None, or a preset name, config mapping, YAML file path or
            `qube_suite.randomization.Randomization`, drawn per world at every start.
        **task_kwargs: `voltage_limit`, `observation`, `random` (seed).
    """

    def __init__(self, task: str, num_envs: int,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 control_frequency: float = DEFAULT_CONTROL_FREQUENCY, time_limit: float = DEFAULT_TIME_LIMIT,
                 threads: int | None = None, reset_hook: ResetHook | None = None, randomization: Any = None,
                 render_mode: str | None = None, **task_kwargs):
        if render_mode is not None:
            raise ValueError("the vector environment does not render; make a single environment to watch one")
        if not (isinstance(num_envs, int) and not isinstance(num_envs, bool) and num_envs >= 1):
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        check_keywords(task_kwargs, keywords_of(QubeVectorEnv, skip=("task", "num_envs"))
                       + suite.task_keywords("qube", task),
                       f"keyword arguments for the vector environment of {task!r}")
        modes = [mode.value for mode in AutoresetMode]
        if autoreset_mode not in [*AutoresetMode, *modes]:
            raise ValueError(f"unknown autoreset_mode {autoreset_mode!r}; valid: {', '.join(modes)}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        seed = task_kwargs.pop("random", None)
        if not (seed is None or isinstance(seed, int)):
            raise ValueError(f"random must be an integer seed or None for a vector environment, got {seed!r}")
        self._task = suite.make_task("qube", task, {**task_kwargs, "random": seed}, worlds=num_envs)
        self._steps_per_episode = episode_steps(time_limit, control_frequency)
        config = None if randomization is None else randomization_.load(randomization)
        self._batch = QubeBatch(num_envs, control_frequency, threads)
        self._randomizer = None if config is None else randomization_.Randomizer(
            config, self._batch, 1.0 / control_frequency)
        self._reset_hook = reset_hook
        self._randoms = self._task.randoms

        self.num_envs = num_envs
        self.single_action_space = action_space(self._task.action_spec(None))
        self.single_observation_space = observation_space(self._task.observation_spec(None))
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": [],
                         "render_fps": int(round(control_frequency))}
        self.render_mode = None
        self._follows_target = getattr(self._task, "follows_target", False)
        self._step_counts = np.zeros(num_envs, dtype=np.int64)
        self._ended = np.zeros(num_envs, dtype=bool)
        self._started = False
        self._every = np.ones(num_envs, dtype=bool)
        self._every.flags.writeable = False  # the info mask of values every world has, shared by all steps

    @property
    def batch(self) -> QubeBatch:
        """The simulated Qubes (accessors return one value per world)."""
        return self._batch

    @property
    def randomization(self) -> randomization_.Randomization | None:
        """The randomization each world draws from when it starts an episode, or None."""
        return None if self._randomizer is None else self._randomizer.config

    @property
    def task(self):
        """The task, evaluating all worlds at once."""
        return self._task

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        """Start episodes in every world, or in those of `options["reset_mask"]` (bool array, shape (N,))."""
        if seed is None or isinstance(seed, int):
            super().reset(seed=seed)  # seeds `self.np_random`, which the worlds do not use
        worlds = np.arange(self.num_envs)
        if options is not None and "reset_mask" in options:
            mask = np.asarray(options["reset_mask"])
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},)")
            worlds = np.flatnonzero(mask)
        seeds = self._seeds(seed)
        self._started = True
        for world in worlds.tolist():
            if seeds[world] is not None:
                self._randoms[world].seed(seeds[world])
        draws = self._start(worlds)
        observations = self._observations()
        info = self._info()
        if len(worlds) < self.num_envs:
            started = np.zeros(self.num_envs, dtype=bool)
            started[worlds] = True
            info = {key: (started if key.startswith("_") else value) for key, value in info.items()}
        return observations, self._with_draws(info, draws)

    def step(self, actions):
        """Apply one voltage per world for one control period; see the class docstring for autoreset."""
        batch, task = self._batch, self._task
        task.before_step(actions, batch)  # checks the actions before anything moves
        if not self._started:
            raise RuntimeError("call reset() before step()")
        restarting = None
        if self._ended.any():
            if self.autoreset_mode is AutoresetMode.DISABLED:
                raise RuntimeError(f"worlds {np.flatnonzero(self._ended).tolist()} have ended; reset them "
                                   "with reset(options={'reset_mask': mask}) before step()")
            restarting = self._ended.copy()  # NEXT_STEP: these worlds start over instead of stepping
        batch.step()
        self._step_counts += 1
        diverged = batch.physics_error if restarting is None else batch.physics_error & ~restarting
        draws = {} if restarting is None else self._start(np.flatnonzero(restarting))
        rewards, terminated, truncated = judge_step(task, batch, diverged, self._step_counts,
                                                    self._steps_per_episode)
        if restarting is not None:
            rewards[restarting] = 0.0
            terminated[restarting] = truncated[restarting] = False
        self._ended = terminated | truncated
        observations = self._observations()
        info = self._with_draws(self._info(), draws)
        if diverged.any():
            info["physics_error"], info["_physics_error"] = diverged, diverged
        if self.autoreset_mode is AutoresetMode.SAME_STEP and self._ended.any():
            observations, info = self._restart_ended(observations, info)
            if diverged.any():  # in final_info, and here too, as in the other modes
                info["physics_error"], info["_physics_error"] = diverged, diverged
        return observations, rewards, terminated, truncated, info

    def close_extras(self, **kwargs) -> None:
        self._batch.close()

    # -- helpers ------------------------------------------------------------------------

    def _seeds(self, seed) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, (int, np.integer)):
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"seed must be an int, None or a sequence of {self.num_envs} seeds, "
                             f"got {seed!r}")
        return seeds

    def _start(self, worlds: np.ndarray) -> dict[int, randomization_.Sample]:
        """Start episodes in `worlds`; returns what each world's randomization drew."""
        draws = {}
        for world in worlds.tolist():
            random = self._randoms[world]
            if self._randomizer is not None:
                draws[world] = self._randomizer.draw(random, world)
            if self._reset_hook is not None:
                self._reset_hook(self._batch, world, random)
            self._task.initialize_episode(self._batch, world)
        self._batch.measure_afresh(worlds)  # as a single environment's reset context does on closing
        self._step_counts[worlds] = 0
        self._ended[worlds] = False
        return draws

    def _observations(self) -> np.ndarray:
        return np.stack(self._task.observation_values(self._batch), axis=1, dtype=np.float32)

    def _info(self) -> dict[str, np.ndarray]:
        every = self._every
        info = {"time": self._batch.time().copy(), "_time": every,
                "voltage": self._batch.voltage().copy(), "_voltage": every}
        if self._follows_target:
            info["target"], info["_target"] = np.array(self._task.target), every
        return info

    def _with_draws(self, info: dict, draws: dict[int, randomization_.Sample]) -> dict:
        """`info` with each world's draws added as its single environment's reset info has them."""
        for world, drawn in draws.items():
            self._add_info(info, {"parameters": drawn.parameters, "effects": drawn.effects}, world)
        return info

    def _restart_ended(self, observations: np.ndarray, info: dict) -> tuple[np.ndarray, dict]:
        ended = self._ended.copy()
        final_obs = np.full(self.num_envs, None, dtype=object)
        for world in np.flatnonzero(ended).tolist():
            final_obs[world] = observations[world]
        final_info = {key: (ended if key.startswith("_") else value) for key, value in info.items()}
        draws = self._start(np.flatnonzero(ended))
        observations = self._observations()
        info = self._with_draws(self._info(), draws)
        info.update(final_obs=final_obs, _final_obs=ended, final_info=final_info, _final_info=ended)
        return observations, info


def make_vector_env(task: str, num_envs: int = 1, domain: str = "qube", **kwargs) -> QubeVectorEnv:
    """Vector entry point of the registered ids (`gymnasium.make_vec`): a batch of simulated Qube
    pendulums (domain "qube", the one device with a batch so far)."""
    if domain != "qube":
        raise ValueError(f"the vector environment simulates Qube pendulums (domain 'qube'), not {domain!r}")
    return QubeVectorEnv(task, num_envs, **kwargs)
