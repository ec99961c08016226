"""Load Qube environments by domain and task name, like `dm_control.suite`.

    from qube_suite import suite
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from qube_suite.environment import DEFAULT_CONTROL_FREQUENCY, Environment
from qube_suite.tasks import SUITE as _TASKS

_DOMAIN_MODULES = {
    "qube": "qube_suite.domains.qube",
}
"""Domain name -> module with `make_physics(control_frequency, parameters)`."""

ENVIRONMENT_KWARGS = ("control_frequency", "time_limit")
"""Keys `environment_kwargs` may hold."""

TASKS_BY_DOMAIN: dict[str, tuple[str, ...]] = {domain: tuple(_TASKS) for domain in _DOMAIN_MODULES}
"""Domain name -> names of its tasks."""

ALL_TASKS: tuple[tuple[str, str], ...] = tuple(
    (domain, task) for domain, tasks in TASKS_BY_DOMAIN.items() for task in tasks)
"""Every (domain, task) pair."""


def _tagged(tag: str) -> tuple[tuple[str, str], ...]:
    return tuple((domain, task) for domain in _DOMAIN_MODULES for task in _TASKS.tagged(tag))


BENCHMARKING = _tagged("benchmarking")
"""The dense tasks."""
SPARSE = _tagged("sparse")
"""The sparse-reward variants."""
FOLLOW = _tagged("follow")
"""The tasks with a moving arm target."""


def load(domain_name: str, task_name: str, task_kwargs: Mapping[str, Any] | None = None,
         environment_kwargs: Mapping[str, Any] | None = None,
         randomization: Any = None) -> Environment:
    """A `dm_env` environment for `task_name` on `domain_name`.

    Args:
        domain_name: "qube" (MuJoCo simulation).
        task_name: one of `TASKS_BY_DOMAIN[domain_name]`.
        task_kwargs: passed to the task: `random` (seed), `voltage_limit` (V),
            `observation` ("state" or "trig").
        environment_kwargs: `control_frequency` (Hz, default 250) and
            `time_limit` (s, default 8.192).
        randomization: domain randomization drawn at every reset: a preset name
            ("none", "mild", "moderate", "sim2real"), a config mapping, the path of
            a YAML file, or a `qube_suite.randomization.Randomization`; None: off.

    Raises:
        ValueError: unknown names or invalid arguments; the message lists valid values.
    """
    if domain_name not in _DOMAIN_MODULES:
        raise ValueError(f"unknown domain {domain_name!r}; valid domains: {', '.join(_DOMAIN_MODULES)}")
    if task_name not in TASKS_BY_DOMAIN[domain_name]:
        raise ValueError(f"unknown task {task_name!r} for domain {domain_name!r}; valid tasks: "
                         f"{', '.join(TASKS_BY_DOMAIN[domain_name])}")
    environment_kwargs = dict(environment_kwargs or {})
    unknown = set(environment_kwargs) - set(ENVIRONMENT_KWARGS)
    if unknown:
        raise ValueError(f"unknown environment_kwargs {sorted(unknown)}; "
                         f"valid: {', '.join(ENVIRONMENT_KWARGS)}")
    task = _TASKS[task_name](**dict(task_kwargs or {}))
    domain = importlib.import_module(_DOMAIN_MODULES[domain_name])
    frequency = environment_kwargs.get("control_frequency", DEFAULT_CONTROL_FREQUENCY)
    physics = domain.make_physics(control_frequency=frequency)
    return Environment(physics, task, randomization=randomization, **environment_kwargs)
