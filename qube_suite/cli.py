"""The `qube-suite` command line (also `python -m qube_suite`).

Each subcommand is a `_<name>` function and an `_add_<name>` parser builder below,
registered in `SUBCOMMANDS`. User mistakes (`ValueError`, `OSError`, a missing
optional extra, a hardware stop) end in one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import pathlib
import sys
import time
from typing import Any

from qube_suite import devices
from qube_suite.progress import Progress

VIDEO_FPS = 30.0
"""Video frames per second unless --fps says otherwise (or the control rate, if lower): smooth to the
eye, and rendering every 4 ms control step would take eight times longer."""

DEMO_PLOT = "qube_demo.png"
"""Where `qube-suite demo` writes its plot when matplotlib is installed."""

EPILOG = """examples:
  qube-suite demo                 swing the simulated Qube up (energy shaping) and plot it
  qube-suite list                 domains, tasks, Gymnasium ids, presets, controllers, policies
  qube-suite run --task balance --controller balance --episodes 3 --video balance.mp4
  qube-suite eval --task balance --controller balance --episodes 20 --json
  qube-suite eval --task balance --controller ppo:balance    a shipped learned policy (or a .npz file)
  qube-suite train --task balance --algo ppo --steps 500000 --seed 0 --out runs/balance
  qube-suite bench --quick        step speed against Gymnasium, dm_control and raw MuJoCo

'qube-suite COMMAND --help' describes each command."""


# -- list ------------------------------------------------------------------------------------


def _list(args: argparse.Namespace) -> int:
    from qube_suite import baselines, randomization, suite
    from qube_suite.devices.qube.tasks import SUITE
    from qube_suite.policies import shipped
    from qube_suite.wrappers import gymnasium_id

    print("domains:", ", ".join(suite.TASKS_BY_DOMAIN))
    print("\ntasks (suite name, Gymnasium ids in simulation and on hardware, tags):")
    rows = [(task, gymnasium_id(task), gymnasium_id(task, "qube_hardware"),
             ", ".join(tag for tag in SUITE.tags() if task in SUITE.tagged(tag))) for task in SUITE]
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    for row in rows:
        cells = (cell.ljust(width) for cell, width in zip(row, [*widths, 0], strict=True))
        print("  " + "  ".join(cells).rstrip())
    print("\nrandomization presets (--randomization; or a YAML file):", ", ".join(randomization.PRESETS))
    print("\ncontrollers (--controller) and the tasks they suit:")
    width = max(map(len, baselines.names()))
    for name, controller in baselines.names().items():
        print(f"  {name.ljust(width)}  {', '.join(getattr(controller, 'tasks', ())) or 'any'}")
    print("\nshipped policies (--controller, or --policy FILE.npz):", ", ".join(shipped()) or "none")
    return 0


# -- running episodes ------------------------------------------------------------------------


REALTIME_DOMAIN_KWARGS = {"qube_hardware": {"realtime": True}}
"""Domains that keep to the wall clock themselves with these `domain_kwargs`; the others are
paced by sleeping (`RealtimePacer`)."""


class RealtimePacer:
    """A step hook that sleeps until each control step's time has come on the wall clock.

    A loop already slower than real time (e.g. while rendering video) is not slowed further.
    """

    def __init__(self) -> None:
        self._start = 0.0

    def __call__(self, step: int, environment: Any) -> None:
        now = time.perf_counter()
        if step == 0:
            self._start = now
            return
        delay = self._start + step / environment.control_frequency - now
        if delay > 0:
            time.sleep(delay)


class ProgressHook:
    """A step hook that advances a `Progress` by one per control step."""

    def __init__(self, progress: Progress):
        self.progress = progress

    def __call__(self, step: int, environment: Any) -> None:
        if step:
            self.progress.update()


def _add_quiet(parser: argparse.ArgumentParser) -> None:
    """`--quiet` for a long command (see `qube_suite.progress` for what it silences)."""
    parser.add_argument("--quiet", action="store_true",
                        help="no progress output (otherwise: a bar on a terminal, a line per 10 %% in logs)")


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def _frame_rate(text: str) -> float | str:
    """--fps: a positive number, or "control" for one frame per control step."""
    return text if text == "control" else _positive_float(text)


def _frame_size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be WIDTHxHEIGHT in pixels, e.g. 640x480, got {text}") \
            from None
    return width, height


def _presets() -> str:
    """The randomization presets' names, for help texts."""
    from qube_suite.randomization.presets import PRESETS

    return ", ".join(PRESETS)


def _add_hardware_arguments(parser: argparse.ArgumentParser) -> None:
    """--device and --board, for commands that run on the hardware domain."""
    parser.add_argument("--device", choices=("qube_servo2", "qube_servo3"), default=None,
                        help="with qube_hardware: which Qube (default: qube_servo2)")
    parser.add_argument("--board", default=None,
                        help="with qube_hardware: simulated (the substitute board, default), or the card "
                             "of a real Qube through Quanser's SDK: qube_servo2_usb or qube_servo3_usb")


def _hardware_domain_kwargs(args: argparse.Namespace) -> dict[str, str]:
    """domain_kwargs from --device and --board (which need a hardware domain, e.g. qube_hardware)."""
    chosen = {name: getattr(args, name) for name in ("device", "board") if getattr(args, name) is not None}
    if chosen and not (args.domain in devices.domains() and devices.domain(args.domain).hardware):
        raise ValueError(f"--{' and --'.join(chosen)} {'needs' if len(chosen) == 1 else 'need'} "
                         "--domain qube_hardware or another device's hardware domain")
    return chosen


def _add_policy_arguments(parser: argparse.ArgumentParser) -> None:
    """What acts in the episodes: exactly one of the group's options."""
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--controller", help="a controller or shipped policy of 'qube-suite list', e.g. mpc, "
                                            "balance or ppo:balance")
    group.add_argument("--policy", metavar="FILE.npz",
                       help="a learned policy file ('qube-suite train' writes them)")


def _add_target_arguments(parser: argparse.ArgumentParser) -> None:
    """The follow tasks' target schedule (task keywords of `qube_suite.tasks.follow`)."""
    target = parser.add_argument_group("follow tasks' target (see qube_suite.tasks.follow)")
    target.add_argument("--target", help="jump (default: redrawn about twice a second), steps, sine, fixed, "
                                         "or a CSV file with the header 'time,target' (s, rad)")
    target.add_argument("--target-amplitude", type=float, metavar="RAD",
                        help="jump, steps: targets within +-RAD; sine: its amplitude")
    target.add_argument("--target-hold-time", type=float, metavar="S",
                        help="steps: time each target is held; jump: the mean time")
    target.add_argument("--target-frequency", type=float, metavar="HZ", help="sine: its frequency")
    target.add_argument("--target-angle", type=float, metavar="RAD", help="fixed: the target")


def _target_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The task keywords of the target options given."""
    names = ("target", "target_amplitude", "target_hold_time", "target_frequency", "target_angle")
    return {name: getattr(args, name) for name in names if getattr(args, name) is not None}


def _make_policy(args: argparse.Namespace, environment: Any) -> tuple[Any, str]:
    """The policy the arguments name, built for `environment`, and its name."""
    from qube_suite.evaluation import policy_for
    from qube_suite.policies import load_policy

    if args.policy is not None:
        policy, name = load_policy(args.policy), args.policy
    else:
        policy, name = policy_for(args.controller, environment, args.domain), args.controller
    _note_if_meant_for_other_tasks(name, policy, args.task)
    return policy, name


def _note_if_meant_for_other_tasks(name: str, policy: Any, task: str) -> None:
    """Tell the user on stderr when the controller or policy is meant for other tasks than `task`."""
    from qube_suite.devices.qube.tasks import SUITE
    from qube_suite.evaluation import meant_for

    suited = meant_for(policy) if task in SUITE else ()  # an unknown task is an error of its own
    if suited and task not in suited:
        print(f"qube-suite: note: {name!r} is meant for {', '.join(suited)}", file=sys.stderr)


def _count(number: int, noun: str) -> str:
    """"1 episode", "2 episodes"."""
    return f"{number} {noun}{'' if number == 1 else 's'}"


def _add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """Files written about the episodes."""
    outputs = parser.add_argument_group("outputs")
    outputs.add_argument("--video", metavar="FILE.mp4",
                         help="film the episodes into one mp4 (needs the media extra)")
    outputs.add_argument("--fps", type=_frame_rate,
                         help=f"video frames per second, at most the control rate, or 'control' for one "
                              f"frame per control step (default: {VIDEO_FPS:g}, or the control rate if "
                              f"lower); steps between frames are skipped, playback stays at real speed")
    outputs.add_argument("--camera", default="front_oblique",
                         help="video camera: front_oblique (default), front or top")
    outputs.add_argument("--size", type=_frame_size, default=(640, 480), metavar="WIDTHxHEIGHT",
                         help="video frame size in pixels, even numbers (default: 640x480)")
    outputs.add_argument("--plot", metavar="FILE.png",
                         help="plot the first episode: states, voltage, reward and LED over time "
                              "(needs the media extra)")
    outputs.add_argument("--record", metavar="FILE.jsonl",
                         help="record every step (time, state, observation, action, voltages, reward, "
                              "LED; raw board readings on qube_hardware) as JSON lines, written as the "
                              "episodes run, so a crash loses at most the last step; read it with "
                              "qube_suite.recording.load_recording")


def _check_output_paths(args: argparse.Namespace) -> None:
    """Fail before any episode runs if an output file's folder does not exist."""
    for option in ("video", "plot", "record"):
        path = getattr(args, option)
        if path and not pathlib.Path(path).resolve().parent.is_dir():
            raise ValueError(f"--{option} {path}: the folder {pathlib.Path(path).parent} does not exist")


def _video_recorder(args: argparse.Namespace, environment: Any):
    """The video hook the arguments ask for, checked against `environment`; None without --video."""
    if args.video is None:
        return None
    from qube_suite import media

    width, height = args.size
    if args.fps is None:
        fps = min(VIDEO_FPS, environment.control_frequency)
    elif args.fps == "control":
        fps = None  # one frame per control step
    elif args.fps > environment.control_frequency:
        raise ValueError(f"--fps {args.fps:g} exceeds the control rate of "
                         f"{environment.control_frequency:g} Hz")
    else:
        fps = args.fps
    recorder = media.VideoRecorder(args.video, fps, args.camera, width, height)
    recorder.renderer.render(environment.physics)  # a wrong camera, size or OpenGL fails now
    return recorder


def media_films_after_episode(environment: Any) -> bool:
    """True on hardware: videos are filmed from the episode's trace after it has run."""
    from qube_suite import media

    return media.films_after_episode(environment)


def _recorder(args: argparse.Namespace, environment: Any, policy_name: str, path: str | None):
    """The episode recorder writing `path` (--record, or --live's), observing `environment`; None
    without a path."""
    if path is None:
        return None
    from qube_suite import recording

    return recording.Recorder(path, environment, metadata={
        "domain": args.domain, "task": args.task, "policy": policy_name, "randomization": args.randomization,
        "board": args.board, "realtime": args.realtime})


def _write_outputs(args: argparse.Namespace, traces: list) -> None:
    """Write the files the arguments ask for from the episodes' traces; say where recordings went."""
    if args.record:
        print(f"recording of {_count(len(traces), 'episode')} written to {args.record}")
    if args.plot:
        from qube_suite import plotting

        plotting.plot_episode(traces[0], args.plot)
        print(f"plot of episode 1 written to {args.plot}")


def _run(args: argparse.Namespace) -> int:

    _check_output_paths(args)
    if args.plot:  # a missing extra fails before the episodes run
        from qube_suite import extras

        extras.require("matplotlib", "--plot")
    with _live_scope(args) as record:
        return _run_episodes(args, record)


def _run_episodes(args: argparse.Namespace, record: str | None) -> int:
    from qube_suite import episodes, suite

    domain_kwargs = dict(REALTIME_DOMAIN_KWARGS.get(args.domain, {})) if args.realtime else {}
    domain_kwargs.update(_hardware_domain_kwargs(args))
    task_kwargs = {"random": args.seed, **_target_kwargs(args)}
    environment = suite.load(args.domain, args.task, task_kwargs=task_kwargs,
                             randomization=args.randomization, domain_kwargs=domain_kwargs)
    policy, recorder, episode_recorder = None, None, None
    try:
        policy, name = _make_policy(args, environment)
        recorder = _video_recorder(args, environment)
        episode_recorder = _recorder(args, environment, name, record)
        film_after = recorder is not None and media_films_after_episode(environment)
        hooks = [recorder] if recorder is not None and not film_after else []
        if args.realtime and args.domain not in REALTIME_DOMAIN_KWARGS:
            hooks.append(RealtimePacer())
        traces = []
        total = args.episodes * environment.episode_steps
        with Progress(total, "step", f"{name} on {args.domain}/{args.task}", quiet=args.quiet) as progress:
            for episode in range(args.episodes):
                seed = args.seed + episode
                trace = episodes.run_episode(environment, policy, [ProgressHook(progress), *hooks],
                                             label=f"{name} on {args.domain}/{args.task}, seed {seed}",
                                             seed=seed)
                traces.append(trace)
                if film_after:  # hardware: rendered from the trace, never inside the loop
                    recorder.film(trace, environment.control_frequency)
                progress.advance_to((episode + 1) * environment.episode_steps)  # an early end skips ahead
                end = "terminated" if trace.terminated else "time limit"
                progress.write(f"episode {episode + 1} (seed {seed}): return {trace.episode_return:.1f}, "
                           f"{trace.steps} steps, {end}")
    finally:
        if recorder is not None:
            recorder.close()
        if episode_recorder is not None:
            episode_recorder.close()
        if hasattr(policy, "close"):
            policy.close()
        environment.close()
    if args.episodes > 1:
        returns = [trace.episode_return for trace in traces]
        print(f"mean return {sum(returns) / len(returns):.1f} over {args.episodes} episodes")
    if recorder is not None:
        print(f"video of {recorder.frames} frames written to {args.video}")
    _write_outputs(args, traces)
    return 0


def _add_run(commands) -> None:
    run = commands.add_parser(
        "run", help="run episodes with a controller; optionally film and plot them",
        description="Run seeded episodes of a task with a controller and print each return.",
        epilog="examples:\n"
               "  qube-suite run --task swingup --controller mpc --plot swingup.png\n"
               "  qube-suite run --task balance --controller balance --episodes 3 --randomization mild\n"
               "  qube-suite run --task swingup --controller mpc --video swingup.mp4 --fps 30\n"
               "  qube-suite run --task balance --controller balance --record balance.jsonl\n"
               "  qube-suite run --domain qube_hardware --task balance --controller balance --realtime\n"
               "  qube-suite run --domain qube_hardware --board qube_servo2_usb --task balance "
               "--controller balance",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("--domain", default="qube", help="qube (simulation, default) or qube_hardware")
    run.add_argument("--task", required=True, help="a task of 'qube-suite list', e.g. swingup")
    _add_policy_arguments(run)
    run.add_argument("--episodes", type=_positive_int, default=1, help="number of episodes (default: 1)")
    run.add_argument("--seed", type=int, default=0, help="seed of the first episode; then seed + 1, ... "
                                                         "(default: 0)")
    run.add_argument("--randomization", help=f"a preset ({_presets()}) or a YAML file")
    _add_hardware_arguments(run)
    run.add_argument("--realtime", action="store_true",
                     help="keep to the wall clock: sleep in simulation, the substitute board's realtime "
                          "mode on qube_hardware")
    _add_target_arguments(run)
    _add_output_arguments(run)
    _add_live(run)
    _add_quiet(run)
    run.set_defaults(run=_run)


# -- demo ------------------------------------------------------------------------------------


def _demo(args: argparse.Namespace) -> int:
    from qube_suite import baselines, episodes, extras, suite
    from qube_suite.conventions import GOAL_PENDULUM_TOLERANCE

    plot_path = args.plot
    if plot_path is None and extras.available("matplotlib"):
        plot_path = DEMO_PLOT
    elif plot_path is not None:
        extras.require("matplotlib", "--plot")
    environment = suite.load("qube", "swingup", task_kwargs={"random": args.seed})
    controller = baselines.for_environment("swingup", environment)
    print(f"Swing-up on the simulated Qube-Servo 2 at {environment.control_frequency:g} Hz, "
          f"{environment.task.voltage_limit:g} V limit, energy-shaping controller (seed {args.seed})")
    start = time.perf_counter()
    with Progress(environment.episode_steps, "step", "swing-up", quiet=args.quiet) as progress:
        trace = episodes.run_episode(environment, controller, [ProgressHook(progress)],
                                     label=f"energy-shaping swing-up, seed {args.seed}")
    controller.close()
    print(f"return {trace.episode_return:.1f} of {environment.episode_steps} "
          f"({trace.steps} steps, {time.perf_counter() - start:.1f} s wall time)")
    upright = trace.time[abs(trace.state[:, 1]) <= GOAL_PENDULUM_TOLERANCE]
    if len(upright):
        print(f"upright after {upright[0]:.2f} s; "
              f"largest arm angle {math.degrees(max(abs(trace.state[:, 0]))):.0f} deg")
    else:
        print("the pendulum did not reach upright")
    if plot_path is None:
        print(f"for a plot of the episode: {extras.MEDIA_HINT}")
    else:
        from qube_suite import plotting

        plotting.plot_episode(trace, plot_path)
        print(f"plot written to {plot_path}")
    return 0


def _add_demo(commands) -> None:
    demo = commands.add_parser(
        "demo", help="swing up the simulated Qube, print the return and plot the episode",
        description=f"Swing the simulated Qube up, print the return and, with matplotlib (the media "
                    f"extra), plot the episode to {DEMO_PLOT}.",
        epilog="examples:\n  qube-suite demo\n  qube-suite demo --seed 3 --plot seed3.png",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    demo.add_argument("--seed", type=int, default=0, help="seed of the start state and the controller")
    demo.add_argument("--plot", metavar="FILE.png", help=f"where to write the plot (default: {DEMO_PLOT})")
    _add_quiet(demo)
    demo.set_defaults(run=_demo)


# -- eval and bench --------------------------------------------------------------------------


def _eval(args: argparse.Namespace) -> int:
    import json

    from qube_suite.evaluation import evaluate
    from qube_suite.policies import load_policy

    policy = args.controller if args.policy is None else load_policy(args.policy)
    _note_if_meant_for_other_tasks(args.controller or args.policy, policy, args.task)
    with _live_scope(args) as record:
        result = evaluate(policy, domain=args.domain, task=args.task, episodes=args.episodes,
                          seed=args.seed, progress=not args.quiet, task_kwargs=_target_kwargs(args),
                          domain_kwargs=_hardware_domain_kwargs(args) or None, record=record)
    summary = result.to_dict()
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        episodes = _count(summary["episodes"], "episode")
        print(f"{summary['policy']} on {summary['domain']}/{summary['task']}, {episodes} from seed "
              f"{summary['seed']}:")
        compute = ("" if summary["step_time_median_ms"] is None else
                   f", compute per step {summary['step_time_median_ms']:.3f} ms median, "
                   f"{summary['step_time_p99_ms']:.3f} ms p99")
        print(f"  return {summary['mean_return']:.1f} +- {summary['std_return']:.1f}, "
              f"success {100 * summary['success_rate']:.0f} %{compute}")
        failed = summary["failed_resets"]
        if failed:
            print(f"  reset failed in {_count(len(failed), 'episode')} ({', '.join(map(str, failed))}): the "
                  "start was not reached, so each counts as failed with return 0")
        if summary["follow_error"] is not None:
            print(f"  arm from its target after the first 2 s: {summary['follow_error']:.3f} rad on average")
    return 0


def _add_eval(commands) -> None:
    evaluation = commands.add_parser(
        "eval", help="score a controller on a task over seeded episodes",
        description="Score a controller: mean return, success rate and compute time per step.",
        epilog="example:\n  qube-suite eval --task swingup --controller mpc --episodes 20 --json",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    evaluation.add_argument("--domain", default="qube", help="domain name (default: qube)")
    evaluation.add_argument("--task", required=True, help="task name, e.g. swingup")
    _add_policy_arguments(evaluation)
    evaluation.add_argument("--episodes", type=int, default=20, help="number of episodes (default: 20)")
    evaluation.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: 0)")
    evaluation.add_argument("--json", action="store_true", help="print the result as JSON")
    _add_live(evaluation)
    _add_target_arguments(evaluation)
    _add_hardware_arguments(evaluation)
    _add_quiet(evaluation)
    evaluation.set_defaults(run=_eval)


def _bench(args: argparse.Namespace) -> int:
    from qube_suite import benchmark

    return benchmark.main(quick=args.quick)


def _add_bench(commands) -> None:
    bench = commands.add_parser(
        "bench", help="measure step speed against peers and raw MuJoCo",
        description="Measure step and reset speed against Gymnasium's InvertedPendulum, dm_control's "
                    "cartpole and raw MuJoCo, interleaved in one process (minutes; --quick: seconds).",
        epilog="examples:\n  qube-suite bench\n  qube-suite bench --quick",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    bench.add_argument("--quick", action="store_true", help="short rounds and fewer batch sizes (seconds)")
    bench.set_defaults(run=_bench)


SINGLE_RUN_OPTIONS = ("algo", "steps", "seed", "randomization", "domain", "num_envs", "init", "history",
                      "device", "board", "target", "target_amplitude", "target_hold_time", "target_frequency",
                      "target_angle", "calibration")
"""`train` options that make one training run instead of the task's recipe."""


JAX_RUN_OPTIONS = ("steps", "seed", "randomization", "target", "target_amplitude", "target_hold_time",
                   "target_frequency", "target_angle")
"""`train` options of one run that the jax backend takes."""


def _train(args: argparse.Namespace) -> int:
    from qube_suite.training import recipes, train

    backend = args.backend or "sb3"
    if args.list_recipes:
        print(recipes.listing(backend))
        return 0
    single = [name for name in SINGLE_RUN_OPTIONS if getattr(args, name) is not None]
    if backend == "jax":
        return _train_jax(args, single)
    recipe = args.recipe or (args.task if args.task in recipes.RECIPES and not single else None)
    if args.recipe and single:
        raise ValueError(f"--recipe runs the recipe's own stages; drop --{single[0].replace('_', '-')}")
    if recipe is None and args.task is None:
        raise ValueError("give --task (and options of one run), --recipe or --list-recipes")
    if recipe is not None:
        policy = recipes.run(recipe, out=args.out, progress=not args.quiet, evaluations=args.evaluations,
                             eval_episodes=args.eval_episodes, checkpoints=args.checkpoints)
        print(f"recipe {recipe} done; policy {policy}")
        return 0
    init = args.init  # with a calibration and no init, train fine-tunes the task's (adaptive) policy
    result = train(args.task, algo=args.algo or "ppo", steps=args.steps or 2_000_000, seed=args.seed or 0,
                   domain=args.domain or "qube", calibration=args.calibration,
                   randomization=args.randomization, out=args.out, num_envs=args.num_envs,
                   evaluations=args.evaluations, eval_episodes=args.eval_episodes,
                   checkpoints=args.checkpoints, init=init, progress=not args.quiet,
                   hyperparameters=None if args.history is None else {"history": args.history},
                   task_kwargs=_target_kwargs(args), domain_kwargs=_hardware_domain_kwargs(args) or None)
    print(f"trained {result.steps} steps in {result.wall_time:.0f} s; best evaluation return "
          f"{result.best_mean_return:.1f}; policy {result.policy} (logs in {result.directory})")
    return 0


def _train_jax(args: argparse.Namespace, single: list[str]) -> int:
    """`train --backend jax`: the task's jax recipe, or one run with --steps/--seed/--randomization and a
    follow task's target options."""
    from qube_suite.training import recipes

    refused = [name for name in single if name not in JAX_RUN_OPTIONS]
    if refused:
        raise ValueError(f"--backend jax takes --{', --'.join(o.replace('_', '-') for o in JAX_RUN_OPTIONS)}"
                         f" of one run, not --{refused[0].replace('_', '-')}")
    name = args.recipe or args.task
    if name is None:
        raise ValueError("give --task (and options of one run) or --recipe")
    if not single:
        policy = recipes.run(name, out=args.out, progress=not args.quiet, backend="jax")
        print(f"recipe {name} (jax) done; policy {policy}")
        return 0
    from qube_suite.mjx import training as jax_training

    result = jax_training.train(args.task, steps=args.steps or 60_000_000, seed=args.seed or 0,
                                randomization=args.randomization or "none",
                                out=args.out or f"runs/jax_{args.task}_{args.seed or 0}",
                                progress=None if args.quiet else print, task_kwargs=_target_kwargs(args))
    print(f"trained {args.steps or 60_000_000} steps in {result.wall_time:.0f} s; last evaluation return "
          f"{result.evaluations[-1][1]:.1f}; policy {result.policy_path}")
    return 0


def _add_train(commands) -> None:
    training = commands.add_parser(
        "train", help="train a policy: stable-baselines3 (the 'rl' extra) or Brax on MJX ('jax')",
        description="Train PPO or SAC on a task; write checkpoints, evaluations, CSV and TensorBoard logs "
                    "and the policy as a numpy file that 'eval --controller FILE.npz' runs.",
        epilog="examples:\n  qube-suite train --task swingup                 (its recipe: every stage)\n"
               "  qube-suite train --list-recipes\n"
               "  qube-suite train --task balance --steps 500000 --out runs/balance\n"
               "  qube-suite train --task swingup --steps 3000000 --randomization sim2real\n"
               "  qube-suite train --task swingup --backend jax   (on a GPU; the 'jax' extra)",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    training.add_argument("--task", default=None, help="task name, e.g. swingup; alone, it runs the task's "
                          "recipe (--list-recipes), with any option of one run (--steps, ...) one run")
    training.add_argument("--recipe", default=None, help="run this recipe (see --list-recipes)")
    training.add_argument("--list-recipes", action="store_true",
                          help="list the recipes: stages, steps, expected wall time, target")
    training.add_argument("--backend", choices=("sb3", "jax"), default=None,
                          help="sb3: stable-baselines3 on the numpy domains (default); jax: Brax's PPO on "
                               "MJX, for a GPU (the 'jax' extra; docs/gpu-training.md)")
    training.add_argument("--algo", choices=("ppo", "sac"), default=None, help="algorithm (default: ppo)")
    training.add_argument("--steps", type=_positive_int, default=None,
                          help="environment steps (default: 2000000)")
    training.add_argument("--seed", type=int, default=None, help="seed (default: 0)")
    training.add_argument("--randomization", default=None,
                          help=f"preset ({_presets()}) or YAML file (default: none)")
    training.add_argument("--domain", choices=tuple(devices.domains()), default=None,
                          help="domain to train on (default: qube)")
    training.add_argument("--num-envs", type=_positive_int, default=None,
                          help="environments stepped together (default: 64 for ppo, 4 for sac)")
    training.add_argument("--evaluations", type=_positive_int, default=20,
                          help="evaluations of the deterministic policy during training (default: 20)")
    training.add_argument("--eval-episodes", type=_positive_int, default=8,
                          help="episodes per evaluation (default: 8)")
    training.add_argument("--checkpoints", type=_positive_int, default=10,
                          help="checkpoints saved (default: 10)")
    training.add_argument("--init", default=None,
                          help="start from the model of a previous run (its directory), e.g. balance before "
                               "swingup, swingup before swingup_follow, or to fine-tune with a "
                               "randomization; or from the actor of a PPO policy file or shipped policy")
    training.add_argument("--calibration", default=None, metavar="FILE.yaml",
                          help="train for the Qube of this calibration ('qube-suite calibrate'): under a "
                               "randomization centred on it, from the task's adaptive policy "
                               "(ppo:swingup_adaptive) or else its shipped one, unless --init")
    training.add_argument("--history", type=int, default=None, metavar="K",
                          help="the policy also sees its last K observations and voltages (default: 0)")
    training.add_argument("--out", default=None, help="run directory (default: runs/ALGO_TASK_SEED; of a "
                          "recipe: runs/RECIPE, a subdirectory per stage)")
    _add_target_arguments(training)
    _add_hardware_arguments(training)
    _add_quiet(training)
    training.set_defaults(run=_train)


def _add_list(commands) -> None:
    listing = commands.add_parser(
        "list", help="list domains, tasks, Gymnasium ids, presets, controllers and policies",
        description="List what can be run: domains, tasks with their Gymnasium ids and tags, "
                    "randomization presets, controllers with the tasks they suit, shipped policies.",
        epilog="example:\n  qube-suite list", formatter_class=argparse.RawDescriptionHelpFormatter)
    listing.set_defaults(run=_list)


# -- calibrate -------------------------------------------------------------------------------


def _calibrate(args: argparse.Namespace) -> int:
    from qube_suite import calibration
    from qube_suite.calibration import calibration_file

    out = pathlib.Path(args.out)
    if out.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--out must name a .yaml file, got {args.out!r}")
    if args.recording is not None and not all(path.endswith(".jsonl") for path in args.recording):
        return _calibrate_recordings(args, out)
    if args.recording is not None:
        if len(args.recording) > 1:
            raise ValueError("an excitation experiment (.jsonl) is calibrated on its own: give one")
        result = calibration.calibrate_recording(args.recording[0], board_type=args.board)
    else:
        domain_kwargs = {} if args.board is None else {"board": args.board}
        recording = out.with_suffix(".jsonl")
        print(f"running the {args.seconds:g} s excitation experiment on {args.domain}; recording {recording}")
        result = calibration.calibrate(args.domain, domain_kwargs, seconds=args.seconds, seed=args.seed,
                                       recording=recording)
    result.save(out)
    print(f"calibration: {out}; randomization config: {calibration_file.randomization_path(out)}")
    try:
        from qube_suite.calibration import report

        page, figure = report.write(result, out.with_suffix(".html"))
        print(f"report: {page} ({figure})")
    except ImportError as error:
        print(f"no report: {error}")
    prediction = result.prediction
    print(f"0.5 s-ahead prediction on held-out segments: {prediction['calibrated_rms']:.4f} rad "
          f"(nominal model: {prediction['nominal_rms']:.4f} rad)")
    for name, (low, high) in result.intervals.items():
        print(f"  {name:24s} {result.parameters[name]:10.4g}   95 % [{low:.4g}, {high:.4g}]")
    return 0


def _calibrate_recordings(args: argparse.Namespace, out: pathlib.Path) -> int:
    """Calibrate from CSV or .npz recordings of any logger (`calibration.recordings`)."""
    from qube_suite import calibration
    from qube_suite.calibration import calibration_file, recordings

    conventions = recordings.Conventions(degrees=args.degrees,
                                         pendulum_zero_hanging=args.pendulum_zero_hanging,
                                         arm_sign=-1 if args.flip_arm else 1,
                                         pendulum_sign=-1 if args.flip_pendulum else 1)
    result = calibration.calibrate_recordings(args.recording, args.device, conventions)
    result.save(out)
    print(f"calibration: {out}; randomization config: {calibration_file.randomization_path(out)}")
    print(f"latency {1e3 * result.actuation['latency_seconds']:.2f} ms; identified combinations: "
          + ", ".join(f"{name} {value:.4g}" for name, value in result.combinations.items()))
    for name, (low, high) in result.intervals.items():
        value = result.parameters.get(name, result.actuation.get(name))
        print(f"  {name:24s} {value:10.4g}   95 % [{low:.4g}, {high:.4g}]")
    return 0


def _add_calibrate(commands) -> None:
    calibrate = commands.add_parser(
        "calibrate", help="identify a Qube's model from a one-minute experiment",
        description="Run the excitation experiment on a Qube (or take a recording of it) and fit the "
                    "model's parameters with 95 % intervals; write the calibration (YAML), a randomization "
                    "config centred on it and a report (HTML and PNG) beside --out.",
        epilog="examples:\n"
               "  qube-suite calibrate --domain qube_hardware --board qube_servo2_usb --out my_qube.yaml\n"
               "  qube-suite calibrate --recording my_qube.jsonl --out my_qube.yaml\n"
               "  qube-suite calibrate --recording run1.csv run2.csv --device qube_servo2 --out my_qube.yaml",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    source = calibrate.add_mutually_exclusive_group(required=True)
    source.add_argument("--domain", choices=("qube_hardware",),
                        help="run the experiment on this domain (a board: the substitute by default; the fit "
                             "needs the motor current, which only a board measures)")
    source.add_argument("--recording", nargs="+", metavar="FILE",
                        help="fit recordings made earlier: one excitation experiment (JSON lines), or "
                             "recordings from any logger (CSV, .npz or .mat with time, voltage, arm_angle, "
                             "pendulum_angle; see docs/calibration.md), fitted together")
    calibrate.add_argument("--device", choices=("qube_servo2", "qube_servo3"), default="qube_servo2",
                           help="with CSV/.npz recordings: the Qube they come from (default: qube_servo2)")
    calibrate.add_argument("--degrees", action="store_true", help="CSV/.npz angles are in degrees")
    calibrate.add_argument("--pendulum-zero-hanging", action="store_true",
                           help="CSV/.npz pendulum angle is 0 hanging (the suite's 0 is upright)")
    calibrate.add_argument("--flip-arm", action="store_true", help="CSV/.npz arm angle has the opposite sign")
    calibrate.add_argument("--flip-pendulum", action="store_true",
                           help="CSV/.npz pendulum angle has the opposite sign")
    calibrate.add_argument("--board", default=None,
                           help="board: simulated (default), or the real board's type, e.g. qube_servo2_usb; "
                                "with --recording, the board type the recording must come from")
    calibrate.add_argument("--seconds", type=_positive_float, default=60.0,
                           help="experiment duration, at most 60 s (default: 60)")
    calibrate.add_argument("--seed", type=int, default=0, help="seed of the excitation (default: 0)")
    calibrate.add_argument("--out", required=True, help="the calibration file to write (.yaml)")
    calibrate.set_defaults(run=_calibrate)


def _export_recording(args: argparse.Namespace) -> int:
    from qube_suite.calibration import recordings

    print(f"episode {args.episode} written to {recordings.export(args.source, args.out, args.episode)}")
    return 0


def _add_recording(commands) -> None:
    recording = commands.add_parser("recording", help="convert the suite's recordings")
    actions = recording.add_subparsers(dest="action", required=True)
    export = actions.add_parser(
        "export", help="write an episode of a recording (JSON lines) as CSV for calibration and other tools",
        description="Write one episode of a qube_suite recording in the CSV format 'qube-suite calibrate "
                    "--recording' reads (time, voltage, arm_angle, pendulum_angle, ...).")
    export.add_argument("source", help="the recording (.jsonl)")
    export.add_argument("--out", required=True, help="the CSV file to write")
    export.add_argument("--episode", type=int, default=0, help="which episode (default: 0)")
    export.set_defaults(run=_export_recording)




# -- check-board ------------------------------------------------------------------------------


def _check_board(args: argparse.Namespace) -> int:
    from qube_suite.hardware.bringup import check_board

    device = args.device or ("qube_servo3" if args.board == "qube_servo3_usb" else "qube_servo2")
    checks = check_board(board=args.board or "simulated", device=device, identifier=args.identifier,
                         interactive=not args.non_interactive)
    failed = [check.name for check in checks if check.passed is False]
    print(f"{len(checks) - len(failed)} of {len(checks)} checks passed or skipped"
          + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


def _add_check_board(commands) -> None:
    check = commands.add_parser(
        "check-board", help="guided bring-up of a Qube: amplifier, LED, encoder signs, a small pulse",
        description="Open the board and check the amplifier's enable and fault inputs, cycle the LED, "
                    "ask you to turn the arm and the pendulum by hand and print the signs the encoders "
                    "see, apply a 0.5 V pulse for 0.2 s (the arm must turn the positive way, the current "
                    "must have the voltage's sign), compare the tachometer with the encoder's derivative, "
                    "and close the board with the motor off. Exit code 1 if a check failed.",
        epilog="examples:\n  qube-suite check-board --board qube_servo2_usb\n"
               "  qube-suite check-board --board qube_servo3_usb\n"
               "  qube-suite check-board --non-interactive     # the substitute board, no questions",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    check.add_argument("--board", default=None,
                       help="simulated (the substitute, default), qube_servo2_usb or qube_servo3_usb")
    check.add_argument("--device", choices=("qube_servo2", "qube_servo3"), default=None,
                       help="which Qube (default: the one --board names, else qube_servo2)")
    check.add_argument("--identifier", default="0", help="the board's number (default: 0)")
    check.add_argument("--non-interactive", action="store_true",
                       help="skip the steps that need a person at the Qube (LED colours, hand moves)")
    check.set_defaults(run=_check_board)


def _adapt(args: argparse.Namespace) -> int:
    from qube_suite.training import calibrated

    domain_kwargs = _hardware_domain_kwargs(args)
    report = calibrated.adapt(args.task, args.domain, domain_kwargs, out=args.out, init=args.init,
                              steps=args.steps, seconds=args.seconds, episodes=args.episodes, seed=args.seed,
                              progress=not args.quiet)
    print(report.table())
    print(f"calibration {report.calibration}; fine-tuned policy {report.policy} "
          f"({report.training_wall_time_s:.0f} s of training); use {report.kept}; "
          f"all in {args.out}/adapt.json")
    return 0


def _add_adapt(commands) -> None:
    adapt = commands.add_parser(
        "adapt", help="calibrate a Qube, fine-tune a policy for it, evaluate it on the board",
        description="The whole loop for a Qube nobody described: the excitation experiment on its board, "
                    "a calibration, PPO fine-tuning in simulation under a randomization centred on it, and "
                    "the policy's episodes on the board before and after (needs the 'rl' extra).",
        epilog="examples:\n"
               "  qube-suite adapt --task swingup --domain qube_hardware --board qube_servo2_usb\n"
               "  qube-suite adapt --task swingup --domain qube_hardware --seconds 20 --steps 200000 "
               "--episodes 2   (the substitute, in minutes)",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    adapt.add_argument("--task", default="swingup", help="task with a shipped policy (default: swingup)")
    adapt.add_argument("--domain", choices=("qube_hardware",), default="qube_hardware",
                       help="where the Qube is: a board (the substitute unless --board)")
    _add_hardware_arguments(adapt)
    adapt.add_argument("--init", default=None,
                       help="policy to fine-tune (default: ppo:TASK_adaptive if shipped, else ppo:TASK)")
    adapt.add_argument("--seconds", type=_positive_float, default=60.0,
                       help="calibration experiment, at most 60 s (default: 60)")
    adapt.add_argument("--steps", type=_positive_int, default=1_000_000,
                       help="fine-tuning steps in simulation (default: 1000000)")
    adapt.add_argument("--episodes", type=_positive_int, default=10,
                       help="evaluation episodes on the board, per policy (default: 10)")
    adapt.add_argument("--seed", type=int, default=0, help="seed (default: 0)")
    adapt.add_argument("--out", default="runs/adapt", help="directory for everything (default: runs/adapt)")
    _add_quiet(adapt)
    adapt.set_defaults(run=_adapt)


# -- live scopes and watch -----------------------------------------------------------------


def _add_live(parser: argparse.ArgumentParser) -> None:
    """--live: scopes in another process, fed by the recording (qube_suite.live)."""
    parser.add_argument("--live", nargs="?", const="viewer", metavar="viewer|web|FILE.rrd",
                        help="live scopes of theta, alpha, voltage, current, reward and LED and the digital "
                             "twin, in another process fed by the recording (--record, else a temporary "
                             "file): Rerun's viewer (default), its web viewer, or saved to a .rrd file "
                             "(needs the live extra)")


@contextlib.contextmanager
def _live_scope(args: argparse.Namespace):
    """The recording to write (`args.record`, or a temporary file with --live), while `watch` follows
    it in another process; the watcher is told the recording is complete at the end."""
    if not args.live:
        yield getattr(args, "record", None)
        return
    import tempfile

    from qube_suite import extras, live

    extras.require("rerun", "--live", extra="live")
    with tempfile.TemporaryDirectory(prefix="qube_suite_live_") as folder:
        record = getattr(args, "record", None) or str(pathlib.Path(folder) / "live.jsonl")
        pathlib.Path(record).write_text("")  # the watcher follows it from the start
        watcher = live.start_watcher(record, args.live)
        try:
            yield record
        finally:
            live.finish_watcher(watcher)


def _watch(args: argparse.Namespace) -> int:
    from qube_suite import live

    done = live.stdin_closed() if args.until_stdin_closes else None
    sink = None if args.sink == "none" else args.sink
    rows = live.watch(args.recording, follow=args.follow, done=done, sink=sink, save=args.save,
                      twin=not args.no_twin)
    print(f"{rows} rows of {args.recording} shown" + (f"; scopes saved to {args.save}" if args.save else ""))
    return 0


def _add_watch(commands) -> None:
    watch = commands.add_parser(
        "watch", help="live scopes of a recording being written (or a replay of a finished one)",
        description="Show a recording's theta, alpha, voltage, current, reward and LED as scrolling plots "
                    "of the last seconds, and the digital twin in the measured angles, in Rerun's viewer "
                    "(needs the live extra: pip install 'qube_suite[live]').",
        epilog="examples:\n  qube-suite watch balance.jsonl --follow     (while 'run ... --record "
               "balance.jsonl' runs)\n  qube-suite watch balance.jsonl              (a replay)\n"
               "  qube-suite watch balance.jsonl --sink web    (in a browser)\n"
               "  qube-suite watch balance.jsonl --sink none --save balance.rrd",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    watch.add_argument("recording", help="a recording (run/eval/view --record)")
    watch.add_argument("--follow", action="store_true",
                       help="go on showing lines as they are written, until Ctrl-C")
    watch.add_argument("--until-stdin-closes", action="store_true",
                       help="with --follow: stop once standard input closes (how run --live ends it)")
    watch.add_argument("--sink", choices=("viewer", "web", "none"), default="viewer",
                       help="Rerun's viewer (default), its web viewer served on this machine, or none")
    watch.add_argument("--save", metavar="FILE.rrd", help="also save the scopes (replay: rerun FILE.rrd)")
    watch.add_argument("--no-twin", action="store_true", help="no digital twin (it needs OpenGL)")
    watch.set_defaults(run=_watch)


# -- view ------------------------------------------------------------------------------------


def _view(args: argparse.Namespace) -> int:
    from qube_suite import viewer

    if args.record:
        _check_output_paths(argparse.Namespace(video=None, plot=None, record=args.record))
    result = viewer.view(args.task, domain=args.domain, controller=args.controller, policy=args.policy,
                         teleop=args.teleop, randomization=args.randomization, seconds=args.seconds,
                         record=args.record, seed=args.seed)
    print(f"{result.simulated_time:.2f} s simulated in {result.wall_time:.2f} s of wall-clock time "
          f"(pauses excluded), {_count(result.episodes, 'episode')}"
          + (f"; recording written to {args.record}" if args.record else ""))
    return 0


def _add_view(commands) -> None:
    from qube_suite.viewer import KEYS

    keys = "\n".join(f"  {key:16s}{meaning}" for key, meaning in KEYS)
    view = commands.add_parser(
        "view", help="watch and drive the simulated Qube in a window, at real time",
        description="Open MuJoCo's viewer on a task at real time, with a controller or policy in the loop "
                    "and/or the keyboard driving the motor; theta, alpha, voltage, reward and return are "
                    "shown over the scene. On macOS run it with mjpython: "
                    "'mjpython -m qube_suite.cli view ...'.",
        epilog=f"keys:\n{keys}\n\nexamples:\n"
               "  qube-suite view --task swingup --teleop\n"
               "  qube-suite view --task swingup --controller swingup --teleop\n"
               "  qube-suite view --task balance --policy runs/balance/policy.npz --randomization mild\n"
               "  qube-suite view --task swingup --teleop --seconds 30 --record drive.jsonl",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    view.add_argument("--task", required=True, help="a task of 'qube-suite list', e.g. swingup")
    view.add_argument("--domain", choices=("qube", "qube_hardware"), default="qube",
                      help="qube (default) or qube_hardware: the substitute board, shown as its digital twin")
    actor = view.add_mutually_exclusive_group()
    actor.add_argument("--controller", help="a controller or shipped policy, e.g. swingup or ppo:balance")
    actor.add_argument("--policy", metavar="FILE.npz", help="a learned policy file")
    view.add_argument("--teleop", action="store_true", help="drive the motor with the arrow keys")
    view.add_argument("--randomization", help=f"a preset ({_presets()}) or a YAML file")
    view.add_argument("--seconds", type=_positive_float, help="stop after this much simulated time (s)")
    view.add_argument("--record", metavar="FILE.jsonl", help="record every step (the format of run --record)")
    view.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: 0)")
    view.set_defaults(run=_view)


SUBCOMMANDS = (_add_demo, _add_list, _add_run, _add_eval, _add_view, _add_watch, _add_train, _add_bench,
               _add_calibrate, _add_check_board, _add_adapt, _add_recording)
"""Parser builders of the subcommands, in the order `--help` lists them."""


def build_parser() -> argparse.ArgumentParser:
    """The `qube-suite` argument parser."""
    parser = argparse.ArgumentParser(
        prog="qube-suite", description="Control and RL tasks on the Quanser Qube-Servo 2.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True, metavar="command")
    for add in SUBCOMMANDS:
        add(commands)
    return parser


@contextlib.contextmanager
def _exit_cleanly_on_sigterm():
    """Let SIGTERM (e.g. `kill`, a job scheduler) unwind like Ctrl-C while a command runs, so that
    it closes its environment: on hardware the motor stops and the board closes. Python's default
    would end the process at once, leaving a real board to its watchdog."""
    import signal
    import threading

    def terminate(signum, frame):
        raise SystemExit(128 + signum)

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _message(error: BaseException) -> str:
    """What to tell the user: an operating-system error on a file as "FILE: what went wrong"
    rather than Python's "[Errno N] ..."."""
    if isinstance(error, OSError) and error.filename is not None and error.strerror:
        return f"{error.filename}: {error.strerror}"
    return str(error)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with `argv` (default: `sys.argv[1:]`); return the exit code."""
    from qube_suite.hardware.errors import HardwareError

    args = build_parser().parse_args(argv)
    try:
        with _exit_cleanly_on_sigterm():
            return args.run(args)
    except (ValueError, OSError, ImportError, HardwareError) as error:
        print(f"qube-suite: error: {' '.join(_message(error).split())}", file=sys.stderr)  # one line
        return 2
    except KeyboardInterrupt:
        print("qube-suite: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
