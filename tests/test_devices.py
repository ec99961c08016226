"""The device registry is the one list of devices that the suite, Gymnasium and the command line read."""

import dataclasses

import gymnasium
import pytest

from qube_suite import cli, devices, suite
from qube_suite.tasks import SUITE
from qube_suite.wrappers import GYMNASIUM_IDS, HARDWARE_GYMNASIUM_IDS, gymnasium_id, registration


def test_the_qube_pendulum_is_found_by_discovery_with_its_two_domains():
    assert list(devices.devices()) == ["aero2", "qube", "qube_disk"]
    assert list(devices.domains()) == ["aero2", "aero2_hardware", "qube", "qube_hardware", "qube_disk",
                                       "qube_disk_hardware"]
    hardware = devices.domain("qube_hardware")
    assert hardware.hardware and hardware.device.name == "qube"
    assert hardware.module().__name__ == "qube_suite.devices.qube.hardware"
    assert set(suite.TASKS_BY_DOMAIN) == {"aero2", "aero2_hardware", "qube", "qube_hardware", "qube_disk",
                                          "qube_disk_hardware"}
    with pytest.raises(ValueError, match=r"unknown domain 'qube_aero'; valid domains: aero2, aero2_hardware, "
                                         r"qube, qube_hardware, "):
        suite.load("qube_aero", "swingup")


@pytest.fixture
def second_device(monkeypatch):
    """A second device found in the registry: the pendulum's domains and tasks under another name."""
    qube = devices.devices()["qube"]
    twin = dataclasses.replace(qube, name="twin", gymnasium_prefix="Twin")
    monkeypatch.setattr(devices, "devices", lambda: {"qube": qube, "twin": twin})
    monkeypatch.setattr(SUITE, "_listeners", list(SUITE._listeners))  # the twin's listener goes with it
    monkeypatch.setattr(registration, "_SUBSCRIBED", set(registration._SUBSCRIBED))
    yield twin
    for env_id in [env_id for env_id in gymnasium.registry if env_id.startswith("QubeSuite/Twin")]:
        gymnasium.registry.pop(env_id)


def test_a_device_in_the_registry_is_loaded_listed_and_registered_everywhere(second_device):
    assert list(suite.TASKS_BY_DOMAIN) == ["qube", "qube_hardware", "twin", "twin_hardware"]
    assert ("twin_hardware", "rotor") in suite.BENCHMARKING
    environment = suite.load("twin", "swingup", task_kwargs={"random": 0})
    environment.reset()
    environment.close()
    assert gymnasium_id("balance_sparse", "twin_hardware") == "QubeSuite/TwinBalanceSparseHardware-v0"
    assert GYMNASIUM_IDS["QubeSuite/TwinSwingup-v0"] == "swingup"
    assert HARDWARE_GYMNASIUM_IDS["QubeSuite/TwinRotorHardware-v0"] == "rotor"
    registration.register_environments()
    assert gymnasium.spec("QubeSuite/TwinDampenHardware-v0").kwargs == {"task": "dampen",
                                                                        "domain": "twin_hardware"}
    arguments = cli.build_parser().parse_args(["train", "--task", "swingup", "--domain", "twin_hardware"])
    assert arguments.domain == "twin_hardware"


def test_a_device_whose_folder_has_another_name_is_refused(monkeypatch):
    class Found:
        name = "elsewhere"

    qube = devices.devices()["qube"]
    monkeypatch.setattr(devices.pkgutil, "iter_modules", lambda path: [Found])
    monkeypatch.setattr(devices.importlib, "import_module", lambda name: type("Module", (), {"DEVICE": qube}))
    devices.devices.cache_clear()
    try:
        with pytest.raises(ValueError, match="qube_suite/devices/elsewhere is named 'qube'"):
            devices.devices()
    finally:
        monkeypatch.undo()
        devices.devices.cache_clear()
    assert list(devices.devices()) == ["aero2", "qube", "qube_disk"]
