"""`qube-suite list` advertises only options the commands take."""

import re

import pytest

from qube_suite import cli


def test_every_option_list_advertises_is_taken_by_run_and_eval(capsys):
    assert cli.main(["list"]) == 0
    listed = capsys.readouterr().out
    advertised = set(re.findall(r"--[a-z][a-z-]+", listed))
    assert {"--controller", "--policy", "--randomization"} <= advertised
    parser = cli.build_parser()
    for command in ("run", "eval"):
        for option in advertised:
            value = "x.npz" if option == "--policy" else "x"
            arguments = ["--task", "balance"] + ([] if option in ("--controller", "--policy")
                                                 else ["--controller", "balance"])
            if command == "eval" and option == "--randomization":
                continue  # eval scores the nominal task
            args = parser.parse_args([command, *arguments, option, value])
            assert getattr(args, option[2:].replace("-", "_")) == value


def test_eval_takes_a_policy_file_like_run(capsys, tmp_path):
    with pytest.raises(SystemExit):  # exactly one of --controller and --policy
        cli.build_parser().parse_args(["eval", "--task", "balance", "--controller", "balance",
                                       "--policy", "x.npz"])
    assert cli.main(["eval", "--task", "balance", "--policy", str(tmp_path / "none.npz")]) == 2
    assert "no policy file at" in capsys.readouterr().err
