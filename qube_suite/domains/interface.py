"""The domain interface: everything a task may ask of a Qube, simulated or real.

Tasks are written against `QubePhysics` only, so the same task runs on the MuJoCo
domain (`qube`) and on the hardware domain (`qube_hardware`). Angles are in
radians, wrapped to (-pi, pi]; alpha = 0 is the pendulum upright, +-pi hanging.

A batch of simulated Qubes (`qube_suite.devices.qube.batch.QubeBatch`, behind the
vector environment) has the same accessors returning one value per world as
arrays, and `reset_world(world, state)` in place of `reset_to`; task formulas are
written to accept either.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np


class QubePhysics(Protocol):
    """What a Qube domain provides to tasks and environments."""

    latency_steps: int
    """Control steps from an observation to the first sample at which the voltage answering
    it acts: 0 in simulation (a step applies its voltage at once), 1 on hardware (a step
    reads the next sample, then writes). Controllers predict the state over it
    (`qube_suite.devices.qube.controllers.for_environment` passes it to them)."""

    physics_error: str | None
    """Why the last `step` was undone because the simulation diverged, else None (always None on
    hardware, where faults raise)."""

    def arm_angle(self) -> float:
        """Arm angle theta (rad), 0 = centred at the front."""

    def pendulum_angle(self) -> float:
        """Pendulum angle alpha (rad), 0 = upright."""

    def arm_velocity(self) -> float:
        """d theta / dt (rad/s): exact in simulation, estimated on hardware."""

    def pendulum_velocity(self) -> float:
        """d alpha / dt (rad/s): exact in simulation, estimated on hardware."""

    def qube_state(self) -> np.ndarray:
        """[theta, alpha, dtheta, dalpha] as a new float64 array."""

    def voltage(self) -> float:
        """Motor voltage (V) applied since the last `set_voltage`."""

    def applied_voltage(self) -> float:
        """Motor voltage (V) the motor receives: the command after actuator effects (and, on
        hardware, the board wrapper's clip)."""

    def set_voltage(self, volts: float) -> None:
        """Apply a motor voltage (V); callers have validated and limited it."""

    def set_led(self, rgb: Sequence[float]) -> None:
        """Show an (r, g, b) colour, each in [0, 1], on the status LED."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Start an episode from [theta, alpha, dtheta, dalpha].

        Set exactly in simulation; approached by reset controllers on hardware.
        """

    def time(self) -> float:
        """Time since the episode started (s)."""

    def timestep(self) -> float:
        """Interval of one `step` (s)."""

    def step(self, nstep: int = 1) -> None:
        """Advance by `nstep` timesteps with the voltage held."""

    def end_episode(self) -> None:
        """The episode is over: hardware stops driving the motor until the next reset."""

    def stop_motor(self) -> None:
        """An action was refused: hardware writes 0 V at once (the next valid step drives again)."""

    def drawable(self):
        """A MuJoCo physics (`devices.qube.simulation.Physics`) showing the state and LED, to render."""

    def close(self) -> None:
        """Release the Qube: on hardware, stop the motor and close the board."""


@runtime_checkable
class SeededSubstitute(Protocol):
    """A domain whose Qube can be put back where a seed says (the hardware domain's substitute
    board): `seed_substitute(seed)` before a reset makes a seeded episode repeatable."""

    def seed_substitute(self, seed: int) -> None: ...


class MeasuredState:
    """The state accessors of `QubePhysics` for a domain that keeps what it observes in
    `_measured` = (theta, alpha, dtheta, dalpha) (rad, rad/s, angles wrapped) and the
    commanded voltage in `_voltage` (V)."""

    _measured: Sequence[float]
    _voltage: float

    def arm_angle(self) -> float:
        """Measured arm angle theta (rad) in (-pi, pi], 0 = centred at the front."""
        return self._measured[0]

    def pendulum_angle(self) -> float:
        """Measured pendulum angle alpha (rad) in (-pi, pi], 0 = upright."""
        return self._measured[1]

    def arm_velocity(self) -> float:
        """Measured d theta / dt (rad/s)."""
        return self._measured[2]

    def pendulum_velocity(self) -> float:
        """Measured d alpha / dt (rad/s)."""
        return self._measured[3]

    def qube_state(self) -> np.ndarray:
        """Measured [theta, alpha, dtheta, dalpha] (rad, rad/s), angles wrapped."""
        return np.array(self._measured)

    def voltage(self) -> float:
        """Motor voltage (V) commanded by the last `set_voltage`."""
        return self._voltage


class BoardClockAndLed:
    """What every board-backed physics has alike: the LED colour to show from the next sample on,
    and time counted in board samples. Expects `_led`, `_samples`, `_episode_start` and
    `_frequency` (Hz) set by the physics."""

    def set_led(self, rgb: Sequence[float]) -> None:
        """Show (r, g, b) on the LED from the next sample on."""
        self._led = (float(rgb[0]), float(rgb[1]), float(rgb[2]))

    def led(self) -> tuple[float, float, float]:
        """The LED colour being shown."""
        return self._led

    def time(self) -> float:
        """Board time since the episode started (s)."""
        return (self._samples - self._episode_start) / self._frequency

    def timestep(self) -> float:
        """One sample (s)."""
        return 1.0 / self._frequency


class BoardLifecycle:
    """Stepping a board-backed physics sample by sample, stopping its motors after a failure and
    closing it for good, for a device whose domain keeps no other resource. Expects `qube` (the
    board's wrapper, `qube_suite.hardware.quanser.QuanserWrapper`), `_effects`
    (`qube_suite.domains.effects.Effects`), `_voltage` (the commanded voltage, V), `_sample(volts)`
    (one sample writing `volts`), `_start_sampling()` (an episode's first sample, at 0 V, and the
    commanded voltage set to 0), `_closed` and `_twin` (its digital twin, a MuJoCo physics, or
    None) set by the physics."""

    def step(self, nstep: int = 1) -> None:
        """Wait for the next `nstep` samples, writing the commanded voltage at each."""
        volts = self._effects.actuate(self._voltage)
        try:
            for _ in range(nstep):
                self._sample(volts)
        except BaseException:
            self._stop()
            raise

    def reset(self) -> None:
        """Get the board ready for an episode: open it the first time, else wake it from idle; then
        the device's first sample at 0 V (`_start_sampling`)."""
        if self._closed:
            raise RuntimeError("this hardware environment was closed and its board released; make a new one")
        try:
            if not self.qube.is_open:
                self.qube.open()
            else:
                self.qube.resume()
            self._start_sampling()
        except BaseException:
            self._stop()
            raise

    def free(self) -> None:
        """Stop the motors and close the board (dm_control's `close()` calls it)."""
        self.close()

    def end_episode(self) -> None:
        """Stop driving until the next reset: the motors at 0 V, the amplifiers disabled."""
        if self.qube.is_open and not self.qube.is_idle:
            self.qube.idle()

    def close(self) -> None:
        """Stop the motors and close the board, for good: a later `reset` raises."""
        self._closed = True
        try:
            self.qube.close()
        finally:
            if self._twin is not None:
                self._twin.close()
                self._twin = None

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
        return self._closed

    def _stop(self) -> None:
        """Leave the motors stopped after a failure: idle (0 V, amplifiers off), or closed if idling
        fails."""
        if self.qube.is_open and not self.qube.is_idle:
            try:
                self.qube.idle()
            except BaseException:
                self.qube.close()
                raise


class SimulationLifecycle:
    """What every simulated physics (a `dm_control.mujoco.Physics`) has alike: time counted from the
    episode's start, no motor to stop (time stands still between steps), and closing for good."""

    def time(self) -> float:
        """Simulated time since the episode started (s)."""
        return self._data_ptr.time

    def end_episode(self) -> None:
        """Nothing to stop in simulation."""

    def stop_motor(self) -> None:
        """Nothing to stop in simulation: time stands still between steps."""

    def close(self) -> None:
        """Free MuJoCo's data and any rendering context; the physics cannot be used afterwards."""
        if hasattr(self, "_data"):
            self.free()

    @property
    def closed(self) -> bool:
        """Whether `close()` freed the simulation: resets, rendering and pickling raise then."""
        return not hasattr(self, "_data")
