"""benchmarks/held_out.py: the substitute's own plant and calibrated controllers as extra rows."""

import importlib
import json
import pathlib
import sys

import pytest

from qube_suite.devices.qube import parameters
from qube_suite.hardware.plant import plant_parameters

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def held_out():
    sys.path.insert(0, str(BENCHMARKS))  # its worker processes import it by name
    try:
        yield importlib.import_module("held_out")
    finally:
        sys.path.remove(str(BENCHMARKS))


@pytest.mark.slow
def test_substitute_and_calibrated_rows_about_a_named_plant(held_out, monkeypatch, tmp_path, capsys):
    out = tmp_path / "cells.json"
    monkeypatch.setattr(sys, "argv", [
        "held_out.py", "--base", "estimated", "--plants", "1", "--episodes", "1", "--substitute",
        "--policy", "swingup", "--calibrated", "swingup", "--json", str(out)])
    held_out.main()
    cells = json.loads(out.read_text())["cells"]
    assert sorted((cell["policy"], str(cell["plant"])) for cell in cells) == [
        ("swingup", "0"), ("swingup", "substitute"),
        ("swingup (calibrated)", "0"), ("swingup (calibrated)", "substitute")]
    substitute = next(cell for cell in cells if cell["plant"] == "substitute")
    assert substitute["parameters"] == plant_parameters("qube_servo2_usb", "estimated")
    table = capsys.readouterr().out
    assert "| swingup (calibrated) | all 1 held-out |" in table


def test_plants_are_drawn_about_the_substitutes_default_plant_unless_another_is_named(held_out):
    real_inertia = plant_parameters()["rotor_inertia"]
    default, real, estimated = (held_out.draw_plants(4, 2026, base) for base in (None, "real_qube_servo2",
                                                                                 "estimated"))
    for plant, named in zip(default, real, strict=True):
        assert plant_parameters(overrides=plant) == plant_parameters(overrides=named)
    for plants, inertia in ((default, real_inertia), (estimated, parameters.NOMINAL["rotor_inertia"])):
        ratios = [plant_parameters(overrides=plant)["rotor_inertia"] / inertia for plant in plants]
        assert all(1 - held_out.RELATIVE["rotor_inertia"] <= r <= 1 + held_out.RELATIVE["rotor_inertia"]
                   for r in ratios)
    assert all(plant_parameters(overrides=plant)["latency"] == 0.0 for plant in estimated)


def test_calibrated_takes_only_controllers(held_out, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["held_out.py", "--calibrated", "ppo:swingup"])
    with pytest.raises(SystemExit):
        held_out.main()
    assert "--calibrated takes controllers" in capsys.readouterr().err
