"""Inputs a fuzz of the public surface found: each is a clear ValueError naming the mistake, and on the
command line one line on stderr with exit code 2."""

import json
import pathlib

import numpy as np
import pytest

from qube_suite import cli, policies, randomization, suite
from qube_suite.policies import mlp
from qube_suite.recording import load_recording

SHIPPED_POLICY = policies.shipped()["ppo:balance"]


def policy_variant(tmp_path, name, meta_raw=None, arrays_changed=None, **meta_changes) -> pathlib.Path:
    """The shipped balance policy with `meta_changes` in its record or `arrays_changed` arrays."""
    with np.load(SHIPPED_POLICY) as arrays:
        arrays = dict(arrays)
    meta = {**json.loads(str(arrays["meta"])), **meta_changes}
    arrays["meta"] = np.array(json.dumps(meta) if meta_raw is None else meta_raw)
    arrays.update(arrays_changed or {})
    path = tmp_path / f"{name}.npz"
    np.savez_compressed(path, **arrays)
    return path


def corrupt_payload(tmp_path) -> pathlib.Path:
    """A policy file whose zip directory is intact but one compressed member is garbage (zlib.error)."""
    data = bytearray(SHIPPED_POLICY.read_bytes())
    start = data.index(b"weight_1.npy") + len("weight_1.npy")  # the member's data follows its name
    data[start + 20:start + 120] = bytes(range(100))
    path = tmp_path / "corrupt.npz"
    path.write_bytes(bytes(data))
    return path


# -- configs and keywords ------------------------------------------------------------------------


@pytest.mark.parametrize("text, message", [
    ("effects: [1, 2\n", "not a valid randomization YAML file: while parsing"),
    ("parameters: !!python/object/apply:os.system ['echo hi']\n", "not a valid randomization YAML file"),
])
def test_a_bad_yaml_file_is_a_value_error(tmp_path, text, message):
    path = tmp_path / "config.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        randomization.load(path)


@pytest.mark.parametrize("kwargs, message", [
    ({"task_kwargs": {"random": "abc"}}, "random must be None, an integer seed"),
    ({"task_kwargs": {"random": -1}}, "random must be None, an integer seed"),
    ({"domain_kwargs": {"parameters": {"pendulum_mass": None}}},
     "'pendulum_mass' must be a number, got None"),
    ({"domain_kwargs": {"parameters": {"pendulum_mass": "0.02"}}}, "'pendulum_mass' must be a number"),
    ({"randomization": {"effects": {"quantization": {"counts_per_revolution": 10**400}}}},
     "counts_per_revolution must be a finite number, got an integer of 401 digits"),
    ({"randomization": {"effects": {"quantization": {"counts_per_revolution": 2**40}}}},
     "counts_per_revolution must be in"),
    ({"randomization": {"effects": {"action_delay": {"steps": 10**9}}}}, r"steps must be in \[0, 2000\]"),
    ({"randomization": {"effects": {"action_delay": {"seconds": 1e7}}}}, r"seconds must be in \[0, 1\] s"),
    ({"randomization": {"effects": {"action_delay": {"seconds": 1e300}}}}, r"seconds must be in \[0, 1\] s"),
    ({"randomization": {"effects": {"observation_delay": {"steps": {"distribution": "uniform", "low": 0,
                                                                   "high": 10**9}}}}},
     "steps must be in"),
])
def test_impossible_simulation_arguments_are_value_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        suite.load("qube", "swingup", **kwargs).reset()


@pytest.mark.parametrize("domain_kwargs, message", [
    ({"max_voltage": "10"}, "max_voltage must be a positive number, got '10'"),
    ({"max_voltage": float("nan")}, "max_voltage must be a positive number"),
    ({"plant": "x"}, "unknown plant 'x'; named plants: estimated, real_qube_servo2"),
    ({"plant": 3}, "plant must be a mapping"),
])
def test_impossible_hardware_arguments_are_value_errors(domain_kwargs, message):
    with pytest.raises(ValueError, match=message):
        suite.load("qube_hardware", "swingup", domain_kwargs=domain_kwargs)


@pytest.mark.parametrize("number", [np.float32, np.float64, np.int64, np.int32])
def test_numpy_scalars_are_numbers(number):
    env = suite.load("qube", "balance", task_kwargs={"voltage_limit": number(3)},
                     environment_kwargs={"control_frequency": number(250), "time_limit": number(2)})
    assert env.task.voltage_limit == 3.0 and env.control_frequency == 250.0 and env.episode_steps == 500
    from qube_suite import baselines

    assert baselines.make("balance", voltage_limit=number(3)).voltage_limit == 3.0


# -- policy files ----------------------------------------------------------------------------------


@pytest.mark.parametrize("make, message", [
    (lambda tmp: policy_variant(tmp, "list_meta", meta_raw=json.dumps([{"format": 1}])),
     "meta must be a mapping"),
    (lambda tmp: policy_variant(tmp, "infinite", voltage_limit=float("inf")),
     "voltage_limit must be a finite number"),
    (lambda tmp: policy_variant(tmp, "text_clip", clip="5"), "clip must be a finite number"),
    (lambda tmp: policy_variant(tmp, "zero_epsilon", epsilon=0.0,
                                arrays_changed={"observation_var": np.zeros(6, np.float32)}),
     "a variance is 0 and epsilon is 0"),
    (lambda tmp: policy_variant(tmp, "complex", arrays_changed={"weight_0": np.ones((64, 6), np.complex64)}),
     "weight_0 must hold real numbers"),
    (corrupt_payload, "not a readable policy file"),
])
def test_bad_policy_files_are_value_errors(tmp_path, make, message):
    path = make(tmp_path)
    with pytest.raises(ValueError, match=message):
        mlp.load(path)
    assert cli.main(["eval", "--task", "balance", "--policy", str(path), "--episodes", "1"]) == 2


def test_the_corrupt_payload_is_the_zlib_error_case(tmp_path):
    import zipfile
    import zlib

    with zipfile.ZipFile(corrupt_payload(tmp_path)) as archive, pytest.raises(zlib.error):
        archive.read("weight_1.npy")


# -- recordings ------------------------------------------------------------------------------------


HEADER = '{"format": "qube_suite.recording", "version": 1}\n'


@pytest.mark.parametrize("lines, message", [
    ('{"episode": {"index": 0}}\n[1, 2]\n', "line 2: an episode header without its list of column names"),
    ('{"episode": {"index": 0, "columns": ["a", "b"]}}\n[1, 2]\n[1, 2, 3]\n',
     "line 4: a row of 3 values where the episode has 2 columns"),
    ('[1, 2]\n', "line 2: a row before any episode header"),
    ('{"episode": {"index": 0, "columns": ["a"]}}\n["x"]\n',
     "line 3: a row with a value that is not a number"),
    ('{"episode": {"index": 0, "columns": ["a"]}}\n7\n', "line 3: neither a row"),
])
def test_damaged_recordings_name_the_line(tmp_path, lines, message):
    path = tmp_path / "damaged.jsonl"
    path.write_text(HEADER + lines)
    with pytest.raises(ValueError, match=message):
        load_recording(path)


# -- the command line ------------------------------------------------------------------------------


def test_command_line_mistakes_are_one_line_and_exit_2(tmp_path, capsys):
    config = tmp_path / "config.yaml"
    config.write_text("effects: [1, 2\n")
    assert cli.main(["run", "--task", "balance", "--controller", "balance", "--episodes", "1",
                     "--randomization", str(config)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("qube-suite: error: ") and error.count("\n") == 1
    assert "not a valid randomization YAML file" in error
