"""benchmarks/sim2real.py keeps each score: a second invocation computes nothing, a changed policy is
scored again, and the rows of an earlier sim2real.json (before scores were kept) are read and imported.
A tiny grid in local Ray mode (skipped without Ray)."""

import importlib.util
import json
import pathlib
import shutil
import sys

import numpy as np
import pytest

from qube_suite.policies import load_policy, save, shipped

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"

pytestmark = [pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="needs ray[tune]"),
              pytest.mark.filterwarnings("ignore:Tight layout not applied")]  # long policy paths as row names


@pytest.fixture(scope="module")
def sim2real():
    sys.path.insert(0, str(BENCHMARKS))  # the script imports its sibling held_out
    spec = importlib.util.spec_from_file_location("sim2real", BENCHMARKS / "sim2real.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["sim2real"] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("sim2real", None)
    sys.path.remove(str(BENCHMARKS))


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    """One local Ray for the module's grids (`run_grid` uses a running Ray as it is)."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def run(sim2real, monkeypatch, runs, *options):
    """One invocation of the script on `runs`: the jobs it scored, and its sim2real.json."""
    scored = []
    real = sim2real.run_grid

    def recording(function, jobs, **kwargs):
        scored.extend(job["run"] + " / " + job["condition"] for job in jobs)
        return real(function, jobs, **kwargs)

    monkeypatch.setattr(sim2real, "run_grid", recording)
    monkeypatch.setattr(sys, "argv", [
        "sim2real.py", "--runs", str(runs), "--no-train", "--held-out-only", "--held-out", "1",
        "--episodes", "1", "--jobs", "2", "--rows", "model-based (nominal)", "--plot", str(runs / "main.png"),
        "--held-out-plot", str(runs / "held_out.png"), *options])
    sim2real.main()
    return sorted(scored), json.loads((runs / "sim2real.json").read_text())


def scores(table):
    return {(row["run"], row["condition"]): row["mean_return"] for row in table["rows"]}


@pytest.mark.slow
def test_scores_are_kept_and_reused_and_a_changed_policy_is_scored_again(sim2real, monkeypatch, tmp_path):
    policy = tmp_path / "mine.npz"
    shutil.copy(shipped()["ppo:swingup_adaptive"], policy)
    expected = sorted(f"{run} / {condition}" for run in ("model-based (nominal)", str(policy))
                      for condition in ("hardware", "held-out 0"))
    first, table = run(sim2real, monkeypatch, tmp_path, "--policies", str(policy))
    assert first == expected
    assert len(list((tmp_path / "scores").glob("*.json"))) == 4
    again, same = run(sim2real, monkeypatch, tmp_path, "--policies", str(policy))
    assert again == []  # nothing new computed
    assert scores(same) == scores(table) and len(same["summary"]) == 2
    # a row added by a later invocation joins the kept ones; the earlier rows stay without being asked for
    changed = load_policy(policy)
    changed.biases[-1] = changed.biases[-1] + 0.5  # a retrained policy: same path, other content
    save(changed, policy)
    third, merged = run(sim2real, monkeypatch, tmp_path, "--rows", "model-based (nominal)", "--policies",
                        str(policy))
    assert third == sorted(f"{policy} / {condition}" for condition in ("hardware", "held-out 0"))
    assert set(scores(merged)) == set(scores(table))
    kept = {(row["run"], row["condition"]) for row in merged["rows"] if "fingerprint" in row}
    assert kept == set(scores(table))


@pytest.mark.slow
def test_the_rows_of_an_earlier_sim2real_json_are_summarized_and_imported(sim2real, monkeypatch, tmp_path):
    rows = [{"run": "model-based (nominal)", "training_seed": 0, "condition": condition,
             "mean_return": value, "return_ci": [value, value], "success_rate": 1.0,
             "success_ci": [0.2, 1.0], "returns": [value]}
            for condition, value in (("hardware", 1790.0), ("held-out 0", 1810.0))]
    earlier = {"rows": rows, "training": {}, "summary": []}
    (tmp_path / "sim2real.json").write_text(json.dumps(earlier))
    scored, table = run(sim2real, monkeypatch, tmp_path, "--summary-only")
    assert scored == [] and scores(table) == {(r["run"], r["condition"]): r["mean_return"] for r in rows}
    assert table["summary"][0]["row"] == "model-based (nominal)"
    assert table["summary"][0]["mean_return"] == pytest.approx(1810.0)  # the held-out plant's
    (tmp_path / "sim2real.json").unlink()
    old = tmp_path / "old.json"
    old.write_text(json.dumps(earlier))
    scored, table = run(sim2real, monkeypatch, tmp_path, "--import-scores", str(old))
    assert scored == []  # both imported as this invocation's jobs, so not scored again
    assert all("fingerprint" in row for row in table["rows"])
    assert scores(table) == {(r["run"], r["condition"]): r["mean_return"] for r in rows}
    np.testing.assert_array_equal([len(list((tmp_path / "scores").glob("*.json")))], [2])
