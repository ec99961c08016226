"""The wrapper's compiled samples on the substitute (`_hil_sim.ClearSamples`) against its board calls
and checks one by one: the same readings, board, refusals and safety stops, bit for bit."""

import math

import numpy as np
import pytest

from qube_suite.hardware import QubeServo2, QubeServo3, conventions


def _random_voltages(rng):
    """What a controller or a user may hand to `action`: mostly good numbers, sometimes not."""
    kind = rng.integers(21)
    volts = float(rng.uniform(-14.0, 14.0)) if rng.random() < 0.2 else float(rng.normal(0.0, 1.0))
    return [volts, [volts], np.array([volts]), np.float32(volts), (volts,), volts, [volts], volts,
            volts, [volts], volts, volts, math.nan, [math.inf], [volts, volts], "1.0",
            [np.float64(volts)], [1], [True], [math.nan], [-math.inf]][kind]


def _random_led(rng):
    kind = rng.integers(26)
    colour = tuple(float(x) for x in rng.random(3))
    strided = np.repeat(np.array(colour), 2)[::2]                  # an array that is not contiguous
    return [colour, (1.5, 0.0, 0.0), (math.nan, 0.0, 0.0), list(colour), strided, *[None] * 15,
            (0.0, -0.5, 1.0), (1.0, 0, 0.5), colour[:2], (*colour, 0.0), (np.float64(0.3), 0.2, 0.1),
            (0.2, True, 0.1)][kind]


def _disturb(rng, qube):
    """A fault, a stall of the loop, a move of the Qube or a resume, now and then."""
    board = qube.board
    event = rng.integers(150)
    if event == 0:
        board.set_amplifier_fault(True)
    elif 8 <= event < 20:
        board.set_amplifier_fault(False)
    elif event == 1:
        board.glitch_encoder(int(rng.integers(2)), int(rng.choice([2, 40, 700, -900])))
    elif event == 2:
        board.block_arm(bool(rng.integers(2)))
    elif event == 3:
        board.stall(float(rng.choice([0.004, 0.012, 0.03, 0.2])))
    elif event == 4:
        board.set_true_state([float(rng.choice([0.0, 0.5, 2.2, -2.3])), math.pi, 0.0, 0.0])
    elif event == 5 and qube.is_idle:
        qube.resume()
    elif event == 6:
        qube.reset_encoders()
    elif event == 7:
        qube.idle()
    elif event == 20:                          # the checks' settings changed on an open board
        qube.arm_limit = [None, 0.5, 2.0, 2.1][rng.integers(4)]
    elif event == 21:
        qube.max_encoder_speed = [None, 5.0, 50.0, 500.0][rng.integers(4)]
    elif event == 22:
        qube.max_missed_samples = [None, 0, 2, 10][rng.integers(4)]


def _step(rng, qube):
    """One action (or return_arm) with random input: its outcome, as readings or the error raised."""
    voltages, led = _random_voltages(rng), _random_led(rng)
    act = qube.return_arm if rng.random() < 0.2 else qube.action
    theta = qube.board.true_state()[0]
    if abs(theta) > math.radians(50.0) and rng.random() < 0.8:  # bring it back, as a reset does
        act, voltages = qube.return_arm, conventions.board_voltage(-math.copysign(2.0, theta))
    if qube.is_idle:
        qube.resume()
    try:
        currents, encoders, others = act(voltages, led=led)
    except Exception as error:
        return type(error).__name__, str(error)
    return currents.tobytes(), encoders.tobytes(), others.tobytes()


def _state(qube):
    board = qube.board
    return (board.true_state().tobytes(), board.applied_voltage, board.amplifier_enabled, board.led,
            board.time, board.watchdog_is_expired(), qube.missed_samples, qube.stall_warning, qube.is_idle,
            qube._last_counts, qube._overflows_seen, qube._return_from, qube._held_samples)


@pytest.mark.parametrize("make", [
    lambda: QubeServo2(),
    lambda: QubeServo3(frequency=1000.0, max_missed_samples=3),
    lambda: QubeServo2(arm_limit=None, max_encoder_speed=None, max_missed_samples=None),
    lambda: QubeServo2(plant={"bench_vibration": 4e-4}, arm_limit=math.radians(60.0), max_encoder_speed=50.0),
], ids=["servo2", "servo3-1kHz", "checks-off", "swaying-tight"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_samples_give_the_board_calls_numbers_bit_for_bit(make, seed):
    compiled, stepwise = make(), make()
    with compiled, stepwise:
        assert compiled._clear_samples is not None
        stepwise._clear_samples = None             # every sample through the board calls and checks
        clear = []
        after_clear = compiled._after_clear_sample
        compiled._after_clear_sample = lambda copy: clear.append(1) or after_clear(copy)
        outcomes = {}
        for name, qube in (("compiled", compiled), ("stepwise", stepwise)):
            rng = np.random.default_rng(seed)
            outcomes[name] = []
            for _ in range(1500):
                _disturb(rng, qube)
                outcomes[name].append((_step(rng, qube), _state(qube)))
    for k, (mine, theirs) in enumerate(zip(outcomes["compiled"], outcomes["stepwise"], strict=True)):
        assert mine == theirs, f"step {k} differs"
    errors = {outcome[0] for outcome, _ in outcomes["compiled"] if isinstance(outcome[0], str)}
    assert "ValueError" in errors and len(errors) >= 3                             # refusals and stops met
    assert len(clear) > 300                                                          # and clear samples


def test_a_refused_voltage_writes_0_volts_on_the_compiled_path_too():
    with QubeServo2() as qube:
        assert qube._clear_samples is not None
        for _ in range(3):
            qube.action(4.0)
        assert qube.board.applied_voltage == 4.0
        for refused in (math.nan, [math.inf], [True], "1.0", [1.0, 2.0]):
            qube.action(4.0)
            with pytest.raises(ValueError):
                qube.action(refused)
            assert qube.board.written_voltage == 0.0 and qube.board.amplifier_enabled


def test_the_compiled_path_is_for_the_fast_substitute_only():
    with QubeServo2(realtime=True) as qube:
        assert qube._clear_samples is None
