"""The registry of devices: the physical plants of the suite, each with its domains and tasks.

Every subpackage of `qube_suite.devices` that declares a `DEVICE` is a device, found
by discovery (as dm_control's suite finds its domain modules): adding a device adds
its folder and nothing else. A device named `<device>` has two domains, `<device>`
(its MuJoCo simulation) and `<device>_hardware` (a Quanser board, the substitute or
a real one). `suite.load`, the Gymnasium registration and the command line read
their domains and tasks from here.

    from qube_suite import devices
    devices.domain("qube_hardware").device.name     # "qube"
    list(devices.domains())                         # ["qube", "qube_hardware", ...]
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import pkgutil
from collections.abc import Mapping
from types import ModuleType

HARDWARE_SUFFIX = "_hardware"
"""A device's hardware domain is named `<device>_hardware`."""


@dataclasses.dataclass(frozen=True)
class Device:
    """A physical plant: where its domains and its tasks live, as modules imported when first used.

    Attributes:
        name: the device's name, also its simulated domain's.
        description: one line for listings.
        simulation: module of the simulated domain: `make_physics(control_frequency,
            **domain_kwargs)` and the tuple `DOMAIN_KWARGS` of the keys `domain_kwargs` may hold.
        hardware: module of the hardware domain, alike.
        tasks: module holding the device's tasks as `SUITE` (a `qube_suite.tasks.registry.TaskSuite`).
        controllers: module of its controllers: `CONTROLLERS` (name -> class), `make(name, **kwargs)`
            and `for_environment(name, environment)`.
        gymnasium_prefix: its tasks' Gymnasium ids are `QubeSuite/<prefix><Task>[Hardware]-v0`.
        feature_map: what its learned policies see of an observation (a name in
            `qube_suite.policies.features.FEATURE_MAPS`).
        batch: module of its batch simulation behind `gymnasium.make_vec`'s native vector env, or
            None: `make_vec` then steps single environments (Gymnasium's own `SyncVectorEnv`).
        substitute: module of the substitute board's plant for a device on a card of its own
            (`CARD_TYPE` and `make_plant()`, see `qube_suite.hardware.board_plant`), or None: a device
            on a Qube's card runs on the board's own Furuta plant.
    """

    name: str
    description: str
    simulation: str
    hardware: str
    tasks: str
    controllers: str
    gymnasium_prefix: str = ""
    feature_map: str = "trig"
    batch: str | None = None
    substitute: str | None = None

    @property
    def domain_names(self) -> tuple[str, str]:
        """The simulated domain's name and the hardware domain's."""
        return self.name, self.name + HARDWARE_SUFFIX

    def controller_module(self) -> ModuleType:
        """The module of its controllers (`CONTROLLERS`, `for_environment`), imported."""
        return importlib.import_module(self.controllers)

    def task_suite(self):
        """The device's tasks: name -> factory, tagged (its tasks module's `SUITE`)."""
        return importlib.import_module(self.tasks).SUITE


@dataclasses.dataclass(frozen=True)
class Domain:
    """One of a device's two domains."""

    name: str
    device: Device
    hardware: bool

    @property
    def module_name(self) -> str:
        """The module that makes its physics (`make_physics`, `DOMAIN_KWARGS`)."""
        return self.device.hardware if self.hardware else self.device.simulation

    def module(self) -> ModuleType:
        """The module that makes its physics, imported."""
        return importlib.import_module(self.module_name)

    def task_names(self) -> tuple[str, ...]:
        """Names of the device's tasks, those registered so far."""
        return tuple(self.device.task_suite())


@functools.cache
def devices() -> Mapping[str, Device]:
    """Device name -> device: every subpackage of `qube_suite.devices` with a `DEVICE`, by name."""
    found = {}
    for module in sorted(pkgutil.iter_modules(__path__), key=lambda module: module.name):
        device = getattr(importlib.import_module(f"{__name__}.{module.name}"), "DEVICE", None)
        if isinstance(device, Device):
            if device.name != module.name:
                raise ValueError(f"the device in qube_suite/devices/{module.name} is named {device.name!r}: "
                                 "a device's folder has its name")
            found[device.name] = device
    return found


def domains() -> dict[str, Domain]:
    """Domain name -> domain, every device's simulation then hardware."""
    return {name: Domain(name, device, hardware) for device in devices().values()
            for name, hardware in zip(device.domain_names, (False, True), strict=True)}


def domain(name: str) -> Domain:
    """The domain called `name`. Raises ValueError for an unknown name, listing the valid ones."""
    known = domains()
    if name not in known:
        raise ValueError(f"unknown domain {name!r}; valid domains: {', '.join(known)}")
    return known[name]
