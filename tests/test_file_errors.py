"""Files a user names that are missing or malformed: a ValueError naming the file in Python, one line
and exit code 2 on the command line."""

import pytest

from qube_suite import cli, randomization, recording, suite
from qube_suite.calibration import calibration_file
from qube_suite.files import MissingFileError

MALFORMED_YAML = "parameters: {arm_mass: [1, 2\n"


@pytest.fixture
def malformed(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(MALFORMED_YAML)
    return path


def test_a_malformed_calibration_is_a_value_error_naming_the_file(malformed):
    with pytest.raises(ValueError, match=f"{malformed} is not a valid calibration YAML file"):
        calibration_file.load(malformed)
    with pytest.raises(ValueError, match=f"{malformed} is not a valid calibration YAML file"):
        suite.load("qube", "balance", domain_kwargs={"parameters": str(malformed)})


@pytest.mark.parametrize("read", [
    calibration_file.load,
    recording.load_recording,
    randomization.load,
    lambda path: suite.load("qube", "balance", domain_kwargs={"parameters": path}),
], ids=["calibration", "recording", "randomization", "parameters"])
def test_a_missing_file_is_a_value_error_and_a_file_not_found_error_naming_it(read, tmp_path):
    missing = tmp_path / "missing.yaml"
    with pytest.raises(MissingFileError) as raised:
        read(str(missing))
    assert isinstance(raised.value, ValueError) and isinstance(raised.value, FileNotFoundError)
    assert str(raised.value).startswith(f"{missing}: no such ") and "Errno" not in str(raised.value)


def one_line_error(capsys, argv):
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("qube-suite: error: "), captured.err
    assert "Errno" not in lines[0] and "Traceback" not in captured.err
    return lines[0]


def test_train_with_a_malformed_calibration_is_one_line(capsys, malformed):
    pytest.importorskip("stable_baselines3")
    line = one_line_error(capsys, ["train", "--task", "balance", "--steps", "64", "--calibration",
                                   str(malformed), "--quiet", "--out", str(malformed.parent / "run")])
    assert str(malformed) in line


@pytest.mark.parametrize("option", [["--randomization"], ["--policy"]])
def test_run_with_a_missing_file_is_one_line_naming_it(capsys, tmp_path, option):
    missing = tmp_path / ("missing.yaml" if option == ["--randomization"] else "missing.npz")
    argv = ["run", "--task", "balance", *option, str(missing), "--quiet"]
    if option != ["--policy"]:
        argv += ["--controller", "balance"]
    assert str(missing) in one_line_error(capsys, argv)
