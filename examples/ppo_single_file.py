"""PPO in one file, in the style of CleanRL's ppo_continuous_action.py, on any QubeSuite id.

Gymnasium 1.x wrappers and vector API, torch for the networks; everything PPO does is
in this file. Needs torch (install its CPU build: see the README's Training section).

    python examples/ppo_single_file.py --env-id QubeSuite/Balance-v0 --total-timesteps 500000
    python examples/ppo_single_file.py --short    # a few seconds: two small iterations

Settings follow the usual continuous-control PPO (Schulman et al. 2017; CleanRL's and
rl-zoo3's defaults): 2 x 64 tanh networks, a state-independent log-std, GAE(0.95), 10
epochs of 32 minibatches, clip 0.2, observations and rewards normalised.
"""

from __future__ import annotations

import argparse
import time

import gymnasium
import numpy as np
import torch
from torch import nn
from torch.distributions import Normal

import qube_suite  # noqa: F401  (registers the QubeSuite ids)


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="QubeSuite/Balance-v0")
    parser.add_argument("--total-timesteps", type=int, default=500_000)
    parser.add_argument("--num-envs", type=int, default=8)
    parser.add_argument("--num-steps", type=int, default=256, help="steps per environment per rollout")
    parser.add_argument("--learning-rate", type=float, default=3e-4)
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--gae-lambda", type=float, default=0.95)
    parser.add_argument("--update-epochs", type=int, default=10)
    parser.add_argument("--num-minibatches", type=int, default=32)
    parser.add_argument("--clip-coef", type=float, default=0.2)
    parser.add_argument("--ent-coef", type=float, default=0.0)
    parser.add_argument("--vf-coef", type=float, default=0.5)
    parser.add_argument("--max-grad-norm", type=float, default=0.5)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--short", action="store_true", help="two iterations of 2 x 128 steps (a smoke test)")
    args = parser.parse_args(argv)
    if args.short:
        args.total_timesteps, args.num_envs, args.num_steps, args.num_minibatches = 512, 2, 128, 4
    args.batch_size = args.num_envs * args.num_steps
    args.minibatch_size = max(1, args.batch_size // args.num_minibatches)
    return args


def make_env(env_id: str, gamma: float):
    """A thunk for the vector environment: the QubeSuite env with Gymnasium 1.x's wrappers."""
    def thunk():
        env = gymnasium.make(env_id)
        env = gymnasium.wrappers.RecordEpisodeStatistics(env)  # before normalising: true returns
        env = gymnasium.wrappers.ClipAction(env)
        env = gymnasium.wrappers.NormalizeObservation(env)
        env = gymnasium.wrappers.TransformObservation(env, lambda obs: np.clip(obs, -10, 10),
                                                      env.observation_space)
        env = gymnasium.wrappers.NormalizeReward(env, gamma=gamma)
        return gymnasium.wrappers.TransformReward(env, lambda reward: float(np.clip(reward, -10, 10)))
    return thunk


def layer(inputs: int, outputs: int, std: float = np.sqrt(2)) -> nn.Linear:
    """A linear layer with orthogonal weights of gain `std` and zero biases."""
    linear = nn.Linear(inputs, outputs)
    nn.init.orthogonal_(linear.weight, std)
    nn.init.constant_(linear.bias, 0.0)
    return linear


class Agent(nn.Module):
    """Separate actor and critic MLPs; a Gaussian policy with a learned, state-independent log-std."""

    def __init__(self, observations: int, actions: int):
        super().__init__()
        self.critic = nn.Sequential(layer(observations, 64), nn.Tanh(), layer(64, 64), nn.Tanh(),
                                    layer(64, 1, std=1.0))
        self.actor_mean = nn.Sequential(layer(observations, 64), nn.Tanh(), layer(64, 64), nn.Tanh(),
                                        layer(64, actions, std=0.01))
        self.actor_logstd = nn.Parameter(torch.zeros(1, actions))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x)

    def action_and_value(self, x: torch.Tensor, action: torch.Tensor | None = None):
        mean = self.actor_mean(x)
        distribution = Normal(mean, self.actor_logstd.expand_as(mean).exp())
        if action is None:
            action = distribution.sample()
        return action, distribution.log_prob(action).sum(1), distribution.entropy().sum(1), self.critic(x)


def train(args: argparse.Namespace) -> tuple[Agent, list[float]]:
    """Run PPO; returns the agent and the (unnormalised) returns of the episodes that ended."""
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    envs = gymnasium.vector.SyncVectorEnv([make_env(args.env_id, args.gamma) for _ in range(args.num_envs)],
                                         autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP)
    n_obs, n_act = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    agent = Agent(n_obs, n_act)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    shape = (args.num_steps, args.num_envs)
    obs, actions = torch.zeros(shape + (n_obs,)), torch.zeros(shape + (n_act,))
    logprobs, rewards, dones, values = (torch.zeros(shape) for _ in range(4))
    next_obs = torch.tensor(envs.reset(seed=args.seed)[0], dtype=torch.float32)
    next_done = torch.zeros(args.num_envs)
    episode_returns: list[float] = []
    iterations = max(1, args.total_timesteps // args.batch_size)
    start = time.time()

    for iteration in range(1, iterations + 1):
        optimizer.param_groups[0]["lr"] = (1.0 - (iteration - 1.0) / iterations) * args.learning_rate
        for step in range(args.num_steps):  # collect a rollout
            obs[step], dones[step] = next_obs, next_done
            with torch.no_grad():
                action, logprob, _, value = agent.action_and_value(next_obs)
            values[step], actions[step], logprobs[step] = value.flatten(), action, logprob
            observation, reward, terminated, truncated, infos = envs.step(action.numpy())
            rewards[step] = torch.tensor(reward, dtype=torch.float32)
            next_obs = torch.tensor(observation, dtype=torch.float32)
            next_done = torch.tensor(np.logical_or(terminated, truncated), dtype=torch.float32)
            if "episode" in infos:
                episode_returns += infos["episode"]["r"][infos["_episode"]].tolist()

        with torch.no_grad():  # generalised advantage estimation
            next_value = agent.value(next_obs).reshape(1, -1)
            advantages = torch.zeros_like(rewards)
            last = torch.zeros(args.num_envs)
            for t in reversed(range(args.num_steps)):
                not_done = 1.0 - (next_done if t == args.num_steps - 1 else dones[t + 1])
                following = next_value if t == args.num_steps - 1 else values[t + 1]
                delta = rewards[t] + args.gamma * following * not_done - values[t]
                advantages[t] = last = delta + args.gamma * args.gae_lambda * not_done * last
            returns = advantages + values

        b_obs, b_actions = obs.reshape(-1, n_obs), actions.reshape(-1, n_act)
        b_logprobs, b_advantages = logprobs.reshape(-1), advantages.reshape(-1)
        b_returns = returns.reshape(-1)
        indices = np.arange(args.batch_size)
        for _ in range(args.update_epochs):  # optimise the clipped surrogate
            np.random.shuffle(indices)
            for first in range(0, args.batch_size, args.minibatch_size):
                mb = indices[first:first + args.minibatch_size]
                _, new_logprob, entropy, new_value = agent.action_and_value(b_obs[mb], b_actions[mb])
                ratio = (new_logprob - b_logprobs[mb]).exp()
                mb_advantages = b_advantages[mb]
                if len(mb) > 1:
                    mb_advantages = (mb_advantages - mb_advantages.mean()) / (mb_advantages.std() + 1e-8)
                clipped = ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)
                policy_loss = torch.max(-mb_advantages * ratio, -mb_advantages * clipped).mean()
                value_loss = 0.5 * ((new_value.flatten() - b_returns[mb]) ** 2).mean()
                loss = policy_loss - args.ent_coef * entropy.mean() + args.vf_coef * value_loss
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()

        recent = np.mean(episode_returns[-20:]) if episode_returns else float("nan")
        print(f"iteration {iteration}/{iterations}: {iteration * args.batch_size} steps, "
              f"mean episode return {recent:.1f}, {time.time() - start:.0f} s", flush=True)
    envs.close()
    return agent, episode_returns


if __name__ == "__main__":
    train(parse_args())
