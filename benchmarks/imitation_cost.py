"""What an imitation step costs: the teacher's labels (one `swingup` controller per world against
`BatchedSwingup`) and the fit (passes and minibatch), each against its peer in the same run.

Teachers: 64 worlds of `swingup` under `wide` (history 8, as `swingup_adaptive`), the teacher's
voltages sent; each labelling is timed for the per-world controllers and the batch on the same
features, interleaved, in CPU time of this process (the machine may be shared). Also the time to
design them: 64 designs (each solves its Riccati equations) against one.

Fit: the actor of `swingup_adaptive` (two tanh layers of 128) fitted by least squares to the labels
of those steps, from the same start, for each (passes, minibatch) setting; reports the CPU time and
the mean squared error (V^2) on all labels after each pass.

    python benchmarks/imitation_cost.py [--steps 800] [--fits 8x4096 2x1024]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from qube_suite import baselines
from qube_suite.conventions import ObservationLayout
from qube_suite.devices.qube.controllers.batched import BatchedSwingup
from qube_suite.training import imitation
from qube_suite.training.environments import make_vec_env

WORLDS = 64


def teachers(steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Time the two teachers over `steps` vector steps; return the features and labels seen."""
    venv = make_vec_env("swingup", WORLDS, 0, exploring_starts=imitation.EXPLORING_STARTS, history=8,
                        randomization="wide")
    limit = float(venv.action_space.high[0])
    design = {"voltage_limit": limit, "latency_steps": imitation.TEACHER_LATENCY_STEPS}
    start = time.process_time()
    controllers = [baselines.make("swingup", **design) for _ in range(WORLDS)]
    designs_each = time.process_time() - start
    start = time.process_time()
    batch = BatchedSwingup(baselines.make("swingup", **design), WORLDS)
    design_once = time.process_time() - start
    for controller in controllers:
        controller.observation_layout = ObservationLayout("trig")
    observations = venv.reset()
    inputs, labels, worst = [], [], 0.0
    each = once = 0.0
    for _ in range(steps):
        features = observations[:, :6]
        start = time.process_time()
        expected = np.array([controller(row) for controller, row in zip(controllers, features, strict=True)])
        each += time.process_time() - start
        start = time.process_time()
        volts = batch(ObservationLayout("trig").split_rows(features)[0])
        once += time.process_time() - start
        worst = max(worst, float(np.abs(volts - expected).max()))
        inputs.append(observations)
        labels.append(volts)
        observations, _, dones, _ = venv.step(volts[:, None])
        for world in np.flatnonzero(dones):
            controllers[world].reset()
        batch.reset(dones)
    venv.close()
    print(f"teacher labels, {WORLDS} worlds, {steps} steps (CPU s): one controller per world {each:.2f}, "
          f"batched {once:.2f}: {each / once:.1f} x; largest difference {worst:.1e} V")
    print(f"design (CPU s): {WORLDS} controllers {designs_each:.2f}, one {design_once:.3f}")
    return np.concatenate(inputs).astype(np.float32), np.concatenate(labels).astype(np.float32)


def fits(inputs: np.ndarray, labels: np.ndarray, settings: list[tuple[int, int]]) -> None:
    """Fit the actor from one start with each (passes, minibatch) setting; print cost and error."""
    import torch

    torch.set_num_threads(1)
    mean, var = inputs.mean(axis=0), inputs.var(axis=0)
    x = torch.as_tensor(np.clip((inputs - mean) / np.sqrt(var + 1e-8), -10.0, 10.0).astype(np.float32))
    y = torch.as_tensor(labels)
    for passes, minibatch in settings:
        torch.manual_seed(0)
        random = np.random.default_rng(0)
        actor = torch.nn.Sequential(torch.nn.Linear(x.shape[1], 128), torch.nn.Tanh(),
                                    torch.nn.Linear(128, 128), torch.nn.Tanh(), torch.nn.Linear(128, 1))
        optimizer = torch.optim.Adam(actor.parameters(), lr=imitation.LEARNING_RATE)
        cost, errors = 0.0, []
        for _ in range(passes):
            start = time.process_time()
            for batch in torch.as_tensor(random.permutation(len(y))).split(minibatch):
                loss = torch.nn.functional.mse_loss(actor(x[batch])[:, 0], y[batch])
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
            cost += time.process_time() - start
            with torch.no_grad():
                errors.append(float(torch.nn.functional.mse_loss(actor(x)[:, 0], y)))
        print(f"fit {passes} passes of {minibatch} on {len(y)} labels: {cost:.1f} CPU s, error after each "
              f"pass (V^2): {', '.join(f'{e:.3f}' for e in errors)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=800, help="vector steps of 64 worlds")
    parser.add_argument("--fits", nargs="+", default=["8x4096", "2x1024"], help="PASSESxMINIBATCH")
    args = parser.parse_args()
    inputs, labels = teachers(args.steps)
    fits(inputs, labels, [tuple(int(n) for n in setting.split("x")) for setting in args.fits])


if __name__ == "__main__":
    main()
