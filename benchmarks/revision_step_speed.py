"""Gymnasium step speed of two versions of qube_suite, measured interleaved in one run.

    python benchmarks/revision_step_speed.py 4ddcb67            # that commit against this tree
    python benchmarks/revision_step_speed.py 4ddcb67 HEAD --env QubeSuite/Balance-v0
    python benchmarks/revision_step_speed.py main --num-envs 1024 --steps 200   # the vector env
    python benchmarks/revision_step_speed.py main --randomization sim2real   # a randomized step

Each version is exported (`git archive`; the working tree for "."), and rounds of
timed steps alternate between them, each in a fresh subprocess, so that load from
other processes on a shared machine falls on both alike. Steps are timed in CPU
time of the process (`time.process_time`), which other processes' share of a busy
machine does not inflate as it does wall time. Prints the best and the median CPU
time per step of each version and their ratio. Only the pure-Python parts
are compared: an exported version gets the working tree's compiled extensions, each put
beside that version's own `.pyx` of the same name wherever it keeps it (build them first:
`python setup.py build_ext --inplace`); the package imports them but the simulated step does
not run them.
"""

from __future__ import annotations

import argparse
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile

REPOSITORY = pathlib.Path(__file__).resolve().parent.parent

TIMER = """
import sys, time
import gymnasium, numpy as np
import qube_suite
env = gymnasium.make(sys.argv[1], **({"randomization": sys.argv[3]} if sys.argv[3] else {}))
steps = int(sys.argv[2])
action = np.zeros(1, np.float32)
env.reset(seed=0)
for _ in range(2000):                                 # warm up
    if env.step(action)[3]:
        env.reset(seed=0)
best = float("inf")
for _ in range(5):
    env.reset(seed=0)
    start = time.process_time()
    for _ in range(steps):
        env.step(action)
    best = min(best, (time.process_time() - start) / steps)
print(best)
"""

VECTOR_TIMER = """
import sys, time
import gymnasium, numpy as np
import qube_suite
env = gymnasium.make_vec(sys.argv[1], num_envs=int(sys.argv[4]),
                         **({"randomization": sys.argv[3]} if sys.argv[3] else {}))
steps = int(sys.argv[2])
actions = np.zeros((env.num_envs, 1), np.float32)
env.reset(seed=0)
for _ in range(steps):                                # warm up; ended worlds restart (autoreset)
    env.step(actions)
best = float("inf")
for _ in range(5):
    start = time.process_time()
    for _ in range(steps):
        env.step(actions)
    best = min(best, (time.process_time() - start) / steps)
print(best)
"""


def export(revision: str, folder: pathlib.Path) -> pathlib.Path:
    """The package source of `revision` ("." is the working tree) as an importable folder."""
    if revision == ".":
        return REPOSITORY
    target = folder / revision.replace("/", "_")
    target.mkdir()
    archive = subprocess.run(["git", "-C", str(REPOSITORY), "archive", revision, "qube_suite"],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive, check=True)
    built = {path.name.split(".")[0]: path for path in (REPOSITORY / "qube_suite").rglob("*.so")}
    for source in (target / "qube_suite").rglob("*.pyx"):  # where that revision keeps each extension
        if source.stem not in built:
            raise SystemExit(f"no compiled {source.stem} here: run `python setup.py build_ext --inplace`")
        shutil.copy(built[source.stem], source.with_name(built[source.stem].name))
    return target


def seconds_per_step(source: pathlib.Path, env_id: str, steps: int, num_envs: int | None = None,
                     randomization: str | None = None) -> float:
    """Best of five timed runs of `steps` steps with the package at `source`, in a new process;
    of the vector env of `num_envs` worlds if given; `randomization`: a preset name, or None."""
    command = [TIMER if num_envs is None else VECTOR_TIMER, env_id, str(steps), randomization or ""]
    if num_envs is not None:
        command.append(str(num_envs))
    result = subprocess.run([sys.executable, "-c", *command], check=True,
                            capture_output=True, text=True, cwd=source,
                            env={"PYTHONPATH": str(source), "MUJOCO_GL": "disable"})
    return float(result.stdout.split()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("before", help="git revision to compare against")
    parser.add_argument("after", nargs="?", default=".", help="git revision, or . for the working tree")
    parser.add_argument("--env", default="QubeSuite/Swingup-v0", help="Gymnasium id")
    parser.add_argument("--rounds", type=int, default=7, help="alternating rounds (default: 7)")
    parser.add_argument("--steps", type=int, default=2000, help="steps per timed run (episode length)")
    parser.add_argument("--num-envs", type=int, default=None,
                        help="time the vector env (gymnasium.make_vec) of this many worlds instead")
    parser.add_argument("--randomization", help="a preset to randomize the timed steps with (default: none)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        sources = {name: export(name, pathlib.Path(folder)) for name in (args.before, args.after)}
        times: dict[str, list[float]] = {name: [] for name in sources}
        for _ in range(args.rounds):
            for name, source in sources.items():
                times[name].append(seconds_per_step(source, args.env, args.steps, args.num_envs,
                                                    args.randomization))
    for name, values in times.items():
        print(f"{name:>12}: best {min(values) * 1e6:6.2f} us/step (CPU), "
              f"median {statistics.median(values) * 1e6:6.2f}")
    before, after = (min(times[name]) for name in sources)
    what = args.env if args.num_envs is None else f"{args.env} x {args.num_envs} worlds"
    print(f"{what}: {args.after} takes {after / before:.3f} x the time of {args.before} per step")
    return 0


if __name__ == "__main__":
    sys.exit(main())
