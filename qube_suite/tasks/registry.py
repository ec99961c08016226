"""The registry of task factories, tagged like dm_control's suites, with the keywords each takes."""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable

from dm_control.utils import containers

from qube_suite.tasks.batch_safety import check_batch_safety

NOT_TASK_KEYWORDS = ("worlds", "sparse")
"""Constructor arguments that are no task keyword: `worlds` is the vector environment's (a batch of
N Qubes), `sparse` a variant's (the separate task `<task>_sparse`)."""

_BY_KEYWORD = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)


class TaskSuite(containers.TaggedTasks):
    """Task name -> factory returning a task, tagged (dm_control's `TaggedTasks`).

    `register` adds a factory after checking that its task is batch-safe and that its
    keywords can be read (`keywords`); whoever `subscribe`s hears of every task, those
    registered before and after (the Gymnasium registration gives each its ids).
    """

    def __init__(self, probe: type | None = None, probe_states=None):
        """`probe`, `probe_states`: how `check_batch_safety` stands in for the device's domain
        (default: the pendulum's)."""
        super().__init__()
        self._listeners: list[Callable[[str], None]] = []
        self._probe = {"probe": probe, "probe_states": probe_states}

    def register(self, *tags: str) -> Callable[[Callable], Callable]:
        """Decorator registering a task factory under its function's name, with `tags`.

        The factory takes the task keywords and `worlds` and returns the task; a factory
        that passes `**kwargs` on names its task class in its return annotation (`-> MyTask`),
        whose constructors then say which keywords it takes. It is registered only if its
        task is batch-safe (`check_batch_safety`), else `BatchSafetyError` names the method
        at fault. A registered task loads by name at once: `suite.load("qube", name)`,
        `gymnasium.make("QubeSuite/<Name>-v0")`, `QubeVectorEnv(name, N)`.
        """
        def add(factory: Callable) -> Callable:
            check_batch_safety(factory, name=factory.__name__, **self._probe)
            task_keywords(factory)  # raises if they cannot be read
            self.add(*tags)(factory)
            for listener in self._listeners:
                listener(factory.__name__)
            return factory
        return add

    def keywords(self, name: str) -> tuple[str, ...]:
        """The keywords task `name` takes (`task_keywords` of its factory)."""
        return task_keywords(self[name])

    def subscribe(self, listener: Callable[[str], None]) -> None:
        """Call `listener(name)` for every registered task, now and whenever one is registered."""
        self._listeners.append(listener)
        for name in self:
            listener(name)


def task_keywords(factory: Callable) -> tuple[str, ...]:
    """The keywords a task factory (a function or a task class) takes, less `NOT_TASK_KEYWORDS`.

    They are read from its signature, and where it passes `**kwargs` on, from the
    constructors of the task class it returns (its return annotation), up the class's
    bases while each constructor passes `**kwargs` on. Raises TypeError if a factory
    passes `**kwargs` on without naming its task class.
    """
    names: list[str] = []
    if isinstance(factory, type):
        task_class = factory
    else:
        if not _add_keywords(factory, names):
            return _task_keywords(names)
        try:
            task_class = typing.get_type_hints(factory).get("return")
        except NameError:  # an annotation naming a class out of the factory's module's reach
            task_class = None
        if not isinstance(task_class, type):
            raise TypeError(f"task factory {factory.__name__!r} passes **kwargs on: annotate the task "
                            f"class it returns (def {factory.__name__}(**kwargs) -> MyTask) so that its "
                            "keywords can be checked")
    for cls in task_class.__mro__:
        if "__init__" in vars(cls) and not _add_keywords(vars(cls)["__init__"], names):
            break
    return _task_keywords(names)


def _add_keywords(function: Callable, names: list[str]) -> bool:
    """Append to `names` the keywords `function` takes that are not there yet; whether it takes
    `**kwargs`."""
    parameters = list(inspect.signature(function).parameters.values())
    names.extend(parameter.name for parameter in parameters if parameter.kind in _BY_KEYWORD
                 and parameter.name not in names and parameter.name != "self")
    return any(parameter.kind is inspect.Parameter.VAR_KEYWORD for parameter in parameters)


def _task_keywords(names: list[str]) -> tuple[str, ...]:
    return tuple(name for name in names if name not in NOT_TASK_KEYWORDS)


SUITE = TaskSuite()
"""The Qube pendulum's tasks; tags: benchmarking, sparse, follow."""

register = SUITE.register
"""Decorator registering a Qube task factory (`TaskSuite.register`)."""
