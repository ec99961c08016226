"""The controller Quanser's Aero 2 labs teach, by name: `lqr`, state feedback with integral action.

It is designed from the Aero's linear model at level, `linear_model(parameters, configuration)`,
derived from the parameter table (not from the MJCF): the body's and the rotors' momentum balances
in the joint coordinates [pitch, yaw, front rotor angle, back rotor angle] (yaw absent when locked),

    M dv/dt = Q(x, V),

M the mass matrix (the body's inertias Jp, Jy and each rotor's spin inertia J, coupled where a
shaft is parallel to the pitch or yaw axis), Q the generalised forces: pivot damping, the gravity
stiffness Mb g Dm at small pitch, each propeller's thrust kf w times the arm Dt and its drag torque
-kd w on the axis its shaft points along, and each motor's torque kt (V - km w) / Rm on its shaft
(whose reaction on the beam the coupled mass matrix carries). The state is [pitch, yaw, pitch rate,
yaw rate, front and back rotor speeds] (2-DOF) or [pitch, pitch rate, front and back rotor speeds]
(pitch only), as the tasks observe it.

The LQR acts on the state's error from the equilibrium that holds the target (the rotor speeds and
voltages that hold that pitch and yaw, from the same model) and on the integral of the pitch (and yaw)
errors, with the gain of the discrete Riccati equation of the zero-order-hold discretisation
(Bryson's rule for the weights). Its output is the equilibrium's voltages plus the feedback,
clipped to the voltage limit; the integral stops growing while the output saturates.

    from qube_suite.devices.aero2 import controllers
    controller = controllers.for_environment("lqr", env)
    volts = controller(observation)          # (front, back), V
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import scipy.linalg

from qube_suite.arguments import checked_controller
from qube_suite.devices.aero2 import parameters as aero_parameters
from qube_suite.devices.aero2.conventions import RECOMMENDED_VOLTAGE, check_configuration
from qube_suite.policies.mlp import flat_values


def linear_model(parameters: Mapping[str, float] | None = None, configuration: str = "2dof",
                 yaw: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of dx/dt = A x + B V at level and at rest, x the configuration's state (see the module's
    docstring), V the (front, back) voltages; from the parameter table by long name. `yaw=False` leaves
    the 2-DOF model's yaw and yaw rate out (the pitch task on the 2-DOF Aero, whose yaw it ignores)."""
    check_configuration(configuration)
    p = aero_parameters.resolve(parameters)
    spin = aero_parameters.rotor_assembly_inertia(p)
    arm, kf, kd = p["thrust_arm"], p["thrust_constant"], p["propeller_drag"]
    torque_per_volt = p["motor_torque_constant"] / p["motor_resistance"]
    back_emf = torque_per_volt * p["motor_back_emf"]
    stiffness = aero_parameters.gravity_stiffness(p)
    if configuration == "2dof":
        # Coordinates [pitch, yaw, front rotor, back rotor]. The front shaft is the yaw axis; the back
        # shaft is along +y, against the pitch axis (-y).
        mass = np.array([[p["pitch_inertia"], 0.0, 0.0, -spin],
                         [0.0, p["yaw_inertia"], spin, 0.0],
                         [0.0, spin, spin, 0.0],
                         [-spin, 0.0, 0.0, spin]])
        # Generalised forces per [pitch, yaw, pitch rate, yaw rate, w front, w back] and per volt.
        forces = np.array([
            [-stiffness, 0.0, -p["pitch_damping"], 0.0, arm * kf, kd],
            [0.0, 0.0, 0.0, -p["yaw_damping"], -kd, arm * kf],
            [0.0, 0.0, 0.0, 0.0, -kd - back_emf, 0.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, -kd - back_emf]])
        positions, rates = 2, 4
    else:
        # Coordinates [pitch, front rotor, back rotor]: both shafts vertical, both thrusts lifting.
        mass = np.diag([p["pitch_inertia"], spin, spin])
        forces = np.array([
            [-stiffness, -p["pitch_damping"], arm * kf, -arm * kf],
            [0.0, 0.0, -kd - back_emf, 0.0],
            [0.0, 0.0, 0.0, -kd - back_emf]])
        positions, rates = 1, 3
    inputs = np.zeros((len(mass), 2))
    inputs[-2:, :] = np.eye(2) * torque_per_volt
    size = positions + rates
    a, b = np.zeros((size, size)), np.zeros((size, 2))
    a[:positions, positions:2 * positions] = np.eye(positions)
    a[positions:, :] = np.linalg.solve(mass, forces)
    b[positions:, :] = np.linalg.solve(mass, inputs)
    if configuration == "2dof" and not yaw:
        kept = [0, 2, 4, 5]
        return a[np.ix_(kept, kept)], b[kept]
    return a, b


class AeroLQR:
    """LQR with integral action on the Aero's linear model: `volts = controller(observation)`,
    `reset()` per episode.

    Args:
        control_frequency: control steps per second (Hz).
        voltage_limit: output clip (V) of each thruster.
        parameters: the Aero's parameters to design for, by long name (nominal by default).
        configuration: "2dof" or "pitch_only", the domain's.
        yaw: whether the task holds the yaw too (hover, track) or the pitch alone (pitch).
        angle_tolerance (pitch, rad, default 0.05), yaw_tolerance (rad, default 0.1), rate_tolerance
        (rad/s, default 0.5), speed_tolerance (rad/s, default 400), integral_tolerance (rad s, default
        0.2): Bryson's rule, each state weight the inverse square of its tolerance, each voltage's
        1 / voltage_limit^2.
    """

    name: ClassVar[str] = "lqr"
    tasks: ClassVar[tuple[str, ...]] = ("pitch", "pitch_sparse", "hover", "hover_sparse", "track",
                                        "track_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = RECOMMENDED_VOLTAGE,
                 parameters: Mapping[str, float] | None = None, configuration: str = "2dof",
                 yaw: bool = True, angle_tolerance: float = 0.05, yaw_tolerance: float = 0.1,
                 rate_tolerance: float = 0.5, speed_tolerance: float = 400.0,
                 integral_tolerance: float = 0.2):
        self.period = 1.0 / control_frequency
        self.voltage_limit = float(voltage_limit)
        self.configuration = configuration
        a, b = linear_model(parameters, configuration, yaw)
        self._a, self._b = a, b
        axes = 2 if configuration == "2dof" and yaw else 1
        self._axes = axes
        size = len(a)
        # Augmented with the integrals of the angle errors: d/dt z = angles - targets.
        augmented_a = np.zeros((size + axes, size + axes))
        augmented_a[:size, :size] = a
        augmented_a[size:, :axes] = np.eye(axes)
        augmented_b = np.vstack([b, np.zeros((axes, 2))])
        n = size + axes
        block = np.zeros((n + 2, n + 2))
        block[:n, :n], block[:n, n:] = augmented_a, augmented_b
        discrete = scipy.linalg.expm(block * self.period)
        a_d, b_d = discrete[:n, :n], discrete[:n, n:]
        angles = [angle_tolerance, yaw_tolerance][:axes]
        tolerances = angles + [rate_tolerance] * axes + [speed_tolerance] * 2 + [integral_tolerance] * axes
        q = np.diag(np.array(tolerances, dtype=np.float64) ** -2)
        r = np.eye(2) * self.voltage_limit**-2
        s = scipy.linalg.solve_discrete_are(a_d, b_d, q, r)
        self.gain_matrix = np.linalg.solve(r + b_d.T @ s @ b_d, b_d.T @ s @ a_d)
        """K of V = V_eq - K [x - x_eq, z], shape (2, state size + axes)."""
        self._integral = np.zeros(axes)

    @property
    def observation_size(self) -> int:
        """Values of the task's flat observation: the state, then one target per angle."""
        return len(self._a) + self._axes

    def equilibrium(self, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(state, voltages) of the linear model at rest at the angles `targets` (pitch[, yaw], rad): the
        rotor speeds and voltages that hold them there."""
        axes, size = self._axes, len(self._a)
        # Unknowns: the two rotor speeds and the two voltages; rates zero, angles given.
        unknown_columns = np.hstack([self._a[axes:, size - 2:], self._b[axes:, :]])
        known = self._a[axes:, :axes] @ targets
        solution = np.linalg.lstsq(unknown_columns, -known, rcond=None)[0]
        state = np.concatenate([targets, np.zeros(axes), solution[:2]])
        return state, solution[2:]

    def reset(self) -> None:
        """Forget the previous episode (the integrals)."""
        self._integral = np.zeros(self._axes)

    def __call__(self, observation: Any) -> np.ndarray:
        """(front, back) voltages (V) for `observation`."""
        values = flat_values(observation, self.observation_size)
        size = len(self._a)
        state, targets = values[:size], values[size:]
        equilibrium_state, equilibrium_volts = self.equilibrium(targets)
        error = state - equilibrium_state
        unclipped = equilibrium_volts - self.gain_matrix @ np.concatenate([error, self._integral])
        volts = np.clip(unclipped, -self.voltage_limit, self.voltage_limit)
        if np.array_equal(volts, unclipped):  # conditional integration: no wind-up while saturated
            self._integral += error[:self._axes] * self.period
        return volts

    def close(self) -> None:
        """Nothing to release."""


CONTROLLERS: dict[str, type[AeroLQR]] = {AeroLQR.name: AeroLQR}
"""Controller name -> class."""


def make(name: str, **kwargs) -> AeroLQR:
    """The controller called `name`, built with `kwargs`. Raises ValueError for an unknown name or keyword
    (listing the valid ones)."""
    return checked_controller(CONTROLLERS, name, kwargs)(**kwargs)


def for_environment(name: str, environment, **kwargs) -> AeroLQR:
    """The controller called `name` for a suite environment of the Aero: its control frequency, its task's
    voltage limit, its domain's configuration and parameters; `kwargs` add or override settings."""
    physics = environment.physics
    settings = {"control_frequency": environment.control_frequency,
                "voltage_limit": environment.task.voltage_limit,
                "configuration": physics.configuration,
                "yaw": environment.task.needs_yaw,
                "parameters": getattr(physics, "parameters", None)}
    return make(name, **{**settings, **kwargs})


