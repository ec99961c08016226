"""The hardware commands of docs/hardware.md, each run N times in a row on a wall-clock board.

The board is the wall-clock stand-in for Quanser's `quanser.hardware`
(tests/doubles: its board runs in a process of its own, as a real board is
separate hardware); the commands run exactly as docs/hardware.md prints them, on
the real-board code path (`--board qube_servo2_usb`), while another process
spins on the second core. For each command: how many runs exited 0, and the
worst sample period the board saw between two watchdog reloads while it drove
(at 250 Hz the period is 4 ms; the missed-sample stop trips beyond 44 ms, the
watchdog at 100 ms).

    python benchmarks/bench_commands.py              # 20 runs of each command (about 15 minutes)
    python benchmarks/bench_commands.py --runs 3
    python benchmarks/bench_commands.py --realtime   # the commands under `chrt -f 10`
    python benchmarks/bench_commands.py --live       # run and eval with live scopes (--live FILE.rrd)

`--realtime` runs each command as a lab would run a control loop on a busy
computer: with real-time scheduling (`chrt -f 10`, needs the privilege) and
single-threaded BLAS (`OPENBLAS_NUM_THREADS=1` etc.: a real-time thread must not
wait for normal-priority worker threads, which it would starve).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOUBLES = ROOT / "tests" / "doubles"
DOCS = ROOT / "docs" / "hardware.md"


def documented_commands() -> list[str]:
    """The `qube-suite` commands of the "Run a task" section of docs/hardware.md."""
    section = DOCS.read_text().split("## 4. Run a task", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [line.strip() for line in block.splitlines() if line.startswith("qube-suite ")]


def _exit_on_sigterm(signum, frame) -> None:
    """SIGTERM unwinds like Ctrl-C, so that the spinner and the board server are stopped."""
    raise SystemExit(128 + signum)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--realtime", action="store_true", help="run the commands under chrt -f 10")
    parser.add_argument("--match", default="", help="only the commands containing this text")
    parser.add_argument("--live", action="store_true",
                        help="run and eval with live scopes in another process, saved to a .rrd file "
                             "(no display needed; the scopes' work is the same as for a viewer)")
    args = parser.parse_args()
    sys.path.insert(0, str(DOUBLES))
    from board_server import BoardServer

    cli = [sys.executable, "-m", "qube_suite.cli"]
    single_threaded = {}
    if args.realtime:
        cli = ["chrt", "-f", "10", *cli]
        single_threaded = {name: "1" for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                  "MKL_NUM_THREADS")}
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        cores = sorted(os.sched_getaffinity(0))
        if len(cores) > 1:
            os.sched_setaffinity(spinner.pid, {cores[-1]})
        with tempfile.TemporaryDirectory() as directory:
            server = BoardServer(directory)
            try:
                run_commands(args, cli, single_threaded, server, directory, cores)
            finally:
                server.stop()
    finally:
        spinner.kill()
        spinner.wait()


def run_commands(args, cli: list[str], single_threaded: dict[str, str], server, directory: str,
                 cores: list[int]) -> None:
    """Run each documented command `args.runs` times on `server`'s board and print the counts."""
    environment = {**os.environ, **server.environment(), **single_threaded,
                   "PYTHONPATH": os.pathsep.join([str(DOUBLES), os.environ.get("PYTHONPATH", "")])}
    print(f"{args.runs} runs of each command{' under chrt -f 10' if args.realtime else ''}; another "
          f"process spins on core {cores[-1]}; "
          f"load average {os.getloadavg()[0]:.1f} at the start")
    commands = documented_commands()
    if args.live:
        commands = [command + " --live scopes.rrd" for command in commands
                    if command.split()[1] in ("run", "eval") and "--video" not in command]
    for command in [command for command in commands if args.match in command]:
        successes, worst, errors, started = 0, 0.0, [], time.perf_counter()
        for _ in range(args.runs):
            result = subprocess.run(cli + shlex.split(command)[1:], env=environment, cwd=directory,
                                    capture_output=True, text=True)
            state = server.state()
            period = state["worst_period"] if state else 0.0
            worst = max(worst, period)
            ok = result.returncode == 0 and state["closed_cleanly"] and not state["amplifier_enabled"]
            successes += ok
            if not ok:
                errors.append(result.stderr.strip().splitlines()[-1] if result.stderr.strip() else
                              f"exit {result.returncode}")
        print(f"\n{command}\n  {successes}/{args.runs} succeeded; worst sample period "
              f"{1e3 * worst:.1f} ms; {time.perf_counter() - started:.0f} s; load average "
              f"{os.getloadavg()[0]:.1f}")
        for error in sorted(set(errors)):
            print(f"  failure: {error}")


if __name__ == "__main__":
    main()
