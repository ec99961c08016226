"""The `qube-suite` command line."""

import subprocess
import sys

from qube_suite import cli


def test_list_shows_tasks_ids_and_controllers(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    assert "swingup_follow_sparse" in out and "QubeSuite/Rotor-v0" in out and "mpc" in out


def test_demo_swings_up_and_prints_the_return(capsys):
    assert cli.main(["demo", "--seed", "2"]) == 0
    out = capsys.readouterr().out
    episode_return = float(out.split("return ")[1].split()[0])
    assert episode_return > 1700 and "upright after" in out


def test_user_mistakes_are_one_line_errors_with_nonzero_exit():
    result = subprocess.run([sys.executable, "-m", "qube_suite", "demo", "--seed", "x"],
                            capture_output=True, text=True)
    assert result.returncode == 2 and "invalid int value" in result.stderr
    assert "Traceback" not in result.stderr
    result = subprocess.run([sys.executable, "-m", "qube_suite", "fly"], capture_output=True, text=True)
    assert result.returncode == 2 and "invalid choice" in result.stderr


def test_bench_quick_prints_one_table_with_ratios(capsys):
    assert cli.main(["bench", "--quick"]) == 0
    out = capsys.readouterr().out
    rows = {line.split("  ")[0]: line for line in out.splitlines() if "  " in line}
    for name in ("qube_suite Gymnasium step (Swingup-v0)", "qube_suite dm_env step (swingup)",
                 "qube_suite vector env, N=16", "Gymnasium InvertedPendulum-v5 step",
                 "dm_control cartpole swingup step", "raw MuJoCo: Python loop of mj_step on qube.xml",
                 "raw mujoco.rollout, 2 threads, N=16", "reset: qube_suite Gymnasium (Swingup-v0)"):
        assert name in rows, name
        assert float(rows[name].split()[len(name.split())].replace(",", "")) > 0  # the best rate
    assert "%" in rows["qube_suite vector env, N=16"]  # share of the raw rollout limit
    for name in ("reset: qube_suite Gymnasium (Swingup-v0)", "reset: qube_suite vector env, N=16 (per world)",
                 "qube_suite vector env, N=16"):
        assert rows[name].endswith("×)")  # the randomization column: the sim2real rate and its ratio
    assert "qube_suite vector env, N=16, sim2real" in rows
