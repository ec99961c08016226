"""examples/ppo_single_file.py, the CleanRL-style PPO, runs on QubeSuite ids in its short mode."""

import importlib.util
import pathlib

import pytest

EXAMPLE = pathlib.Path(__file__).resolve().parent.parent / "examples" / "ppo_single_file.py"


@pytest.mark.parametrize("env_id", ["QubeSuite/Balance-v0", "QubeSuite/SwingupFollow-v0"])
def test_single_file_ppo_trains_in_short_mode(env_id, capsys):
    torch = pytest.importorskip("torch")
    spec = importlib.util.spec_from_file_location("ppo_single_file", EXAMPLE)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    agent, _ = example.train(example.parse_args(["--short", "--env-id", env_id]))
    assert "iteration 2/2: 512 steps" in capsys.readouterr().out
    assert all(torch.isfinite(parameter).all() for parameter in agent.parameters())
    assert torch.count_nonzero(agent.actor_logstd) > 0  # starts at 0: the updates moved it
