"""The Qube tasks, registered in `SUITE` by name with tags."""

from qube_suite.tasks import balance, dampen, rotor, swingup  # noqa: F401  (registers the tasks)
from qube_suite.tasks.balance import Balance, BalanceFollow
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.batch_safety import BatchSafetyError, check_batch_safety
from qube_suite.tasks.dampen import Dampen
from qube_suite.tasks.registry import SUITE, register
from qube_suite.tasks.rotor import Rotor
from qube_suite.tasks.swingup import Swingup, SwingupFollow

__all__ = ["SUITE", "BatchSafetyError", "QubeTask", "check_batch_safety", "register",
           "Swingup", "SwingupFollow", "Balance", "BalanceFollow", "Dampen", "Rotor"]
