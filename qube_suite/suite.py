"""Load Qube environments by domain and task name, like `dm_control.suite`.

    from qube_suite import suite
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Mapping
from typing import Any

from qube_suite.arguments import check_keywords, keywords_of
from qube_suite.environment import DEFAULT_CONTROL_FREQUENCY, Environment
from qube_suite.tasks import SUITE as _TASKS
from qube_suite.tasks import QubeTask
from qube_suite.tasks.follow import SCHEDULE_KEYWORDS

_DOMAIN_MODULES = {
    "qube": "qube_suite.domains.qube",
    "qube_hardware": "qube_suite.domains.qube_hardware",
}
"""Domain name -> module with `make_physics(control_frequency, **domain_kwargs)` and the tuple
`DOMAIN_KWARGS` of the keys `domain_kwargs` may hold."""

ENVIRONMENT_KWARGS = ("control_frequency", "time_limit", "flat_observation")
"""Keys `environment_kwargs` may hold."""

TASK_KWARGS = keywords_of(QubeTask, skip=("worlds",)) + SCHEDULE_KEYWORDS
"""Keys `task_kwargs` may hold (every task takes the same, but for the target schedule's, which only
the follow tasks take; sparse variants are separate tasks)."""

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
REWARD_VIZ = tuple((domain, task) for domain, task in BENCHMARKING if domain == "qube")
"""The tasks whose `visualize_reward` dm_control's suite tests check (in simulation; every task and the
hardware domain's digital twin have it too): the pendulum's colour blends with the reward."""


def load(domain_name: str, task_name: str, task_kwargs: Mapping[str, Any] | None = None,
         environment_kwargs: Mapping[str, Any] | None = None,
         randomization: Any = None, domain_kwargs: Mapping[str, Any] | None = None) -> Environment:
    """A `dm_env` environment for `task_name` on `domain_name`.

    Args:
        domain_name: "qube" (MuJoCo simulation) or "qube_hardware" (a Quanser
            board: the compiled substitute by default, or a real Qube).
        task_name: one of `TASKS_BY_DOMAIN[domain_name]`.
        task_kwargs: passed to the task: `random` (seed), `voltage_limit` (V),
            `observation` ("state" or "trig"); in follow tasks, the target schedule
            (`target`, `target_amplitude`, ...: see `qube_suite.tasks.follow`).
        environment_kwargs: `control_frequency` (Hz, default 250), `time_limit` (s,
            default 8.192) and `flat_observation` (dm_control's: one concatenated
            array under the key "observations").
        domain_kwargs: passed to the domain: for "qube", `parameters` (physical
            parameters by long name); for "qube_hardware", `board`, `device`, `plant`,
            `realtime`, `max_voltage`, `reset_voltage_limit`, `reset_timeout`,
            `identifier`, `check_encoders`, `zero_encoders` and `parameters` (this
            Qube's, e.g. a calibration: its reset controllers are designed for them;
            see `qube_suite.domains.qube_hardware.Physics`).
        randomization: domain randomization drawn at every reset: a preset name
            ("none", "mild", "moderate", "sim2real"), a config mapping, the path of
            a YAML file, or a `qube_suite.randomization.Randomization`; None: off.

    Raises:
        ValueError: unknown names or invalid arguments; the message lists valid values
            (an unknown keyword is also a TypeError).
    """
    task = make_task(domain_name, task_name, task_kwargs)
    environment_kwargs = dict(environment_kwargs or {})
    check_keywords(environment_kwargs, ENVIRONMENT_KWARGS, "environment_kwargs")
    domain = importlib.import_module(_DOMAIN_MODULES[domain_name])
    domain_kwargs = dict(domain_kwargs or {})
    check_keywords(domain_kwargs, domain.DOMAIN_KWARGS, f"domain_kwargs of domain {domain_name!r}")
    frequency = environment_kwargs.get("control_frequency", DEFAULT_CONTROL_FREQUENCY)
    physics = domain.make_physics(control_frequency=frequency, **domain_kwargs)
    if hasattr(physics, "set_reset_controllers"):
        _hand_reset_controllers(physics)
    board_limit = getattr(physics, "max_voltage", math.inf)
    if task.voltage_limit > board_limit:
        physics.close()
        raise ValueError(f"the task's voltage_limit of {task.voltage_limit:g} V exceeds the board's "
                         f"max_voltage of {board_limit:g} V; lower voltage_limit or raise max_voltage")
    return Environment(physics, task, randomization=randomization, **environment_kwargs)


def _hand_reset_controllers(physics) -> None:
    """Give a hardware domain the controllers that reach its episodes' starts. Domains never import
    controllers, so they are built here, for the domain's own Qube (its device's motor and the
    `parameters` or calibration it was given), before its board first samples."""
    from qube_suite import baselines

    settings = physics.reset_controller_settings()
    physics.set_reset_controllers({name: baselines.make(name, **settings)
                                   for name in physics.reset_controller_names})


def make_task(domain_name: str, task_name: str, task_kwargs: Mapping[str, Any] | None = None,
              worlds: int | None = None) -> QubeTask:
    """The task `task_name` of `domain_name`, made with `task_kwargs` (see `load`).

    `worlds`: None for one Qube, or N for a task evaluating a batch of N Qubes (the
    vector environment's; `random` then seeds world i with `random + i`).

    Raises:
        ValueError: unknown names or invalid arguments; the message lists valid values.
    """
    if domain_name not in _DOMAIN_MODULES:
        raise ValueError(f"unknown domain {domain_name!r}; valid domains: {', '.join(_DOMAIN_MODULES)}")
    if task_name not in _TASKS:  # the registry as it is now: tasks registered after import too
        raise ValueError(f"unknown task {task_name!r} for domain {domain_name!r}; valid tasks: "
                         f"{', '.join(_TASKS)}")
    task_kwargs = dict(task_kwargs or {})
    check_keywords(task_kwargs, TASK_KWARGS, "task_kwargs")
    schedule = sorted(set(task_kwargs) & set(SCHEDULE_KEYWORDS))
    if schedule and task_name not in _TASKS.tagged("follow"):
        raise ValueError(f"{', '.join(schedule)}: only the follow tasks "
                         f"({', '.join(_TASKS.tagged('follow'))}) have a target schedule")
    if worlds is not None:
        task_kwargs["worlds"] = worlds
    return _TASKS[task_name](**task_kwargs)
