"""Step-speed benchmark: named measurements run interleaved in one process, printed as one table.

Every measurement builds its subject once and then runs in rounds, all
measurements taking turns in each round, so that load from other processes on a
shared machine falls on all of them alike; a row reports its best round (and the
median). Ratios compare rows of the same run. Single environments are stepped with
a zero action; the time of their resets is left out of the step rows (a reset row
measures it). Rows ending in the name of a randomization preset measure the same
with that randomization (drawn at every reset, effects at every step); the column
"with randomization" repeats their rate beside the plain row's, with the ratio.
Add a row by appending a `Measurement` to the list `measurements()` returns.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np
from tqdm import tqdm

VECTOR_SIZES = (1, 4, 16, 64, 256, 1024)
RANDOMIZED_SIZES = (64, 1024)
"""Vector sizes also measured with randomization."""
RANDOMIZATION = "sim2real"
"""Preset of the randomized rows."""
ROLLOUT_THREADS = 2
PEER = "Gymnasium InvertedPendulum-v5 step"
DM_PEER = "dm_control cartpole swingup step"
PEER_RESET = "reset: Gymnasium InvertedPendulum-v5"
REAL_TIME = "reference: real time at 250 Hz (not measured)"
REAL_TIME_FREQUENCY = 250.0


@dataclasses.dataclass
class Measurement:
    """One row: `make()` builds the subject and returns `run(calls) -> seconds`, the time spent in
    `calls` calls of the measured operation, each doing `work` units (env-steps or resets)."""

    name: str
    make: Callable[[], Callable[[int], float]]
    work: int = 1
    unit: str = "steps"
    peer: str | None = None
    """Row whose rate this one is divided by (×)."""
    limit: str | None = None
    """Row that bounds this one (shown as a percentage)."""
    randomized: str | None = None
    """Row measuring the same with randomization (shown in the randomization column)."""


@dataclasses.dataclass
class Result:
    measurement: Measurement
    rates: list[float] = dataclasses.field(default_factory=list)
    error: str | None = None

    @property
    def best(self) -> float:
        return max(self.rates) if self.rates else float("nan")


# -- subjects ------------------------------------------------------------------------------


def _single_steps(step, reset, ended) -> Callable[[int], float]:
    """Time `calls` steps, resetting (untimed) whenever `ended(result)`."""
    reset()

    def run(calls: int) -> float:
        elapsed, done = 0.0, 0
        while done < calls:
            start = time.perf_counter()
            while done < calls:
                result = step()
                done += 1
                if ended(result):
                    break
            elapsed += time.perf_counter() - start
            if ended(result):
                reset()
        return elapsed

    return run


def _repeated(operation) -> Callable[[int], float]:
    def run(calls: int) -> float:
        start = time.perf_counter()
        for _ in range(calls):
            operation()
        return time.perf_counter() - start

    return run


def _gymnasium_step(env_id: str, **kwargs) -> Callable[[], Callable[[int], float]]:
    def make():
        import gymnasium

        env = gymnasium.make(env_id, **kwargs)
        action = np.zeros(env.action_space.shape, env.action_space.dtype)
        return _single_steps(lambda: env.step(action), lambda: env.reset(seed=0),
                             lambda result: result[2] or result[3])

    return make


def _dm_env_step(load) -> Callable[[], Callable[[int], float]]:
    def make():
        env = load()
        action = np.zeros(env.action_spec().shape)
        return _single_steps(lambda: env.step(action), env.reset, lambda timestep: timestep.last())

    return make


def _qube_dm_env():
    from qube_suite import suite

    return suite.load("qube", "swingup", task_kwargs={"random": 0})


def _hardware_dm_env():
    from qube_suite import suite

    return suite.load("qube_hardware", "swingup", task_kwargs={"random": 0})


def _substitute_action() -> Callable[[int], float]:
    """`QubeServo2.action` on the substitute board in its fast mode, kept open for the run."""
    from qube_suite.hardware import QubeServo2

    qube = QubeServo2(frequency=REAL_TIME_FREQUENCY)
    qube.open()
    volts = np.zeros(1)
    return _repeated(lambda: qube.action(volts))


def _real_time() -> Callable[[int], float]:
    """Not a measurement: the rate a real board keeps, `REAL_TIME_FREQUENCY` samples per second."""
    return lambda calls: calls / REAL_TIME_FREQUENCY


def _cartpole():
    from dm_control import suite as dm_suite

    return dm_suite.load("cartpole", "swingup", task_kwargs={"random": 0})


def _vector_env(num_envs: int, randomization: str | None = None):
    import gymnasium

    return gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=num_envs,
                              vectorization_mode="vector_entry_point", randomization=randomization)


def _vector_step(num_envs: int, randomization: str | None = None) -> Callable[[], Callable[[int], float]]:
    def make():
        env = _vector_env(num_envs, randomization)
        env.reset(seed=0)
        actions = np.zeros((num_envs, 1), np.float32)
        return _repeated(lambda: env.step(actions))

    return make


def _raw_mj_step() -> Callable[[int], float]:
    import mujoco

    from qube_suite.devices.qube import simulation as qube

    model = qube.make_physics().model.ptr
    data = mujoco.MjData(model)
    substeps = qube.substeps_per_control_period(250.0)
    return _repeated(lambda: mujoco.mj_step(model, data, substeps))


def _raw_rollout(num_worlds: int, control_steps: int = 1) -> Callable[[], Callable[[int], float]]:
    def make():
        import mujoco
        import mujoco.rollout

        from qube_suite.devices.qube import batch as qube_batch
        from qube_suite.devices.qube import simulation as qube

        model = qube_batch.physics_model(250.0)
        substeps = qube.substeps_per_control_period(250.0)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
        data = mujoco.MjData(model)
        start = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, start, spec)
        states = np.tile(start, (num_worlds, 1))
        control = np.zeros((num_worlds, substeps * control_steps, model.nu))
        out = np.empty((num_worlds, substeps * control_steps, start.size))
        pool = mujoco.rollout.Rollout(nthread=ROLLOUT_THREADS)
        datas = [mujoco.MjData(model) for _ in range(ROLLOUT_THREADS)]
        models = [model] * num_worlds
        ctrl = mujoco.mjtState.mjSTATE_CTRL.value
        return _repeated(lambda: pool.rollout(models, datas, states, control, control_spec=ctrl,
                                              skip_checks=True, nstep=substeps * control_steps, state=out))

    return make


def _gymnasium_reset(randomization: str | None = None) -> Callable[[], Callable[[int], float]]:
    def make():
        import gymnasium

        return _repeated(gymnasium.make("QubeSuite/Swingup-v0", randomization=randomization).reset)

    return make


def _vector_reset(num_envs: int, randomization: str | None = None) -> Callable[[], Callable[[int], float]]:
    def make():
        return _repeated(_vector_env(num_envs, randomization).reset)

    return make


def _peer_reset() -> Callable[[int], float]:
    import gymnasium

    env = gymnasium.make("InvertedPendulum-v5")
    return _repeated(env.reset)


def measurements(vector_sizes=VECTOR_SIZES, randomized_sizes=RANDOMIZED_SIZES) -> list[Measurement]:
    """The rows of the table, in order; `randomized_sizes` (among `vector_sizes`) also with randomization."""
    single_step = "qube_suite Gymnasium step (Swingup-v0)"
    single_reset = "reset: qube_suite Gymnasium (Swingup-v0)"
    rows = [
        Measurement(single_step, _gymnasium_step("QubeSuite/Swingup-v0"), peer=PEER,
                    randomized=f"{single_step}, {RANDOMIZATION}"),
        Measurement(f"{single_step}, {RANDOMIZATION}",
                    _gymnasium_step("QubeSuite/Swingup-v0", randomization=RANDOMIZATION), peer=single_step),
        Measurement("qube_suite dm_env step (swingup)", _dm_env_step(_qube_dm_env), peer=DM_PEER),
    ]
    for n in vector_sizes:
        name = f"qube_suite vector env, N={n}"
        randomized = n in randomized_sizes
        rows.append(Measurement(name, _vector_step(n), work=n, unit="env-steps", peer=PEER,
                                limit=f"raw mujoco.rollout, {ROLLOUT_THREADS} threads, N={n}",
                                randomized=f"{name}, {RANDOMIZATION}" if randomized else None))
        if randomized:
            rows.append(Measurement(f"{name}, {RANDOMIZATION}", _vector_step(n, RANDOMIZATION), work=n,
                                    unit="env-steps", peer=name))
    rows += [
        Measurement(PEER, _gymnasium_step("InvertedPendulum-v5")),
        Measurement(DM_PEER, _dm_env_step(_cartpole)),
        Measurement("raw MuJoCo: Python loop of mj_step on model.xml", _raw_mj_step),
    ]
    for n in vector_sizes:
        rows.append(Measurement(f"raw mujoco.rollout, {ROLLOUT_THREADS} threads, N={n}", _raw_rollout(n),
                                work=n, unit="env-steps"))
    longest = max(vector_sizes)
    rows += [
        Measurement(f"raw mujoco.rollout, {ROLLOUT_THREADS} threads, N={longest}, 100 steps a call",
                    _raw_rollout(longest, 100), work=100 * longest, unit="env-steps"),
        Measurement(single_reset, _gymnasium_reset(), unit="resets", peer=PEER_RESET,
                    randomized=f"{single_reset}, {RANDOMIZATION}"),
        Measurement(f"{single_reset}, {RANDOMIZATION}", _gymnasium_reset(RANDOMIZATION), unit="resets",
                    peer=single_reset),
    ]
    for n in randomized_sizes:
        name = f"reset: qube_suite vector env, N={n} (per world)"
        randomized = f"reset: qube_suite vector env, N={n}, {RANDOMIZATION} (per world)"
        rows += [Measurement(name, _vector_reset(n), work=n, unit="resets", peer=PEER_RESET,
                             randomized=randomized),
                 Measurement(randomized, _vector_reset(n, RANDOMIZATION), work=n, unit="resets", peer=name)]
    rows += [
        Measurement(PEER_RESET, _peer_reset, unit="resets"),
        Measurement("hardware substitute: QubeServo2.action, fast mode", _substitute_action,
                    unit="samples", peer=REAL_TIME),
        Measurement("qube_suite dm_env step on qube_hardware (swingup, substitute)",
                    _dm_env_step(_hardware_dm_env), peer=REAL_TIME),
        Measurement(REAL_TIME, _real_time, unit="samples"),
    ]
    return rows


# -- running and printing ----------------------------------------------------------------------


def run(rows: list[Measurement], rounds: int, seconds: float, progress: bool = False) -> list[Result]:
    """Build every row's subject, then run `rounds` interleaved rounds of about `seconds` each per row.

    `progress`: show a progress bar (tqdm, on stderr, on a terminal) over the rows' calibration and
    the rounds.
    """
    bar = tqdm(total=len(rows) + rounds, unit="round", disable=None if progress else True, desc="benchmark",
               leave=False)
    results, runners = [], []
    for row in rows:
        bar.update()
        result = Result(row)
        try:
            runner = row.make()
            runner(1)
            calls = 1
            while runner(calls) < seconds / 10:  # calibrate the calls per round
                calls *= 4
            runners.append((result, runner, max(1, int(calls * seconds / max(runner(calls), 1e-9)))))
        except Exception as error:  # a peer that cannot run here is reported, not fatal
            result.error = f"unavailable: {type(error).__name__}: {error}"[:80]
        results.append(result)
    for _ in range(rounds):
        for result, runner, calls in runners:
            result.rates.append(calls * result.measurement.work / runner(calls))
        bar.update()
    bar.close()
    return results


def table(results: list[Result]) -> str:
    """The results as an aligned text table."""
    by_name = {result.measurement.name: result for result in results}
    header = ("measurement", "best /s", "median /s", "µs per call", "× peer", "% of limit",
              "with randomization")
    lines = []
    for result in results:
        row = result.measurement
        if result.error:
            lines.append((row.name, result.error, "", "", "", "", ""))
            continue
        best = result.best
        peer, limit = by_name.get(row.peer), by_name.get(row.limit)
        ratio = f"{best / peer.best:.2f}" if peer and peer.rates else ""
        share = f"{100 * best / limit.best:.0f} %" if limit and limit.rates else ""
        twin = by_name.get(row.randomized)
        randomized = f"{twin.best:,.0f} ({twin.best / best:.2f}×)" if twin and twin.rates else ""
        lines.append((row.name, f"{best:,.0f} {row.unit}", f"{statistics.median(result.rates):,.0f}",
                      f"{1e6 * row.work / best:.2f}", ratio, share, randomized))
    widths = [max(len(str(line[i])) for line in [header, *lines]) for i in range(len(header))]
    out = ["  ".join(cell.ljust(width) if i == 0 else cell.rjust(width)
                     for i, (cell, width) in enumerate(zip(line, widths, strict=True))).rstrip()
           for line in [header, *lines]]
    out.insert(1, "-" * len(out[0]))
    return "\n".join(out)


def describe_machine() -> str:
    """One line: CPUs, processor, Python, MuJoCo and date."""
    import mujoco

    return (f"{os.cpu_count()} CPUs ({platform.processor() or platform.machine()}), Python "
            f"{platform.python_version()}, MuJoCo {mujoco.__version__}, {time.strftime('%Y-%m-%d')}")


def main(quick: bool = False) -> int:
    """Run the benchmark and print the table; `quick`: short rounds and fewer batch sizes."""
    rounds, seconds = (2, 0.05) if quick else (15, 0.25)
    rows = measurements((1, 16, 256), (16,)) if quick else measurements()
    print(f"qube_suite step speed: {describe_machine()}")
    print(f"best of {rounds} interleaved rounds of ~{seconds:g} s per row; × peer: rate / the peer's "
          f"({PEER}, {DM_PEER} or real time); % of limit: rate / raw rollout at the same N; "
          f"with randomization: the rate with the {RANDOMIZATION} preset (× the plain rate)\n")
    print(table(run(rows, rounds, seconds, progress=True)))
    return 0
