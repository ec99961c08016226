"""Gymnasium ids `QubeSuite/<Task>-v0`, registered when `qube_suite` is imported."""

from __future__ import annotations

import functools
from collections.abc import Iterator, Mapping
from typing import Any

import gymnasium
from gymnasium.envs.registration import WrapperSpec

from qube_suite import devices, suite
from qube_suite.arguments import check_keywords, keywords_of
from qube_suite.wrappers.gym_env import QubeEnv
from qube_suite.wrappers.vector_env import make_vector_env

NAMESPACE = "QubeSuite"

HARDWARE_SUFFIX = "Hardware"
"""Suffix of the ids on a device's hardware domain."""


def gymnasium_id(task_name: str, domain_name: str = "qube") -> str:
    """`QubeSuite/SwingupSparse-v0` for ("swingup_sparse", "qube"); `...Hardware-v0` on hardware; a device's
    `gymnasium_prefix` before the task's name."""
    domain = devices.domain(domain_name)
    task = "".join(part.capitalize() for part in task_name.split("_"))
    suffix = HARDWARE_SUFFIX if domain.hardware else ""
    return f"{NAMESPACE}/{domain.device.gymnasium_prefix}{task}{suffix}-v0"


class _GymnasiumIds(Mapping):
    """Gymnasium id -> suite task name, of every device's simulated (or hardware) domain, read from the
    registries at every lookup: a task registered after import is there."""

    def __init__(self, hardware: bool):
        self._hardware = hardware

    def _ids(self) -> dict[str, str]:
        return {gymnasium_id(task, name): task for name, domain in devices.domains().items()
                if domain.hardware == self._hardware for task in domain.task_names()}

    def __getitem__(self, env_id: str) -> str:
        return self._ids()[env_id]

    def __iter__(self) -> Iterator[str]:
        return iter(self._ids())

    def __len__(self) -> int:
        return len(self._ids())


GYMNASIUM_IDS: Mapping[str, str] = _GymnasiumIds(hardware=False)
"""Gymnasium id -> suite task name, simulated domains."""

HARDWARE_GYMNASIUM_IDS: Mapping[str, str] = _GymnasiumIds(hardware=True)
"""Gymnasium id -> suite task name, hardware domains."""


def make_env(task: str, domain: str = "qube", render_mode: str | None = None, randomization: Any = None,
             domain_kwargs: dict[str, Any] | None = None, width: int = 640, height: int = 480,
             camera: str = "front_oblique", **kwargs) -> QubeEnv:
    """Entry point of the registered ids.

    `kwargs` go to the environment (`control_frequency`, `time_limit`) or the task
    (`voltage_limit`, `observation`, `random`); `domain_kwargs` as in `suite.load`. An
    unknown keyword is a TypeError (and a ValueError) listing the valid ones.
    """
    valid = keywords_of(make_env, skip=("task", "domain")) + suite.ENVIRONMENT_KWARGS + suite.task_keywords(
        domain, task)
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
    """Register every task of every device under its ids, now and whenever a task is registered
    later: on the simulated domain for `gymnasium.make` and `gymnasium.make_vec`, on the hardware
    domain for `gymnasium.make`. Calling it again does nothing."""
    for device in devices.devices().values():
        if device.name not in _SUBSCRIBED:
            _SUBSCRIBED.add(device.name)
            device.task_suite().subscribe(functools.partial(_register_task, device))


_SUBSCRIBED: set[str] = set()
"""Devices whose task registries `register_environments` listens to."""


def _register_task(device: devices.Device, task: str) -> None:
    """Register `task` of `device` on its two domains (an id already taken is left as it is)."""
    simulation, hardware = device.domain_names
    env_id = gymnasium_id(task, simulation)
    if env_id not in gymnasium.registry:
        vector = {} if device.batch is None else {"vector_entry_point": make_vector_env}
        gymnasium.register(env_id, entry_point=make_env, kwargs={"task": task, "domain": simulation},
                           **vector, **CHECKS_BUILT_IN)
    env_id = gymnasium_id(task, hardware)
    if env_id not in gymnasium.registry:
        gymnasium.register(env_id, entry_point=make_env, nondeterministic=True,
                           kwargs={"task": task, "domain": hardware},
                           additional_wrappers=(HARDWARE_GUARD,), **CHECKS_BUILT_IN)
