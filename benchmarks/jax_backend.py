"""The JAX backend (`qube_suite.mjx`) against the numpy vector environment, and training on it.

    python benchmarks/jax_backend.py throughput [--worlds 256 1024] [--steps 100] [--presets none sim2real] \
        [--tasks swingup rotor swingup_follow]
    python benchmarks/jax_backend.py train --task swingup --randomization sim2real --steps 150000000 \
        --out runs/jax_swingup [--set num_updates_per_batch=4 ...] [--json FILE]

`throughput`: env steps per second with a policy network in the loop (Brax's PPO
policy, randomly initialised, deterministic actions): MJX worlds batched with
`jax.vmap` inside one `jax.lax.scan` per measurement (compilation excluded), and
in the same run the numpy vector environment (`gymnasium.make_vec`, native batch of
MuJoCo rollouts) with the same number of worlds, the same task and preset and a
network of the same shape on the same features run by numpy (the peer); by default
swing-up on the nominal plant and under `sim2real`. `--tasks` measures others: the
rotor's revolution count and a follow task's target are carried in the JAX state.
`train`: Brax PPO on the backend (`qube_suite.mjx.training`; `--set` changes one of its
`HYPERPARAMETERS`), the policy of every
evaluation kept as `snapshots/<steps>.npz` for evaluation on the numpy domains
(`qube-suite eval`, `benchmarks/held_out.py`); end-to-end env steps per second
between the first and last evaluation (compilation excluded) and the wall times.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import jax
import jax.numpy as jnp
import numpy as np
from brax.training.agents.ppo import networks as ppo_networks

from qube_suite.mjx import training
from qube_suite.mjx.environment import QubeMjx
from qube_suite.policies import features

PRESETS = ("none", "sim2real")
"""The presets `throughput` measures unless told others."""


def mjx_rate(task: str, preset: str, worlds: int, steps: int) -> float:
    """Env steps/s of `worlds` MJX worlds running `steps` steps of `task` with a policy in the loop."""
    env = QubeMjx(task, randomization=preset)
    keys = jax.random.split(jax.random.PRNGKey(0), worlds)
    batch, axes = env.draw_worlds(env.sys, keys) if preset != "none" else (env.sys, None)
    network = ppo_networks.make_ppo_networks(env.observation_size, env.action_size)
    params = network.policy_network.init(jax.random.PRNGKey(1))
    normalizer = _identity_normalizer(env.observation_size)

    def world(sys, key):
        env.sys = sys
        state = env.reset(key)

        def body(state, _):
            logits = network.policy_network.apply(normalizer, params, state.obs)
            action = jnp.tanh(logits[: env.action_size])
            return env.step(state, action), None

        state, _ = jax.lax.scan(body, state, None, length=steps)
        return state.reward

    run = jax.jit(jax.vmap(world, in_axes=(axes, 0)))
    run(batch, keys).block_until_ready()  # compile
    start = time.perf_counter()
    run(batch, keys).block_until_ready()
    return worlds * steps / (time.perf_counter() - start)


def numpy_rate(task: str, preset: str, worlds: int, steps: int) -> float:
    """Env steps/s of the numpy vector environment with `worlds` worlds of `task`, a network of the same
    shape in numpy on the same features."""
    import gymnasium

    from qube_suite.wrappers.registration import gymnasium_id

    envs = gymnasium.make_vec(gymnasium_id(task), num_envs=worlds,
                              vectorization_mode="vector_entry_point", randomization=preset)
    observations, _ = envs.reset(seed=0)
    rng = np.random.default_rng(0)
    sizes = [features.trig(observations).shape[1], 32, 32, 32, 32, 2]
    layers = [(rng.normal(size=(b, a)) / np.sqrt(a), np.zeros(b))
              for a, b in zip(sizes, sizes[1:], strict=False)]
    start = time.perf_counter()
    for _ in range(steps):
        x = features.trig(observations)
        for i, (weight, bias) in enumerate(layers):
            x = x @ weight.T + bias
            if i < len(layers) - 1:
                x = x / (1.0 + np.exp(-x))
        observations, *_ = envs.step(np.tanh(x[:, :1]) * 3.0)
    rate = worlds * steps / (time.perf_counter() - start)
    envs.close()
    return rate


def _identity_normalizer(size: int):
    from brax.training.acme import running_statistics, specs

    return running_statistics.init_state(specs.Array((size,), jnp.dtype("float32")))


def throughput(args) -> dict:
    rows = []
    for task, preset, worlds in itertools.product(args.tasks, args.presets, args.worlds):
        row = {"task": task, "preset": preset, "worlds": worlds,
               "mjx_steps_per_s": mjx_rate(task, preset, worlds, args.steps)}
        if worlds <= args.numpy_worlds_max:
            row["numpy_steps_per_s"] = numpy_rate(task, preset, worlds, max(10, args.steps // 10))
            row["ratio"] = row["mjx_steps_per_s"] / row["numpy_steps_per_s"]
        print(json.dumps(row), flush=True)
        rows.append(row)
    return {"throughput": rows}


def hyperparameter(text: str) -> tuple[str, int | float]:
    """`KEY=VALUE` of `--set` as (key, number); argparse reports a malformed one."""
    key, equals, value = text.partition("=")
    known = {**training.HYPERPARAMETERS, **training.ENVIRONMENT_SETTINGS}
    if not equals or key not in known:
        raise argparse.ArgumentTypeError(f"expected KEY=NUMBER with KEY one of {', '.join(known)}, "
                                         f"got {text!r}")
    try:
        return key, int(value) if value.lstrip("-").isdigit() else float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{key}: expected a number, got {value!r}") from None


def train(args) -> dict:
    hyperparameters = dict(args.set)
    if args.num_envs is not None:
        hyperparameters["num_envs"] = args.num_envs
    if args.num_evals is not None:
        hyperparameters["num_evals"] = args.num_evals
    result = training.train(args.task, steps=args.steps, randomization=args.randomization, seed=args.seed,
                            out=args.out, hyperparameters=hyperparameters, snapshots=True)
    (first_steps, _, first_time), (last_steps, _, last_time) = result.evaluations[1], result.evaluations[-1]
    rate = (last_steps - first_steps) / (last_time - first_time) if last_time > first_time else float("nan")
    return {"train": {"task": args.task, "randomization": args.randomization, "steps": args.steps,
                      "hyperparameters": hyperparameters,
                      "wall_time_s": result.wall_time, "evaluations": result.evaluations,
                      "end_to_end_steps_per_s": rate, "policy": str(result.policy_path)}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    rate = commands.add_parser("throughput")
    rate.add_argument("--worlds", type=int, nargs="+", default=[256, 1024])
    rate.add_argument("--steps", type=int, default=100)
    rate.add_argument("--numpy-worlds-max", type=int, default=4096,
                      help="largest world count the numpy peer runs (it scales linearly)")
    rate.add_argument("--presets", nargs="+", default=list(PRESETS), help="randomization presets to measure")
    rate.add_argument("--tasks", nargs="+", default=["swingup"], help="tasks to measure")
    learn = commands.add_parser("train")
    learn.add_argument("--task", default="swingup")
    learn.add_argument("--randomization", default="none")
    learn.add_argument("--steps", type=int, default=60_000_000)
    learn.add_argument("--seed", type=int, default=0)
    learn.add_argument("--num-envs", type=int, default=None)
    learn.add_argument("--num-evals", type=int, default=None)
    learn.add_argument("--out", default="runs/jax")
    learn.add_argument("--set", type=hyperparameter, action="append", default=[], metavar="KEY=VALUE",
                       help="change one of Brax PPO's settings (qube_suite.mjx.training.HYPERPARAMETERS) or "
                            "the environment's (ENVIRONMENT_SETTINGS: history=8, privileged_critic=1)")
    for command in (rate, learn):
        command.add_argument("--json", default=None, help="append the result to this JSON-lines file")
    args = parser.parse_args()
    result = throughput(args) if args.command == "throughput" else train(args)
    result["devices"] = [str(device) for device in jax.devices()]
    print(json.dumps(result), flush=True)
    if args.json:
        with open(args.json, "a") as file:
            file.write(json.dumps(result) + "\n")


if __name__ == "__main__":
    main()
