"""Score any policy on any task and domain.

    from qube_suite import evaluate
    result = evaluate("balance", domain="qube", task="balance", episodes=20, seed=0)
    result.mean_return, result.success_rate

Success is the task's own rule (`QubeTask.at_goal` at every step, `QubeTask.succeeded`
at the episode's end; documented in docs/controllers.md):
  * swing-up and balance tasks: not terminated, and the pendulum within 10 degrees
    of upright throughout the final 2 s;
  * dampen tasks: not terminated, and the pendulum within 10 degrees of hanging
    throughout the final 2 s;
  * rotor: at least 5 net revolutions.

On a board, an episode whose reset could not reach its start (`ResetError`: the reset
controllers gave up within the reset timeout, motor stopped) never ran: it counts as failed,
with return 0, its index is listed in `failed_resets`, and the next episode resets again
(`start_or_fail`, the rule of every episode loop that scores episodes).

Follow tasks also report how well the arm follows its target: the mean of
|theta - theta_target| (rad) over every step after an episode's first 2 s (the
return hides it: the arm's share of the reward is small).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from typing import Any

import dm_env
import numpy as np

from qube_suite import baselines, devices, recording, suite
from qube_suite.hardware.errors import ResetError
from qube_suite.policies import load_policy, names_a_policy, shipped
from qube_suite.progress import Progress
from qube_suite.tasks.base import success_steps


@dataclasses.dataclass
class EvaluationResult:
    """Returns and success over seeded episodes; compute per step for controllers: the wall-clock
    time of each policy call and the CPU time of the calling thread during it (s), which leaves
    out the time other processes hold the CPU."""

    domain: str
    task: str
    policy: str
    episodes: int
    seed: int
    returns: list[float]
    successes: list[bool]
    step_times: np.ndarray = dataclasses.field(repr=False)
    step_cpu_times: np.ndarray = dataclasses.field(repr=False)
    follow_error: float | None = None
    """Mean |theta - theta_target| (rad) over the steps after each episode's first 2 s; None for a
    task without a target or when no episode lasted 2 s."""
    failed_resets: list[int] = dataclasses.field(default_factory=list)
    """Episodes (0: the first) whose reset could not reach the start: failed, return 0."""

    @property
    def mean_return(self) -> float:
        return float(np.mean(self.returns))

    @property
    def std_return(self) -> float:
        return float(np.std(self.returns))

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.successes))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary; step times in milliseconds (None when no episode took a step)."""
        stepped = len(self.step_times) > 0
        return {
            "domain": self.domain, "task": self.task, "policy": self.policy,
            "episodes": self.episodes, "seed": self.seed,
            "mean_return": self.mean_return, "std_return": self.std_return,
            "success_rate": self.success_rate, "returns": self.returns,
            "follow_error": self.follow_error, "failed_resets": self.failed_resets,
            "step_time_median_ms": float(np.median(self.step_times) * 1e3) if stepped else None,
            "step_time_p99_ms": float(np.percentile(self.step_times, 99) * 1e3) if stepped else None,
            "step_cpu_time_p99_ms": float(np.percentile(self.step_cpu_times, 99) * 1e3) if stepped else None,
        }


FAILED_RESET_RETURN = 0.0
"""Return of an episode whose reset could not reach its start: it never ran."""


def start_or_fail(environment) -> dm_env.TimeStep | None:
    """`environment.reset()`'s first TimeStep, or None when a board's reset could not reach the
    episode's start (`ResetError`; the motor is already stopped and the next reset drives again).
    The caller counts that episode as failed, with return `FAILED_RESET_RETURN`."""
    try:
        return environment.reset()
    except ResetError:
        return None


def policy_for(spec: str, environment, domain: str = "qube") -> Callable[[Any], float]:
    """The policy `spec` names, for a suite `environment` of `domain`: a controller of the domain's
    device (`baselines.names(domain)`) built by its `for_environment`, a shipped learned
    policy ("ppo:balance") or the path of a policy file (.npz). Raises ValueError naming the valid ones."""
    controllers = devices.domain(domain).device.controller_module()
    if spec in controllers.CONTROLLERS:
        return controllers.for_environment(spec, environment)
    if names_a_policy(spec):
        policy = load_policy(spec)
        policy.observation_layout = environment.task.observation_layout
        return policy
    raise ValueError(f"unknown controller or policy {spec!r}: valid controllers are "
                     f"{', '.join(controllers.CONTROLLERS)}; shipped policies "
                     f"{', '.join(shipped()) or 'none'}; or give the path of a .npz policy file")


def meant_for(policy: str | Callable[[Any], float]) -> tuple[str, ...]:
    """The tasks a controller (by name), learned policy (by name or file) or policy object is
    meant for; () for any task, or for a name `policy_for` will refuse."""
    if isinstance(policy, str):
        if policy in baselines.names():
            return tuple(getattr(baselines.names()[policy], "tasks", ()))
        if not names_a_policy(policy):
            return ()
        policy = load_policy(policy)
    return tuple(getattr(policy, "tasks", ()))


def evaluate(policy: str | Callable[[Any], float], domain: str = "qube", task: str = "swingup",
             episodes: int = 20, seed: int = 0, randomization: Any = None,
             task_kwargs: dict[str, Any] | None = None, environment_kwargs: dict[str, Any] | None = None,
             progress: bool = False, domain_kwargs: dict[str, Any] | None = None,
             record: str | os.PathLike | None = None) -> EvaluationResult:
    """Run `episodes` episodes (seeds `seed`, `seed + 1`, ...) of `policy` and score them.

    Args:
        policy: a controller name from `qube_suite.devices.qube.controllers.CONTROLLERS` (built by
            `baselines.for_environment`: the environment's control frequency, voltage
            limit and latency), a learned policy for `qube_suite.policies.load_policy`
            ("ppo:balance" or a policy file's path), or any callable mapping a dm_env
            observation to a voltage (with an optional `reset()` called before each episode).
        domain, task, randomization, task_kwargs, environment_kwargs, domain_kwargs: as
            `suite.load` (e.g. `domain_kwargs={"plant": {...}}` for the hardware substitute).
        progress: show progress on stderr (`qube_suite.progress`: a bar on a terminal,
            a line per 10 % otherwise).
        record: write every step to this file as it runs (`qube_suite.recording`).

    The environment is closed at the end, also when the policy raises or Ctrl-C lands: on
    hardware the motor stops and the board closes.
    """
    if not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    environment = suite.load(domain, task, task_kwargs={"random": seed, **(task_kwargs or {})},
                             environment_kwargs=environment_kwargs, randomization=randomization,
                             domain_kwargs=domain_kwargs)
    recorder = None
    try:  # on hardware, whatever happens, the motor stops and the board closes
        if record is not None:
            recorder = recording.Recorder(record, environment, metadata={
                "domain": domain, "task": task, "policy": policy if isinstance(policy, str) else None})
        return _evaluate(policy, environment, domain, task, episodes, seed, progress)
    finally:
        if recorder is not None:
            recorder.close()
        environment.close()


def _evaluate(policy, environment, domain: str, task: str, episodes: int, seed: int,
              progress: bool) -> EvaluationResult:
    name = policy if isinstance(policy, str) else getattr(policy, "name", type(policy).__name__)
    if isinstance(policy, str):
        policy = policy_for(policy, environment, domain)
    follows_target = environment.task.follows_target
    settled = success_steps(environment.control_frequency)
    returns, successes, step_times, step_cpu_times = [], [], [], []
    arm_errors, failed_resets = [], []
    bar = Progress(episodes, "episode", f"{name} on {domain}/{task}", quiet=not progress)
    try:
        for episode in range(episodes):
            environment.task.random.seed(seed + episode)
            if hasattr(policy, "reset"):
                policy.reset()
            timestep = start_or_fail(environment)
            if timestep is None:
                returns.append(FAILED_RESET_RETURN)
                successes.append(False)
                failed_resets.append(episode)
                bar.update()
                continue
            episode_return, at_goal = 0.0, []
            while not timestep.last():
                start, cpu_start = time.perf_counter(), time.thread_time()
                action = policy(timestep.observation)
                step_times.append(time.perf_counter() - start)
                step_cpu_times.append(time.thread_time() - cpu_start)
                timestep = environment.step(action)
                episode_return += timestep.reward
                at_goal.append(environment.task.at_goal(environment.physics))
                if follows_target and len(at_goal) > settled:
                    arm_errors.append(abs(environment.physics.arm_angle() - environment.task.target))
            returns.append(float(episode_return))
            successes.append(environment.task.succeeded(np.array(at_goal), timestep.discount == 0.0,
                                                        environment.control_frequency))
            bar.set_postfix(mean_return=f"{np.mean(returns):.1f}")
            bar.update()
    finally:
        bar.close()
        if hasattr(policy, "close"):
            policy.close()
    return EvaluationResult(domain, task, name, episodes, seed, returns, successes, np.array(step_times),
                            np.array(step_cpu_times), float(np.mean(arm_errors)) if arm_errors else None,
                            failed_resets)
