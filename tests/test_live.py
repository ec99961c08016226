"""Live scopes (`qube_suite.live`, `qube-suite watch`, `run/eval --live`): what reaches Rerun, read back
from the saved stream; the recording followed line by line as it is written."""

import json
import threading

import numpy as np
import pytest

from qube_suite import baselines, cli, episodes, live, recording, suite

rerun = pytest.importorskip("rerun", reason="the live scope needs the live extra (rerun-sdk)")
from rerun.chunk import RrdReader  # noqa: E402


def saved_scopes(path):
    """{entity path: list of its chunks' record batches} of a saved .rrd stream."""
    scopes = {}
    for chunk in RrdReader(path).stream().to_chunks():
        scopes.setdefault(str(chunk.entity_path), []).append(chunk)
    return scopes


def scalars(chunks):
    values = []
    for chunk in chunks:
        batch = chunk.to_record_batch()
        column = next(name for name in batch.schema.names if name.endswith("Scalars:scalars"))
        values.extend(np.concatenate(batch.column(column).to_pylist()))
    return np.array(values)


@pytest.fixture(scope="module")
def swingup_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("live") / "swingup.jsonl"
    environment = suite.load("qube", "swingup", task_kwargs={"random": 0})
    with recording.Recorder(path, environment):
        episodes.run_episode(environment, baselines.for_environment("swingup", environment), seed=0)
    environment.close()
    return path


@pytest.mark.render
def test_a_replay_sends_every_reading_and_the_twin_in_the_measured_angles(swingup_recording, tmp_path):
    saved = tmp_path / "scopes.rrd"
    assert live.watch(swingup_recording, sink=None, save=saved) == 2049
    scopes = saved_scopes(saved)
    episode = recording.load_recording(swingup_recording).episodes[0]
    for name in ("theta", "alpha", "voltage", "reward"):
        np.testing.assert_array_equal(scalars(scopes[f"/scope/{name}"]), episode[name], err_msg=name)
    assert len(scalars(scopes["/scope/led"])) == 3 * 2049
    twin_frames = sum(chunk.num_rows for chunk in scopes["/twin"])
    assert twin_frames == pytest.approx(episode["time"][-1] / live.TWIN_PERIOD, abs=2)


@pytest.mark.render
def test_the_twin_mirrors_the_angles_and_the_led():
    twin = live.Twin()
    try:
        hanging = twin(0.0, np.pi, np.array([0.0, 1.0, 0.0]))
        turned = twin(1.0, 0.0, np.array([0.0, 1.0, 0.0]))
        red = twin(0.0, np.pi, np.array([1.0, 0.0, 0.0]))
    finally:
        twin.close()
    assert hanging.std() > 10
    assert np.abs(hanging.astype(float) - turned).mean() > 1  # the arm and the pendulum moved
    difference = red.astype(float) - hanging
    assert difference[..., 0].sum() > 0 > difference[..., 1].sum()  # the LED turned from green to red


def test_lines_are_read_as_they_are_written_and_a_cut_line_waits(tmp_path):
    path = tmp_path / "growing.jsonl"
    path.write_bytes(b'{"format": "qube_suite.recording"}\n[1, 2')
    done = threading.Event()
    batches = live.follow_lines(path, follow=True, done=done)
    assert next(batches) == [{"format": "qube_suite.recording"}]
    with open(path, "ab") as file:
        file.write(b"]\n[3]\n")
    assert next(batches) == [[1, 2], [3]]
    done.set()
    assert list(batches) == []


@pytest.mark.render
@pytest.mark.parametrize("command", [["run"], ["eval", "--episodes", "1"]])
def test_run_and_eval_live_feed_a_watcher_in_another_process(tmp_path, command, capsys):
    saved = tmp_path / "live.rrd"
    assert cli.main([*command, "--task", "balance", "--controller", "balance", "--quiet", "--live",
                     str(saved)]) == 0
    scopes = saved_scopes(saved)
    balance = scalars(scopes["/scope/alpha"])
    assert len(balance) == 2049 and np.abs(balance).max() < 0.35  # the whole episode, held upright
    assert sum(chunk.num_rows for chunk in scopes["/twin"]) >= 1


def test_watch_of_a_missing_recording_is_one_line(capsys, tmp_path):
    assert cli.main(["watch", str(tmp_path / "missing.jsonl"), "--sink", "none",
                     "--save", str(tmp_path / "x.rrd")]) == 2
    assert "no such recording file" in capsys.readouterr().err


def test_a_file_that_is_not_a_recording_is_refused(tmp_path):
    path = tmp_path / "other.jsonl"
    path.write_text(json.dumps({"format": "something else"}) + "\n")
    with pytest.raises(ValueError, match="not a qube_suite recording"):
        live.watch(path, sink=None, save=tmp_path / "x.rrd")
