"""docs/hardware.md: its examples run on a real board's code path (the wall-clock stand-in), only
the marked substitute example on the substitute, and its commands parse."""

import pathlib
import re
import shlex

import pytest
from wall_clock import wall_clock_board_fixture  # noqa: F401

from qube_suite import cli

DOCS = (pathlib.Path(__file__).resolve().parent.parent / "docs" / "hardware.md").read_text()
SUBSTITUTE = DOCS.split("## Without a Qube: the substitute board", 1)
REAL_BOARD_BLOCKS = re.findall(r"```python\n(.*?)```", SUBSTITUTE[0], re.S)
SUBSTITUTE_BLOCKS = re.findall(r"```python\n(.*?)```", SUBSTITUTE[1], re.S)


@pytest.mark.slow
def test_the_real_board_examples_run_on_a_real_boards_code_path(wall_clock_board):
    assert len(REAL_BOARD_BLOCKS) == 2
    for index, code in enumerate(REAL_BOARD_BLOCKS):
        assert "true_state" not in code and "qube_servo2_usb" in code   # nothing substitute-only
        exec(compile(code, f"docs/hardware.md python block {index}", "exec"), {})
    state = wall_clock_board.state()
    assert state["closed_cleanly"] and not state["amplifier_enabled"]


def test_the_substitute_examples_run():
    assert len(SUBSTITUTE_BLOCKS) == 2
    for index, code in enumerate(SUBSTITUTE_BLOCKS):
        exec(compile(code, f"docs/hardware.md substitute example {index}", "exec"), {})


def test_the_commands_parse_and_name_a_real_board():
    commands = [line.split("#")[0] for block in re.findall(r"```bash\n(.*?)```", DOCS, re.S)
                for line in block.splitlines() if line.startswith("qube-suite ")]
    assert len(commands) == 4
    parser = cli.build_parser()
    for command in commands:
        args = parser.parse_args(shlex.split(command)[1:])
        assert args.board == "qube_servo2_usb" and getattr(args, "domain", "qube_hardware") == "qube_hardware"
