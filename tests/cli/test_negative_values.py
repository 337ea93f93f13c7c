"""Option values may start with a minus sign (``--target -0.9,0.9``), and a usage error is one line."""

from __future__ import annotations

import json

import pytest

from krl.cli import build_parser, main

VECTOR_OPTIONS = [
    (["expert", "run"], "--target", "-0.9,0.9", "target", ["-0.9,0.9"]),
    (["expert", "run"], "--command", "-0.3,0,0.1", "command", "-0.3,0,0.1"),
    (["kernel", "run"], "--target", "-1,-2", "target", ["-1,-2"]),
    (["kernel", "run"], "--command", "-.2,0,-0.1", "command", "-.2,0,-0.1"),
    (["agent", "run"], "--target", "-0.9,0.9", "target", ["-0.9,0.9"]),
    (["agent", "run"], "--command", "-0.5,-0.1,0", "command", "-0.5,-0.1,0"),
    (["collect", "--out", "data"], "--target-distance", "-1,2", "target_distance", "-1,2"),
]


@pytest.mark.parametrize(("command", "option", "value", "dest", "expected"), VECTOR_OPTIONS)
def test_a_vector_option_takes_a_leading_minus(command, option, value, dest, expected):
    args = build_parser().parse_args([*command, option, value])
    assert getattr(args, dest) == expected


def test_repeated_and_scalar_values_keep_their_order():
    argv = ["agent", "run", "--target", "-0.9,0.9", "--target", "1,-2", "--seed", "-3", "--json"]
    args = build_parser().parse_args(argv)
    assert args.target == ["-0.9,0.9", "1,-2"] and args.seed == -3 and args.json


def test_words_after_a_double_dash_are_left_alone():
    parser = build_parser()
    assert parser.join_negative_values(["--", "--target", "-1,2"]) == ["--", "--target", "-1,2"]
    assert parser.join_negative_values(["--out", "-x"]) == ["--out", "-x"]  # not a number: untouched


def test_a_negative_command_walks(capsys):
    argv = ["kernel", "run", "--command", "-0.2,0,0", "--duration", "3", "--json"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["sim_seconds"] == pytest.approx(3.0) and result["mean_velocity"][0] < 0  # backwards


def test_a_malformed_negative_vector_is_the_vector_error(capsys):
    assert main(["kernel", "run", "--target", "-0.9,north", "--json"]) == 2
    error = capsys.readouterr().err
    assert error == "krl: error: --target expects 2 comma-separated numbers, got '-0.9,north'\n"


@pytest.mark.parametrize(
    "argv",
    [["agent", "run", "--target"], ["expert", "run", "--command"], ["kernel", "run", "--target", "--json"]],
)
def test_a_missing_value_is_one_line(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(argv)
    assert exit_info.value.code == 2
    error = capsys.readouterr().err
    prog = "krl " + " ".join(argv[:2])
    assert error == f"{prog}: error: argument {argv[2]}: expected one argument (see `{prog} --help`)\n"
