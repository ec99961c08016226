"""The Aero 2 on the fast substitute board: its own plant's physics, the board domain's resets, and
every exit leaving both motors at 0 V."""

import gc
import math

import numpy as np
import pytest

from qube_suite import suite
from qube_suite.devices.aero2 import conventions, hardware, parameters, substitute
from qube_suite.hardware import _hil_sim
from qube_suite.hardware.board_plant import BoardPlant, substitute_plant

ON = np.array([True, True])


def run(plant, volts, seconds, step=0.004):
    for _ in range(round(seconds / step)):
        plant.advance(step, np.asarray(volts, dtype=float), ON)
    return plant.true_state()


def load(task="hover", time_limit=0.2, **domain_kwargs):
    if task.startswith("pitch"):
        domain_kwargs.setdefault("configuration", "pitch_only")
    return suite.load("aero2_hardware", task, task_kwargs={"random": 0},
                      environment_kwargs={"time_limit": time_limit}, domain_kwargs=domain_kwargs)


def assert_both_off(board):
    np.testing.assert_array_equal(board.applied_voltage, [0.0, 0.0])
    assert not board.amplifier_enabled


# -- the plant -----------------------------------------------------------------------------------

def test_the_plant_keeps_the_board_protocol_and_is_found_by_its_card():
    plant = substitute_plant(substitute.CARD_TYPE)
    assert isinstance(plant, BoardPlant) and isinstance(plant, substitute.Aero2Plant)
    assert plant.parameters == substitute.make_plant().parameters      # the default, hidden Aero


def test_the_hidden_parameters_differ_from_the_table_reproducibly():
    hidden = substitute.make_plant().parameters
    nominal = {**parameters.NOMINAL, **substitute.PLANT_DEFAULTS}
    ratios = {name: hidden[name] / nominal[name] for name in substitute.SPREADS}
    assert all(0.5 < r < 2.0 for r in ratios.values())
    assert sum(abs(r - 1.0) > 0.03 for r in ratios.values()) >= 8          # most differ plausibly
    assert substitute.make_plant(seed=5).parameters != hidden
    assert substitute.make_plant(seed=5).parameters == substitute.make_plant(seed=5).parameters
    assert substitute.make_plant({"thrust_constant": 7e-4}).parameters == {**nominal, "thrust_constant": 7e-4}
    with pytest.raises(ValueError, match="unknown plant parameter 'thrust'"):
        substitute.make_plant({"thrust": 1.0})


def test_a_rotor_is_first_order_with_the_tables_time_constant_and_gain():
    plant = substitute.make_plant({"rotor_friction": 0.0}, configuration="pitch_only")
    values = plant.parameters
    tau, gain = parameters.rotor_time_constant(values), parameters.rotor_speed_gain(values)
    front_after_tau = run(plant, [6.0, 6.0], tau, step=tau / 50)[4]
    assert front_after_tau == pytest.approx(6.0 * gain * (1.0 - math.exp(-1.0)), rel=0.01)
    assert run(plant, [6.0, 6.0], 10 * tau)[4] == pytest.approx(6.0 * gain, rel=1e-3)


def test_rotor_friction_is_a_dead_zone():
    plant = substitute.make_plant(configuration="pitch_only")
    below = plant.parameters["rotor_friction"] * plant.parameters["motor_resistance"] / \
        plant.parameters["motor_torque_constant"] * 0.9
    assert run(plant, [below, -below], 1.0)[4:].tolist() == [0.0, 0.0]


def test_pitch_settles_where_thrust_balances_the_weight():
    plant = substitute.make_plant(configuration="pitch_only")
    p = plant.parameters
    pitch, _, pitch_rate, _, front, back = run(plant, [8.0, 0.0], 60.0)
    weight = p["body_mass"] * p["gravity"] * p["center_of_mass_offset"]
    thrust_torque = p["thrust_arm"] * p["thrust_constant"] * front
    assert back == 0.0 and pitch_rate == 0.0                               # at rest, stuck by friction
    assert abs(thrust_torque - weight * math.sin(pitch)) <= p["pitch_friction"] * 1.0001
    assert 0.2 < pitch < conventions.PITCH_LIMIT


def test_the_beam_swings_back_level_and_sticks_within_its_friction():
    plant = substitute.make_plant()
    plant.set_true_state([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
    pitch, yaw, pitch_rate, yaw_rate, *_ = run(plant, [0.0, 0.0], 40.0)
    p = plant.parameters
    band = p["pitch_friction"] / (p["body_mass"] * p["gravity"] * p["center_of_mass_offset"])
    assert pitch_rate == 0.0 and abs(pitch) <= band and yaw == 0.0


def test_the_pitch_stops_hold_the_beam():
    plant = substitute.make_plant(configuration="pitch_only")
    pitches = [run(plant, [24.0, -24.0], 0.05)[0] for _ in range(100)]
    assert max(pitches) == pytest.approx(conventions.PITCH_LIMIT)
    assert max(pitches) <= conventions.PITCH_LIMIT


def test_the_thrusters_turn_the_aero_the_conventions_way():
    plant = substitute.make_plant()
    pitch, yaw = run(plant, [6.0, 0.0], 0.5)[:2]
    assert pitch > 0.0 and yaw < 0.0          # front lifts; its motor's reaction turns yaw negative
    plant = substitute.make_plant()
    pitch, yaw = run(plant, [0.0, 6.0], 0.5)[:2]
    assert yaw > 0.0 and pitch > 0.0          # back pushes yaw positive; its reaction raises pitch
    plant = substitute.make_plant(configuration="pitch_only")
    assert run(plant, [0.0, 6.0], 0.5)[0] < 0.0                   # pitch-only: the back one lifts the back


def test_the_gyroscopic_torque_couples_a_spinning_rotor_to_the_other_axis():
    """A yaw rate turns a spinning front rotor's momentum: Omega x h has a pitch part."""
    def pitch_after(front_speed):
        plant = substitute.make_plant({"pitch_friction": 0.0, "yaw_friction": 0.0})
        plant.set_true_state([0.0, 0.0, 0.0, 0.0, 0.0, front_speed])
        plant.set_true_state([0.0, 0.0, 0.0, 2.0, 0.0, front_speed])
        plant.advance(0.01, np.zeros(2), np.array([False, False]))
        return plant.true_state()[2]
    assert pitch_after(300.0) != pytest.approx(pitch_after(0.0), abs=1e-4)


@pytest.mark.parametrize("configuration", ["2dof", "pitch_only"])
def test_the_plant_agrees_with_the_controllers_linear_model_for_small_voltages(configuration):
    """Two derivations, one per side (the substitute's nonlinear equations here, the LQR's linear model
    by the simulation side): for small voltages from rest they must move the Aero alike."""
    import scipy.linalg

    from qube_suite.devices.aero2 import controllers

    plant = substitute.make_plant({"pitch_friction": 0.0, "yaw_friction": 0.0, "rotor_friction": 0.0,
                                   "motor_inductance": 0.0}, configuration=configuration)
    volts = np.array([1.0, 0.6])
    state = run(plant, volts, 1.0)
    a, b = controllers.linear_model(None, configuration)
    n = len(a)
    block = np.zeros((n + 2, n + 2))
    block[:n, :n], block[:n, n:] = a, b
    linear = scipy.linalg.expm(block)[:n, n:] @ volts              # from rest, 1 s of constant voltages
    if configuration == "pitch_only":
        state = state[[0, 2, 4, 5]]
    np.testing.assert_allclose(state, linear, rtol=0.01, atol=1e-5)


def test_the_board_reads_counts_floored_at_the_aeros_resolutions():
    board = _hil_sim.HIL(plant=substitute.make_plant())
    board.open(substitute.CARD_TYPE, "0")
    board.set_true_state([0.1, -0.2, 0.0, 0.0, 0.0, 0.0])
    counts = np.zeros(2, dtype=np.int32)
    board.read_encoder(np.array([2, 3], dtype=np.uint32), 2, counts)
    assert counts.tolist() == [math.floor(0.1 * conventions.PITCH_COUNTS_PER_RADIAN),
                               math.floor(-0.2 * conventions.YAW_COUNTS_PER_RADIAN)]
    board.close()


# -- the board domain ------------------------------------------------------------------------------

@pytest.mark.parametrize("task", ["pitch", "pitch_sparse", "hover", "hover_sparse", "track", "track_sparse"])
def test_every_task_runs_on_the_substitute(task):
    env = load(task, time_limit=0.5)
    step, steps = env.reset(), 0
    while not step.last():
        step = env.step(np.array([2.0, -1.0]))
        steps += 1
        assert 0.0 <= step.reward <= 1.0
    assert steps == 125
    assert_both_off(env.physics.qube.board)
    env.close()


def test_a_reset_brings_the_aero_level_and_at_rest_at_the_asked_yaw():
    env = load("hover", time_limit=1.0)
    physics = env.physics
    step = env.reset()
    while not step.last():
        step = env.step(np.array([10.0, 8.0]))                    # leave it pitched, turning, rotors spinning
    moved = physics.qube.board.true_state()
    assert abs(moved[0]) > 0.1 and abs(moved[4]) > 50.0
    with physics.reset_context():
        physics.reset_to([0.1, 0.4, 0.2, 0.0, 30.0, 0.0])
    pitch, yaw, pitch_rate, yaw_rate, front, back = physics.qube.board.true_state()
    assert abs(pitch) <= hardware.PITCH_TOLERANCE + 0.002 and abs(yaw - 0.4) <= hardware.YAW_TOLERANCE + 0.002
    assert abs(pitch_rate) < 0.06 and abs(yaw_rate) < 0.06 and abs(front) < 5.0 and abs(back) < 5.0
    assert physics.time() == 0.0 and physics.qube.board.led == pytest.approx(hardware.RESET_LED)
    env.close()


def test_a_reset_that_cannot_finish_raises_with_both_motors_stopped():
    env = load("hover", reset_timeout=1.0)
    physics = env.physics
    env.reset()
    board = physics.qube.board
    board.set_amplifier_fault(True)                               # nothing drives: the yaw cannot turn
    with pytest.raises(hardware.ResetError, match="did not come level"), physics.reset_context():
        physics.reset_to([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    board.set_amplifier_fault(False)
    assert physics.qube.is_idle
    assert_both_off(board)
    env.close()


def test_every_exit_leaves_both_motors_at_zero():
    env = load("hover", time_limit=0.1)
    wrapper = env.physics.qube
    step = env.reset()
    board = wrapper.board
    while not step.last():                                        # truncation: idle
        step = env.step(np.array([5.0, 5.0]))
    assert wrapper.is_idle
    assert_both_off(board)
    env.reset()
    env.step(np.array([5.0, 5.0]))
    env.step(np.array([5.0, 5.0]))
    assert board.applied_voltage.tolist() == [5.0, 5.0]
    with pytest.raises(ValueError):                               # a refused action: 0 V on both at once
        env.step(np.array([5.0, math.nan]))
    np.testing.assert_array_equal(board.applied_voltage, [0.0, 0.0])
    env.step(np.array([5.0, 5.0]))
    board.fail_read(KeyboardInterrupt())                          # Ctrl-C inside a board call
    with pytest.raises(KeyboardInterrupt):
        env.step(np.array([5.0, 5.0]))
    assert wrapper.is_idle
    assert_both_off(board)
    env.reset()
    env.step(np.array([5.0, 5.0]))
    board.fail_read(RuntimeError("a failure inside a step"))      # any exception
    with pytest.raises(RuntimeError):
        env.step(np.array([5.0, 5.0]))
    assert_both_off(board)
    env.reset()
    env.step(np.array([5.0, 5.0]))
    env.close()                                                   # close
    assert not wrapper.is_open
    assert_both_off(board)


def test_garbage_collection_leaves_both_motors_at_zero():
    env = load("hover")
    env.reset()
    env.step(np.array([6.0, -6.0]))
    board = env.physics.qube.board
    assert board.amplifier_enabled
    del env
    gc.collect()
    assert not board.is_valid()
    assert_both_off(board)


def test_voltages_are_clipped_on_each_thruster():
    physics = hardware.make_physics(max_voltage=5.0)
    with physics.reset_context():
        physics.reset_to(np.zeros(6))
    physics.set_voltage([12.0, -7.0])
    physics.step()
    assert physics.qube.board.applied_voltage.tolist() == [5.0, -5.0]
    assert physics.applied_voltage().tolist() == [5.0, -5.0]
    physics.close()
    with pytest.raises(ValueError, match="24 V"):
        hardware.make_physics(max_voltage=30.0)


def test_a_real_board_takes_no_substitute_parameters():
    with pytest.raises(ValueError, match="substitute"):
        hardware.make_physics(board=substitute.CARD_TYPE, parameters={"thrust_constant": 1e-3})


def test_the_gymnasium_hardware_ids_pass_the_checker_and_refuse_nan_at_zero_volts():
    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import qube_suite  # noqa: F401  (registers the ids)

    env = gymnasium.make("QubeSuite/Aero2HoverHardware-v0")
    check_env(env.unwrapped, skip_render_check=True)
    env.reset(seed=0)
    env.step(np.array([6.0, 6.0], dtype=np.float32))
    board = env.unwrapped.physics.qube.board
    with pytest.raises(ValueError):
        env.step(np.array([6.0, np.nan], dtype=np.float32))
    np.testing.assert_array_equal(board.applied_voltage, [0.0, 0.0])
    env.close()
    assert_both_off(board)
