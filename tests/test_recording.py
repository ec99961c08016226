"""Episode recordings: what is written, reading back, partial files, and a process killed mid-episode."""

import json
import os
import signal
import subprocess
import sys
import textwrap

import gymnasium
import numpy as np
import pytest

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import baselines, cli, episodes, recording, suite
from qube_suite.hardware import conventions

SHORT = {"time_limit": 0.2}


def test_recording_matches_the_episode_trace_and_holds_the_randomization(tmp_path):
    path = tmp_path / "balance.jsonl"
    env = suite.load("qube", "balance_follow", task_kwargs={"random": 0}, environment_kwargs=SHORT,
                     randomization="moderate")
    with recording.Recorder(path, env, metadata={"policy": "lqr"}):
        traces = [episodes.run_episode(env, baselines.make("balance"), seed=seed) for seed in (7, 8)]
        samples = [env.randomization_sample]
    saved = recording.load_recording(path)
    assert saved.metadata["policy"] == "lqr" and not saved.truncated and len(saved.episodes) == 2
    for episode, trace, seed in zip(saved.episodes, traces, (7, 8), strict=True):
        assert episode.header["seed"] == seed and episode.steps == trace.steps == 50
        np.testing.assert_array_equal(episode["time"], trace.time)
        state = np.stack([episode[column] for column in ("theta", "alpha", "dtheta", "dalpha")], 1)
        np.testing.assert_array_equal(state, trace.state)
        np.testing.assert_array_equal(episode["voltage"], trace.voltage)
        np.testing.assert_array_equal(episode["reward"][1:], trace.reward[1:])
        assert np.isnan(episode["reward"][0]) and np.isnan(episode["action"][0])
        np.testing.assert_array_equal(episode["obs_target_0"], trace.target)
        np.testing.assert_array_equal(np.stack([episode["led_r"], episode["led_g"], episode["led_b"]], 1),
                                      trace.led)
        assert episode.end == {"steps": 50, "terminated": False, "truncated": True, "physics_error": None}
        assert list(episode["last"]) == [0.0] * 50 + [1.0]
    assert saved.episodes[1].header["randomization"]["parameters"] == pytest.approx(samples[0].parameters)
    effects = saved.episodes[1].header["randomization"]["effects"]
    assert effects["action_delay"]["steps"] == samples[0].effects["action_delay"]["steps"]
    applied, voltage = saved.episodes[0]["applied_voltage"], saved.episodes[0]["voltage"]
    assert not np.array_equal(applied[2:], voltage[2:])                  # offset and delayed by the effects


def test_gymnasium_episodes_are_recorded_with_their_seed_and_a_physics_error(tmp_path):
    path = tmp_path / "rotor.jsonl"
    env = gymnasium.make("QubeSuite/Rotor-v0", time_limit=0.1)
    with recording.Recorder(path, env):
        env.reset(seed=3)
        env.step(np.array([2.5], np.float32))
        env.unwrapped.physics.set_parameters({"arm_damping": 10.0})      # diverges
        env.step(np.array([2.5], np.float32))
    episode = recording.load_recording(path).episodes[0]
    assert episode.header["seed"] == 3 and episode.header["task"] == "Rotor"
    assert episode["action"][1:].tolist() == [2.5, 2.5] and episode["voltage"][1:].tolist() == [2.5, 2.5]
    assert episode.end["terminated"] and "diverged" in episode.end["physics_error"]
    assert np.isfinite(episode["alpha"]).all()


def test_hardware_recordings_hold_the_raw_board_readings(tmp_path):
    path = tmp_path / "hardware.jsonl"
    with suite.load("qube_hardware", "swingup", task_kwargs={"random": 0}, environment_kwargs=SHORT) as env, \
            recording.Recorder(path, env, metadata={"domain": "qube_hardware"}):
        timestep = env.reset(seed=0)
        while not timestep.last():
            timestep = env.step(np.array([5.0]))
    episode = recording.load_recording(path).episodes[0]
    counts = episode["raw_encoder_arm"]
    assert np.array_equal(counts, np.round(counts)) and counts[-1] != counts[1]
    np.testing.assert_allclose([conventions.arm_angle(c) for c in counts], episode["theta"], atol=1e-12)
    assert episode["applied_voltage"][1:].tolist() == [3.0] * 50                # the task's 3 V limit
    assert np.all(episode["raw_missed_samples"] == 0)
    assert {"raw_current", "raw_tachometer"} <= set(episode.data)


def test_a_cut_off_last_line_is_ignored_and_damage_elsewhere_is_an_error(tmp_path):
    path = tmp_path / "run.jsonl"
    env = suite.load("qube", "swingup", task_kwargs={"random": 0}, environment_kwargs=SHORT)
    with recording.Recorder(path, env):
        env.reset()
        for _ in range(10):
            env.step([1.0])
    text = path.read_bytes()
    path.write_bytes(text[:-7])                                         # the last row cut mid-number
    saved = recording.load_recording(path)
    assert saved.truncated and saved.episodes[0].steps == 9 and saved.episodes[0].end is None
    lines = text.split(b"\n")
    lines[3] = lines[3][:5]
    path.write_bytes(b"\n".join(lines))
    with pytest.raises(ValueError, match="line 4.*damaged"):
        recording.load_recording(path)
    path.write_text(json.dumps({"something": "else"}) + "\n")
    with pytest.raises(ValueError, match="not a qube_suite recording"):
        recording.load_recording(path)


def test_one_recorder_per_environment(tmp_path):
    env = suite.load("qube", "swingup")
    recorder = recording.Recorder(tmp_path / "a.jsonl", env)
    with pytest.raises(RuntimeError, match="one per environment"):
        recorder.attach(suite.load("qube", "swingup"))
    recorder.close()
    assert env.observers == []


CHILD = textwrap.dedent("""
    import sys, time
    import numpy as np
    from qube_suite import recording, suite
    env = suite.load(sys.argv[2], "swingup", task_kwargs={"random": 0},
                     environment_kwargs={"time_limit": 0.5})
    recorder = recording.Recorder(sys.argv[1], env)
    steps = 0
    for episode in range(3):
        timestep = env.reset()
        while not timestep.last():
            timestep = env.step(np.array([1.0]))
            steps += 1
            if episode == 2 and timestep.mid() and steps % 20 == 0:
                print(steps, flush=True)          # after the step, so after its row was written
                time.sleep(600)                   # killed here, in the middle of the third episode
""")


@pytest.mark.slow
@pytest.mark.timeout(120)
@pytest.mark.parametrize("domain", ["qube", "qube_hardware"])
def test_a_process_killed_mid_episode_leaves_every_finished_step(domain, tmp_path):
    path = tmp_path / "killed.jsonl"
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(path), domain], stdout=subprocess.PIPE,
                             text=True)
    printed = int(child.stdout.readline())
    os.kill(child.pid, signal.SIGKILL)
    child.wait(timeout=30)
    saved = recording.load_recording(path)
    rows = sum(episode.steps for episode in saved.episodes)
    assert rows == printed                                              # every finished step is on disk
    assert len(saved.episodes) == 3
    assert saved.episodes[0].end is not None and saved.episodes[-1].end is None
    for episode in saved.episodes:
        np.testing.assert_array_equal(episode["step"], np.arange(episode.steps + 1))
        assert np.isfinite(episode["alpha"]).all()


def test_run_records_its_episodes_from_the_command_line(tmp_path, capsys):
    path = tmp_path / "run.jsonl"
    argv = ["run", "--task", "balance", "--controller", "balance", "--episodes", "2", "--seed", "4",
            "--record", str(path)]
    assert cli.main(argv) == 0
    assert f"recording of 2 episodes written to {path}" in capsys.readouterr().out
    saved = recording.load_recording(path)
    assert saved.metadata["task"] == "balance" and saved.metadata["policy"] == "balance"
    assert [episode.header["seed"] for episode in saved.episodes] == [4, 5]
    assert [episode.steps for episode in saved.episodes] == [2048, 2048]
    assert cli.main(["run", "--task", "balance", "--controller", "balance",
                     "--record", str(tmp_path / "missing" / "x.jsonl")]) == 2
