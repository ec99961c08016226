"""Gymnasium ids `QubeSuite/<Task>-v0`, registered when `qube_suite` is imported."""

from __future__ import annotations

from typing import Any

import gymnasium
from gymnasium.envs.registration import WrapperSpec

from qube_suite import suite
from qube_suite.arguments import check_keywords, keywords_of
from qube_suite.wrappers.gym_env import QubeEnv
from qube_suite.wrappers.vector_env import make_vector_env

NAMESPACE = "QubeSuite"


DOMAIN_SUFFIXES = {"qube": "", "qube_hardware": "Hardware"}
"""Domain name -> suffix of its Gymnasium ids."""


def gymnasium_id(task_name: str, domain_name: str = "qube") -> str:
    """`QubeSuite/SwingupSparse-v0` for ("swingup_sparse", "qube"); `...Hardware-v0` on hardware."""
    if domain_name not in DOMAIN_SUFFIXES:
        raise ValueError(f"unknown domain {domain_name!r}; valid domains: {', '.join(DOMAIN_SUFFIXES)}")
    task = "".join(part.capitalize() for part in task_name.split("_"))
    return f"{NAMESPACE}/{task}{DOMAIN_SUFFIXES[domain_name]}-v0"


GYMNASIUM_IDS: dict[str, str] = {gymnasium_id(task): task for task in suite.TASKS_BY_DOMAIN["qube"]}
"""Gymnasium id -> suite task name, simulated domain."""

HARDWARE_GYMNASIUM_IDS: dict[str, str] = {
    gymnasium_id(task, "qube_hardware"): task for task in suite.TASKS_BY_DOMAIN["qube_hardware"]}
"""Gymnasium id -> suite task name, hardware domain."""


def make_env(task: str, domain: str = "qube", render_mode: str | None = None, randomization: Any = None,
             domain_kwargs: dict[str, Any] | None = None, width: int = 640, height: int = 480,
             camera: str = "front_oblique", **kwargs) -> QubeEnv:
    """Entry point of the registered ids.

    `kwargs` go to the environment (`control_frequency`, `time_limit`) or the task
    (`voltage_limit`, `observation`, `random`); `domain_kwargs` as in `suite.load`. An
    unknown keyword is a TypeError (and a ValueError) listing the valid ones.
    """
    valid = keywords_of(make_env, skip=("task", "domain")) + suite.ENVIRONMENT_KWARGS + suite.TASK_KWARGS
    check_keywords(kwargs, valid, f"keyword arguments for {gymnasium_id(task, domain)}")
    environment_kwargs = {key: kwargs.pop(key) for key in suite.ENVIRONMENT_KWARGS if key in kwargs}
    environment = suite.load(domain, task, task_kwargs=kwargs, environment_kwargs=environment_kwargs,
                             randomization=randomization, domain_kwargs=domain_kwargs)
    return QubeEnv(environment, render_mode=render_mode, width=width, height=height, camera=camera)


CHECKS_BUILT_IN = {"order_enforce": False, "disable_env_checker": True}
"""`gymnasium.make` leaves out its `OrderEnforcing` and `PassiveEnvChecker` wrappers (about 1.5 us
of every step's 15): `QubeEnv` refuses to step before `reset` or after an episode's end itself,
and the test suite runs Gymnasium's full `check_env` on every id. `gymnasium.make(id,
disable_env_checker=False)` still adds the checker."""


HARDWARE_GUARD = WrapperSpec("StopMotorAtEpisodeEnd", "qube_suite.wrappers.gym_env:StopMotorAtEpisodeEnd", {})
"""Wrapped around every hardware id, outside `gymnasium.make`'s own wrappers (its `TimeLimit`): the
motor stops at once when one of them ends the episode or raises (`gym_env.StopMotorAtEpisodeEnd`)."""


def register_environments() -> None:
    """Register every id of `GYMNASIUM_IDS` (for `gymnasium.make` and `gymnasium.make_vec`) and of
    `HARDWARE_GYMNASIUM_IDS` (`gymnasium.make`), once."""
    for env_id, task in GYMNASIUM_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=make_env, vector_entry_point=make_vector_env,
                               kwargs={"task": task}, **CHECKS_BUILT_IN)
    for env_id, task in HARDWARE_GYMNASIUM_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=make_env, nondeterministic=True,
                               kwargs={"task": task, "domain": "qube_hardware"},
                               additional_wrappers=(HARDWARE_GUARD,), **CHECKS_BUILT_IN)
