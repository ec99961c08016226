"""The `swingup` controller for many worlds at once: each world's design and episode state in arrays.

    design = baselines.make("swingup", voltage_limit=10.0, latency_steps=1)
    batch = BatchedSwingup(design, worlds=64)
    volts = batch(states)            # states: rows [theta, alpha, dtheta, dalpha]; volts: one per world
    batch.sent(volts_really_sent)    # as `Controller.sent`, per world
    batch.redesign(3, other_design)  # world 3 runs another design (its model, gains, latency) from now
    batch.reset(mask)                # new episodes in the worlds of a boolean mask

Imitation labels every state of 64 simulated worlds with the controller's voltage
(`qube_suite.training.imitation`); 64 Python controllers cost more than the
simulation itself. This runs the law of `SwingupController` (`swingup.py`: the
energy shaping of `energy.py`, the balance LQR of `lqr.py`, the switch between them
and the swing-to-swing energy adaptation) and its `StateObserver` (`observer.py`)
on arrays of worlds, in the same order of operations: each world's voltage is the
per-world controller's to within rounding of numpy's trigonometric functions
(`tests/test_batched_controller.py` holds them within 1e-12 V). The gains, matrices,
model coefficients and latency are read from `design` for every world, so its Riccati
equations are solved once for all; `redesign` gives one world another design (a
teacher built for the plant a world drew). The equations are explained in those modules.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from qube_suite.angles import TAU
from qube_suite.devices.qube.controllers import energy as shaping_law
from qube_suite.devices.qube.controllers import observer as observer_law
from qube_suite.devices.qube.controllers import swingup as swingup_law
from qube_suite.devices.qube.controllers.model import RigidBodyModel

_PER_WORLD = ("_lqr_limit", "_catch_level", "_release_level", "_pump_torque", "_centre_limit", "_drain_speed",
              "_stiffness", "_damping", "_shaping_limit", "_offset_scale", "_offset_slope")
"""The design's numbers each world holds its own of (one per world)."""


def _wrap(angle: np.ndarray) -> np.ndarray:
    """`qube_suite.angles.wrap_angle` over an array (rad, to (-pi, pi])."""
    return math.pi - np.remainder(math.pi - angle, TAU)


class BatchedSwingup:
    """`worlds` copies of the `swingup` controller `design` (a `SwingupController`), run as one.

    Args:
        design: the controller whose model, gains, limits and latency every world uses.
        worlds: how many worlds (a positive integer).
    """

    def __init__(self, design: swingup_law.SwingupController, worlds: int):
        if not isinstance(design, swingup_law.SwingupController):
            raise ValueError(f"design must be a SwingupController, got {type(design).__name__}")
        if not (isinstance(worlds, int) and worlds >= 1):
            raise ValueError(f"worlds must be a positive integer, got {worlds!r}")
        self.worlds = worlds
        self.voltage_limit = design.voltage_limit
        self._substeps, self._substep = design.observer._substeps, design.observer._substep
        self.model = RigidBodyModel(**{field.name: np.full(worlds, getattr(design.model, field.name))
                                       for field in dataclasses.fields(RigidBodyModel)})
        self._latency = np.zeros(worlds, int)
        self._world_index = np.arange(worlds)
        self._gains = np.zeros((2, 3, worlds))
        self._lqr_gain, self._cost_matrix = np.zeros((worlds, 4)), np.zeros((worlds, 4, 4))
        for name in _PER_WORLD:
            setattr(self, name, np.zeros(worlds))
        self._voltages = np.zeros((design.observer.latency_steps + 1, worlds))
        for world in range(worlds):
            self.redesign(world, design)
        self._started = np.zeros(worlds, bool)
        self._state = np.zeros((4, worlds))
        self._bias = np.zeros((2, worlds))
        self._balancing = np.zeros(worlds, bool)
        self._energy_set = np.zeros(worlds)
        self._upper_side = np.zeros(worlds)
        self._peak_alpha = np.zeros(worlds)
        self._peak_energy = np.zeros(worlds)
        self._excess = np.zeros(worlds)
        self._crossed = np.zeros(worlds, bool)  # whether `_excess` holds a value (the controller's not None)
        self.reset(np.ones(worlds, bool))

    def redesign(self, world: int, design: swingup_law.SwingupController) -> None:
        """Run `design` (a `SwingupController` of this batch's voltage limit and control frequency) in
        world `world` from its next episode (`reset`): its model, gains, limits and latency."""
        if not isinstance(design, swingup_law.SwingupController):
            raise ValueError(f"design must be a SwingupController, got {type(design).__name__}")
        observer, balance, shaping, model = design.observer, design.balance, design.shaping, design.model
        if design.voltage_limit != self.voltage_limit or observer._substep != self._substep:
            raise ValueError("a design's voltage limit and control frequency must be the batch's: "
                             f"{design.voltage_limit} V and {self._substep * self._substeps} s per period, "
                             f"got {self.voltage_limit} V and {observer._substep * observer._substeps} s")
        for field in dataclasses.fields(RigidBodyModel):
            getattr(self.model, field.name)[world] = getattr(model, field.name)
        self._latency[world] = observer.latency_steps
        missing = observer.latency_steps + 1 - len(self._voltages)
        if missing > 0:  # a longer memory of voltages sent; the newest stay last
            self._voltages = np.concatenate([np.zeros((missing, self.worlds)), self._voltages])
        self._gains[:, :, world] = observer.gains
        self._lqr_gain[world], self._cost_matrix[world] = balance.gain, balance.cost_matrix
        values = {"_lqr_limit": balance.voltage_limit, "_catch_level": design.catch_level,
                  "_release_level": design.release_level, "_pump_torque": shaping.pump_torque,
                  "_centre_limit": shaping.centre_limit, "_drain_speed": shaping.drain_speed,
                  "_stiffness": shaping.stiffness, "_damping": shaping.damping,
                  "_shaping_limit": shaping.voltage_limit,
                  "_offset_scale": model.coupling / math.sqrt(model.base_inertia * model.swing_inertia),
                  "_offset_slope": math.sqrt(model.swing_inertia / model.base_inertia)}
        for name in _PER_WORLD:
            getattr(self, name)[world] = values[name]

    def reset(self, worlds: np.ndarray) -> None:
        """Forget the previous episode in the worlds of the boolean mask `worlds`."""
        worlds = np.asarray(worlds, bool)
        self._forget_estimate(worlds)
        self._balancing[worlds] = False
        self._energy_set[worlds] = swingup_law.ENERGY_MARGIN * self.model.swing_up_energy[worlds]
        self._upper_side[worlds] = 0.0
        self._peak_alpha[worlds] = math.pi
        self._peak_energy[worlds] = 0.0
        self._crossed[worlds] = False

    def _forget_estimate(self, worlds: np.ndarray) -> None:
        self._started[worlds] = False
        self._bias[:, worlds] = 0.0
        self._voltages[:, worlds] = 0.0

    def __call__(self, states: np.ndarray) -> np.ndarray:
        """Each world's voltage (V) for its measured row [theta, alpha, dtheta, dalpha] of `states`."""
        states = np.asarray(states, np.float64)
        if states.shape != (self.worlds, 4):
            raise ValueError(f"states must have shape ({self.worlds}, 4), got {states.shape}")
        estimate = self._estimate(states.T)
        theta, alpha, dtheta, dalpha = estimate
        bias_theta, bias_alpha = self._bias
        unmodelled = self._arm_inertia(alpha) * bias_theta - self.model.coupling * np.cos(alpha) * bias_alpha
        volts = self._voltage_for(estimate) - unmodelled / self.model.torque_per_volt
        volts = np.minimum(np.maximum(volts, -self.voltage_limit), self.voltage_limit)
        self._voltages = np.roll(self._voltages, -1, axis=0)
        self._voltages[-1] = volts
        return volts

    def sent(self, volts: np.ndarray) -> None:
        """Each world's voltage (V) really sent in answer to its last measurement (`Controller.sent`)."""
        self._voltages[-1] = np.asarray(volts, np.float64)

    # The observer (observer.StateObserver.__call__), every world at once.

    def _estimate(self, measured: np.ndarray) -> np.ndarray:
        theta, alpha = measured[0], measured[1]
        started = self._started
        if started.any():
            predicted = self._advance(self._state, self._sent_before(0))
            errors = (theta - predicted[0], _wrap(alpha - predicted[1]))
            far = np.maximum(np.abs(errors[0]), np.abs(errors[1])) > observer_law.RESYNC_ANGLE
            corrected = started & ~far
            for joint, (error, gain) in enumerate(zip(errors, self._gains, strict=True)):
                predicted[joint] += gain[0] * error
                predicted[2 + joint] += gain[1] * error
                bias = self._bias[joint]
                self._bias[joint] = np.where(corrected, bias + gain[2] * error, bias)
            predicted[1] = _wrap(predicted[1])
            self._state = np.where(corrected, predicted, self._state)
            self._forget_estimate(started & far)
        fresh = ~self._started
        self._state[:, fresh] = measured[:, fresh]
        self._started[fresh] = True
        state = self._state
        for k in range(1, int(self._latency.max()) + 1):
            state = np.where(k <= self._latency, self._advance(state, self._sent_before(k)), state)
        return np.array([state[0], _wrap(state[1]), state[2], state[3]])

    def _sent_before(self, k: int) -> np.ndarray:
        """Each world's voltage sent `latency - k` measurements before the last one (its own latency;
        the last one's where that is later)."""
        newest = len(self._voltages) - 1
        rows = np.minimum(newest - self._latency + k, newest)
        return self._voltages[rows, self._world_index]

    def _advance(self, state: np.ndarray, volts: np.ndarray) -> np.ndarray:
        return np.array(observer_law.advance(self._accelerations, self._bias, state, volts, self._substep,
                                             self._substeps))

    # The model (model.RigidBodyModel), over arrays.

    def _arm_inertia(self, alpha: np.ndarray) -> np.ndarray:
        s = np.sin(alpha)
        return self.model.base_inertia + self.model.swing_inertia * s * s

    def _accelerations(self, alpha, dtheta, dalpha, volts):
        return self.model.accelerations_at(np.sin(alpha), np.cos(alpha), dtheta, dalpha, volts)

    def _energy(self, alpha, dtheta, dalpha):
        model = self.model
        c = np.cos(alpha)
        kinetic = (self._arm_inertia(alpha) * dtheta * dtheta - 2.0 * model.coupling * c * dtheta * dalpha
                   + model.pendulum_inertia * dalpha * dalpha)
        return 0.5 * kinetic + model.gravity_torque * (c - 1.0)

    # The control law (swingup.SwingupController.voltage_for and what it calls).

    def _voltage_for(self, state: np.ndarray) -> np.ndarray:
        level = np.where(self._balancing, self._release_level, self._catch_level)
        error = state.T  # the LQR's error from upright at arm angle 0
        cost = np.einsum("wi,wij,wj->w", error, self._cost_matrix, error)
        self._balancing = cost < level
        self._learn_from_swing(state)
        lqr = -np.einsum("wi,wi->w", error, self._lqr_gain)
        lqr = np.minimum(np.maximum(lqr, -self._lqr_limit), self._lqr_limit)
        return np.where(self._balancing, lqr, self._shaping(state))

    def _learn_from_swing(self, state: np.ndarray) -> None:
        _, alpha, dtheta, dalpha = state
        model = self.model
        upper = np.abs(alpha) < math.pi / 2
        entering = upper & (self._upper_side == 0.0)
        self._upper_side = np.where(entering, np.copysign(1.0, alpha), self._upper_side)
        self._peak_alpha[entering] = math.pi
        self._crossed[entering] = False
        higher = upper & (np.abs(alpha) < self._peak_alpha)
        self._peak_alpha = np.where(higher, np.abs(alpha), self._peak_alpha)
        self._peak_energy = np.where(higher, self._energy(alpha, dtheta, dalpha), self._peak_energy)
        crossing = upper & (alpha * self._upper_side < 0.0) & ~self._crossed
        self._excess = np.where(crossing, 0.5 * model.upright_swing_inertia * dalpha * dalpha, self._excess)
        self._crossed |= crossing
        leaving = ~upper & (self._upper_side != 0.0)
        band = shaping_law.ENERGY_BAND * model.swing_up_energy
        settled = np.abs(self._peak_energy - self._energy_set) < band
        adapting = leaving & settled & ~self._balancing
        shortfall = model.gravity_torque * (1.0 - np.cos(self._peak_alpha))
        change = np.where(self._crossed, -self._excess, shortfall)
        adapted = self._energy_set + swingup_law.ADAPTATION * change
        highest = swingup_law.ENERGY_MARGIN_LIMIT * model.swing_up_energy
        adapted = np.minimum(np.maximum(adapted, 0.0), highest)
        self._energy_set = np.where(adapting, adapted, self._energy_set)
        self._upper_side[leaving] = 0.0

    def _shaping(self, state: np.ndarray) -> np.ndarray:
        """`energy.EnergyShaping.voltage` towards each world's set energy."""
        theta, alpha, dtheta, dalpha = state
        model = self.model
        error = (self._energy_set - self._energy(alpha, dtheta, dalpha)) / (
            shaping_law.ENERGY_BAND * model.swing_up_energy)
        phase = dalpha * np.cos(alpha)
        with np.errstate(invalid="ignore"):
            drain = self._pump_torque * np.maximum(error, -1.0) * np.tanh(dtheta / self._drain_speed)
            add = self._pump_torque * error * np.tanh(phase / shaping_law.PHASE_SPEED)
        bang = self._pump_torque * np.copysign(1.0, phase)
        pump = np.where(error < 0.0, drain, np.where(error < 1.0, add, bang))
        centre = theta - self._offset_scale * np.arctan(self._offset_slope * np.sin(alpha))
        outwards = pump * centre > 0.0
        pump = np.where(outwards, pump * np.maximum(0.0, 1.0 - np.abs(centre) / self._centre_limit), pump)
        arm_inertia = self._arm_inertia(alpha)
        centre_speed = (arm_inertia * dtheta - model.coupling * np.cos(alpha) * dalpha) / arm_inertia
        torque = pump - self._stiffness * centre - self._damping * centre_speed
        volts = torque / model.torque_per_volt + model.back_emf * dtheta
        return np.minimum(np.maximum(volts, -self._shaping_limit), self._shaping_limit)
