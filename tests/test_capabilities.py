"""Each domain has the capabilities it declares, and code asks for them rather than probing attributes."""

import pytest

from qube_suite import capabilities, suite
from qube_suite.devices.qube import hardware as qube_hardware
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.batch import QubeBatch
from qube_suite.randomization import Randomizer, load

ALL = {name: getattr(capabilities, name) for name in (
    "Randomizable", "SensorEffects", "ActuatorEffects", "StepDurationEffects", "Batch", "HasBoard",
    "NeedsResetControllers", "HasDesignParameters", "Closable")}


def _capabilities(domain) -> set[str]:
    return {name for name, protocol in ALL.items() if isinstance(domain, protocol)}


def test_each_domain_has_the_capabilities_of_its_kind():
    simulation = qube.make_physics()
    assert _capabilities(simulation) == {"Randomizable", "SensorEffects", "ActuatorEffects",
                                         "StepDurationEffects", "Closable"}
    simulation.close()
    board = qube_hardware.make_physics()
    assert _capabilities(board) == {"SensorEffects", "ActuatorEffects", "HasBoard", "NeedsResetControllers",
                                    "HasDesignParameters", "Closable"}
    board.close()
    batch = QubeBatch(2)
    assert _capabilities(batch) == {"Randomizable", "SensorEffects", "ActuatorEffects", "StepDurationEffects",
                                    "Batch"}
    batch.close()


def test_a_domain_lacking_a_capability_is_refused_by_name_before_any_episode():
    class Jitterless:
        """A domain that measures through effects but has no control period to jitter."""

        def set_sensor_model(self, sensor_model):
            self.sensor_model = sensor_model

    config = load({"effects": {"observation_noise": {"std": [0.01, 0.01, 0.1, 0.1]}}})
    domain = Jitterless()
    Randomizer(config, domain, 0.004)
    assert domain.sensor_model is not None
    with pytest.raises(ValueError, match="Jitterless cannot apply control_jitter"):
        Randomizer(load({"effects": {"control_jitter": {"fraction": 0.05}}}), domain, 0.004)
    with pytest.raises(ValueError, match="Jitterless cannot change physical parameters"):
        Randomizer(load("mild"), domain, 0.004)


def test_the_suite_hands_reset_controllers_to_the_domains_that_need_them():
    environment = suite.load("qube_hardware", "balance")
    assert isinstance(environment.physics, capabilities.NeedsResetControllers)
    assert set(environment.physics._controllers) == set(environment.physics.reset_controller_names)
    environment.close()
