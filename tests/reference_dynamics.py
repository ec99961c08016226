"""An independent closed-form model of the Qube's rotary pendulum.

Derived here by Lagrange's equations, not from the MJCF. Coordinates: arm angle
theta about the vertical, pendulum angle alpha about the arm's axis (0 upright).
With l = Lp/2 the distance from pivot to the pendulum's centre of mass and the
pendulum's inertias about its centre (J_h about the hinge axis, J_n about the
axis normal to hinge and rod, J_a about the rod):

    M11 = Jr + Jm + mp Lr^2 + (mp l^2 + J_n) sin^2(alpha) + J_a cos^2(alpha)
    M12 = -mp Lr l cos(alpha)
    M22 = J_h + mp l^2
    K   = mp l^2 + J_n - J_a

    M11 theta'' + M12 alpha'' + 2 K s c theta' alpha' + mp Lr l s alpha'^2
        = kt (V - km theta') / Rm - Dr theta'
    M12 theta'' + M22 alpha'' - K s c theta'^2 - mp g l s = -Dp alpha'

(s = sin alpha, c = cos alpha). With J_n = J_a = Jm = 0 (`workbook=True`) these are
the equations of Quanser's rotary-pendulum workbook, which leave out the rod's
inertia about the vertical and the rotor's inertia.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp


class FurutaPendulum:
    """Closed-form dynamics with the parameters given by long name."""

    def __init__(self, p: dict[str, float], axial_inertia: float, workbook: bool = False):
        self.Rm, self.kt, self.km = p["motor_resistance"], p["motor_torque_constant"], p["motor_back_emf"]
        self.Jm = p["rotor_inertia"]
        self.mr, self.Lr, self.Dr = p["arm_mass"], p["arm_length"], p["arm_damping"]
        self.mp, self.Lp, self.Dp = p["pendulum_mass"], p["pendulum_length"], p["pendulum_damping"]
        self.g = p["gravity"]
        self.Jr = self.mr * self.Lr**2 / 12.0
        self.Jp = self.mp * self.Lp**2 / 12.0  # J_h
        self.Jn = 0.0 if workbook else self.Jp
        self.Ja = 0.0 if workbook else axial_inertia
        self.Jm = 0.0 if workbook else self.Jm
        self.lc = self.Lp / 2.0

    def acceleration(self, state, voltage: float) -> tuple[float, float]:
        _, alpha, dtheta, dalpha = state
        s, c = math.sin(alpha), math.cos(alpha)
        mp, lc, Lr = self.mp, self.lc, self.Lr
        m11 = self.Jr + self.Jm + mp * Lr**2 + (mp * lc**2 + self.Jn) * s * s + self.Ja * c * c
        m12 = -mp * Lr * lc * c
        m22 = self.Jp + mp * lc**2
        k = mp * lc**2 + self.Jn - self.Ja
        torque = self.kt * (voltage - self.km * dtheta) / self.Rm
        f1 = torque - self.Dr * dtheta - 2.0 * k * s * c * dtheta * dalpha - mp * Lr * lc * s * dalpha**2
        f2 = -self.Dp * dalpha + k * s * c * dtheta**2 + mp * self.g * lc * s
        det = m11 * m22 - m12 * m12
        return (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det

    def derivative(self, _t, state, voltage):
        ddtheta, ddalpha = self.acceleration(state, voltage)
        return [state[2], state[3], ddtheta, ddalpha]

    def simulate(self, state0, voltages, period: float) -> np.ndarray:
        """States after each zero-order-held voltage in `voltages`, shape (N+1, 4)."""
        states = [np.asarray(state0, float)]
        for v in voltages:
            sol = solve_ivp(self.derivative, (0.0, period), states[-1], args=(float(v),),
                            method="DOP853", rtol=1e-11, atol=1e-12)
            states.append(sol.y[:, -1])
        return np.array(states)

    def linearized_upright(self) -> tuple[np.ndarray, np.ndarray]:
        """Continuous-time (A, B) at the upright equilibrium, state [theta, alpha, dtheta, dalpha]."""
        mp, lc, Lr = self.mp, self.lc, self.Lr
        m = np.array([[self.Jr + self.Jm + mp * Lr**2 + self.Ja, -mp * Lr * lc],
                      [-mp * Lr * lc, self.Jp + mp * lc**2]])
        minv = np.linalg.inv(m)
        stiffness = np.array([[0.0, 0.0], [0.0, mp * self.g * lc]])        # d(force)/d(angle)
        damping = np.diag([self.Dr + self.kt * self.km / self.Rm, self.Dp])  # -d(force)/d(velocity)
        a = np.zeros((4, 4))
        a[:2, 2:] = np.eye(2)
        a[2:, :2] = minv @ stiffness
        a[2:, 2:] = -minv @ damping
        b = np.zeros((4, 1))
        b[2:, 0] = minv @ np.array([self.kt / self.Rm, 0.0])
        return a, b
