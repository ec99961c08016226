"""The registry of task factories, tagged like dm_control's suites."""

from __future__ import annotations

from collections.abc import Callable

from dm_control.utils import containers

from qube_suite.tasks.batch_safety import check_batch_safety

SUITE = containers.TaggedTasks()
"""Task name -> factory returning a task; tags: benchmarking, sparse, follow."""


def register(*tags: str) -> Callable[[Callable], Callable]:
    """Decorator registering a task factory in `SUITE` under its function's name, with `tags`.

    The factory takes the task keywords (`random`, `voltage_limit`, `observation`,
    `worlds`, ...) and returns the task. It is registered only if its task is batch-safe
    (`qube_suite.tasks.batch_safety.check_batch_safety`), else `BatchSafetyError` names the
    method at fault. Registered tasks load by name: `suite.load("qube", name)`,
    `QubeVectorEnv(name, N)`.
    """
    def add(factory: Callable) -> Callable:
        check_batch_safety(factory, name=factory.__name__)
        return SUITE.add(*tags)(factory)
    return add
