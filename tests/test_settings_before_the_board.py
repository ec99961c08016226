"""Settings that would fail after the Qube has been driven are refused before the board opens."""

import pytest

from qube_suite import cli
from qube_suite.hardware import _hil_sim


@pytest.fixture(name="opened")
def opened_fixture(monkeypatch):
    """Boards opened during the test (the substitute's `HIL.open` logged)."""
    log = []

    class LoggingHIL(_hil_sim.HIL):
        def open(self, card_type, card_identifier):
            log.append(card_type)
            return super().open(card_type, card_identifier)

    monkeypatch.setattr(_hil_sim, "HIL", LoggingHIL)
    return log


@pytest.mark.parametrize("seconds", ["8", "19.9", "61"])
def test_calibrate_refuses_a_duration_it_cannot_fit_before_the_board_opens(opened, tmp_path, capsys, seconds):
    code = cli.main(["calibrate", "--domain", "qube_hardware", "--seconds", seconds,
                     "--out", str(tmp_path / "q.yaml")])
    assert code == 2 and opened == []
    assert "at least 20 s" in capsys.readouterr().err


def test_adapt_without_the_rl_extra_is_refused_before_the_board_opens(opened, tmp_path, capsys, monkeypatch):
    from qube_suite import training

    monkeypatch.setattr(training, "RL_EXTRA", (*training.RL_EXTRA, "a_package_that_is_not_installed"))
    code = cli.main(["adapt", "--task", "swingup", "--seconds", "20", "--out", str(tmp_path / "adapt")])
    assert code == 2 and opened == []
    assert "a_package_that_is_not_installed" in capsys.readouterr().err
