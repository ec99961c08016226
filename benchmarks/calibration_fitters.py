"""Which fitter calibrates the Qube better: the equation-error fit or MuJoCo rollouts (output error)?

On the same experiments on hidden plants of the substitute (drawn as in
`benchmarks/calibration.py`), compares

* `equation error`: `qube_suite.calibration.fit` (the Qube's momentum balances and motor
  circuit, weak form, `mujoco.minimize.least_squares`);
* `output error`: the simulated Qube (`devices.qube.simulation`, MuJoCo) rolled out over short
  windows (multiple shooting: `WINDOW` s from every `SPACING` s of the training blocks,
  each from the lag-free filter's state at its start) under the recorded voltages,
  its angles fitted to the encoders' by `mujoco.minimize.least_squares` over the
  same parameters scaled near 1 (batched rollouts, `mujoco.rollout`, one model per
  finite-difference column). Angles alone give only kt / Rm and kt km / Rm, so the
  motor's resistance and back-EMF come from the circuit equation as in the first fitter.

Reports each fitter's relative error per parameter (median, worst) and its wall time.

    python benchmarks/calibration_fitters.py [--plants 5] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time

import mujoco
import mujoco.minimize
import mujoco.rollout
import numpy as np

from qube_suite import calibration
from qube_suite.calibration import experiment, fit, measurements
from qube_suite.devices.qube import simulation as qube

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from calibration import hidden_plant, truth  # noqa: E402  (the benchmark beside this one)

WINDOW = 0.3
"""Length of each rollout (s)."""
SPACING = 0.25
"""Time between the rollouts' starts (s)."""
MECHANICAL = ("motor_torque_constant", "pendulum_mass", "pendulum_length", "arm_damping", "arm_friction",
              "cable_stiffness", "pendulum_damping", "pendulum_friction")
"""Parameters the output-error fit estimates (scaled as in `fit`)."""


def output_error_fit(m: measurements.Measurements, samples: np.ndarray, circuit: dict[str, float]) -> dict:
    """The output-error estimate of `MECHANICAL` on the sample indices `samples`, with the motor's
    resistance and back-EMF from `circuit`."""
    h = m.sample_time
    steps = round(WINDOW / h)
    inside = np.zeros(len(m), dtype=bool)
    inside[samples] = True
    starts = np.array([k for k in range(40, len(m) - steps - 40, round(SPACING / h))
                       if inside[k:k + steps + 1].all()])
    theta, dtheta = m.derivatives(m.theta)
    alpha, dalpha = m.derivatives(m.alpha)
    physics = qube.make_physics(1.0 / h)
    model, data = physics.model.ptr, physics.data.ptr
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.zeros((len(starts), mujoco.mj_stateSize(model, spec)))
    initial[:, 1:5] = np.stack([theta[starts], alpha[starts], dtheta[starts], dalpha[starts]], axis=-1)
    control = np.stack([m.voltage[k:k + steps] for k in starts])[..., None]
    measured = np.stack([np.stack([m.theta[k + 1:k + steps + 1], m.alpha[k + 1:k + steps + 1]], axis=-1)
                         for k in starts])
    scales = np.array([fit.SCALES[fit.NAMES.index(name)] for name in MECHANICAL])
    models = [mujoco.MjModel.from_xml_path(str(qube.MODEL_PATH)) for _ in range(len(MECHANICAL) + 1)]

    def residual(x: np.ndarray) -> np.ndarray:
        x = x.reshape(len(MECHANICAL), -1)
        columns = []
        for column in range(x.shape[1]):
            model_k = models[column]
            model_k.opt.timestep = model.opt.timestep
            qube.write_parameters(model_k, data, {**circuit, **dict(zip(MECHANICAL, x[:, column] * scales,
                                                                        strict=True))})
            state, _ = mujoco.rollout.rollout(model_k, data, initial, control)
            columns.append((state[:, :, 1:3] - measured).ravel())
        return np.stack(columns, axis=1)

    x0 = np.ones(len(MECHANICAL))
    lower = np.array([0.3, 0.3, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    upper = np.array([3.0, 3.0, 3.0, 30.0, 30.0, 30.0, 30.0, 30.0])
    x, _ = mujoco.minimize.least_squares(x0, residual, bounds=[lower, upper], verbose=0, max_iter=30)
    physics.close()
    return dict(zip(MECHANICAL, x * scales, strict=True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plants", type=int, default=5)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    errors = {"equation error": [], "output error": []}
    times = {"equation error": [], "output error": []}
    for index in range(args.plants):
        plant = hidden_plant(rng)
        true = truth(plant)
        recording = tempfile.mktemp(suffix=".jsonl")
        experiment.run(recording, "qube_hardware", {"plant": plant}, seed=index)
        m = measurements.load(recording)
        train = np.flatnonzero(~calibration.held_out(m))
        start = time.perf_counter()
        result = fit.fit(m, train)
        times["equation error"].append(time.perf_counter() - start)
        equation = result.values
        start = time.perf_counter()
        output = output_error_fit(m, train, {name: equation[name] for name in ("motor_resistance",
                                                                                 "motor_back_emf")})
        times["output error"].append(time.perf_counter() - start)
        for name, estimates in (("equation error", equation), ("output error", output)):
            errors[name].append({p: estimates[p] - true[p] for p in MECHANICAL} | {
                f"{p} (relative)": estimates[p] / true[p] - 1.0 for p in MECHANICAL[:3]})
        print(f"plant {index}: " + "; ".join(
            f"{name}: " + ", ".join(f"{p} {errors[name][-1][p + ' (relative)']:+.3f}" for p in MECHANICAL[:3])
            + f", arm_friction {errors[name][-1]['arm_friction']:+.2e}, {times[name][-1]:.1f} s"
            for name in errors), flush=True)
    for name in errors:
        print(f"\n{name}: wall time median {np.median(times[name]):.1f} s")
        for key in errors[name][0]:
            values = np.abs([row[key] for row in errors[name]])
            print(f"  {key:34s} median {np.median(values):.3g}  worst {values.max():.3g}")


if __name__ == "__main__":
    main()
