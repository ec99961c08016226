"""The Aero 2's calibration through the engine finds the substitute's hidden parameters within the
intervals it reports, from its excitation experiment."""

import numpy as np
import pytest

from qube_suite.devices.aero2 import calibration, parameters, substitute


@pytest.mark.parametrize("seed", [None, 3])
def test_the_calibration_recovers_the_substitutes_hidden_parameters(tmp_path, seed):
    path = calibration.record_experiment(tmp_path / "aero.npz", domain_kwargs={"plant_seed": seed})
    found = calibration.calibrate_recording(path)
    truth = substitute.make_plant(seed=seed).parameters
    for q in calibration.UNKNOWNS:
        low, high = found.intervals[q.name]
        assert low <= truth[q.name] <= high, (q.name, truth[q.name], low, high)
    for name in ("motor_resistance", "motor_back_emf", "propeller_inertia", "propeller_drag",
                 "thrust_constant", "center_of_mass_offset"):
        low, high = found.intervals[name]
        assert high - low < 0.15 * truth[name], name                     # informative, not vacuous
        assert abs(found.parameters[name] / parameters.NOMINAL[name] - 1.0) < 0.5
    moved = [name for name in ("thrust_constant", "center_of_mass_offset", "propeller_drag")
             if not found.intervals[name][0] <= parameters.NOMINAL[name] <= found.intervals[name][1]]
    assert moved                                                        # it found what differs from nominal
    assert found.parameters["motor_torque_constant"] == found.parameters["motor_back_emf"]
    assert set(found.identified) == {"rotor_friction", "pitch_friction"}


def test_a_file_that_is_no_experiment_is_refused(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, time=np.arange(10.0))
    with pytest.raises(ValueError, match="not an Aero 2 experiment"):
        calibration.calibrate_recording(path)
    with pytest.raises(ValueError, match="at least"):
        calibration.record_experiment(tmp_path / "short.npz", seconds=1.0)
