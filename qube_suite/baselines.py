"""Controllers by name, each device's own, found through the device registry.

    from qube_suite import baselines
    controller = baselines.make("swingup", control_frequency=250.0, voltage_limit=3.0, latency_steps=0)
    controller = baselines.for_environment("swingup", env)   # the same, read from a suite environment
    controller = baselines.for_environment(name, env, domain)  # a controller of another device's domain
    voltage = controller(observation)

`domain` is any domain of the device (its simulation or its hardware) and defaults to the
pendulum's. The controllers themselves live in their device's folder (the pendulum's in
`qube_suite.devices.qube.controllers`, the table of names in its `CONTROLLERS`).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import ModuleType
from typing import Any

from qube_suite import devices


def controllers(domain: str = "qube") -> ModuleType:
    """The module of the controllers of `domain`'s device. Raises ValueError for an unknown domain."""
    return devices.domain(domain).device.controller_module()


def names(domain: str = "qube") -> Mapping[str, type]:
    """Controller name -> class, for `domain`'s device."""
    return controllers(domain).CONTROLLERS


def make(name: str, domain: str = "qube", **kwargs) -> Any:
    """The controller called `name` of `domain`'s device, built with `kwargs` (`control_frequency`
    in Hz, `voltage_limit` in V, ...). Raises ValueError for an unknown name or keyword."""
    return controllers(domain).make(name, **kwargs)


def for_environment(name: str, environment, domain: str = "qube", **kwargs) -> Any:
    """The controller called `name` for a suite `environment` of `domain`: built for its control
    frequency, its task's voltage limit and what its device reads from the domain; `kwargs` add or
    override settings."""
    return controllers(domain).for_environment(name, environment, **kwargs)

