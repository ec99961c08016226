"""`qube_suite.viewer` without a window: its keys, and its loop driven through a stand-in for MuJoCo's
passive viewer that presses keys at chosen steps (tests/test_watching.py opens the real window)."""

import contextlib
import types

import numpy as np
import pytest

from qube_suite import viewer
from qube_suite.recording import load_recording
from qube_suite.viewer import (
    KEY_BACKSPACE,
    KEY_DOWN,
    KEY_EQUAL,
    KEY_LEFT,
    KEY_MINUS,
    KEY_PAGE_DOWN,
    KEY_PAGE_UP,
    KEY_RIGHT,
    KEY_SPACE,
    KEY_UP,
    Controls,
)


def test_arrows_drive_only_with_teleop_and_the_voltage_steps_within_the_limit():
    controls = Controls(teleop=False, voltage_limit=3.0)
    controls.press(KEY_RIGHT, 5)
    assert controls.teleop_voltage() is None
    controls = Controls(teleop=True, voltage_limit=1.0)
    controls.press(KEY_LEFT, 5)
    assert controls.teleop_voltage() == -viewer.DRIVE_VOLTAGE
    for _ in range(10):
        controls.press(KEY_PAGE_UP, 5)
    assert controls.teleop_voltage() == -1.0  # the task's limit
    for _ in range(10):
        controls.press(KEY_PAGE_DOWN, 5)
    assert controls.voltage == viewer.VOLTAGE_STEP
    controls.press(KEY_DOWN, 5)
    assert controls.teleop_voltage() is None


def test_speed_pause_reset_and_push_keys():
    controls = Controls(teleop=False)
    for _ in range(10):
        controls.press(KEY_EQUAL, 5)
    assert controls.speed == max(viewer.SPEEDS)
    for _ in range(20):
        controls.press(KEY_MINUS, 5)
    assert controls.speed == min(viewer.SPEEDS)
    controls.press(KEY_SPACE, 5)
    controls.press(KEY_BACKSPACE, 5)
    controls.press(KEY_UP, 5)
    assert controls.paused and controls.reset and controls.push_steps == 5


class FakeWindow:
    """What `view` uses of MuJoCo's passive viewer; presses `keys[step]` when the loop syncs."""

    def __init__(self, key_callback, keys):
        self.key_callback, self.keys, self.syncs = key_callback, keys, 0
        self.cam = types.SimpleNamespace(type=None, fixedcamid=None)
        self.texts = None

    def is_running(self):
        return True

    def lock(self):
        return contextlib.nullcontext()

    def set_texts(self, texts):
        self.texts = texts

    def sync(self):
        self.syncs += 1
        for key in self.keys.get(self.syncs, ()):
            self.key_callback(key)


def fake_launch(keys, windows):
    @contextlib.contextmanager
    def launch(model, data, key_callback, show_left_ui, show_right_ui):
        window = FakeWindow(key_callback, keys)
        windows.append(window)
        yield window
    return launch


def test_the_controller_balances_in_the_loop(tmp_path):
    windows = []
    result = viewer.view("balance", controller="balance", seconds=1.0, record=tmp_path / "b.jsonl",
                         launch=fake_launch({}, windows))
    assert result.simulated_time == pytest.approx(1.0) and result.episodes == 1
    assert result.wall_time > 0.9  # paced, not faster than real time (how close: tests/test_watching.py)
    episode = load_recording(tmp_path / "b.jsonl").episodes[0]
    assert episode.steps == 250 and np.abs(episode["alpha"]).max() < 0.3
    assert windows[0].cam.fixedcamid >= 0  # the front-oblique camera


def test_keys_take_the_motor_from_the_controller_and_push_the_pendulum(tmp_path):
    keys = {50: [KEY_RIGHT], 100: [KEY_DOWN], 150: [KEY_UP]}
    viewer.view("swingup", teleop=True, seconds=0.8, record=tmp_path / "k.jsonl",
                launch=fake_launch(keys, []))
    episode = load_recording(tmp_path / "k.jsonl").episodes[0]
    voltage = episode["voltage"]
    assert np.all(voltage[1:51] == 0.0) and np.all(voltage[52:101] == viewer.DRIVE_VOLTAGE)
    assert np.all(voltage[102:] == 0.0)
    pendulum_speed = np.abs(episode["dalpha"])
    assert pendulum_speed[160] > pendulum_speed[149] + 0.5  # the push
