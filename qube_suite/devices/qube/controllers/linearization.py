"""Linearisation of the simulated Qube over one control period, and its fastest mode."""

from __future__ import annotations

import numpy as np

from qube_suite.devices.qube import simulation as qube


def linearize(physics: qube.Physics, state, voltage: float, nstep: int,
              epsilon: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Discrete-time (A, B) of x' = F(x, V) over `nstep` physics steps, at (`state`, `voltage`).

    Central finite differences of the simulator itself, so the result is exact
    for its integrator (MuJoCo's `mjd_transitionFD` does not support RK4).
    State order [theta, alpha, dtheta, dalpha]; angles are not wrapped, so
    linearise away from +-pi. Leaves `physics` at an arbitrary state.
    """
    state = np.asarray(state, dtype=np.float64)

    def advance(x: np.ndarray, v: float) -> np.ndarray:
        physics.reset_to(x)
        physics.set_voltage(v)
        physics.step(nstep)
        data = physics.data.ptr
        return np.concatenate([data.qpos, data.qvel])

    a = np.empty((4, 4))
    for i in range(4):
        step = np.zeros(4)
        step[i] = epsilon
        a[:, i] = (advance(state + step, voltage) - advance(state - step, voltage)) / (2 * epsilon)
    b = ((advance(state, voltage + epsilon) - advance(state, voltage - epsilon)) / (2 * epsilon))[:, None]
    return a, b


def fastest_mode(physics: qube.Physics) -> float:
    """Magnitude (1/s) of the fastest mode of the Qube's dynamics, linearised upright at rest over one
    of `physics`'s steps."""
    a, _ = linearize(physics, np.zeros(4), 0.0, 1)
    return float(np.max(np.abs(np.log(np.linalg.eigvals(a).astype(complex))))) / physics.model.opt.timestep
