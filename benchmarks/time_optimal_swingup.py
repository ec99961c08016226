"""The shortest swing-up of the nominal Qube under the voltage limit and the arm's range, by iLQR offline.

For a horizon T, iLQR (the controller's kernel, `qube_suite.devices.qube.controllers.ilqr`) plans
from rest hanging to rest upright with the arm centred: a terminal cost 1000
times the running one, the voltage within +-limit (3 V by default), the arm
paying beyond +-80 degrees. T is bisected between 0.4 s and 2 s, each plan
warm-started from the end of the best one so far, to the shortest T whose plan
still ends upright (|alpha| < 3 degrees, speeds below 0.5 rad/s, the arm within
+-80 degrees throughout): the time-optimal swing-up to within 20 ms. It is replayed open loop in the
MuJoCo simulation (the model the plan was made on) as a check, and drawn beside
the energy-shaping swing-up (`swingup` controller) from the same start.

    nice -n 10 .venv/bin/python benchmarks/time_optimal_swingup.py [--voltage-limit 3]
        [--figure docs/ilqr_swingup.png] [--csv docs/ilqr_swingup_3V.csv]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from qube_suite.devices.qube.controllers._ilqr import Kernel

from qube_suite import baselines, suite
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers.ilqr import Cost
from qube_suite.devices.qube.controllers.model import RigidBodyModel

H = 1 / 250
ARM_RANGE = math.radians(80.0)
HANGING = np.array([0.0, math.pi, 0.0, 0.0])
COST = Cost(pendulum=1.0, arm=0.5, arm_speed=0.01, pendulum_speed=0.01, voltage=0.001, arm_limit=ARM_RANGE,
            limit_weight=1e4, terminal=1000.0)


def upright_at_the_end(states: np.ndarray) -> bool:
    end = states[-1]
    return (abs(math.remainder(end[1], 2 * math.pi)) < math.radians(3.0)
            and max(abs(end[2]), abs(end[3])) < 0.5 and bool(np.all(np.abs(states[:, 0]) <= ARM_RANGE)))


def plan(duration: float, voltage_limit: float, warm: np.ndarray | None, iterations: int = 300) -> Kernel:
    model = RigidBodyModel.from_parameters()
    kernel = Kernel(model, COST, round(duration / H), H, voltage_limit)
    knots = kernel.knots
    if warm is None:
        frequency = math.sqrt(model.gravity_torque / model.pendulum_inertia)
        kernel.U[:] = voltage_limit * np.sin(frequency * np.arange(knots) * H)
    else:
        kernel.U[:] = warm[-knots:] if len(warm) >= knots else np.append(np.zeros(knots - len(warm)), warm)
    kernel.X[:] = HANGING
    target = np.zeros(knots + 1)
    for _ in range(iterations):
        kernel.iterate(HANGING, target, target)
    return kernel


def shortest(voltage_limit: float) -> Kernel:
    """Bisection on T between a horizon too short and one that works, to within 20 ms."""
    short, long = 0.4, 2.0
    best = plan(long, voltage_limit, None)
    if not upright_at_the_end(best.X):
        raise RuntimeError(f"no swing-up within {long} s at {voltage_limit} V")
    while long - short > 0.02:
        duration = round(0.5 * (short + long), 3)
        kernel = plan(duration, voltage_limit, best.U[-round(duration / H):])
        works = upright_at_the_end(kernel.X)
        print(f"  T = {duration:.3f} s: {'upright at the end' if works else 'not upright'}, arm within "
              f"{math.degrees(np.abs(kernel.X[:, 0]).max()):.0f} deg", flush=True)
        if works:
            best, long = kernel, duration
        else:
            short = duration
    return best


def replay(voltages: np.ndarray) -> np.ndarray:
    """States of the MuJoCo simulation from rest hanging under `voltages`, one per control period."""
    physics = qube.make_physics(250.0)
    physics.reset_to(HANGING)
    states = [HANGING]
    for volts in voltages:
        physics.set_voltage(float(volts))
        physics.step(qube.substeps_per_control_period(250.0))
        states.append(np.concatenate([physics.data.qpos, physics.data.qvel]))
    return np.array(states)


def energy_swingup(voltage_limit: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    environment = suite.load("qube", "swingup", task_kwargs={"random": 0, "voltage_limit": voltage_limit})
    controller = baselines.for_environment("swingup", environment)
    environment.reset()
    environment.physics.reset_to(HANGING + np.array([0.0, -0.01, 0.0, 0.0]))  # off the exact balance
    timestep = environment.task.get_observation(environment.physics)
    states, voltages = [np.concatenate([environment.physics.data.qpos, environment.physics.data.qvel])], []
    for _ in range(steps):
        volts = controller(timestep)
        voltages.append(volts)
        timestep = environment.step(volts).observation
        states.append(np.concatenate([environment.physics.data.qpos, environment.physics.data.qvel]))
    return np.array(states), np.array(voltages)


def upright_angle(alpha: np.ndarray) -> np.ndarray:
    """alpha wrapped to [-pi, pi) (rad), 0 upright."""
    return np.remainder(alpha + math.pi, 2 * math.pi) - math.pi


def time_to_upright(states: np.ndarray) -> float:
    """First time (s) from which |alpha| stays within 10 degrees."""
    far = np.flatnonzero(np.abs(upright_angle(states[:, 1])) > math.radians(10))
    return (far[-1] + 1) * H if len(far) else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--voltage-limit", type=float, default=3.0)
    parser.add_argument("--figure", default="docs/ilqr_swingup.png")
    parser.add_argument("--csv", default="docs/ilqr_swingup_3V.csv")
    args = parser.parse_args()
    kernel = shortest(args.voltage_limit)
    planned, voltages = kernel.X.copy(), kernel.U.copy()
    duration = len(voltages) * H
    replayed = replay(voltages)
    drift = np.abs(replayed - planned).max(axis=0)
    print(f"time-optimal swing-up at {args.voltage_limit:g} V: {duration:.2f} s, arm within "
          f"{math.degrees(np.abs(planned[:, 0]).max()):.0f} deg, voltage at the limit "
          f"{100 * np.mean(np.abs(voltages) > 0.99 * args.voltage_limit):.0f} % of the time")
    print(f"open-loop replay in MuJoCo: largest difference from the plan {drift.round(6).tolist()} "
          "(theta, alpha rad; speeds rad/s)")
    energy_states, energy_voltages = energy_swingup(args.voltage_limit, 1250)
    energy_arm = math.degrees(np.abs(energy_states[:, 0]).max())
    print(f"energy-shaping swing-up from the same start: upright (|alpha| < 10 deg for good) after "
          f"{time_to_upright(energy_states):.2f} s, arm within {energy_arm:.0f} deg")
    time = np.arange(len(planned)) * H
    table = np.column_stack([time[1:], planned[1:], voltages])
    np.savetxt(args.csv, table, delimiter=",", fmt="%.5f",
               header="time_s,theta_rad,alpha_rad,dtheta_rad_s,dalpha_rad_s,voltage_V", comments="")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(3, 1, figsize=(7, 6.5), sharex=True)
    energy_time = np.arange(len(energy_states)) * H
    runs = (("iLQR, time-optimal", time, planned, voltages, "-"),
            ("energy shaping + LQR", energy_time, energy_states, energy_voltages, "--"))
    for label, t, states, volts, style in runs:
        axes[0].plot(t, np.degrees(states[:, 0]), style, label=label)
        axes[1].plot(t, np.degrees(upright_angle(states[:, 1])), style, label=label)
        axes[2].plot(t[1:], volts, style, label=label)
    axes[0].axhline(80, color="grey", lw=0.5)
    axes[0].axhline(-80, color="grey", lw=0.5)
    axes[0].set_ylabel("arm angle (deg)")
    axes[1].set_ylabel("pendulum angle (deg)\n0 = upright")
    axes[2].set_ylabel("motor voltage (V)")
    axes[2].set_xlabel("time (s)")
    axes[0].legend(loc="upper right")
    axes[0].set_title(f"Swing-up of the nominal Qube-Servo 2 at {args.voltage_limit:g} V: "
                      f"time-optimal {duration:.2f} s")
    figure.tight_layout()
    figure.savefig(args.figure, dpi=110)
    print(f"wrote {args.figure} and {args.csv}")


if __name__ == "__main__":
    main()
