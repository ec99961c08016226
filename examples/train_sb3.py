"""Train PPO from stable-baselines3 on a Qube task, then score, film and plot the policy.

stable-baselines3 is not a dependency of qube_suite. On a machine without a GPU,
install PyTorch's CPU build first (else pip fetches the much larger CUDA build),
then stable-baselines3:

    pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu
    pip install stable-baselines3

Then, from the repository:

    python examples/train_sb3.py --task balance --timesteps 200000 --video ppo_balance.mp4

PPO learns `balance` in a few minutes on a CPU; `swingup` takes millions of steps.
--short runs a tiny training (seconds) to check the set-up.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys

import numpy as np

from qube_suite import episodes, evaluate, extras, suite
from qube_suite.wrappers import gymnasium_id

INSTALL = ("this example needs stable-baselines3; on a CPU machine install PyTorch's CPU build first:\n"
           "  pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu\n"
           "  pip install stable-baselines3")


class DeterministicPolicy:
    """A trained SB3 model as a qube_suite policy: dm_env observation -> voltage (V)."""

    def __init__(self, model):
        self.model = model

    def __call__(self, observation) -> np.ndarray:
        flat = np.concatenate([np.ravel(value) for value in observation.values()]).astype(np.float32)
        action, _ = self.model.predict(flat, deterministic=True)
        return np.asarray(action, dtype=np.float64)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="balance", help="suite task name (default: balance)")
    parser.add_argument("--timesteps", type=int, default=200_000, help="training steps (default: 200000)")
    parser.add_argument("--envs", type=int, default=16, help="parallel worlds (default: 16)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--video", help="film one episode of the trained policy (mp4)")
    parser.add_argument("--plot", help="plot one episode of the trained policy (png)")
    parser.add_argument("--short", action="store_true",
                        help="a tiny run that checks the set-up: 256 training steps, 1 s episodes")
    args = parser.parse_args(argv)
    if importlib.util.find_spec("stable_baselines3") is None:
        print(INSTALL, file=sys.stderr)
        return 1
    from stable_baselines3 import PPO

    from qube_suite.wrappers.sb3 import make_sb3_vec_env

    timesteps, envs = (256, 2) if args.short else (args.timesteps, args.envs)
    venv = make_sb3_vec_env(gymnasium_id(args.task), num_envs=envs)
    venv.seed(args.seed)
    model = PPO("MlpPolicy", venv, n_steps=128 if args.short else 1024, seed=args.seed, verbose=0)
    model.learn(total_timesteps=timesteps, progress_bar=extras.available("rich") and not args.short)
    venv.close()

    policy = DeterministicPolicy(model)
    short_episodes = {"time_limit": 1.0} if args.short else None
    result = evaluate(policy, task=args.task, episodes=2 if args.short else 10, seed=1000,
                      environment_kwargs=short_episodes)
    print(f"PPO after {timesteps} steps on {args.task}: return {result.mean_return:.1f} "
          f"+- {result.std_return:.1f}, success {100 * result.success_rate:.0f} %")
    environment = suite.load("qube", args.task, task_kwargs={"random": 1000},
                             environment_kwargs=short_episodes)
    if args.video:
        from qube_suite import media

        media.record_video(environment, policy, args.video, fps=50)
        print(f"video written to {args.video}")
    if args.plot:
        from qube_suite import plotting

        trace = episodes.run_episode(environment, policy, label=f"PPO on {args.task}")
        plotting.plot_episode(trace, args.plot)
        print(f"plot written to {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
