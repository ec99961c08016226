"""Watch and drive the simulated Qube live: `qube-suite view` on MuJoCo's own viewer.

    from qube_suite import viewer
    viewer.view("swingup", controller="swingup")            # watch the swing-up controller
    viewer.view("swingup", teleop=True, seconds=60)         # drive the arm with the arrow keys

The window is MuJoCo's passive viewer (`mujoco.viewer.launch_passive`): this module
steps the episode at real time (`pacing.RealTimePacer`, with keys to slow down and
speed up), puts the voltage of the controller, the policy or the keys on the motor,
and writes θ, α, voltage, reward and the episode's return over the scene with the
viewer's own text overlay. The LED shows the task's colour as on the Qube. On
`qube_hardware` the window shows the digital twin of the substitute board's Qube.
Keys (`KEYS`) arrive through the viewer's `key_callback`, in the viewer's thread,
and are queued for the loop; anything they change happens between two steps.

On macOS MuJoCo's viewer needs the main thread of `mjpython` (installed with
MuJoCo): run `mjpython -m qube_suite.cli view ...` there.
"""

from __future__ import annotations

import dataclasses
import math
import queue
import threading
import time
from typing import Any

import mujoco
import numpy as np

from qube_suite import evaluation, recording, suite
from qube_suite.pacing import RealTimePacer
from qube_suite.policies import load_policy

# GLFW key codes, as MuJoCo's viewer reports them to `key_callback`.
KEY_SPACE, KEY_MINUS, KEY_EQUAL, KEY_ENTER, KEY_BACKSPACE = 32, 45, 61, 257, 259
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP, KEY_PAGE_UP, KEY_PAGE_DOWN = 262, 263, 264, 265, 266, 267

KEYS = (
    ("Right / Left", "drive the motor at +V / -V (stays on; --teleop)"),
    ("Down", "stop driving: 0 V, or back to the controller (--teleop)"),
    ("Page Up / Down", "step the drive voltage V up / down by 0.25 V (--teleop)"),
    ("Up", "push the pendulum: a short torque impulse"),
    ("Space", "pause / resume"),
    ("Backspace", "reset the episode"),
    ("- / =", "half / double speed (1/16x to 4x real time)"),
)
"""The keys the window answers (besides MuJoCo's own: mouse to move the camera, Tab for menus)."""

DRIVE_VOLTAGE = 0.5
"""Teleoperation voltage at the start (V): enough to turn the arm a quarter turn in about half a
second from rest (the motor's stall torque kt V / Rm = 2.5 mN m on about 2.3e-4 kg m^2)."""
VOLTAGE_STEP = 0.25
"""What Page Up / Page Down change the drive voltage by (V)."""
PUSH_TORQUE = 0.01
"""Torque of a push on the pendulum (N m), applied for `PUSH_TIME`: an impulse of 2e-4 N m s, about
1.5 rad/s on the pendulum (inertia about its pivot mp Lp^2 / 3 = 1.3e-4 kg m^2)."""
PUSH_TIME = 0.02
"""Duration of a push (s)."""
TEXT_PERIOD = 1 / 15
"""Wall-clock time between updates of the text overlay (s): the viewer takes a frame (about 16 ms)
to accept new text, far longer than a control period, so it is not written at every step."""
VIEWER_CLOSE_TIMEOUT = 10.0
"""Longest wait for MuJoCo's viewer to close its window after the view ends (s)."""

CAMERA = "front_oblique"
"""The camera the window opens with (Escape frees it to the mouse, as in MuJoCo's viewer)."""
SPEEDS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0, 4.0)
"""Playback speeds the - and = keys choose from (simulated s per wall-clock s)."""


@dataclasses.dataclass
class Controls:
    """What the keys have set: the teleoperation drive, its voltage, pause, speed, pending actions."""

    teleop: bool
    drive: int = 0  # -1, 0 or +1: the arrow last pressed
    voltage: float = DRIVE_VOLTAGE
    voltage_limit: float = math.inf
    paused: bool = False
    speed: float = 1.0
    reset: bool = False
    push_steps: int = 0

    def press(self, key: int, push_steps: int) -> None:
        """Apply one key press."""
        if key == KEY_SPACE:
            self.paused = not self.paused
        elif key == KEY_BACKSPACE:
            self.reset = True
        elif key == KEY_UP:
            self.push_steps = push_steps
        elif key in (KEY_MINUS, KEY_EQUAL):
            index = SPEEDS.index(self.speed) + (1 if key == KEY_EQUAL else -1)
            self.speed = SPEEDS[min(max(index, 0), len(SPEEDS) - 1)]
        elif self.teleop and key in (KEY_RIGHT, KEY_LEFT, KEY_DOWN):
            self.drive = {KEY_RIGHT: 1, KEY_LEFT: -1, KEY_DOWN: 0}[key]
        elif self.teleop and key in (KEY_PAGE_UP, KEY_PAGE_DOWN):
            step = VOLTAGE_STEP if key == KEY_PAGE_UP else -VOLTAGE_STEP
            self.voltage = min(max(self.voltage + step, VOLTAGE_STEP), self.voltage_limit)

    def teleop_voltage(self) -> float | None:
        """The voltage the keys ask for (V), or None where the controller (or 0 V) acts."""
        return self.drive * self.voltage if self.teleop and self.drive else None


@dataclasses.dataclass(frozen=True)
class ViewResult:
    """What a `view` ran: simulated and wall-clock time (s, excluding pauses) and episodes started."""

    simulated_time: float
    wall_time: float
    episodes: int


def view(task: str, domain: str = "qube", controller: str | None = None, policy: str | None = None,
         teleop: bool = False, randomization: Any = None, seconds: float | None = None,
         record: str | None = None, seed: int = 0, launch: Any = None) -> ViewResult:
    """Open MuJoCo's viewer on `task` and run it at real time until the window closes or `seconds`
    of simulated time have passed; return what ran.

    Args:
        task, domain, randomization: as `suite.load` ("qube" or "qube_hardware", whose substitute
            board's Qube the window shows as its digital twin).
        controller: a controller or shipped policy by name (`evaluation.policy_for`); policy: a
            policy file; neither: 0 V unless the keys drive.
        teleop: the arrow keys drive the motor (`KEYS`); with a controller they take over while on.
        seconds: stop after this much simulated time (s); None: until the window is closed.
        record: write every step to this file in the suite's recording format (`recording`).
        seed: seed of the first episode; each new episode takes the next.
        launch: the viewer's launcher (default `mujoco.viewer.launch_passive`).
    """
    if controller is not None and policy is not None:
        raise ValueError("give a controller or a policy, not both")
    if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive number, got {seconds}")
    if launch is None:
        from mujoco import viewer as mujoco_viewer

        launch = mujoco_viewer.launch_passive
    environment = suite.load(domain, task, task_kwargs={"random": seed}, randomization=randomization)
    actor, recorder = None, None
    try:
        actor = _actor(controller, policy, environment)
        name = controller or policy or ("keys" if teleop else "0 V")
        if record is not None:
            recorder = recording.Recorder(record, environment, metadata={
                "domain": domain, "task": task, "policy": name, "teleop": teleop,
                "randomization": randomization if isinstance(randomization, str) else None})
        return _run(environment, actor, teleop, seconds, seed, launch)
    finally:
        if recorder is not None:
            recorder.close()
        if actor is not None and hasattr(actor, "close"):
            actor.close()
        environment.close()


def _actor(controller: str | None, policy: str | None, environment: Any):
    """The controller or policy named, built for `environment`; None for neither."""
    if controller is not None:
        return evaluation.policy_for(controller, environment)
    if policy is not None:
        loaded = load_policy(policy)
        loaded.observation_layout = environment.task.observation_layout
        return loaded
    return None


def _run(environment: Any, actor: Any, teleop: bool, seconds: float | None, seed: int,
         launch: Any) -> ViewResult:
    keys: queue.SimpleQueue[int] = queue.SimpleQueue()
    controls = Controls(teleop=teleop, voltage_limit=environment.task.voltage_limit)
    scene = environment.physics.drawable()
    before = set(threading.enumerate())
    with launch(scene.model.ptr, scene.data.ptr, key_callback=keys.put,
                show_left_ui=False, show_right_ui=False) as window:
        viewer_threads = set(threading.enumerate()) - before
        with window.lock():
            window.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            window.cam.fixedcamid = mujoco.mj_name2id(scene.model.ptr, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA)
        overlay = _Overlay(window)
        try:
            result = _loop(environment, actor, controls, keys, window, overlay, seconds, seed)
        finally:
            overlay.close()
    for thread in viewer_threads:  # the viewer tears its window and OpenGL context down in its own
        thread.join(VIEWER_CLOSE_TIMEOUT)  # thread: an interpreter exiting meanwhile crashes or hangs
    return result


def _loop(environment: Any, actor: Any, controls: Controls, keys: queue.SimpleQueue, window: Any,
          overlay: _Overlay, seconds: float | None, seed: int) -> ViewResult:
    """Step episodes at the pace and with the voltage the keys say until the window closes or
    `seconds` of simulated time have run."""
    push_steps = max(1, round(PUSH_TIME * environment.control_frequency))
    pacer = RealTimePacer()
    elapsed, wall, episodes, episode_return = 0.0, 0.0, 0, 0.0

    def start_episode():
        nonlocal episodes, episode_return
        if hasattr(actor, "reset"):
            actor.reset()
        step = environment.reset(seed=seed + episodes)
        episodes += 1
        episode_return = 0.0
        return step

    timestep = start_episode()
    started = time.perf_counter()
    pacer.restart(elapsed)
    while window.is_running() and (seconds is None or elapsed < seconds - 1e-9):
        paused, speed = controls.paused, controls.speed
        while not keys.empty():
            controls.press(keys.get(), push_steps)
        if controls.paused != paused or controls.speed != speed:
            if controls.paused:
                wall += time.perf_counter() - started
            elif paused:
                started = time.perf_counter()
            pacer.set_speed(controls.speed, elapsed)
        if controls.reset:
            controls.reset = False
            timestep = start_episode()
        if controls.paused:
            overlay.show(environment, controls, episode_return)
            time.sleep(1 / 60)
            continue
        voltage = controls.teleop_voltage()
        if voltage is None:
            voltage = 0.0 if actor is None else actor(timestep.observation)
        _push(environment.physics, PUSH_TORQUE if controls.push_steps > 0 else 0.0)
        controls.push_steps = max(0, controls.push_steps - 1)
        timestep = environment.step(np.array([voltage], dtype=float))
        elapsed += 1.0 / environment.control_frequency
        episode_return += timestep.reward
        overlay.show(environment, controls, episode_return)
        pacer.wait(elapsed)
        if timestep.last():
            timestep = start_episode()
    if not controls.paused:
        wall += time.perf_counter() - started
    return ViewResult(elapsed, wall, episodes)


def _push(physics: Any, torque: float) -> None:
    """Apply `torque` (N m) to the simulated pendulum over the next step (MuJoCo's `qfrc_applied`); on
    the hardware domain, whose plant is the board's, nothing."""
    named = getattr(physics, "named", None)
    if named is not None:
        named.data.qfrc_applied["pendulum"] = torque


class _Overlay:
    """The readings and the keys over the scene. The viewer accepts new text only with its next frame,
    which software rendering may take a good part of a second to draw, so a thread of its own hands
    the latest text over, every `TEXT_PERIOD` at most, and the control loop never waits for it."""

    def __init__(self, window: Any):
        self._window = window
        self._texts: list[tuple] | None = None
        self._written = -math.inf
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._hand_over, name="qube-suite view text", daemon=True)
        self._thread.start()

    def show(self, environment: Any, controls: Controls, episode_return: float) -> None:
        """Draw the scene as it is now; renew the text if it is due."""
        with self._window.lock():
            environment.physics.drawable()  # LED colour; on hardware the twin takes the measured state
        now = time.perf_counter()
        if now - self._written >= TEXT_PERIOD:
            self._written = now
            self._texts = _texts(environment, controls, episode_return)
        self._window.sync()

    def close(self) -> None:
        """Stop handing text over."""
        self._stop.set()
        self._thread.join()

    def _hand_over(self) -> None:
        written = None
        while not self._stop.wait(TEXT_PERIOD):
            texts = self._texts
            if texts is not written and self._window.is_running():
                self._window.set_texts(texts)
                written = texts


def _texts(environment: Any, controls: Controls, episode_return: float) -> list[tuple]:
    """The viewer's text overlay: readings at the top left, keys at the bottom left."""
    physics, task = environment.physics, environment.task
    theta, alpha = physics.qube_state()[:2]
    reward = task.get_reward(physics)
    drive = controls.teleop_voltage()
    source = "keys" if drive is not None else "controller"
    readings = "\n".join((f"{math.degrees(theta):+7.1f} deg", f"{math.degrees(alpha):+7.1f} deg",
                          f"{physics.voltage():+6.2f} V ({source})", f"{reward:.3f}", f"{episode_return:.1f}",
                          f"{physics.time():.2f} s",
                          f"{controls.speed:g}x" + (" paused" if controls.paused else ""),
                          f"{controls.voltage:.1f} V" if controls.teleop else "off"))
    names = "theta (arm)\nalpha (pendulum)\nvoltage\nreward\nreturn\ntime\nspeed\ndrive"
    keys = "\n".join(key for key, _ in KEYS)
    meanings = "\n".join(meaning for _, meaning in KEYS)
    return [(mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_TOPLEFT, names, readings),
            (mujoco.mjtFontScale.mjFONTSCALE_100, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT, keys, meanings)]
