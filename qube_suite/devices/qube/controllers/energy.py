"""Energy shaping: drive the Qube's total energy to a set value while keeping the arm centred.

The motor changes the total energy E of arm and pendulum only through its work,
dE/dt = tau theta', and the angular momentum p about the motor axis only through
its torque (see `qube_suite.devices.qube.controllers.model`). Split the arm angle as
theta = psi + g(alpha): g is the part the pendulum's swing carries the arm through
by itself (with p = 0), psi the swing centre, psi' = p / M11. Then

    dE/dt = tau (psi' + g'(alpha) alpha'),   g'(alpha) = mp Lr l cos(alpha) / M11.

The law adds two torques:

* pump, with e = (E_set - E) / (b 2 mp g l) and the torque T:
  - adding energy, 0 < e < 1: T e tanh(alpha' cos(alpha) / w). Its work on the
    g' alpha' term raises E on every swing however hard the pendulum's reaction
    pushes the arm about; its work on psi' averages out over a swing. For e >= 1
    the tanh becomes a sign (bang-bang), which also starts a pendulum at rest.
  - draining, e < 0: T max(e, -1) tanh(theta' / v), a damper on the arm whose
    work tau theta' is never positive. Its damping T / v = B w0 is the arm's
    impedance at the pendulum's natural frequency w0, a matched load: in
    simulation dampers several times stiffer or softer drain more slowly.
    (Draining with the alpha' cos(alpha) phase instead locks into a swing whose
    work on psi' cancels the drain.)
  T is capped so that a square wave of it alone would swing psi by about
  +-`PUMP_EXCURSION` at w0. The pump fades as psi approaches `ARM_LIMIT - max g`
  while it pushes the arm outwards.
* centring: tau_c = -B (wc^2 psi + 2 zeta wc psi'): a damped spring on the
  swing centre only, which leaves the pendulum-driven motion g(alpha) free
  instead of fighting it (a spring on theta itself takes the pendulum's energy
  away).

Centring on psi rather than theta, and pumping total rather than pendulum energy,
is what lets a 3 V motor, whose stall torque is no larger than the pendulum's
reaction torque, swing the Qube up within +-60 degrees of arm travel.
"""

from __future__ import annotations

import math

from qube_suite.conventions import ARM_LIMIT
from qube_suite.devices.qube.controllers.model import RigidBodyModel

ENERGY_BAND = 0.1
"""Energy error (fraction of 2 mp g l) at which the pump reaches full torque."""
PHASE_SPEED = 0.5
"""w (rad/s): alpha' cos(alpha) beyond which the pump's direction is fully switched."""
PUMP_EXCURSION = 0.7
"""psi amplitude (rad) that sets the largest pumping torque."""
CENTRING_FREQUENCY = 8.0
"""wc (rad/s) of the spring on the swing centre, below the pendulum's 10.7 rad/s."""
CENTRING_DAMPING = 0.5
"""zeta of the spring on the swing centre."""


class EnergyShaping:
    """Voltage that moves the total energy towards a set value, arm centred (see the module).

    Args:
        model: the Qube's rigid-body model.
        voltage_limit: output clip (V).
    """

    def __init__(self, model: RigidBodyModel, voltage_limit: float):
        self.model = model
        self.voltage_limit = voltage_limit
        natural_frequency_squared = model.gravity_torque / model.pendulum_inertia
        square_wave_gain = 4.0 / math.pi  # first harmonic of a unit square wave
        self.pump_torque = min(voltage_limit * model.torque_per_volt,
                               PUMP_EXCURSION * model.base_inertia * natural_frequency_squared
                               / square_wave_gain)
        self.centre_limit = ARM_LIMIT - model.swing_offset(math.pi / 2)
        # Drain damping B w0, the arm's impedance at the pendulum's frequency, saturating at T.
        self.drain_speed = self.pump_torque / (model.base_inertia * math.sqrt(natural_frequency_squared))
        self.stiffness = model.base_inertia * CENTRING_FREQUENCY**2
        self.damping = 2.0 * CENTRING_DAMPING * model.base_inertia * CENTRING_FREQUENCY

    def voltage(self, state, energy_set: float) -> float:
        """Voltage (V, clipped) for `state` [theta, alpha, dtheta, dalpha] towards total energy
        `energy_set` (J), swing centre 0."""
        theta, alpha, dtheta, dalpha = state
        model = self.model
        error = (energy_set - model.energy(alpha, dtheta, dalpha)) / (ENERGY_BAND * model.swing_up_energy)
        phase = dalpha * math.cos(alpha)
        if error < 0.0:  # drain: a damper on the arm, whose work tau theta' is never positive
            pump = self.pump_torque * max(error, -1.0) * math.tanh(dtheta / self.drain_speed)
        elif error < 1.0:
            pump = self.pump_torque * error * math.tanh(phase / PHASE_SPEED)
        else:  # far below the set energy: bang-bang, which also starts a pendulum at rest
            pump = self.pump_torque * math.copysign(1.0, phase)
        centre = model.swing_centre(theta, alpha)
        if pump * centre > 0.0:
            pump *= max(0.0, 1.0 - abs(centre) / self.centre_limit)
        centre_speed = model.angular_momentum(alpha, dtheta, dalpha) / model.arm_inertia(alpha)
        torque = pump - self.stiffness * centre - self.damping * centre_speed
        volts = model.voltage_for_torque(torque, dtheta)
        return min(max(volts, -self.voltage_limit), self.voltage_limit)
