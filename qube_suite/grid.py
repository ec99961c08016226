"""Run a grid of independent jobs (training runs, evaluations) as Ray Tune trials.

    from qube_suite.grid import run_grid
    results = run_grid(score, [{"policy": "ppo:swingup", "seed": s} for s in range(3)])

Each job is a JSON-ready dict; `function(job)` runs in a Ray worker and returns a
JSON-ready result; `run_grid` returns the results in the jobs' order. Ray runs
the trials on this machine's cores by default (one core per trial), or on a Ray
cluster given its `address` ("auto" for the cluster this process runs in, or
"ray://head:10001"). Ray Tune schedules and records the trials (`storage`:
where its records go). Needs the optional `grid` extra (`ray[tune]`),
imported only here.
"""

from __future__ import annotations

import importlib.util
import json
import os
import pathlib
import sys
import tempfile
from collections.abc import Callable
from typing import Any

INSTALL_HINT = "pip install 'qube_suite[grid]' (Ray Tune)"


def require_ray() -> None:
    """ImportError, saying how to install it, unless Ray Tune is importable."""
    if importlib.util.find_spec("ray") is None:
        raise ImportError(f"running a grid needs ray[tune]: {INSTALL_HINT}")


def _script_modules(function: Callable) -> list:
    """The module of `function` and its sibling modules, if it is a script or test module (not in a
    package), which Ray workers could not import by name."""
    module = sys.modules.get(function.__module__)
    if module is None or "." in module.__name__ or not getattr(module, "__file__", None):
        return []
    directory = pathlib.Path(module.__file__).resolve().parent
    return [m for name, m in list(sys.modules.items()) if "." not in name and getattr(m, "__file__", None)
            and pathlib.Path(m.__file__).resolve().parent == directory]


def run_grid(function: Callable[[dict[str, Any]], Any], jobs: list[dict[str, Any]],
             address: str | None = None, cpus_per_trial: float = 1.0, cpus: int | None = None,
             name: str = "grid", storage: str | pathlib.Path | None = None) -> list[Any]:
    """`[function(job) for job in jobs]`, run as Ray Tune trials, in the jobs' order.

    Args:
        function: a function of one job (picklable: module level, or defined in a script).
        jobs: JSON-ready dicts, one per trial.
        address: a Ray cluster's address; None starts Ray on this machine with `cpus` cores
            (default: all of them).
        cpus_per_trial: cores reserved per trial (trials run side by side as cores allow).
        name, storage: the experiment's name and directory of Ray Tune's records
            (default: a temporary directory).

    Raises RuntimeError naming the failed jobs if any trial fails.
    """
    require_ray()
    import ray
    from ray import tune

    if not jobs:
        return []
    for module in _script_modules(function):  # workers cannot import these: they travel by value
        ray.cloudpickle.register_pickle_by_value(module)
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=address, num_cpus=None if address else (cpus or os.cpu_count()),
                 include_dashboard=False, log_to_driver=False, configure_logging=False)

    def trial(config: dict[str, Any]) -> dict[str, str]:
        return {"result": json.dumps(function(config["cell"]["job"]))}

    cells = [{"index": i, "job": job} for i, job in enumerate(jobs)]
    storage = pathlib.Path(storage or tempfile.mkdtemp(prefix="qube_suite_grid_")).resolve()
    try:
        tuner = tune.Tuner(tune.with_resources(trial, {"cpu": cpus_per_trial}),
                           param_space={"cell": tune.grid_search(cells)},
                           run_config=tune.RunConfig(name=name, storage_path=str(storage), verbose=0))
        grid = tuner.fit()
    finally:
        if started_here:
            ray.shutdown()
    results: list[Any] = [None] * len(jobs)
    failed = []
    for result in grid:
        index = result.config["cell"]["index"]
        if result.error is not None or "result" not in (result.metrics or {}):
            failed.append(f"job {index} ({jobs[index]}): {result.error}")
        else:
            results[index] = json.loads(result.metrics["result"])
    if failed:
        raise RuntimeError(f"{len(failed)} of {len(jobs)} trials failed: " + "; ".join(failed))
    return results
