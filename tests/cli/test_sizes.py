"""``--video-size WIDTHxHEIGHT`` of the run commands and ``krl view --duration``: their one-line errors."""

from __future__ import annotations

import pytest

from krl.cli import main
from krl.cli.common import CliError, parse_size, video_size_default


def test_a_size_is_two_positive_integers():
    assert parse_size("320x240", "--video-size") == (320, 240)
    assert parse_size("64X48", "--video-size") == (64, 48)
    assert video_size_default() == "640x480"  # VideoRecorder's own defaults


@pytest.mark.parametrize("text", ["320", "0x240", "-1x5", "wide x tall", "320x"])
def test_a_bad_size_names_the_option(text):
    with pytest.raises(CliError, match=r"--video-size expects WIDTHxHEIGHT in pixels"):
        parse_size(text, "--video-size")


def test_a_bad_video_size_fails_before_the_run(tmp_path, capsys):
    video = tmp_path / "walk.mp4"
    assert main(["kernel", "run", "--video", str(video), "--video-size", "0x3", "--targets", "1"]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not video.exists()


@pytest.mark.parametrize("duration", ["0", "-2"])
def test_view_needs_a_positive_duration(duration, capsys):
    assert main(["view", "--duration", duration]) == 2
    assert capsys.readouterr().err == f"krl: error: --duration must be > 0 s, got {duration}\n"
