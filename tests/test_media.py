"""Offscreen frames of every domain (the LED shows the reward) and mp4 videos."""

import gymnasium
import imageio_ffmpeg
import numpy as np
import pytest
from conftest import requires_offscreen_gl

from qube_suite import baselines, media, suite
from qube_suite.devices.qube import simulation as qube

pytestmark = requires_offscreen_gl


def short_env(task="swingup", seconds=0.4, seed=0):
    return suite.load("qube", task, task_kwargs={"random": seed}, environment_kwargs={"time_limit": seconds})


def led_mask(renderer, physics):
    """Pixels that change when only the LED's colour changes (leaves the LED green)."""
    physics.set_led((1.0, 0.0, 0.0))
    red = renderer.render(physics).astype(int)
    physics.set_led((0.0, 1.0, 0.0))
    green = renderer.render(physics).astype(int)
    return np.abs(red - green).sum(axis=2) > 60


@pytest.mark.slow
def test_frames_have_the_size_camera_and_content_asked_for(physics):
    physics.reset_to([0.4, 0.3, 0.0, 0.0])
    frames = {}
    for camera in ("front_oblique", "front", "top"):
        with media.FrameRenderer(camera, width=160, height=120) as renderer:
            frames[camera] = renderer.render(physics)
        assert frames[camera].shape == (120, 160, 3) and frames[camera].dtype == np.uint8
        assert frames[camera].std() > 10  # not blank
    assert not np.array_equal(frames["front"], frames["top"])


def test_bad_camera_and_size_are_clear_errors(physics):
    with pytest.raises(ValueError, match="valid cameras: front_oblique, front, top"):
        media.FrameRenderer("side").render(physics)
    with pytest.raises(ValueError, match="offscreen buffer of 1280 x 960"):
        media.FrameRenderer(width=2000, height=100).render(physics)
    with pytest.raises(ValueError, match="positive integers"):
        media.FrameRenderer(width=0)


@pytest.mark.slow
def test_led_pixels_are_red_at_low_reward_and_green_at_high_reward():
    renderer = media.FrameRenderer("front", width=320, height=240)
    colours = {}
    for task, controller in (("swingup", lambda observation: 0.0), ("balance", baselines.make("balance"))):
        env = short_env(task)
        timestep = env.reset()
        for _ in range(20):
            timestep = env.step(controller(timestep.observation))
        frame = renderer.render(env.physics)
        mask = led_mask(renderer, env.physics)
        assert mask.sum() > 50
        colours[task] = (timestep.reward, frame[mask].mean(axis=0))
    (low_reward, low), (high_reward, high) = colours["swingup"], colours["balance"]
    assert low_reward < 0.3 and high_reward > 0.95
    assert low[0] > high[0] + 60 and high[1] > low[1] + 60  # red falls, green rises with the reward
    renderer.close()


@pytest.mark.slow
def test_hardware_frames_show_the_measured_angles():
    hardware = suite.load("qube_hardware", "swingup").physics  # with its reset controllers
    renderer = media.FrameRenderer("front_oblique", width=160, height=120)
    try:
        hardware.reset()  # opens the substitute board: hanging at rest
        start = renderer.render(hardware)
        hardware.set_voltage(2.0)
        hardware.step(60)
        measured = hardware.qube_state()
        assert abs(measured[0]) > 0.2  # the arm moved
        frame = renderer.render(hardware)
        twin = hardware.drawable()
        np.testing.assert_allclose(twin.true_state(), measured, atol=1e-12)
        assert twin.led() == hardware.led()
        reference = qube.make_physics()
        reference.reset_to(measured)
        reference.set_led(hardware.led())
        expected = media.FrameRenderer("front_oblique", width=160, height=120).render(reference)
        assert np.abs(frame.astype(int) - expected).max() <= 1
        assert np.abs(frame.astype(int) - start).mean() > 1
    finally:
        renderer.close()
        hardware.close()


@pytest.mark.slow
def test_gymnasium_frames_follow_camera_and_size():
    env = gymnasium.make("QubeSuite/Swingup-v0", render_mode="rgb_array", camera="top", width=200, height=100)
    env.reset(seed=0)
    frame = env.render()
    physics = env.unwrapped.physics
    expected = media.FrameRenderer("top", width=200, height=100).render(physics)
    assert frame.shape == (100, 200, 3) and np.array_equal(frame, expected)
    env.close()


def test_frames_are_subsampled_to_the_fps():
    due = [step for step in range(250) if media.frame_due(step, 250.0, 30.0)]
    assert len(due) == 30 and due[:3] == [0, 9, 17]
    assert all(media.frame_due(step, 250.0, 250.0) for step in range(250))


def read_video(path):
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    frames = [np.frombuffer(data, np.uint8).reshape(height, width, 3) for data in reader]
    return meta, frames


@pytest.mark.slow
def test_record_video_films_episodes_at_the_fps(tmp_path):
    path = tmp_path / "swing.mp4"
    traces = media.record_video(short_env(), lambda observation: 1.0, path, episodes=2, fps=25,
                                camera="front", width=96, height=72)
    assert len(traces) == 2 and all(trace.steps == 100 for trace in traces)
    meta, frames = read_video(path)
    assert meta["fps"] == 25 and meta["size"] == (96, 72)
    assert len(frames) == 2 * 11  # steps 0, 10, ..., 100 of each 0.4 s episode
    assert path.stat().st_size > 2000
    first, last = frames[0].astype(int), frames[10].astype(int)
    assert first.std() > 10 and np.abs(first - last).mean() > 1  # the arm turned


def test_video_errors(tmp_path):
    with pytest.raises(ValueError, match="even"):
        media.VideoRecorder(tmp_path / "odd.mp4", width=95)
    with pytest.raises(ValueError, match="exceeds the control rate"):
        media.record_video(short_env(), lambda observation: 0.0, tmp_path / "fast.mp4", fps=500)
    with pytest.raises(ValueError, match="frame of shape"):
        frames = [np.zeros((8, 8, 3), np.uint8), np.zeros((8, 10, 3), np.uint8)]
        media.write_video(tmp_path / "mixed.mp4", frames, fps=10)


@pytest.mark.slow
def test_write_video_from_gymnasium_frames(tmp_path):
    env = gymnasium.make("QubeSuite/Swingup-v0", render_mode="rgb_array", width=64, height=48)
    env.reset(seed=0)
    frames = []
    for _ in range(5):
        env.step(np.array([3.0], np.float32))
        frames.append(env.render())
    env.close()
    assert media.write_video(tmp_path / "gym.mp4", frames, fps=env.metadata["render_fps"]) == 5
    meta, written = read_video(tmp_path / "gym.mp4")
    assert len(written) == 5 and meta["fps"] == 250


def test_missing_media_extra_says_how_to_install(monkeypatch, tmp_path):
    from qube_suite import extras

    monkeypatch.setattr(extras, "available", lambda module: False)
    with pytest.raises(ImportError, match=r"pip install 'qube_suite\[media\]'"):
        media.VideoWriter(tmp_path / "x.mp4", fps=10)
