"""The Qube-Servo 2/3 rotary pendulum (Furuta pendulum): domains `qube` and `qube_hardware`."""

from qube_suite.devices import Device

DEVICE = Device(
    name="qube",
    description="Qube-Servo 2/3 rotary pendulum (Furuta pendulum)",
    simulation="qube_suite.domains.qube",
    hardware="qube_suite.domains.qube_hardware",
    tasks="qube_suite.tasks",
    batch="qube_suite.domains.qube_batch",
)
"""The pendulum: its Gymnasium ids have no prefix (`QubeSuite/Swingup-v0`)."""
