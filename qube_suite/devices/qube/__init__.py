"""The Qube-Servo 2/3 rotary pendulum (Furuta pendulum): domains `qube` and `qube_hardware`.

Files: `parameters.py` (the table, by long name, with sources; `real_qube_servo2.yaml`, a real
Qube-Servo 2's calibration), `model.xml` and `scene.xml` (the MJCF), `simulation.py` (the MuJoCo
domain), `batch.py` (many Qubes in one MuJoCo model, behind the vector environment), `hardware.py`
(the board domain), `tasks/` (`SUITE`), `controllers/` (the model-based baselines) and `policies/`
(the shipped learned policies), then this declaration.
"""

from qube_suite.devices import Device

DEVICE = Device(
    name="qube",
    description="Qube-Servo 2/3 rotary pendulum (Furuta pendulum)",
    simulation="qube_suite.devices.qube.simulation",
    hardware="qube_suite.devices.qube.hardware",
    tasks="qube_suite.devices.qube.tasks",
    controllers="qube_suite.devices.qube.controllers",
    batch="qube_suite.devices.qube.batch",
)
"""The pendulum: its Gymnasium ids have no prefix (`QubeSuite/Swingup-v0`)."""
