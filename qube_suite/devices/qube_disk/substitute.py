"""The substitute board's plant for the disk-loaded Qube.

The substitute board (`qube_suite.hardware._hil_sim.HIL`) integrates a motor with a rigid load
on its shaft (its "arm") and a pendulum hinged at the load's edge, with the motor's electrical
ODE, the amplifier's limits, Coulomb friction on the shaft, stall detection and the encoder's
quantisation. With the pendulum's mass made negligible and its own friction, damping and the
bench's sway turned off, what remains is the disk-loaded Qube: one shaft of inertia
Jm + Jh + md rd^2 / 2 under the motor torque, viscous damping and Coulomb friction, read by
encoder 0. `plant_overrides` gives those plant parameters (`qube_suite.hardware.plant`
names) from the disk's table, the motor rows of the board's own Qube (Qube-Servo 2 or 3)
included; what is not the disk's keeps the estimated plant's values (the shaft's Coulomb
friction of 1e-3 N m, the amplifier): no recordings of a real disk-loaded Qube exist, and the
real Qube-Servo 2's plant (`plant.DEFAULT_PLANTS`) is a pendulum's, its cable and dead zone
included.

The plant is independent of the MJCF: it is the board's own C integrator (RK4 at 10 kHz with
the motor's inductance, implicit Coulomb friction), not MuJoCo.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from qube_suite.devices.qube_disk import parameters as disk_parameters
from qube_suite.hardware.plant import ESTIMATED, plant_parameters

VANISHING_PENDULUM_MASS = 1e-9
"""Mass (kg) left to the absent pendulum (the plant needs one): it still swings as the shaft turns,
its motion being independent of its mass, but its torque on the shaft stays below 1e-11 N m, eight
orders under the shaft's friction, and its encoder is not read."""

STAND_IN_LENGTH = math.sqrt(6.0)
"""The shaft's load as the plant's arm: a rod of the disk's mass and length sqrt(6) rd has the
disk's inertia, (md (sqrt(6) rd)^2) / 12 = md rd^2 / 2."""


def plant_overrides(board_type: str, parameters: Mapping[str, float] | None = None) -> dict[str, float]:
    """Every plant parameter (by `qube_suite.hardware.plant` names) of a disk-loaded Qube on
    `board_type`, with the disk's `parameters` (by the disk table's long names; its motor rows replace
    the board's), the others the estimated plant's. Raises ValueError for an unknown name or an
    impossible value."""
    disk = disk_parameters.resolve(parameters)
    motor = plant_parameters(board_type, ESTIMATED)
    given = dict(parameters or {})
    for name in disk_parameters.MOTOR_NAMES:
        if name not in given:
            disk[name] = motor[name]
    arm_length = STAND_IN_LENGTH * disk["disk_radius"]
    load = disk_parameters.disk_inertia(disk["disk_mass"], disk["disk_radius"])
    arm_mass = 12.0 * (load - VANISHING_PENDULUM_MASS * arm_length**2) / arm_length**2
    overrides = dict(motor)
    overrides.update({name: disk[name] for name in disk_parameters.MOTOR_NAMES})
    overrides["rotor_inertia"] = disk["rotor_inertia"] + disk["hub_inertia"]
    overrides.update(arm_mass=arm_mass, arm_length=arm_length, arm_damping=disk["disk_damping"],
                     pendulum_mass=VANISHING_PENDULUM_MASS, pendulum_damping=0.0, pendulum_friction=0.0,
                     bench_vibration=0.0, cable_stiffness=0.0)
    if disk["disk_friction"] > 0.0:
        overrides["arm_friction"] = disk["disk_friction"]
    return overrides
