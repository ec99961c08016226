"""Load Qube environments by domain and task name, like `dm_control.suite`.

    from qube_suite import suite
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

from qube_suite import devices
from qube_suite.arguments import check_keywords
from qube_suite.capabilities import HasBoard, NeedsResetControllers
from qube_suite.environment import DEFAULT_CONTROL_FREQUENCY, Environment
from qube_suite.tasks import QubeTask

ENVIRONMENT_KWARGS = ("control_frequency", "time_limit", "flat_observation")
"""Keys `environment_kwargs` may hold."""


class _TasksByDomain(Mapping):
    """Domain name -> names of its tasks, read from the device registry at every lookup: a task
    registered after import is there."""

    def __getitem__(self, domain_name: str) -> tuple[str, ...]:
        return devices.domain(domain_name).task_names()

    def __iter__(self) -> Iterator[str]:
        return iter(devices.domains())

    def __len__(self) -> int:
        return len(devices.domains())


TASKS_BY_DOMAIN: Mapping[str, tuple[str, ...]] = _TasksByDomain()
"""Domain name -> names of its tasks (the tasks registered so far)."""


def tagged(tag: str) -> tuple[tuple[str, str], ...]:
    """Every (domain, task) pair whose task has `tag` ("benchmarking", "sparse", "follow")."""
    return tuple((name, task) for name, domain in devices.domains().items()
                 for task in domain.device.task_suite().tagged(tag))


_PAIRS = {
    "ALL_TASKS": lambda: tuple((domain, task) for domain, tasks in TASKS_BY_DOMAIN.items() for task in tasks),
    "BENCHMARKING": lambda: tagged("benchmarking"),
    "SPARSE": lambda: tagged("sparse"),
    "FOLLOW": lambda: tagged("follow"),
    "REWARD_VIZ": lambda: tuple(pair for pair in tagged("benchmarking") if pair[0] == "qube"),
}
"""dm_control's tuples of (domain, task) pairs, read at every access: `ALL_TASKS`, `BENCHMARKING` (the
dense tasks), `SPARSE` (the sparse-reward variants), `FOLLOW` (the tasks with a moving arm target),
`REWARD_VIZ` (the tasks whose `visualize_reward` dm_control's suite tests check, in simulation; every
task and the hardware domain's digital twin have it too: the pendulum's colour blends with the reward)."""


def __getattr__(name: str):
    if name in _PAIRS:
        return _PAIRS[name]()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def load(domain_name: str, task_name: str, task_kwargs: Mapping[str, Any] | None = None,
         environment_kwargs: Mapping[str, Any] | None = None,
         randomization: Any = None, domain_kwargs: Mapping[str, Any] | None = None) -> Environment:
    """A `dm_env` environment for `task_name` on `domain_name`.

    Args:
        domain_name: "qube" (MuJoCo simulation) or "qube_hardware" (a Quanser
            board: the compiled substitute by default, or a real Qube); every device's
            domains are in `qube_suite.devices.domains()`.
        task_name: one of `TASKS_BY_DOMAIN[domain_name]`.
        task_kwargs: passed to the task's factory, which says which it takes
            (`TaskSuite.keywords`): `random` (seed), `voltage_limit` (V), `observation`
            ("state" or "trig"); in follow tasks, the target schedule (`target`,
            `target_amplitude`, ...: see `qube_suite.tasks.follow`).
        environment_kwargs: `control_frequency` (Hz, default 250), `time_limit` (s,
            default 8.192) and `flat_observation` (dm_control's: one concatenated
            array under the key "observations").
        domain_kwargs: passed to the domain: for "qube", `parameters` (physical
            parameters by long name); for "qube_hardware", `board`, `device`, `plant`,
            `realtime`, `max_voltage`, `reset_voltage_limit`, `reset_timeout`,
            `identifier`, `check_encoders`, `zero_encoders` and `parameters` (this
            Qube's, e.g. a calibration: its reset controllers are designed for them;
            see `qube_suite.devices.qube.hardware.Physics`).
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
    domain = devices.domain(domain_name).module()
    domain_kwargs = dict(domain_kwargs or {})
    check_keywords(domain_kwargs, domain.DOMAIN_KWARGS, f"domain_kwargs of domain {domain_name!r}")
    frequency = environment_kwargs.get("control_frequency", DEFAULT_CONTROL_FREQUENCY)
    physics = domain.make_physics(control_frequency=frequency, **domain_kwargs)
    if isinstance(physics, NeedsResetControllers):
        _hand_reset_controllers(physics)
    board_limit = physics.max_voltage if isinstance(physics, HasBoard) else math.inf
    if task.voltage_limit > board_limit:
        physics.close()
        raise ValueError(f"the task's voltage_limit of {task.voltage_limit:g} V exceeds the board's "
                         f"max_voltage of {board_limit:g} V; lower voltage_limit or raise max_voltage")
    return Environment(physics, task, randomization=randomization, **environment_kwargs)


def _hand_reset_controllers(physics: NeedsResetControllers) -> None:
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
    task_kwargs = dict(task_kwargs or {})
    check_keywords(task_kwargs, task_keywords(domain_name, task_name), f"task_kwargs of task {task_name!r}")
    if worlds is not None:
        task_kwargs["worlds"] = worlds
    return devices.domain(domain_name).device.task_suite()[task_name](**task_kwargs)


def task_keywords(domain_name: str, task_name: str) -> tuple[str, ...]:
    """The keywords `task_kwargs` may hold for `task_name` of `domain_name`: those its factory takes
    (`qube_suite.tasks.registry.task_keywords`).

    Raises:
        ValueError: an unknown domain or task; the message lists the valid ones.
    """
    tasks = devices.domain(domain_name).device.task_suite()
    if task_name not in tasks:
        raise ValueError(f"unknown task {task_name!r} for domain {domain_name!r}; valid tasks: "
                         f"{', '.join(tasks)}")
    return tasks.keywords(task_name)
