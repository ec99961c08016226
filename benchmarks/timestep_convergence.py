"""Choose the physics integrator and timestep by convergence against a much finer run.

For each candidate (integrator, timestep) the Qube is simulated for 2 s at 250 Hz
control on three trajectories (a fall from near upright, a random voltage walk
from hanging, 3 V bang-bang from hanging) and compared with RK4 at 1/64 of 4 ms.
Criterion: angle error below a third of one encoder count (1e-3 rad) and velocity
error below 1e-2 rad/s on every trajectory; among the candidates that pass, the
cheapest per control step wins.

    python benchmarks/timestep_convergence.py
"""

from __future__ import annotations

import math
import time

import mujoco
import numpy as np

from qube_suite.devices.qube import simulation as qube

CONTROL_PERIOD = 0.004
STEPS = 500
ANGLE_TOLERANCE = 1e-3
VELOCITY_TOLERANCE = 1e-2
INTEGRATORS = {"Euler": mujoco.mjtIntegrator.mjINT_EULER,
               "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
               "RK4": mujoco.mjtIntegrator.mjINT_RK4}


def trajectories():
    rng = np.random.default_rng(0)
    yield "fall from upright", [0.0, 0.3, 0.0, 0.0], np.zeros(STEPS)
    yield "random walk", [0.0, math.pi - 0.2, 0.0, 0.0], np.clip(np.cumsum(rng.normal(0, 0.8, STEPS)), -3, 3)
    yield "bang-bang", [0.0, math.pi - 0.05, 0.0, 0.0], 3.0 * np.sign(np.sin(np.arange(STEPS) * 0.1))


def run(integrator, timestep, state0, voltages):
    physics = qube.make_physics()
    model, data = physics.model.ptr, physics.data.ptr
    model.opt.integrator = integrator
    model.opt.timestep = timestep
    nstep = round(CONTROL_PERIOD / timestep)
    physics.reset_to(state0)
    states = np.empty((len(voltages), 4))
    start = time.perf_counter()
    for i, v in enumerate(voltages):
        data.ctrl[0] = v
        mujoco.mj_step(model, data, nstep)
        states[i, :2], states[i, 2:] = data.qpos, data.qvel
    return states, (time.perf_counter() - start) / len(voltages)


def main() -> None:
    cases = list(trajectories())
    references = [run(INTEGRATORS["RK4"], CONTROL_PERIOD / 64, s, v)[0] for _, s, v in cases]
    print(f"{'integrator':13s} {'dt (ms)':>8s} {'max angle err (rad)':>20s} {'max vel err (rad/s)':>20s} "
          f"{'us/control step':>16s}  pass")
    passing = []
    for name, integrator in INTEGRATORS.items():
        for timestep in (0.004, 0.002, 0.001, 0.0005, 0.00025):
            angle_error = velocity_error = cost = 0.0
            for (_, state0, voltages), reference in zip(cases, references, strict=True):
                states, seconds = run(integrator, timestep, state0, voltages)
                angle_error = max(angle_error, np.abs(states[:, :2] - reference[:, :2]).max())
                velocity_error = max(velocity_error, np.abs(states[:, 2:] - reference[:, 2:]).max())
                cost += seconds / len(cases)
            ok = angle_error < ANGLE_TOLERANCE and velocity_error < VELOCITY_TOLERANCE
            if ok:
                passing.append((cost, name, timestep))
            print(f"{name:13s} {timestep * 1e3:8.2f} {angle_error:20.2e} {velocity_error:20.2e} "
                  f"{cost * 1e6:16.1f}  {'yes' if ok else 'no'}")
    cost, name, timestep = min(passing)
    print(f"\nchosen: {name} at {timestep * 1e3:g} ms ({cost * 1e6:.1f} us per control step)")


if __name__ == "__main__":
    main()
