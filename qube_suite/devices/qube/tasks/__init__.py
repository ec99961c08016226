"""The pendulum's tasks, registered in `SUITE` by name with tags."""

from qube_suite.devices.qube.tasks import balance, dampen, rotor, swingup  # noqa: F401  (registers the tasks)
from qube_suite.devices.qube.tasks.balance import Balance, BalanceFollow
from qube_suite.devices.qube.tasks.dampen import Dampen
from qube_suite.devices.qube.tasks.rotor import Rotor
from qube_suite.devices.qube.tasks.swingup import Swingup, SwingupFollow
from qube_suite.tasks.registry import SUITE

__all__ = ["SUITE", "Swingup", "SwingupFollow", "Balance", "BalanceFollow", "Dampen", "Rotor"]
