"""The `qube-suite` command line."""

from __future__ import annotations

import argparse
import math
import sys
import time

EPILOG = """examples:
  qube-suite demo                 swing the simulated Qube up with the energy-shaping controller
  qube-suite demo --seed 3        another start state
  qube-suite list                 domains, tasks, Gymnasium ids and controllers
  qube-suite eval --task balance --controller balance --episodes 20 --json
  qube-suite bench                step speed against Gymnasium, dm_control and raw MuJoCo (minutes)
  qube-suite bench --quick        the same table from a few seconds of measurement
"""


def _demo(args: argparse.Namespace) -> int:
    from qube_suite import baselines, suite

    environment = suite.load("qube", "swingup", task_kwargs={"random": args.seed})
    controller = baselines.for_environment("swingup", environment)
    print(f"Swing-up on the simulated Qube-Servo 2 at {environment.control_frequency:g} Hz, "
          f"{environment.task.voltage_limit:g} V limit, energy-shaping controller (seed {args.seed})")
    start = time.perf_counter()
    timestep = environment.reset()
    episode_return, upright_at, largest_arm_angle = 0.0, None, 0.0
    while not timestep.last():
        timestep = environment.step(controller(timestep.observation))
        episode_return += timestep.reward
        theta, alpha = timestep.observation["state"][:2]
        largest_arm_angle = max(largest_arm_angle, abs(theta))
        if upright_at is None and abs(alpha) < math.radians(10):
            upright_at = environment.physics.time()
    controller.close()
    print(f"return {episode_return:.1f} of {environment.episode_steps} "
          f"({environment.step_count} steps, {time.perf_counter() - start:.1f} s wall time)")
    if upright_at is not None:
        print(f"upright after {upright_at:.2f} s; "
              f"largest arm angle {math.degrees(largest_arm_angle):.0f} deg")
    else:
        print("the pendulum did not reach upright")
    return 0


def _list(args: argparse.Namespace) -> int:
    from qube_suite import baselines, suite
    from qube_suite.tasks import SUITE
    from qube_suite.wrappers import GYMNASIUM_IDS

    print("domains:", ", ".join(suite.TASKS_BY_DOMAIN))
    print("tasks:")
    ids = {task: env_id for env_id, task in GYMNASIUM_IDS.items()}
    for task in SUITE:
        tags = [tag for tag in SUITE.tags() if task in SUITE.tagged(tag)]
        print(f"  {task:24s} {ids[task]:36s} {', '.join(tags)}")
    print("controllers:", ", ".join(baselines.CONTROLLERS))
    return 0


def _eval(args: argparse.Namespace) -> int:
    import json

    from qube_suite.evaluation import evaluate

    result = evaluate(args.controller, domain=args.domain, task=args.task, episodes=args.episodes,
                      seed=args.seed, progress=not args.json)
    summary = result.to_dict()
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"{summary['policy']} on {summary['domain']}/{summary['task']}, {summary['episodes']} episodes "
              f"from seed {summary['seed']}:")
        print(f"  return {summary['mean_return']:.1f} +- {summary['std_return']:.1f}, "
              f"success {100 * summary['success_rate']:.0f} %, compute per step "
              f"{summary['step_time_median_ms']:.3f} ms median, {summary['step_time_p99_ms']:.3f} ms p99")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from qube_suite import benchmark

    return benchmark.main(quick=args.quick)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="qube-suite", description="Control and RL tasks on the Quanser Qube-Servo 2.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True, metavar="command")
    demo = commands.add_parser("demo", help="swing up the simulated Qube and print the return")
    demo.add_argument("--seed", type=int, default=0, help="seed of the start state")
    demo.set_defaults(run=_demo)
    listing = commands.add_parser("list", help="list domains, tasks, Gymnasium ids and controllers")
    listing.set_defaults(run=_list)
    evaluation = commands.add_parser(
        "eval", help="score a controller on a task over seeded episodes",
        epilog="example: qube-suite eval --domain qube --task swingup --controller mpc --episodes 20 --json")
    evaluation.add_argument("--domain", default="qube", help="domain name (default: qube)")
    evaluation.add_argument("--task", required=True, help="task name, e.g. swingup")
    evaluation.add_argument("--controller", required=True, help="controller name, e.g. balance or mpc")
    evaluation.add_argument("--episodes", type=int, default=20, help="number of episodes (default: 20)")
    evaluation.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: 0)")
    evaluation.add_argument("--json", action="store_true", help="print the result as JSON")
    evaluation.set_defaults(run=_eval)
    bench = commands.add_parser("bench", help="measure step speed against peers and raw MuJoCo")
    bench.add_argument("--quick", action="store_true", help="short rounds and fewer batch sizes (seconds)")
    bench.set_defaults(run=_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except (ValueError, OSError) as error:
        print(f"qube-suite: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("qube-suite: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
