"""Evidence for the default voltage limit: the smallest in [3, 10] V allowing a swing-up within +-90 degrees.

Runs the sampling MPC swing-up (`qube_suite.devices.qube.controllers.SamplingMPC`) on the nominal
simulated Qube at increasing voltage limits and stops at the first limit where
every seed swings up and balances without the arm leaving +-90 degrees. Limits
below the allowed range are shown for context. One trajectory at the chosen limit
is written as CSV.

    python benchmarks/voltage_limit.py [--seeds 5] [--csv docs/swingup_3V.csv]
"""

from __future__ import annotations

import argparse
import csv
import math

import numpy as np

from qube_suite import baselines, suite

ALLOWED = [3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0]
CONTEXT = [1.5, 2.0, 2.5]


def swing_up(voltage_limit: float, seed: int, record: list | None = None) -> dict:
    env = suite.load("qube", "swingup", task_kwargs={"random": seed, "voltage_limit": voltage_limit})
    controller = baselines.make("mpc", voltage_limit=voltage_limit, seed=seed)
    timestep = env.reset()
    episode_return, largest_arm_angle, upright_at = 0.0, 0.0, None
    while not timestep.last():
        action = controller(timestep.observation)
        timestep = env.step(action)
        episode_return += timestep.reward
        theta, alpha, dtheta, dalpha = timestep.observation["state"]
        largest_arm_angle = max(largest_arm_angle, abs(theta))
        if upright_at is None and abs(alpha) < math.radians(10):
            upright_at = env.physics.time()
        if record is not None:
            record.append((env.physics.time(), theta, alpha, dtheta, dalpha, env.physics.voltage()))
    controller.close()
    held = timestep.discount == 1.0 and abs(alpha) < math.radians(10)
    return {"return": episode_return, "upright_at": upright_at,
            "largest_arm_deg": math.degrees(largest_arm_angle),
            "success": held and upright_at is not None and largest_arm_angle < math.pi / 2}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--csv", default=None, help="write the seed-0 trajectory at the chosen limit here")
    args = parser.parse_args()

    print(f"{'limit (V)':>9s} {'successes':>10s} {'mean return':>12s} {'upright at (s)':>15s} "
          f"{'max |theta| (deg)':>18s}")
    chosen = None
    for limit in CONTEXT + ALLOWED:
        results = [swing_up(limit, seed) for seed in range(args.seeds)]
        ups = [r["upright_at"] for r in results if r["upright_at"] is not None]
        print(f"{limit:9.1f} {sum(r['success'] for r in results):6d}/{args.seeds:<3d} "
              f"{np.mean([r['return'] for r in results]):12.0f} "
              f"{(f'{np.mean(ups):.2f}' if ups else '-'):>15s} "
              f"{max(r['largest_arm_deg'] for r in results):18.0f}"
              f"{'' if limit in ALLOWED else '   (below the allowed range)'}")
        if limit in ALLOWED and all(r["success"] for r in results):
            chosen = limit
            break
    print(f"\nsmallest limit in [3, 10] V with a swing-up on every seed: {chosen} V")
    if chosen is not None and args.csv:
        record: list = []
        swing_up(chosen, 0, record)
        with open(args.csv, "w", newline="") as file:
            writer = csv.writer(file)
            writer.writerow(["time_s", "theta_rad", "alpha_rad", "dtheta_rad_s", "dalpha_rad_s", "voltage_V"])
            writer.writerows((f"{t:.3f}", *(f"{x:.5f}" for x in row)) for t, *row in record)
        print(f"trajectory written to {args.csv}")


if __name__ == "__main__":
    main()
