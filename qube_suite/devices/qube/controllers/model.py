"""The Qube's rigid-body equations in closed form, for controllers that evaluate them every call.

Coordinates: arm angle theta, pendulum angle alpha (0 upright); s = sin alpha,
c = cos alpha, l = Lp/2. The coefficients are those of `qube_suite/devices/qube/model.xml`
for the physical parameters of `qube_suite.devices.qube.parameters` (Lagrange's equations of
the arm, the rotor and a uniform rod with a small axial inertia Ja):

    M11 theta'' + M12 alpha'' + 2 K s c theta' alpha' + mp Lr l s alpha'^2 = tau - Dr theta'
    M12 theta'' + M22 alpha'' - K s c theta'^2 - mp g l s = -Dp alpha'

    M11 = B + K s^2,  B = Jr + Jm + mp Lr^2 + Ja,  K = mp l^2 + Jp - Ja,
    M12 = -mp Lr l c,  M22 = mp l^2 + Jp,  tau = kt (V - km theta') / Rm.

Solved for the accelerations (`accelerations`), with det = M11 M22 - M12^2 > 0,

    r1 = tau - Dr theta' - 2 K s c theta' alpha' - mp Lr l s alpha'^2,
    r2 = K s c theta'^2 + mp g l s - Dp alpha',
    theta'' = (M22 r1 - M12 r2) / det,   alpha'' = (M11 r2 - M12 r1) / det.

Two exact consequences the controllers build on:

* Total energy E = q'^T M q' / 2 + mp g l (cos alpha - 1) (0 at rest upright,
  -2 mp g l at rest hanging) changes only by the motor's work:
  dE/dt = tau theta' - Dr theta'^2 - Dp alpha'^2.
* The angular momentum about the motor axis, p = M11 theta' + M12 alpha', changes
  only by the motor's torque: dp/dt = tau - Dr theta'. With p = 0 the arm follows
  the swing as theta = g(alpha), g' = mp Lr l c / M11, i.e.
  g(alpha) = mp Lr l / sqrt(B K) atan(sqrt(K / B) sin alpha) (at most 28 degrees
  for the Qube), so psi = theta - g(alpha) obeys psi' = p / M11: the arm's swing
  centre, moved by the motor alone.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from qube_suite.devices.qube import parameters as params


@dataclasses.dataclass(frozen=True)
class RigidBodyModel:
    """Coefficients (SI units) of the equations above for one set of physical parameters."""

    base_inertia: float
    """B = Jr + Jm + mp Lr^2 + Ja: the arm's inertia with the pendulum upright (kg m^2)."""
    swing_inertia: float
    """K = mp l^2 + Jp - Ja: how much the arm's inertia grows with sin^2 alpha (kg m^2)."""
    coupling: float
    """mp Lr l: inertial coupling of arm and pendulum (kg m^2)."""
    pendulum_inertia: float
    """M22 = mp l^2 + Jp: the pendulum's inertia about its pivot (kg m^2)."""
    gravity_torque: float
    """mp g l: the largest gravity torque on the pendulum (N m)."""
    arm_damping: float
    """Dr (N m s/rad)."""
    pendulum_damping: float
    """Dp (N m s/rad)."""
    torque_per_volt: float
    """kt / Rm (N m/V)."""
    back_emf: float
    """km (V s/rad)."""

    @classmethod
    def from_parameters(cls, overrides: Mapping[str, float] | Any = None) -> RigidBodyModel:
        """The model for the nominal parameters updated by `overrides` (long names, or a calibration:
        see `qube_suite.devices.qube.parameters.values_of`)."""
        p = params.resolve(params.values_of(overrides))
        mp, lp, lr = p["pendulum_mass"], p["pendulum_length"], p["arm_length"]
        half = lp / 2.0
        transverse = params.pendulum_inertia(mp, lp)
        axial = 0.5 * mp * params.PENDULUM_ROD_RADIUS**2
        return cls(
            base_inertia=params.arm_inertia(p["arm_mass"], lr) + p["rotor_inertia"] + mp * lr**2 + axial,
            swing_inertia=mp * half**2 + transverse - axial,
            coupling=mp * lr * half,
            pendulum_inertia=mp * half**2 + transverse,
            gravity_torque=mp * p["gravity"] * half,
            arm_damping=p["arm_damping"],
            pendulum_damping=p["pendulum_damping"],
            torque_per_volt=p["motor_torque_constant"] / p["motor_resistance"],
            back_emf=p["motor_back_emf"],
        )

    @property
    def swing_up_energy(self) -> float:
        """2 mp g l: energy (J) from rest hanging to rest upright."""
        return 2.0 * self.gravity_torque

    @property
    def upright_swing_inertia(self) -> float:
        """M22 - (mp Lr l)^2 / B (kg m^2): the pendulum's inertia near upright when the arm moves
        freely with it (p = 0), so that the kinetic energy is this times alpha'^2 / 2."""
        return self.pendulum_inertia - self.coupling**2 / self.base_inertia

    def arm_inertia(self, alpha: float) -> float:
        """M11 (kg m^2) at pendulum angle `alpha` (rad)."""
        s = math.sin(alpha)
        return self.base_inertia + self.swing_inertia * s * s

    def accelerations(self, alpha: float, dtheta: float, dalpha: float, volts: float) -> tuple[float, float]:
        """(theta'', alpha'') (rad/s^2) at pendulum angle `alpha` (rad), speeds `dtheta`, `dalpha`
        (rad/s) and motor voltage `volts` (V): the equations above solved for them."""
        return self.accelerations_at(math.sin(alpha), math.cos(alpha), dtheta, dalpha, volts)

    def accelerations_at(self, s, c, dtheta, dalpha, volts):
        """`accelerations` given the sine `s` and cosine `c` of the pendulum angle: floats, or arrays
        of many worlds."""
        swing = self.swing_inertia * s * c
        m11 = self.base_inertia + self.swing_inertia * s * s
        m12, m22 = -self.coupling * c, self.pendulum_inertia
        torque = self.torque_per_volt * (volts - self.back_emf * dtheta)
        r1 = (torque - self.arm_damping * dtheta - 2.0 * swing * dtheta * dalpha
              - self.coupling * s * dalpha * dalpha)
        r2 = swing * dtheta * dtheta + self.gravity_torque * s - self.pendulum_damping * dalpha
        det = m11 * m22 - m12 * m12
        return (m22 * r1 - m12 * r2) / det, (m11 * r2 - m12 * r1) / det

    def arm_torque(self, alpha: float, ddtheta: float, ddalpha: float) -> float:
        """M11 theta'' + M12 alpha'' (N m): the arm torque that accelerations `ddtheta`, `ddalpha`
        (rad/s^2) take at pendulum angle `alpha` (rad), the pendulum torque being zero."""
        return self.arm_inertia(alpha) * ddtheta - self.coupling * math.cos(alpha) * ddalpha

    def energy(self, alpha: float, dtheta: float, dalpha: float) -> float:
        """Total energy E (J) of arm and pendulum: 0 at rest upright, -2 mp g l at rest hanging."""
        c = math.cos(alpha)
        kinetic = (self.arm_inertia(alpha) * dtheta * dtheta - 2.0 * self.coupling * c * dtheta * dalpha
                   + self.pendulum_inertia * dalpha * dalpha)
        return 0.5 * kinetic + self.gravity_torque * (c - 1.0)

    def angular_momentum(self, alpha: float, dtheta: float, dalpha: float) -> float:
        """p = M11 theta' + M12 alpha' (kg m^2/s), angular momentum about the motor axis."""
        return self.arm_inertia(alpha) * dtheta - self.coupling * math.cos(alpha) * dalpha

    def swing_offset(self, alpha: float) -> float:
        """g(alpha) (rad): the arm angle the pendulum's swing alone carries the arm to (p = 0)."""
        return self.coupling / math.sqrt(self.base_inertia * self.swing_inertia) * math.atan(
            math.sqrt(self.swing_inertia / self.base_inertia) * math.sin(alpha))

    def swing_centre(self, theta: float, alpha: float) -> float:
        """psi = theta - g(alpha) (rad): where the arm would be with the pendulum's swing removed."""
        return theta - self.swing_offset(alpha)

    def voltage_for_torque(self, torque: float, dtheta: float) -> float:
        """Motor voltage (V, unclipped) that gives `torque` (N m) at arm speed `dtheta` (rad/s)."""
        return torque / self.torque_per_volt + self.back_emf * dtheta
