"""The classical controllers that labs teach on the inertia disk, by name: `pd` and `pid` (position),
`pi` (speed), `lqr` (position, with integral action).

Each is designed from the disk's first-order speed model, J dw/dt = (kt/Rm) V - (kt km/Rm + D) w,
that is w = K / (tau s + 1) V with the steady-state gain K (rad/s/V) and time constant tau (s)
of `speed_model`; a position loop sees K / (s (tau s + 1)). Controllers read the task's
observation (`state` then `target`, as a dm_env mapping or a flat vector) and return the motor
voltage (V), clipped to `voltage_limit`.

    from qube_suite.devices.qube_disk import controllers
    controller = controllers.for_environment("pid", env)
    voltage = controller(observation)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import scipy.linalg

from qube_suite.arguments import checked_controller
from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube_disk import parameters as disk_parameters
from qube_suite.policies.mlp import flat_values


def speed_model(parameters: Mapping[str, float] | None = None) -> tuple[float, float]:
    """(K in rad/s/V, tau in s) of the disk's speed response to voltage, from its parameter table."""
    p = disk_parameters.resolve(parameters)
    torque_per_volt = p["motor_torque_constant"] / p["motor_resistance"]
    damping = torque_per_volt * p["motor_back_emf"] + p["disk_damping"]
    return torque_per_volt / damping, disk_parameters.shaft_inertia(p) / damping


class DiskController:
    """Base of the disk's controllers: `voltage = controller(observation)`, `reset()` per episode.

    Args:
        control_frequency: control steps per second (Hz).
        voltage_limit: output clip (V).
        parameters: the disk's parameters to design for, by long name (nominal by default).
    """

    name: ClassVar[str]
    tasks: ClassVar[tuple[str, ...]]
    observation_size: ClassVar[int]
    """Values of the task's flat observation: 3 for position ([theta, dtheta, target]), 2 for speed."""

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None):
        self.period = 1.0 / control_frequency
        self.voltage_limit = float(voltage_limit)
        self.gain, self.time_constant = speed_model(parameters)
        self._integral = 0.0

    def reset(self) -> None:
        """Forget the previous episode (the integral)."""
        self._integral = 0.0

    def __call__(self, observation: Any) -> float:
        """Motor voltage (V) for `observation`."""
        values = flat_values(observation, self.observation_size).tolist()
        volts = self.voltage_for(*values)
        return min(max(volts, -self.voltage_limit), self.voltage_limit)

    def voltage_for(self, *values: float) -> float:
        """The control law on the observation's values."""
        raise NotImplementedError

    def _integrate(self, error: float, gain: float, unclipped: float) -> None:
        """Add `error` over one period to the integral unless the output is saturated in its direction
        (conditional integration: no wind-up)."""
        if abs(unclipped) < self.voltage_limit or (error * unclipped) < 0.0:
            self._integral += error * self.period

    def close(self) -> None:
        """Nothing to release."""

    def pole_placement(self, bandwidth: float, damping: float) -> tuple[float, float]:
        """Gains (g0, g1) of V = g0 x + g1 dx/dt on the motor's first-order speed response (gain K,
        time constant tau) that put the closed loop's two poles at natural frequency `bandwidth`
        (rad/s) with damping ratio `damping`: g0 = wn^2 tau / K, g1 = max(0, (2 zeta wn tau - 1) / K)."""
        tau, k = self.time_constant, self.gain
        return bandwidth**2 * tau / k, max(0.0, (2.0 * damping * bandwidth * tau - 1.0) / k)

class PositionPD(DiskController):
    """V = kp (theta_target - theta) - kd dtheta, placing the closed loop's poles at natural frequency
    `bandwidth` (rad/s) with damping ratio `damping`: kp = wn^2 tau / K, kd = (2 zeta wn tau - 1) / K.

    Args: as `DiskController`, and `bandwidth` (rad/s, default 30), `damping` (default 0.8).
    """

    name = "pd"
    tasks = ("position", "position_sparse")
    observation_size = 3

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, bandwidth: float = 30.0,
                 damping: float = 0.8):
        super().__init__(control_frequency, voltage_limit, parameters)
        self.kp, self.kd = self.pole_placement(bandwidth, damping)

    def voltage_for(self, theta: float, dtheta: float, target: float) -> float:
        return self.kp * (target - theta) - self.kd * dtheta


class PositionPID(PositionPD):
    """V = kp e + ki * integral of e - kd dtheta, e = theta_target - theta: the integral removes the steady
    error that Coulomb friction leaves a PD (it stops short by friction / kp) and does not wind up. The
    gains place the closed loop's poles, tau s^3 + (1 + K kd) s^2 + K kp s + K ki = 0, at natural
    frequency `bandwidth` with damping ratio `damping` and a real pole at `integral_fraction` of it.

    Args: as `PositionPD`, and `integral_fraction` (default 0.5).
    """

    name = "pid"

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, bandwidth: float = 30.0,
                 damping: float = 0.8, integral_fraction: float = 0.5):
        super().__init__(control_frequency, voltage_limit, parameters, bandwidth, damping)
        tau, k, pole = self.time_constant, self.gain, integral_fraction * bandwidth
        self.kd = max(0.0, (tau * (2.0 * damping * bandwidth + pole) - 1.0) / k)
        self.kp = tau * (bandwidth**2 + 2.0 * damping * bandwidth * pole) / k
        self.ki = tau * pole * bandwidth**2 / k

    def voltage_for(self, theta: float, dtheta: float, target: float) -> float:
        error = target - theta
        volts = super().voltage_for(theta, dtheta, target) + self.ki * self._integral
        self._integrate(error, self.ki, volts)
        return volts


class SpeedPI(DiskController):
    """V = kp (w_target - w) + ki * integral of the speed error, placing the closed loop's poles at
    natural frequency `bandwidth` (rad/s) with damping ratio `damping`: ki = wn^2 tau / K,
    kp = (2 zeta wn tau - 1) / K.

    Args: as `DiskController`, and `bandwidth` (rad/s, default 25), `damping` (default 1).
    """

    name = "pi"
    tasks = ("speed", "speed_sparse")
    observation_size = 2

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, bandwidth: float = 25.0,
                 damping: float = 1.0):
        super().__init__(control_frequency, voltage_limit, parameters)
        self.ki, self.kp = self.pole_placement(bandwidth, damping)

    def voltage_for(self, dtheta: float, target: float) -> float:
        error = target - dtheta
        volts = self.kp * error + self.ki * self._integral
        self._integrate(error, self.ki, volts)
        return volts


class PositionLQR(DiskController):
    """Discrete LQR on [theta - theta_target, dtheta, integral of theta - theta_target] of the
    zero-order-hold discretisation of the disk's model, V = -K x.

    Args: as `DiskController`, and the weights: `angle_tolerance` (rad, default 0.3),
    `speed_tolerance` (rad/s, default 20), `integral_tolerance` (rad s, default 0.3): the state
    weights are their inverse squares, the voltage's 1 / voltage_limit^2 (Bryson's rule).
    """

    name = "lqr"
    tasks = ("position", "position_sparse")
    observation_size = 3

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, angle_tolerance: float = 0.3,
                 speed_tolerance: float = 20.0, integral_tolerance: float = 0.3):
        super().__init__(control_frequency, voltage_limit, parameters)
        tau, k = self.time_constant, self.gain
        a = np.array([[0.0, 1.0, 0.0], [0.0, -1.0 / tau, 0.0], [1.0, 0.0, 0.0]])
        b = np.array([[0.0], [k / tau], [0.0]])
        continuous = np.zeros((4, 4))
        continuous[:3, :3], continuous[:3, 3:] = a, b
        discrete = scipy.linalg.expm(continuous * self.period)
        q = np.diag([angle_tolerance**-2, speed_tolerance**-2, integral_tolerance**-2])
        r = np.array([[self.voltage_limit**-2]])
        a_d, b_d = discrete[:3, :3], discrete[:3, 3:]
        s = scipy.linalg.solve_discrete_are(a_d, b_d, q, r)
        self.gain_matrix = np.linalg.solve(r + b_d.T @ s @ b_d, b_d.T @ s @ a_d)[0]

    def voltage_for(self, theta: float, dtheta: float, target: float) -> float:
        error = theta - target
        volts = -float(self.gain_matrix @ np.array([error, dtheta, self._integral]))
        self._integrate(error, 1.0, -volts)
        return volts


CONTROLLERS: dict[str, type[DiskController]] = {
    cls.name: cls for cls in (PositionPD, PositionPID, SpeedPI, PositionLQR)}
"""Controller name -> class."""


def make(name: str, **kwargs) -> DiskController:
    """The controller called `name`, built with `kwargs`. Raises ValueError for an unknown name or keyword
    (listing the valid ones)."""
    return checked_controller(CONTROLLERS, name, kwargs)(**kwargs)


def for_environment(name: str, environment, **kwargs) -> DiskController:
    """The controller called `name` for a suite environment of the disk: its control frequency and its
    task's voltage limit; `kwargs` add or override settings."""
    settings = {"control_frequency": environment.control_frequency,
                "voltage_limit": environment.task.voltage_limit}
    return make(name, **{**settings, **kwargs})


