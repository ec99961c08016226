"""Controllers derived from the Qube model, by name: balance (LQR), swingup, dampen, follow,
rotor (energy shaping with LQRs), mpc (sampling MPC) and ilqr (iLQR MPC). Each estimates the state from the
observed angles with a model-based observer, predicted over the domain's latency.

    from qube_suite import baselines
    controller = baselines.make("swingup", control_frequency=250.0, voltage_limit=3.0, latency_steps=0)
    controller = baselines.for_environment("swingup", env)   # the same, read from a suite environment
    voltage = controller(observation)
"""

from __future__ import annotations

import math

from qube_suite.arguments import checked_controller, is_number, keywords_of
from qube_suite.capabilities import HasDesignParameters
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.dampen import DampenController
from qube_suite.devices.qube.controllers.follow import FollowController
from qube_suite.devices.qube.controllers.ilqr import IterativeLQR
from qube_suite.devices.qube.controllers.lqr import BalanceLQR, lqr_gain
from qube_suite.devices.qube.controllers.mpc import SamplingMPC
from qube_suite.devices.qube.controllers.rotor import RotorController
from qube_suite.devices.qube.controllers.swingup import SwingupController
from qube_suite.devices.qube.simulation import check_control_frequency

CONTROLLERS: dict[str, type[Controller]] = {
    cls.name: cls for cls in (BalanceLQR, SwingupController, DampenController, FollowController,
                              RotorController, SamplingMPC, IterativeLQR)}
"""Controller name -> class."""


def make(name: str, **kwargs) -> Controller:
    """The controller called `name`, built with `kwargs` (`control_frequency` in Hz,
    `voltage_limit` in V, ...).

    Raises ValueError for an unknown name or keyword (listing the valid ones), a
    control frequency outside [10, 2000] Hz or a voltage limit that is not positive.
    """
    cls = checked_controller(CONTROLLERS, name, kwargs)
    if "control_frequency" in kwargs:
        check_control_frequency(kwargs["control_frequency"])
    limit = kwargs.get("voltage_limit", 1.0)
    if not (is_number(limit) and 0.0 < limit < math.inf):
        raise ValueError(f"voltage_limit must be a positive number of volts, got {limit!r}")
    return cls(**kwargs)


def for_environment(name: str, environment, **kwargs) -> Controller:
    """The controller called `name` for a suite `environment`: built for its control frequency,
    its task's voltage limit and its domain's `latency_steps` (and, on hardware, the device's motor
    data: `physics.design_parameters()`), reading the task's observation layout; `kwargs` add or
    override settings."""
    settings = {"control_frequency": environment.control_frequency,
                "voltage_limit": environment.task.voltage_limit,
                "latency_steps": environment.physics.latency_steps}
    physics = environment.physics
    if (isinstance(physics, HasDesignParameters)  # e.g. a Qube-Servo 3's motor
            and name in CONTROLLERS and "parameters" in keywords_of(CONTROLLERS[name])):
        settings["parameters"] = physics.design_parameters()
    controller = make(name, **{**settings, **kwargs})
    controller.observation_layout = environment.task.observation_layout
    return controller


__all__ = ["CONTROLLERS", "BalanceLQR", "Controller", "DampenController", "FollowController", "IterativeLQR",
           "RotorController", "SamplingMPC", "SwingupController", "for_environment", "lqr_gain", "make"]
