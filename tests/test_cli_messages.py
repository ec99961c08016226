"""What the command line tells a new user: lists that are complete, notes where a run makes no sense,
counts in good English, and a video frame rate that does not make filming take minutes."""

import pytest
from conftest import requires_offscreen_gl

from qube_suite import cli, media, randomization, suite


def test_a_wrong_board_lists_the_cards_of_every_qube(capsys):
    assert cli.main(["run", "--domain", "qube_hardware", "--board", "nonsense", "--task", "balance",
                     "--controller", "balance"]) == 2
    err = capsys.readouterr().err
    assert "qube_servo2_usb" in err and "qube_servo3_usb" in err


@pytest.mark.parametrize("command", ["run", "train"])
def test_help_lists_every_randomization_preset(capsys, command):
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for preset in randomization.PRESETS:
        assert preset in text


def test_eval_of_a_policy_on_a_task_it_was_not_meant_for_says_so_and_counts_one_episode(capsys):
    assert cli.main(["eval", "--task", "rotor", "--controller", "ppo:balance", "--episodes", "1",
                     "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "'ppo:balance' is meant for balance" in captured.err
    assert ", 1 episode from seed 0" in captured.out


def test_eval_of_a_policy_on_its_own_task_has_no_note(capsys):
    assert cli.main(["eval", "--task", "balance", "--controller", "ppo:balance", "--episodes", "2",
                     "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "meant for" not in captured.err and ", 2 episodes from seed 0" in captured.out


@requires_offscreen_gl
@pytest.mark.parametrize(("fps", "expected"),
                         [([], 30.0), (["--fps", "control"], None), (["--fps", "10"], 10.0)])
def test_videos_are_filmed_at_30_frames_per_second_unless_asked(tmp_path, fps, expected):
    args = cli.build_parser().parse_args(["run", "--task", "balance", "--controller", "balance", "--video",
                                          str(tmp_path / "v.mp4"), "--size", "64x48", *fps])
    environment = suite.load("qube", "balance")
    recorder = cli._video_recorder(args, environment)
    try:
        assert recorder.fps == expected
        frames = sum(media.frame_due(step, environment.control_frequency,
                                     recorder.fps or environment.control_frequency) for step in range(251))
        assert frames == (251 if expected is None else round(expected) + 1)  # one second of steps
    finally:
        recorder.close()
        environment.close()
