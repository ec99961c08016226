"""One rule for the progress of long commands: a bar on a terminal, a line per 10 % otherwise, --quiet
silences it."""

import io

import pytest

from qube_suite import cli, progress
from qube_suite.progress import Progress


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_log_gets_a_line_per_ten_percent():
    stream = io.StringIO()
    with Progress(2048, "step", "swing-up", delay=0.0, stream=stream) as bar:
        for _ in range(2048):
            bar.update()
    lines = stream.getvalue().splitlines()
    assert lines[0] == "swing-up: 10 % (205/2048 steps)" and lines[-1] == "swing-up: 100 % (2048/2048 steps)"
    assert len(lines) == 10 and "\r" not in stream.getvalue()


def test_skipping_ahead_prints_one_line_and_postfix_shows():
    stream = io.StringIO()
    bar = Progress(10, "episode", "eval", delay=0.0, stream=stream)
    bar.set_postfix(mean_return="1820.5")
    bar.advance_to(7)
    bar.advance_to(5)  # never backwards
    assert stream.getvalue().splitlines() == ["eval: 70 % (7/10 episodes), mean_return 1820.5"]


def test_short_work_leaves_no_lines():
    stream = io.StringIO()
    with Progress(100, "step", "quick", delay=60.0, stream=stream) as bar:
        bar.update(100)
    assert stream.getvalue() == ""


def test_a_terminal_gets_a_bar_and_quiet_gets_nothing():
    terminal = Terminal()
    with Progress(100, "step", "run", stream=terminal) as bar:
        bar.update(50)
    assert "\r" in terminal.getvalue() and "run:" in terminal.getvalue()
    quiet = Terminal()
    with Progress(100, "step", "run", quiet=True, stream=quiet) as bar:
        bar.update(100)
    assert quiet.getvalue() == ""


@pytest.mark.slow
@pytest.mark.parametrize("argv", [
    ["run", "--task", "balance", "--controller", "balance", "--episodes", "1"],
    ["eval", "--task", "balance", "--controller", "balance", "--episodes", "2"],
    ["demo", "--plot", "{tmp}/demo.png"],
])
def test_long_commands_follow_the_rule_and_quiet_silences_them(argv, capsys, monkeypatch, tmp_path):
    monkeypatch.setattr(progress, "DEFAULT_DELAY", 0.0)
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in argv]
    assert cli.main(argv) == 0
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert lines and all(" % (" in line for line in lines) and "\r" not in captured.err
    assert lines[-1].split(": ", 1)[1].startswith("100 %")
    assert cli.main([*argv, "--quiet"]) == 0
    assert capsys.readouterr().err == ""
