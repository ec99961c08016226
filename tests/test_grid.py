"""A tiny grid of evaluations as Ray Tune trials in local mode (skipped without Ray)."""

import importlib.util

import pytest

from qube_suite import evaluate
from qube_suite.grid import run_grid

pytestmark = pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="needs ray[tune]")


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    """One local Ray for the module's grids (`run_grid` uses a running Ray as it is)."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def episode_return(job):
    return evaluate(job["controller"], task=job["task"], episodes=1, seed=job["seed"]).returns[0]


def fails_on_seed_one(job):
    if job["seed"] == 1:
        raise ValueError("no such Qube")
    return job["seed"]


@pytest.mark.slow
def test_a_tiny_grid_runs_as_trials_and_returns_results_in_job_order(tmp_path):
    jobs = [{"controller": "balance", "task": "balance", "seed": 0},
            {"controller": "swingup", "task": "swingup", "seed": 1}]
    results = run_grid(episode_return, jobs, storage=tmp_path)
    assert results == pytest.approx([episode_return(job) for job in jobs])
    assert len(set(results)) > 1  # different cells, different results: the order is checked
    assert any(tmp_path.iterdir())  # Ray Tune kept its records there


@pytest.mark.slow
def test_a_failed_trial_is_reported_with_its_job(tmp_path):
    with pytest.raises(RuntimeError, match=r"1 of 2 trials failed: job 1 \(\{'seed': 1\}\)"):
        run_grid(fails_on_seed_one, [{"seed": 0}, {"seed": 1}], storage=tmp_path)
