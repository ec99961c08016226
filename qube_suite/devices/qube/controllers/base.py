"""What every controller shares: observation in, motor voltage out, through a state observer."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT, ObservationLayout
from qube_suite.devices.qube.controllers.model import RigidBodyModel
from qube_suite.devices.qube.controllers.observer import StateObserver


class Controller:
    """A controller for the Qube: `voltage = controller(observation)`.

    Each call passes the observation's state through the `StateObserver` (the state
    estimated from the angles, predicted over `latency_steps`) to `voltage_for`, the
    control law, cancels the unmodelled torque the observer found, and tells the
    observer the voltage sent. Cancelling: the observer's unexplained accelerations b
    are those of a torque M(alpha) b; its arm component, which the motor can oppose,
    costs -(M b)_theta Rm / kt volts (Coulomb friction, the cable's spring; 0 on the
    nominal model). Subclasses set `name` and `tasks` (the suite tasks it is meant
    for) and implement `voltage_for`; `reset` is called at the start of each episode.

    Observations are read through `observation_layout`, the task's
    (`QubeTask.observation_layout`, set by `qube_suite.devices.qube.controllers.for_environment`); by
    default the state layout, with a target if the controller `follows_target`.

    Args:
        control_frequency: control steps per second (Hz) the controller is designed for.
        voltage_limit: output clip (V).
        parameters: physical parameters of the model to design for (nominal by default).
        latency_steps: control steps between an observation and the first sample at which
            the voltage answering it acts: the domain's `latency_steps` (0 in simulation,
            1 on hardware).
    """

    name: ClassVar[str]
    tasks: ClassVar[tuple[str, ...]]
    follows_target: ClassVar[bool] = False
    """Whether the controller is made only for tasks whose observation has an arm target."""

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        self.voltage_limit = voltage_limit
        self.model = RigidBodyModel.from_parameters(parameters)
        self.observer = StateObserver(self.model, control_frequency, latency_steps)
        self.observation_layout = ObservationLayout(target=self.follows_target)

    def reset(self) -> None:
        """Forget everything about the previous episode."""
        self.observer.reset()

    def __call__(self, observation: Any) -> float:
        """Motor voltage (V) for `observation`."""
        state, target = self.observation_layout.split(observation)
        estimate = self.observer(state)
        unmodelled = self.model.arm_torque(estimate[1], *self.observer.unmodelled_accelerations)
        volts = self.voltage_for(estimate, target) - unmodelled / self.model.torque_per_volt
        volts = min(max(volts, -self.voltage_limit), self.voltage_limit)
        self.observer.command(volts)
        return volts

    def sent(self, volts: float) -> None:
        """Tell the observer that `volts` (V), not the voltage returned, answered the last observation
        (e.g. a learner's voltage while this controller labels its states: `training.imitation`)."""
        self.observer.correct_command(volts)

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V, clipped) for `state` [theta, alpha, dtheta, dalpha] and the arm target (rad)."""
        raise NotImplementedError

    def close(self) -> None:
        """Release threads or other resources."""
