"""How well a model predicts a recording: MuJoCo rollouts from recorded states, 0.5 s ahead.

From a start sample, the simulated Qube (`domains.qube`, the model users train on,
with the parameters under test) is put in the state estimated there (angles plus
the encoder offsets, lag-free velocities) and driven by the recorded voltages,
shifted by the latency, for `HORIZON` seconds; its angles are compared with the
encoders'. Many short rollouts rather than one long one: the pendulum is chaotic
at large swings, so a long rollout's error says more about the start than the model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import mujoco
import mujoco.rollout
import numpy as np

from qube_suite.calibration.measurements import Measurements
from qube_suite.domains import qube

HORIZON = 0.5
"""How far ahead the rollouts predict (s)."""
START_SPACING = 0.1
"""Time between the starts of successive rollouts (s)."""


@dataclasses.dataclass(frozen=True)
class Predictions:
    """Rollouts from the starts `starts` (sample indices): predicted and measured angles, shape
    (starts, samples of the horizon + 1, 2) as [theta, alpha] (rad)."""

    starts: np.ndarray
    time: np.ndarray
    predicted: np.ndarray
    measured: np.ndarray

    @property
    def error_at_horizon(self) -> np.ndarray:
        """[theta, alpha] error (rad) at the horizon of each rollout, shape (starts, 2)."""
        return self.predicted[:, -1] - self.measured[:, -1]

    @property
    def rms_at_horizon(self) -> float:
        """RMS of both angles' errors at the horizon (rad)."""
        return float(np.sqrt(np.mean(self.error_at_horizon**2)))


def predict(measurements: Measurements, parameters: Mapping[str, float], samples: np.ndarray,
            latency: int = 0, offsets: tuple[float, float] = (0.0, 0.0)) -> Predictions:
    """0.5 s-ahead rollouts of the simulated Qube with `parameters` (long names) from starts every
    `START_SPACING` within the sample indices `samples` (whose horizons lie within them too).

    `latency`: samples between a recorded voltage and its action; `offsets`: the encoders' offsets
    (rad), added to the recorded angles.
    """
    h = measurements.sample_time
    steps = round(HORIZON / h)
    inside = np.zeros(len(measurements), dtype=bool)
    inside[samples] = True
    spacing = max(1, round(START_SPACING / h))
    candidates = np.arange(latency + 25, len(measurements) - steps - 25, spacing)
    starts = np.array([k for k in candidates if inside[k:k + steps + 1].all()], dtype=int)
    theta, dtheta = measurements.derivatives(measurements.theta)
    alpha, dalpha = measurements.derivatives(measurements.alpha)
    measured_angles = np.stack([measurements.theta + offsets[0], measurements.alpha + offsets[1]], axis=-1)
    physics = qube.make_physics(1.0 / h, parameters)
    try:
        model, data = physics.model.ptr, physics.data.ptr
        substeps = qube.substeps_per_control_period(1.0 / h)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        initial = np.empty((len(starts), mujoco.mj_stateSize(model, spec)))
        for row, k in enumerate(starts):
            mujoco.mj_resetData(model, data)
            data.qpos[:] = (theta[k] + offsets[0], alpha[k] + offsets[1])
            data.qvel[:] = (dtheta[k], dalpha[k])
            mujoco.mj_getState(model, data, initial[row], spec)
        voltage = measurements.voltage
        control = np.stack([np.repeat(voltage[k - latency:k - latency + steps], substeps) for k in starts])
        state, _ = mujoco.rollout.rollout(model, data, initial, control[..., None])
    finally:
        physics.close()
    qpos = state[:, substeps - 1::substeps, 1:3]  # after each control period; [0] is time
    predicted = np.concatenate([initial[:, None, 1:3], qpos], axis=1)
    measured = np.stack([measured_angles[k:k + steps + 1] for k in starts])
    return Predictions(starts=starts, time=np.arange(steps + 1) * h, predicted=predicted, measured=measured)
