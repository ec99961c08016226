"""Why the iLQR controller takes its derivatives in closed form and runs its iterations compiled.

1. Derivatives, A = dx'/dx and B = dx'/du over one 4 ms control period, at random
   states and voltages, against the exact linearisation of the simulator
   (central differences of MuJoCo's own RK4 step, `baselines.linearization`):
   * closed form: the rigid-body model's Jacobian chained through RK4 (the kernel);
   * `mujoco.mjd_transitionFD` on model.xml, which refuses RK4, with the Euler and
     the implicitfast integrators at 4 ms;
   error as the largest |entry - exact| relative to the largest |exact entry| of
   each of A and B (median and worst over the states), and time per Jacobian.
2. One iLQR iteration over a 0.8 s horizon (200 knots): the numpy transcription
   (`reference_iteration`) against the compiled kernel, on the same problem.

Times are CPU time of the calling thread (`time.thread_time`), which leaves out
the time other processes hold the core: on a shared machine wall-clock times of
sub-millisecond calls mostly measure the scheduler.

    nice -n 10 .venv/bin/python benchmarks/ilqr.py [--states 200] [--repeats 20]
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco
import numpy as np

from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers.ilqr import IterativeLQR, reference_iteration
from qube_suite.devices.qube.controllers.linearization import linearize

H = 1 / 250


def random_states(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    random = np.random.default_rng(seed)
    states = np.column_stack([random.uniform(-1.5, 1.5, count), random.uniform(-math.pi, math.pi, count),
                              random.uniform(-10, 10, count), random.uniform(-25, 25, count)])
    return states, random.uniform(-3, 3, count)


def fd_transition(integrator: int):
    """A function (state, volts) -> (A, B) by `mjd_transitionFD` on model.xml with `integrator` at 4 ms."""
    model = mujoco.MjModel.from_xml_path(str(qube.MODEL_PATH))
    model.opt.timestep = H
    model.opt.integrator = integrator
    data = mujoco.MjData(model)
    a, b = np.zeros((4, 4)), np.zeros((4, 1))

    def jacobians(state, volts):
        data.qpos[:], data.qvel[:], data.ctrl[0] = state[:2], state[2:], volts
        mujoco.mjd_transitionFD(model, data, 1e-6, True, a, b, None, None)
        return a.copy(), b[:, 0].copy()

    return jacobians


def relative_error(estimate: np.ndarray, exact: np.ndarray) -> float:
    return float(np.max(np.abs(estimate - exact)) / np.max(np.abs(exact)))


def derivatives(count: int) -> None:
    states, voltages = random_states(count)
    physics = qube.make_physics(250.0)
    substeps = qube.substeps_per_control_period(250.0)
    exact = [linearize(physics, s, v, substeps) for s, v in zip(states, voltages, strict=True)]
    kernel = IterativeLQR().kernel

    def closed_form(state, volts):
        jacobian = kernel.step(state, volts, H)[1]
        return jacobian[:, :4], jacobian[:, 4]

    methods = {"closed form + RK4 chain (kernel)": closed_form,
               "mjd_transitionFD, Euler": fd_transition(mujoco.mjtIntegrator.mjINT_EULER),
               "mjd_transitionFD, implicitfast": fd_transition(mujoco.mjtIntegrator.mjINT_IMPLICITFAST)}
    print(f"derivatives over one 4 ms step at {count} random states; error relative to the simulator's own")
    print(f"{'method':36s} {'A median':>9s} {'A worst':>9s} {'B median':>9s} {'B worst':>9s} {'us/call':>8s}")
    for name, method in methods.items():
        errors_a, errors_b = [], []
        for (state, volts), (a, b) in zip(zip(states, voltages, strict=True), exact, strict=True):
            estimate_a, estimate_b = method(state, volts)
            errors_a.append(relative_error(estimate_a, a))
            errors_b.append(relative_error(estimate_b, b[:, 0]))
        start = time.thread_time()
        for state, volts in zip(states, voltages, strict=True):
            method(state, volts)
        per_call = (time.thread_time() - start) / count * 1e6
        print(f"{name:36s} {np.median(errors_a):9.1e} {np.max(errors_a):9.1e} {np.median(errors_b):9.1e} "
              f"{np.max(errors_b):9.1e} {per_call:8.1f}")


def iterations(repeats: int) -> None:
    controller = IterativeLQR(horizon=0.8)
    kernel = controller.kernel
    knots = kernel.knots
    x0 = np.array([0.1, 2.8, 0.0, 1.0])
    reference, speed = np.zeros(knots + 1), np.zeros(knots + 1)
    start_plan = 1.5 * np.sin(10.7 * np.arange(knots) * H)
    timings = {"numpy (reference_iteration)": [], "compiled kernel": []}
    for _ in range(repeats):
        U, X, K = start_plan.copy(), np.zeros((knots + 1, 4)), np.zeros((knots, 4))
        start = time.thread_time()
        reference_iteration(controller.model, controller.cost, H, 3.0, x0, U, X, K, reference, speed, 0.0,
                            kernel)
        timings["numpy (reference_iteration)"].append(time.thread_time() - start)
        kernel.U[:], kernel.X[:], kernel.K[:], kernel.regularization = start_plan, 0.0, 0.0, 0.0
        start = time.thread_time()
        kernel.iterate(x0, reference, speed)
        timings["compiled kernel"].append(time.thread_time() - start)
    print(f"\none iLQR iteration, {knots} knots (0.8 s at 250 Hz), {repeats} repeats, one core")
    medians = {name: float(np.median(t)) for name, t in timings.items()}
    for name, t in timings.items():
        print(f"  {name:30s} median {medians[name] * 1e3:8.3f} ms, worst {max(t) * 1e3:8.3f} ms")
    ratio = medians["numpy (reference_iteration)"] / medians["compiled kernel"]
    print(f"  ratio numpy / kernel: {ratio:.0f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    derivatives(args.states)
    iterations(args.repeats)


if __name__ == "__main__":
    main()
