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
