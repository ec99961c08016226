"""The Qube's episode rules, written once for one Qube and for a batch of Qubes.

After the domain has held the action's voltage for a control period, `judge_step`
advances the task's processes and says what the step earned and whether the episode
ends. It works elementwise: on floats and bools for one Qube (`Environment`) and on
arrays with one value per world for a batch (`QubeVectorEnv`), which then differ only
in how they report the result (dm_env's discount, Gymnasium's flags, autoreset).

The rules:

* a step in which the simulation diverged (and was undone) earns 0 and terminates;
* the episode terminates (discount 0) when the Qube leaves the task's safe set
  (`task.in_safe_set`);
* it is truncated (discount 1) after `episode_steps` steps unless it terminated.

The action's check, clipping and application are the task's `before_step`
(`qube_suite.tasks.base.voltage_from_action`), called by both environments before
anything moves.
"""

from __future__ import annotations

from qube_suite.tasks.elementwise import where


def judge_step(task, physics, diverged, step_count, episode_steps: int):
    """Advance `task`'s processes and judge the control step `physics` has just taken.

    Args:
        task: a `qube_suite.tasks.QubeTask` (made with `worlds=N` for a batch).
        physics: the Qube, or the batch of Qubes, after the step.
        diverged: whether the step was undone because the simulation diverged (bool, or
            one per world).
        step_count: control steps taken in the episode, this one included (int, or one
            per world).
        episode_steps: control steps in a full-length episode.

    Returns:
        (reward, terminated, truncated): a float and two bools for one Qube, arrays with
        one value per world for a batch.
    """
    task.after_step(physics)
    reward = where(diverged, 0.0, task.get_reward(physics))
    terminated = (task.in_safe_set(physics) ^ True) | diverged  # `^ True`: `not` for bools and bool arrays
    truncated = (step_count >= episode_steps) & (terminated ^ True)
    return reward, terminated, truncated
