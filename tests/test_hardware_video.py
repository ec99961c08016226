"""Videos of hardware episodes are rendered from the recording after each episode, never in the loop."""

import subprocess
import sys

import numpy as np
import pytest
from conftest import requires_offscreen_gl
from wall_clock import child_environment, wall_clock_board_fixture  # noqa: F401

from qube_suite import media, suite

pytestmark = requires_offscreen_gl


@pytest.mark.slow
def test_no_frame_is_rendered_while_the_board_drives(tmp_path, monkeypatch):
    env = suite.load("qube_hardware", "balance", task_kwargs={"random": 0},
                     environment_kwargs={"time_limit": 0.2})
    driving_while_rendered = []
    render = media.FrameRenderer.render

    def spy(self, physics):
        qube = env.physics.qube
        driving_while_rendered.append(qube.is_open and not qube.is_idle)
        return render(self, physics)

    monkeypatch.setattr(media.FrameRenderer, "render", spy)
    with env:
        traces = media.record_video(env, lambda observation: np.zeros(1), tmp_path / "balance.mp4", fps=25)
    assert len(driving_while_rendered) == 6 and not any(driving_while_rendered)   # 0.2 s at 25 fps + start
    assert (tmp_path / "balance.mp4").stat().st_size > 0 and traces[0].steps == 50


@pytest.mark.slow
def test_the_cli_films_a_real_board_episode_without_missing_samples(wall_clock_board, tmp_path):
    video = tmp_path / "balance.mp4"
    result = subprocess.run(
        [sys.executable, "-m", "qube_suite.cli", "run", "--domain", "qube_hardware",
         "--board", "qube_servo2_usb", "--task", "balance", "--controller", "balance",
         "--video", str(video), "--fps", "10"],
        env=child_environment(wall_clock_board), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert video.stat().st_size > 0 and "video of 82 frames" in result.stdout
    assert wall_clock_board.state()["closed_cleanly"]


@pytest.fixture(autouse=True)
def _media_extra():
    pytest.importorskip("imageio_ffmpeg")
