"""The stable-baselines3 adapter; skipped where stable-baselines3 is not installed (not a dependency)."""

import subprocess
import sys

import numpy as np
import pytest


@pytest.mark.slow
def test_importing_qube_suite_does_not_import_stable_baselines3():
    code = "import qube_suite, qube_suite.wrappers, sys; print('stable_baselines3' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "False"


def test_sb3_vec_env_resets_in_the_step_and_passes_terminal_observations():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import VecEnv

    from qube_suite.wrappers.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("QubeSuite/Swingup-v0", num_envs=3, time_limit=0.02)  # 5 steps
    assert isinstance(venv, VecEnv) and venv.num_envs == 3
    assert venv.observation_space.shape == (4,) and venv.action_space.shape == (1,)
    venv.seed(7)
    first = venv.reset()
    assert first.shape == (3, 4)
    for _ in range(5):
        observations, rewards, dones, infos = venv.step(np.zeros((3, 1), np.float32))
    assert dones.all() and rewards.dtype == np.float32
    assert all(info["TimeLimit.truncated"] for info in infos)
    assert all(info["terminal_observation"].shape == (4,) for info in infos)
    assert not np.array_equal(observations, np.stack([info["terminal_observation"] for info in infos]))
    assert venv.get_attr("num_envs") == [3, 3, 3] and venv.env_is_wrapped(object) == [False] * 3
    venv.close()


def test_sb3_vec_env_reset_infos_hold_what_each_world_drew_for_its_episode():
    pytest.importorskip("stable_baselines3")
    import gymnasium

    from qube_suite.wrappers.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("QubeSuite/Balance-v0", num_envs=2, time_limit=0.02, randomization="sim2real")
    venv.seed(7)
    venv.reset()
    single = gymnasium.make("QubeSuite/Balance-v0", time_limit=0.02, randomization="sim2real")
    _, drawn = single.reset(seed=8)  # world 1 replays a single Qube seeded as it is
    assert venv.reset_infos[1]["parameters"] == pytest.approx(drawn["parameters"])
    assert venv.reset_infos[1]["effects"]["action_delay"] == drawn["effects"]["action_delay"]
    first = dict(venv.reset_infos[1]["parameters"])
    for _ in range(5):  # the episodes end and restart within the fifth step
        venv.step(np.zeros((2, 1), np.float32))
    _, again = single.reset()  # the single Qube's next episode
    assert venv.reset_infos[1]["parameters"] == pytest.approx(again["parameters"])
    assert venv.reset_infos[1]["parameters"] != pytest.approx(first)
    assert "final_obs" not in venv.reset_infos[1] and "_parameters" not in venv.reset_infos[1]
    single.close()
    venv.close()


def test_sb3_trains_on_it_for_a_few_steps():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from qube_suite.wrappers.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("QubeSuite/Balance-v0", num_envs=4)
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    assert model.num_timesteps >= 256
    venv.close()
