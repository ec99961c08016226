"""The `qube-suite` command line."""

import subprocess
import sys

import imageio.v3 as iio
import imageio_ffmpeg
import pytest
from conftest import requires_offscreen_gl

from qube_suite import baselines, cli, extras, policies, suite


def test_list_shows_tasks_ids_presets_controllers_and_policies(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    assert "swingup_follow_sparse" in out and "QubeSuite/Rotor-v0" in out
    assert "QubeSuite/SwingupFollowSparseHardware-v0" in out
    assert "none, mild, moderate, sim2real" in out
    assert ": ppo:balance, ppo:balance_follow, ppo:dampen" in out
    for name, controller in baselines.names().items():
        assert f"  {name}" in out and ", ".join(controller.tasks) in out


def test_run_and_eval_take_learned_policies(capsys, tmp_path):
    assert cli.main(["run", "--task", "balance", "--controller", "ppo:balance"]) == 0
    assert "episode 1 (seed 0): return 204" in capsys.readouterr().out
    policy = tmp_path / "balance.npz"
    policy.write_bytes(policies.shipped()["ppo:balance"].read_bytes())
    assert cli.main(["run", "--task", "balance", "--policy", str(policy)]) == 0
    assert "episode 1 (seed 0): return 204" in capsys.readouterr().out


@pytest.mark.slow
def test_demo_swings_up_prints_the_return_and_plots_it(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["demo", "--seed", "2"]) == 0
    out = capsys.readouterr().out
    episode_return = float(out.split("return ")[1].split()[0])
    assert episode_return > 1700 and "upright after" in out
    assert f"plot written to {cli.DEMO_PLOT}" in out
    assert iio.imread(tmp_path / cli.DEMO_PLOT).std() > 20


def test_demo_without_matplotlib_says_how_to_get_the_plot(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(extras, "available", lambda module: module != "matplotlib")
    load = suite.load
    monkeypatch.setattr(suite, "load", lambda *args, **kwargs: load(
        *args, environment_kwargs={"time_limit": 0.2}, **kwargs))  # a short episode will do
    assert cli.main(["demo"]) == 0
    out = capsys.readouterr().out
    assert "return " in out and "for a plot of the episode: pip install 'qube_suite[media]'" in out
    assert not (tmp_path / cli.DEMO_PLOT).exists()


@pytest.mark.slow
@requires_offscreen_gl
def test_run_prints_returns_and_writes_video_and_plot(capsys, tmp_path):
    video, plot = tmp_path / "balance.mp4", tmp_path / "balance.png"
    assert cli.main(["run", "--task", "balance", "--controller", "balance", "--episodes", "2", "--seed", "4",
                     "--randomization", "mild", "--video", str(video), "--fps", "2", "--camera", "front",
                     "--size", "96x72", "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "episode 1 (seed 4): return 20" in out and "episode 2 (seed 5): return 20" in out
    assert "mean return 20" in out
    assert f"video of 34 frames written to {video}" in out  # steps 0, 125, ..., 2000 of each episode
    reader = imageio_ffmpeg.read_frames(str(video))
    assert next(reader)["size"] == (96, 72) and sum(1 for _ in reader) == 34
    assert video.stat().st_size > 2000
    assert iio.imread(plot).std() > 20


def test_run_paces_the_simulation_by_the_wall_clock(monkeypatch):
    clock, slept = [100.0], []

    def sleep(seconds):
        slept.append(seconds)
        clock[0] += seconds

    monkeypatch.setattr(cli.time, "perf_counter", lambda: clock[0])  # only sleeping takes time
    monkeypatch.setattr(cli.time, "sleep", sleep)
    assert cli.main(["run", "--task", "balance", "--controller", "balance", "--realtime"]) == 0
    assert len(slept) == 2048 and sum(slept) == pytest.approx(8.192)  # a step's 4 ms each


@pytest.mark.parametrize("argv, message", [
    (["--task", "fly", "--controller", "balance"], "unknown task 'fly'"),
    (["--task", "balance", "--controller", "pid"],
     "unknown controller or policy 'pid': valid controllers are balance"),
    (["--task", "balance", "--controller", "balance", "--randomization", "wild"], "valid presets"),
    (["--task", "balance", "--controller", "balance", "--video", "x.mp4", "--camera", "side"],
     "unknown camera 'side'"),
    (["--task", "balance", "--controller", "balance", "--video", "x.mp4", "--fps", "1000"],
     "exceeds the control rate of 250 Hz"),
    (["--task", "balance", "--controller", "balance", "--plot", "no/such/folder/x.png"],
     "the folder no/such/folder does not exist"),
    (["--task", "balance", "--controller", "balance", "--board", "qube_servo2_usb"],
     "--board needs --domain qube_hardware"),
    (["--domain", "qube_hardware", "--board", "qube_usb", "--task", "balance", "--controller", "balance"],
     "board must be 'simulated' or 'qube_servo2_usb'"),
])
def test_run_user_errors_are_one_line(capsys, argv, message):
    assert cli.main(["run", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("qube-suite: error:") and message in err and "\n" not in err


def test_run_needs_a_controller(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", "--task", "balance"])
    assert exit_.value.code == 2 and "--controller" in capsys.readouterr().err


def test_every_subcommand_has_help_with_an_example(capsys):
    for command in ("demo", "list", "run", "eval", "bench"):
        with pytest.raises(SystemExit) as exit_:
            cli.main([command, "--help"])
        assert exit_.value.code == 0
        assert f"qube-suite {command}" in capsys.readouterr().out.split("example")[1]


@pytest.mark.slow
def test_user_mistakes_are_one_line_errors_with_nonzero_exit():
    result = subprocess.run([sys.executable, "-m", "qube_suite", "demo", "--seed", "x"],
                            capture_output=True, text=True)
    assert result.returncode == 2 and "invalid int value" in result.stderr
    assert "Traceback" not in result.stderr
    result = subprocess.run([sys.executable, "-m", "qube_suite", "fly"], capture_output=True, text=True)
    assert result.returncode == 2 and "invalid choice" in result.stderr


@pytest.mark.slow
def test_bench_quick_prints_one_table_with_ratios(capsys):
    assert cli.main(["bench", "--quick"]) == 0
    out = capsys.readouterr().out
    rows = {line.split("  ")[0]: line for line in out.splitlines() if "  " in line}
    for name in ("qube_suite Gymnasium step (Swingup-v0)", "qube_suite dm_env step (swingup)",
                 "qube_suite vector env, N=16", "Gymnasium InvertedPendulum-v5 step",
                 "dm_control cartpole swingup step", "raw MuJoCo: Python loop of mj_step on model.xml",
                 "raw mujoco.rollout, 2 threads, N=16", "reset: qube_suite Gymnasium (Swingup-v0)"):
        assert name in rows, name
        assert float(rows[name].split()[len(name.split())].replace(",", "")) > 0  # the best rate
    assert "%" in rows["qube_suite vector env, N=16"]  # share of the raw rollout limit
    for name in ("reset: qube_suite Gymnasium (Swingup-v0)", "reset: qube_suite vector env, N=16 (per world)",
                 "qube_suite vector env, N=16"):
        assert rows[name].endswith("×)")  # the randomization column: the sim2real rate and its ratio
    assert "qube_suite vector env, N=16, sim2real" in rows
