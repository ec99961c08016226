"""Gymnasium ids `QubeSuite/<Task>-v0`, registered when `qube_suite` is imported."""

from __future__ import annotations

from typing import Any

import gymnasium

from qube_suite import suite
from qube_suite.wrappers.gym_env import QubeEnv
from qube_suite.wrappers.vector_env import make_vector_env

NAMESPACE = "QubeSuite"


def gymnasium_id(task_name: str) -> str:
    """`QubeSuite/SwingupSparse-v0` for "swingup_sparse"."""
    return f"{NAMESPACE}/{''.join(part.capitalize() for part in task_name.split('_'))}-v0"


GYMNASIUM_IDS: dict[str, str] = {gymnasium_id(task): task for task in suite.TASKS_BY_DOMAIN["qube"]}
"""Gymnasium id -> suite task name."""


def make_env(task: str, domain: str = "qube", render_mode: str | None = None, randomization: Any = None,
             width: int = 640, height: int = 480, camera: str = "front_oblique", **kwargs) -> QubeEnv:
    """Entry point of the registered ids.

    `kwargs` go to the environment (`control_frequency`, `time_limit`) or the task
    (`voltage_limit`, `observation`, ...).
    """
    environment_kwargs = {key: kwargs.pop(key) for key in suite.ENVIRONMENT_KWARGS if key in kwargs}
    environment = suite.load(domain, task, task_kwargs=kwargs, environment_kwargs=environment_kwargs,
                             randomization=randomization)
    return QubeEnv(environment, render_mode=render_mode, width=width, height=height, camera=camera)


def register_environments() -> None:
    """Register every id in `GYMNASIUM_IDS` (once), for `gymnasium.make` and `gymnasium.make_vec`."""
    for env_id, task in GYMNASIUM_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=make_env, vector_entry_point=make_vector_env,
                               kwargs={"task": task})
