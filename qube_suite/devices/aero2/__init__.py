"""The Quanser Aero 2: domains `aero2` and `aero2_hardware`.

Files, in the order a new device needs them: `parameters.py` (the table, by long name, with
sources), `conventions.py` (state, action, signs, counts to SI), `model.xml` and `scene.xml`
(the MJCF), `simulation.py` (the MuJoCo domain), `tasks.py` (`SUITE`), `hardware.py` (the board
domain), `controllers.py` (the LQR), `policies/` (the learned hover policy), then this declaration.
"""

from qube_suite.devices import Device

DEVICE = Device(
    name="aero2",
    description="Quanser Aero 2, two thrusters on a beam: 2-DOF helicopter or 1-DOF pitch",
    simulation="qube_suite.devices.aero2.simulation",
    hardware="qube_suite.devices.aero2.hardware",
    tasks="qube_suite.devices.aero2.tasks",
    gymnasium_prefix="Aero2",
    feature_map="plain",
    controllers="qube_suite.devices.aero2.controllers",
    substitute="qube_suite.devices.aero2.substitute",
)
"""The Aero 2: Gymnasium ids `QubeSuite/Aero2<Task>[Hardware]-v0`."""
