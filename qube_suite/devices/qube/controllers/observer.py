"""State observer: the Qube's state from its encoder angles, predicted over the loop's latency.

Why: a real Qube's velocities are estimates. Quanser's 50 s/(s + 50) filter (that
of the `qube_hardware` domain) lags by 1/wc = 20 ms, and near upright, where the
pendulum's speed changes fastest, the lag biases both the energy a swing-up pumps
to and the state an LQR catches (at alpha = 28 degrees: -3.2 rad/s filtered for a
true -1.4). The filter's output carries no information that the sampled angles do
not, so each controller estimates the state from the angles itself, with the model
(`RigidBodyModel.accelerations`) doing what the filter's lag cannot: predicting.

Observer, once per control period T, for the measured angles y:

    prediction  x- = Phi_T(x, u, b): RK4 of the model with the voltage u that acted
                over the period, plus unknown accelerations b = (b_theta, b_alpha),
                which it holds constant (in the physics' substeps of at most 4 ms);
    correction  e_j = y_j - x-_j (alpha's wrapped), then for each joint j
                (angle_j, speed_j, b_j) += (g0, g1, g2)_j e_j.

The gains are the steady-state Kalman gain of each joint seen as a triple
integrator (angle, speed, b), b a random walk driven by white jerk of intensity
sigma_j, measured through the encoder's quantisation, variance q^2/12 with
q = 2 pi / 2048 rad. b stands for the torque the model leaves out: a real Qube's
Coulomb friction (estimated at F = 1e-3 N m on the arm, `hardware/plant.py`), the
cable's spring (1e-3 N m/rad), parameter error. Friction is a telegraph signal:
it flips by 2 F whenever the arm reverses, about twice per swing of the pendulum,
at the rate lambda = w0 / pi (w0^2 = mp g l / M22, 3.4 flips/s). Near upright,
where arm and pendulum move together, a flip accelerates them by
|M^-1 (2 F, 0)| = 19 rad/s^2 each. Over a short time t a telegraph signal's
change has the variance (jump)^2 lambda t of a random walk, so
sigma_j = |M^-1 (2 F, 0)_j| sqrt(lambda): gains of (0.50, 42 /s, 1.8e3 /s^2) at
250 Hz, the error poles at 86 rad/s. Constant unknown torques then cost no
bias (b absorbs them), and the estimate does not lag what the model predicts.
On `qube_hardware` the results are the same for sigma_j ten times smaller or
ten times larger; larger gains pass more of the angles' noise to the speeds and
to b.

Latency: when a voltage acts `latency_steps` = N samples after the measurement it
answers (1 on hardware: a step reads a sample and then writes), the estimate is
predicted N periods ahead with the voltages already sent, and the controller
answers that prediction. For a linear model and an LQR this is exactly the LQR of
the plant augmented with its delay line [x_k, u_(k-N) ... u_(k-1)], cost on x only:
x_(k+N) is fixed by what was already sent, and from there on the problem is the
undelayed one, so u_k = -K x_(k+N).
"""

from __future__ import annotations

import collections
import math

import numpy as np
import scipy.linalg

from qube_suite.angles import wrap_angle
from qube_suite.devices.qube import parameters as params
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers.model import RigidBodyModel

UNMODELLED_TORQUE = 1.0e-3
"""F (N m): size of the arm torque the model leaves out (a real Qube's Coulomb friction)."""
RESYNC_ANGLE = 0.3
"""A measured angle this far (rad) from the prediction restarts the estimate from the
measurement: no unmodelled torque moves the Qube so far in a sample; it means a new
episode without `reset()`."""


def advance(accelerations, bias, state, volts, substep: float, substeps: int) -> tuple:
    """`state` (theta, alpha, dtheta, dalpha: floats, or arrays of worlds) `substeps` RK4 steps of
    `substep` seconds later under `volts` (V), the accelerations `accelerations(alpha, dtheta, dalpha,
    volts)` plus the unknown ones `bias` (rad/s^2); the accelerations do not depend on theta."""
    h = substep
    bias_theta, bias_alpha = bias
    theta, alpha, dtheta, dalpha = state
    for _ in range(substeps):
        a1, b1 = accelerations(alpha, dtheta, dalpha, volts)
        a1, b1 = a1 + bias_theta, b1 + bias_alpha
        v2, w2 = dtheta + 0.5 * h * a1, dalpha + 0.5 * h * b1
        a2, b2 = accelerations(alpha + 0.5 * h * dalpha, v2, w2, volts)
        a2, b2 = a2 + bias_theta, b2 + bias_alpha
        v3, w3 = dtheta + 0.5 * h * a2, dalpha + 0.5 * h * b2
        a3, b3 = accelerations(alpha + 0.5 * h * w2, v3, w3, volts)
        a3, b3 = a3 + bias_theta, b3 + bias_alpha
        v4, w4 = dtheta + h * a3, dalpha + h * b3
        a4, b4 = accelerations(alpha + h * w3, v4, w4, volts)
        a4, b4 = a4 + bias_theta, b4 + bias_alpha
        theta = theta + h / 6.0 * (dtheta + 2.0 * v2 + 2.0 * v3 + v4)
        alpha = alpha + h / 6.0 * (dalpha + 2.0 * w2 + 2.0 * w3 + w4)
        dtheta = dtheta + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        dalpha = dalpha + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
    return theta, alpha, dtheta, dalpha


def kalman_gain(a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Steady-state Kalman gain L (n x m) for x' = a x + w, y = c x + v, cov(w) = q, cov(v) = r.

    The update after each prediction is x += L (y - c x); L = P c^T (c P c^T + r)^-1,
    P the predicted covariance, which solves the filter's discrete Riccati equation.
    """
    p = scipy.linalg.solve_discrete_are(a.T, c.T, q, r)
    return p @ c.T @ np.linalg.inv(c @ p @ c.T + r)


def joint_gain(period: float, jerk: float, noise: float) -> np.ndarray:
    """Kalman gain (g0, g1 (1/s), g2 (1/s^2)) of one joint: angle, speed and unknown acceleration b
    over `period` (s), b a random walk of white jerk intensity `jerk` (rad/s^2.5), angles measured
    with noise of standard deviation `noise` (rad). The process noise is the exact discretisation
    of the white jerk over the period."""
    t = period
    a = np.array([[1.0, t, t * t / 2.0], [0.0, 1.0, t], [0.0, 0.0, 1.0]])
    q = jerk**2 * np.array([[t**5 / 20.0, t**4 / 8.0, t**3 / 6.0],
                            [t**4 / 8.0, t**3 / 3.0, t**2 / 2.0],
                            [t**3 / 6.0, t**2 / 2.0, t]])
    return kalman_gain(a, np.array([[1.0, 0.0, 0.0]]), q, np.array([[noise**2]]))[:, 0]


class StateObserver:
    """[theta, alpha, dtheta, dalpha] estimated from the measured angles (see the module).

    Args:
        model: the Qube's rigid-body model.
        control_frequency: samples per second (Hz).
        latency_steps: samples between a measurement and the first sample at which the
            voltage answering it acts.
    """

    def __init__(self, model: RigidBodyModel, control_frequency: float, latency_steps: int = 0):
        if not (isinstance(latency_steps, int) and latency_steps >= 0):
            raise ValueError(f"latency_steps must be a non-negative integer, got {latency_steps!r}")
        self.model = model
        self.latency_steps = latency_steps
        substeps = qube.substeps_per_control_period(control_frequency)
        self._substeps, self._substep = substeps, 1.0 / (control_frequency * substeps)
        period = 1.0 / control_frequency
        noise = 2.0 * math.pi / params.ENCODER_COUNTS_PER_REVOLUTION / math.sqrt(12.0)
        upright_mass = np.array([[model.base_inertia, -model.coupling],
                                 [-model.coupling, model.pendulum_inertia]])
        jumps = np.abs(np.linalg.solve(upright_mass, [2.0 * UNMODELLED_TORQUE, 0.0]))
        reversal_rate = math.sqrt(model.gravity_torque / model.pendulum_inertia) / math.pi
        self.gains = [tuple(joint_gain(period, jump * math.sqrt(reversal_rate), noise).tolist())
                      for jump in jumps]
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next measurement, velocities included, starts the estimate."""
        self._state: list[float] | None = None
        self._bias = [0.0, 0.0]
        self._voltages = collections.deque([0.0] * (self.latency_steps + 1), maxlen=self.latency_steps + 1)

    def __call__(self, measured: np.ndarray) -> np.ndarray:
        """The state (rad, rad/s) at the sample the next voltage first acts on, given the `measured`
        [theta, alpha, dtheta, dalpha]: only its angles count once the estimate has started."""
        theta, alpha = float(measured[0]), float(measured[1])
        if self._state is not None:
            predicted = self._advance(self._state, self._voltages[0])
            errors = (theta - predicted[0], wrap_angle(alpha - predicted[1]))
            if max(abs(errors[0]), abs(errors[1])) > RESYNC_ANGLE:
                self.reset()
            else:
                for joint, (error, gain) in enumerate(zip(errors, self.gains, strict=True)):
                    predicted[joint] += gain[0] * error
                    predicted[2 + joint] += gain[1] * error
                    self._bias[joint] += gain[2] * error
                predicted[1] = wrap_angle(predicted[1])
                self._state = predicted
        if self._state is None:
            self._state = [theta, alpha, float(measured[2]), float(measured[3])]
        state = self._state
        for k in range(1, self.latency_steps + 1):
            state = self._advance(state, self._voltages[k])
        return np.array([state[0], wrap_angle(state[1]), state[2], state[3]])

    @property
    def unmodelled_accelerations(self) -> tuple[float, float]:
        """b = (b_theta, b_alpha) (rad/s^2): the accelerations the model does not explain."""
        return self._bias[0], self._bias[1]

    def command(self, volts: float) -> None:
        """Record the voltage (V) sent in answer to the last measurement."""
        self._voltages.append(float(volts))

    def correct_command(self, volts: float) -> None:
        """Replace the voltage recorded for the last measurement by `volts` (V), the one really sent."""
        self._voltages[-1] = float(volts)

    def _advance(self, state: list[float], volts: float) -> list[float]:
        """`state` one control period later under `volts` (V) and the unknown accelerations."""
        return list(advance(self.model.accelerations, self._bias, state, volts, self._substep,
                            self._substeps))
