"""The Qube-Servo 2/3 with the inertia-disk module: domains `qube_disk` and `qube_disk_hardware`.

Files, in the order a new device needs them: `parameters.py` (the table, by long name, with
sources), `conventions.py` (state, action, signs, counts to SI), `model.xml` and `scene.xml`
(the MJCF), `simulation.py` (the MuJoCo domain), `tasks.py` (`SUITE`), `substitute.py` (the
substitute board's plant), `hardware.py` (the board domain), `controllers.py` (the classical
baselines), then this declaration.
"""

from qube_suite.devices import Device

DEVICE = Device(
    name="qube_disk",
    description="Qube-Servo 2/3 with the inertia-disk module (position and speed control)",
    simulation="qube_suite.devices.qube_disk.simulation",
    hardware="qube_suite.devices.qube_disk.hardware",
    tasks="qube_suite.devices.qube_disk.tasks",
    gymnasium_prefix="Disk",
    feature_map="plain",
    controllers="qube_suite.devices.qube_disk.controllers",
)
"""The disk: Gymnasium ids `QubeSuite/Disk<Task>[Hardware]-v0`."""
