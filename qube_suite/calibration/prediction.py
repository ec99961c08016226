"""How well a model predicts a recording: MuJoCo rollouts from recorded states, 0.5 s ahead.

From a start sample, the simulated Qube (`devices.qube.simulation`, the model users train on,
with the parameters under test) is put in the state estimated there from the
recording up to the start, and driven by the recorded voltages, shifted by the
latency, for `HORIZON` seconds; its angles are compared with the encoders'.
Many short rollouts rather than one long one: the pendulum is chaotic
at large swings, so a long rollout's error says more about the start than the model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import mujoco
import mujoco.rollout
import numpy as np

from qube_suite.calibration.measurements import Measurements
from qube_suite.devices.qube import simulation as qube

HORIZON = 0.5
"""How far ahead the rollouts predict (s)."""
ESTIMATION_TIME = 0.1
"""Recorded time before each start (s) that its state is estimated from."""
ESTIMATION_ITERATIONS = 2
"""Gauss-Newton iterations of that estimate."""
THROUGH_HORIZON_ITERATIONS = 4
"""Gauss-Newton iterations of a start refitted through the horizon too (from the past's estimate)."""
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
        """[theta, alpha] error (rad) at the horizon of each rollout, shape (starts, 2), wrapped to
        (-pi, pi]: a pendulum predicted one turn off over the top is where it was measured."""
        error = self.predicted[:, -1] - self.measured[:, -1]
        return np.mod(error + np.pi, 2.0 * np.pi) - np.pi

    @property
    def rms_at_horizon(self) -> float:
        """RMS of both angles' errors at the horizon (rad)."""
        return float(np.sqrt(np.mean(self.error_at_horizon**2)))


def predict(measurements: Measurements, parameters: Mapping[str, float], samples: np.ndarray,
            latency: float = 0, offsets: tuple[float, float] = (0.0, 0.0), horizon: float = HORIZON,
            voltage_deadzone: float = 0.0, cable_rest_angle: float = 0.0, cable_slack: float = 0.0,
            smoothed_start: bool = False, start_perturbation: np.ndarray | None = None,
            fit_through_horizon: bool = False) -> Predictions:
    """0.5 s-ahead rollouts of the simulated Qube with `parameters` (long names) from starts every
    `START_SPACING` within the sample indices `samples` (whose windows lie within them too).

    The state at each start is estimated from the `ESTIMATION_TIME` before it only: the model's
    rollout over that time is fitted to the recorded angles (Gauss-Newton on its initial angles and
    speeds, which start from the lag-free filter's estimate), so a prediction uses no recorded
    angle after its start. `latency`: samples between a recorded voltage and its action (a fraction
    mixes neighbouring samples, `fit.delayed_voltage`); `offsets`: the encoders' offsets (rad), added
    to the recorded angles; `horizon`: how far ahead (s); `voltage_deadzone` (V),
    `cable_rest_angle` and `cable_slack` (rad): the effects the simulation adds
    (`devices.qube.simulation.CalibratedActuation`, `devices.qube.simulation.write_cable`).
    `smoothed_start`: start instead from the zero-phase filter's angles and speeds at the start
    itself (which see half its window, 5 samples, past the start): the
    metric of `../shared/real_qube/README.md`, independent of the model.
    `start_perturbation`: [theta, alpha, theta', alpha'] added to every estimated start state before
    its rollout (how much a start's error alone moves a prediction). `fit_through_horizon`: refit
    each estimate to the recorded angles of the horizon too (where that fits the whole window
    better), not a prediction but a diagnostic that sees the future: the error left with the start
    that suits the model best is the model's own.
    """
    from qube_suite.calibration.fit import delayed_voltage

    h = measurements.sample_time
    steps, past = round(horizon / h), round(ESTIMATION_TIME / h)
    inside = np.zeros(len(measurements), dtype=bool)
    inside[samples] = True
    spacing = max(1, round(START_SPACING / h))
    candidates = np.arange(past + 25, len(measurements) - steps - 25, spacing)
    starts = np.array([k for k in candidates if inside[k - past:k + steps + 1].all()], dtype=int)
    angles = np.stack([measurements.theta + offsets[0], measurements.alpha + offsets[1]], axis=-1)
    theta, dtheta = measurements.derivatives(measurements.theta)
    alpha, dalpha = measurements.derivatives(measurements.alpha)
    if smoothed_start:
        past = 0
    first = starts - past
    guess = np.stack([theta[first] + offsets[0], alpha[first] + offsets[1], dtheta[first], dalpha[first]],
                     axis=-1)
    total = past + steps
    acting = delayed_voltage(measurements.voltage, latency)
    acting = np.sign(acting) * np.maximum(np.abs(acting) - voltage_deadzone, 0.0)
    voltages = np.stack([acting[j:j + total] for j in first])
    recorded = np.stack([angles[j:j + total + 1] for j in first])
    with _Simulator(parameters, 1.0 / h, cable_rest_angle, cable_slack) as simulator:
        if smoothed_start:
            state = guess
        else:
            state = simulator.fit_initial_state(guess, voltages[:, :past], recorded[:, :past + 1])
        if fit_through_horizon:
            state = simulator.refit_through(state, voltages, recorded)
        if start_perturbation is None:
            predicted = simulator.rollout(state, voltages)[:, past:]
        else:
            at_start = simulator.advance(state, voltages[:, :past]) + np.asarray(start_perturbation, float)
            predicted = simulator.rollout(at_start, voltages[:, past:])
    return Predictions(starts=starts, time=np.arange(steps + 1) * h, predicted=predicted,
                       measured=recorded[:, past:])


class _Simulator:
    """Batched rollouts of the simulated Qube (`mujoco.rollout`), one physics step per sample or more."""

    def __init__(self, parameters: Mapping[str, float], control_frequency: float,
                 cable_rest_angle: float = 0.0, cable_slack: float = 0.0):
        self._physics = qube.make_physics(control_frequency, parameters)
        cable = {"cable_rest_angle": cable_rest_angle, "cable_slack": cable_slack}
        self._physics.set_calibrated_effects(cable, 1.0 / control_frequency)
        self._substeps = qube.substeps_per_control_period(control_frequency)

    def __enter__(self) -> _Simulator:
        return self

    def __exit__(self, *exc) -> None:
        self._physics.close()

    def rollout(self, states: np.ndarray, voltages: np.ndarray) -> np.ndarray:
        """Angles [theta, alpha] (rollouts, samples + 1, 2) from `states` (rollouts, 4) under
        `voltages` (rollouts, samples), each held for one sample."""
        qpos = self._trajectory(states, voltages)[:, self._substeps - 1::self._substeps, 1:3]
        return np.concatenate([states[:, None, :2], qpos], axis=1)

    def advance(self, states: np.ndarray, voltages: np.ndarray) -> np.ndarray:
        """[theta, alpha, theta', alpha'] (rollouts, 4) after `voltages` (rollouts, samples) from `states`."""
        return self._trajectory(states, voltages)[:, -1, 1:5]

    def _trajectory(self, states: np.ndarray, voltages: np.ndarray) -> np.ndarray:
        """MuJoCo's full physics states (rollouts, physics steps, size) from `states` under `voltages`."""
        model, data = self._physics.model.ptr, self._physics.data.ptr
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        initial = np.zeros((len(states), mujoco.mj_stateSize(model, spec)))
        initial[:, 1:3], initial[:, 3:5] = states[:, :2], states[:, 2:]  # time, qpos, qvel, ...
        control = np.repeat(voltages, self._substeps, axis=1)[..., None]
        trajectory, _ = mujoco.rollout.rollout(model, data, initial, control)
        return trajectory

    def refit_through(self, states: np.ndarray, voltages: np.ndarray, recorded: np.ndarray) -> np.ndarray:
        """`states` refitted to the `recorded` angles of the whole windows (`THROUGH_HORIZON_ITERATIONS`
        of Gauss-Newton), each kept where its rollout fits the window worse than the refit's: upright,
        an undamped Gauss-Newton step can overshoot."""
        refit = self.fit_initial_state(states, voltages, recorded, THROUGH_HORIZON_ITERATIONS)

        def misfit(s: np.ndarray) -> np.ndarray:
            error = self.rollout(s, voltages) - recorded
            return np.sum((np.mod(error + np.pi, 2.0 * np.pi) - np.pi) ** 2, axis=(1, 2))

        return np.where((misfit(refit) < misfit(states))[:, None], refit, states)

    def fit_initial_state(self, guess: np.ndarray, voltages: np.ndarray, recorded: np.ndarray,
                          iterations: int = ESTIMATION_ITERATIONS) -> np.ndarray:
        """The states at the windows' starts whose rollouts under `voltages` best match the `recorded`
        angles (`iterations` of Gauss-Newton from `guess`, finite differences)."""
        state = guess.copy()
        steps = np.array([1e-4, 1e-4, 1e-3, 1e-3])
        for _ in range(iterations):
            batch = np.concatenate([state[None], state[None] + np.diag(steps)[:, None, :]], axis=0)
            angles = self.rollout(batch.reshape(-1, 4), np.tile(voltages, (5, 1))).reshape(5, len(state), -1)
            residual = angles[0] - recorded.reshape(len(state), -1)
            jacobian = (angles[1:] - angles[0]) / steps[:, None, None]        # (4, rollouts, samples x 2)
            normal = np.einsum("irk,jrk->rij", jacobian, jacobian) + 1e-9 * np.eye(4)
            gradient = np.einsum("irk,rk->ri", jacobian, residual)
            state -= np.linalg.solve(normal, gradient[..., None])[..., 0]
        return state
