"""Run one episode of a policy and keep what happened: `run_episode` and `EpisodeTrace`.

    from qube_suite import baselines, episodes, suite
    env = suite.load("qube", "balance", task_kwargs={"random": 0})
    trace = episodes.run_episode(env, baselines.make("balance"))
    trace.episode_return, trace.time[-1], trace.state[:, 1]   # alpha over time

The trace is what `qube_suite.plotting.plot_episode` draws and what the command
line prints; one row per reading: the start, then one after each control step.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

Policy = Callable[[Any], Any]
"""observation -> motor voltage (V); may have `reset()`, called before each episode."""

StepHook = Callable[[int, Any], None]
"""hook(step, environment), called after the reset (step 0) and after every control step."""


@dataclasses.dataclass(frozen=True)
class EpisodeTrace:
    """The readings of one episode, a row per reading: the start, then one per control step.

    Attributes:
        time: (n,) time since the episode started (s).
        state: (n, 4) measured [theta, alpha, dtheta, dalpha] (rad, rad/s); alpha = 0 upright.
        voltage: (n,) motor voltage commanded over the step that ended at `time` (V); 0 at the start.
        reward: (n,) reward of the step that ended at `time`; NaN at the start (dm_env's
            first TimeStep has no reward).
        led: (n, 3) LED colour (r, g, b in [0, 1]) at `time`.
        target: (n,) the arm's goal angle (rad) in follow tasks, else None.
        terminated: the episode left the task's safe set (discount 0) rather than running to
            its time limit.
        label: what ran, e.g. "mpc on qube/swingup, seed 0".
    """

    time: np.ndarray
    state: np.ndarray
    voltage: np.ndarray
    reward: np.ndarray
    led: np.ndarray
    target: np.ndarray | None = None
    terminated: bool = False
    label: str = ""

    @property
    def steps(self) -> int:
        """Control steps taken."""
        return len(self.time) - 1

    @property
    def episode_return(self) -> float:
        """Sum of the rewards."""
        return float(np.sum(self.reward[1:]))

    @property
    def duration(self) -> float:
        """Time from the start to the last reading (s)."""
        return float(self.time[-1])


class _Readings:
    """Rows of an `EpisodeTrace` being collected."""

    def __init__(self, environment: Any):
        self._environment = environment
        self._follows_target = getattr(environment.task, "follows_target", False)
        self.rows: list[tuple] = []

    def read(self, reward: float) -> None:
        physics, task = self._environment.physics, self._environment.task
        target = float(task.target) if self._follows_target else math.nan
        self.rows.append((physics.time(), physics.qube_state(), physics.voltage(), reward, physics.led(),
                          target))

    def trace(self, terminated: bool, label: str) -> EpisodeTrace:
        time, state, voltage, reward, led, target = zip(*self.rows, strict=True)
        return EpisodeTrace(time=np.array(time), state=np.array(state), voltage=np.array(voltage),
                            reward=np.array(reward, dtype=float), led=np.array(led),
                            target=np.array(target) if self._follows_target else None,
                            terminated=terminated, label=label)


def run_episode(environment: Any, policy: Policy, hooks: Iterable[StepHook] = (),
                label: str = "", seed: int | None = None) -> EpisodeTrace:
    """Reset `environment` (a qube_suite dm_env environment), run `policy` to the episode's end,
    and return the trace.

    Args:
        environment: from `suite.load`; its task's random state decides the start.
        policy: maps each dm_env observation to a motor voltage (V); `policy.reset()`,
            if it exists, is called first.
        hooks: each called as `hook(step, environment)` after the reset (step 0) and
            after every control step, e.g. to render frames or keep to real time.
        label: stored in the trace.
        seed: reseed the task's random state at the reset (`environment.reset(seed=...)`); None:
            go on from its present state.
    """
    hooks = tuple(hooks)
    if hasattr(policy, "reset"):
        policy.reset()
    readings = _Readings(environment)
    timestep = environment.reset() if seed is None else environment.reset(seed=seed)
    readings.read(math.nan)
    for hook in hooks:
        hook(0, environment)
    step = 0
    while not timestep.last():
        timestep = environment.step(policy(timestep.observation))
        step += 1
        readings.read(timestep.reward)
        for hook in hooks:
            hook(step, environment)
    return readings.trace(terminated=timestep.discount == 0.0, label=label)
