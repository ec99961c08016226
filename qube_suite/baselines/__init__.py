"""Controllers derived from the Qube model, by name: balance (LQR), swingup, dampen, follow,
rotor (energy shaping with LQRs) and mpc (sampling MPC).

    from qube_suite import baselines
    controller = baselines.make("swingup", control_frequency=250.0, voltage_limit=3.0)
    voltage = controller(observation)
"""

from __future__ import annotations

from qube_suite.baselines.base import Controller, split_observation
from qube_suite.baselines.dampen import Dampen
from qube_suite.baselines.follow import Follow
from qube_suite.baselines.lqr import BalanceLQR, lqr_gain
from qube_suite.baselines.mpc import SamplingMPC
from qube_suite.baselines.rotor import Rotor
from qube_suite.baselines.swingup import SwingUp

CONTROLLERS: dict[str, type[Controller]] = {
    cls.name: cls for cls in (BalanceLQR, SwingUp, Dampen, Follow, Rotor, SamplingMPC)}
"""Controller name -> class."""


def make(name: str, **kwargs) -> Controller:
    """The controller called `name`, built with `kwargs`; ValueError lists valid names."""
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; valid controllers: {', '.join(CONTROLLERS)}")
    return CONTROLLERS[name](**kwargs)


__all__ = ["CONTROLLERS", "BalanceLQR", "Controller", "Dampen", "Follow", "Rotor", "SamplingMPC", "SwingUp",
           "lqr_gain", "make", "split_observation"]
