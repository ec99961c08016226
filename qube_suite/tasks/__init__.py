"""What every device's tasks share: the task base, the registry, the batch-safety rule, the
follow targets' schedules. The pendulum's tasks are in `qube_suite.devices.qube.tasks`."""

from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.batch_safety import BatchSafetyError, check_batch_safety
from qube_suite.tasks.registry import SUITE, TaskSuite, register

__all__ = ["SUITE", "BatchSafetyError", "QubeTask", "TaskSuite", "check_batch_safety", "register"]
