"""Watching the Qube the way a person does: windows on a virtual display (Xvfb), keys pressed with
xdotool, a screenshot taken with ffmpeg's X11 grabber. Skipped, saying why, where Xvfb or xdotool is
missing (`apt-get install xvfb xdotool`)."""

import os
import pathlib
import re
import shutil
import subprocess
import sys
import time

import imageio.v3 as iio
import imageio_ffmpeg
import numpy as np
import pytest

from qube_suite.recording import load_recording
from qube_suite.viewer import DRIVE_VOLTAGE

pytestmark = [pytest.mark.render, pytest.mark.skipif(
    sys.platform != "linux" or not (shutil.which("Xvfb") and shutil.which("xdotool")),
    reason="needs Xvfb and xdotool on Linux (apt-get install xvfb xdotool)")]

SCREEN = (1280, 800)


@pytest.fixture
def display():
    """A fresh Xvfb display; yields the environment for programs that draw on it with GLFW."""
    number = next(n for n in range(90, 200) if not pathlib.Path(f"/tmp/.X11-unix/X{n}").exists()
                  and not pathlib.Path(f"/tmp/.X{n}-lock").exists())
    server = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", f"{SCREEN[0]}x{SCREEN[1]}x24",
                               "-nolisten", "tcp"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 20
    while not pathlib.Path(f"/tmp/.X11-unix/X{number}").exists():
        if time.monotonic() > deadline or server.poll() is not None:
            server.kill()
            pytest.skip("Xvfb did not start")
        time.sleep(0.05)
    environment = {key: value for key, value in os.environ.items() if key != "PYOPENGL_PLATFORM"}
    environment.update(DISPLAY=f":{number}", MUJOCO_GL="glfw")
    yield environment
    server.terminate()
    server.wait(timeout=10)


def xdotool(environment, *arguments):
    return subprocess.run(["xdotool", *arguments], env=environment, capture_output=True, text=True,
                          timeout=60, check=True).stdout


def screenshot(environment, path):
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-loglevel", "error", "-y", "-f", "x11grab",
                    "-video_size", f"{SCREEN[0]}x{SCREEN[1]}", "-i", environment["DISPLAY"], "-frames:v", "1",
                    str(path)], env=environment, check=True, timeout=60)
    return iio.imread(path)


def test_render_mode_human_runs_at_real_time(display):
    script = """
import time, gymnasium, numpy, qube_suite
env = gymnasium.make("QubeSuite/Swingup-v0", render_mode="human")
env.reset(seed=0)
start = time.perf_counter()
for _ in range(500):
    env.step(numpy.zeros(1, dtype=numpy.float32))
print("wall", time.perf_counter() - start, "simulated", env.unwrapped.physics.time())
env.close()
"""
    result = subprocess.run([sys.executable, "-c", script], env=display, capture_output=True, text=True,
                            timeout=120)
    wall, simulated = map(float, re.search(r"wall (\S+) simulated (\S+)", result.stdout).groups())
    assert simulated == pytest.approx(2.0)
    assert wall == pytest.approx(simulated, rel=0.1), f"load average {os.getloadavg()[0]:.1f}"


def test_view_is_driven_by_the_keys_at_real_time(display, tmp_path):
    recording = tmp_path / "drive.jsonl"
    view = subprocess.Popen([sys.executable, "-m", "qube_suite.cli", "view", "--task", "swingup", "--teleop",
                             "--seconds", "3", "--record", str(recording)], env=display,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        window = xdotool(display, "search", "--sync", "--onlyvisible", "--name", "MuJoCo").split()[-1]
        subprocess.run(["xdotool", "windowfocus", "--sync", window], env=display, timeout=10)
        time.sleep(0.2)  # the window takes the focus
        xdotool(display, "key", "Right")  # +DRIVE_VOLTAGE, until another arrow
        time.sleep(0.7)  # longer than a frame of software OpenGL: the viewer reads keys once a frame
        xdotool(display, "key", "Left")  # -DRIVE_VOLTAGE
        time.sleep(0.7)  # longer than a frame of software OpenGL: the viewer reads keys once a frame
        shot = screenshot(display, tmp_path / "view.png")
        xdotool(display, "key", "Down")  # 0 V
        out, err = view.communicate(timeout=60)
    finally:
        view.kill()
    assert view.returncode == 0, err[-2000:]
    simulated, wall = map(float, re.search(r"(\S+) s simulated in (\S+) s", out).groups())
    assert simulated == pytest.approx(3.0, abs=0.01)
    assert wall == pytest.approx(simulated, rel=0.1), f"load average {os.getloadavg()[0]:.1f}"

    episodes = load_recording(recording).episodes  # the arm may leave +-90 degrees: a new episode
    voltage = np.concatenate([episode["voltage"] for episode in episodes])
    forward = np.flatnonzero(np.isclose(voltage, DRIVE_VOLTAGE))
    backward = np.flatnonzero(np.isclose(voltage, -DRIVE_VOLTAGE))
    assert len(forward) > 50 and len(backward) > 50, "the keys did not reach the motor"
    assert forward[-1] < backward[0]  # Right, then Left
    # the arm's speed change (rad/s) under each voltage, summed within episodes (a new episode starts at rest)
    speed_change = {DRIVE_VOLTAGE: 0.0, -DRIVE_VOLTAGE: 0.0}
    for episode in episodes:
        for drive in speed_change:
            driven = np.isclose(episode["voltage"][:-1], drive)
            speed_change[drive] += float(np.diff(episode["dtheta"])[driven].sum())
    assert speed_change[DRIVE_VOLTAGE] > 1.0, speed_change  # the arm sped up the positive way
    assert speed_change[-DRIVE_VOLTAGE] < -1.0, speed_change  # and was driven back

    assert shot.shape[:2] == (SCREEN[1], SCREEN[0])
    assert shot.astype(float).std() > 5, "the screenshot is blank"  # an empty X screen is all black
