"""Every option that sets a number of processes (``--workers``, ``--jobs``) refuses fewer than one in one
line and caps more than the usable cores, saying so (issue 61, H4: ``--workers 1000`` started a process per
run until memory ran out)."""

from __future__ import annotations

import argparse

import pytest
from test_structure import _parsers

from krl.cli import build_parser, main
from krl.cli.common import process_count
from krl.util.parallel import usable_cores

PROCESS_OPTIONS = ("--workers", "--jobs")


def _process_options() -> list[tuple[str, argparse.Action]]:
    """(command, action) of every ``--workers`` and ``--jobs`` option of every ``krl`` command."""
    return [
        (" ".join(words), action)
        for words, parser in _parsers(build_parser())
        for action in parser._actions
        if set(action.option_strings) & set(PROCESS_OPTIONS)
    ]


def test_every_process_option_follows_the_one_rule():
    options = _process_options()
    commands = {command for command, _ in options}
    expected = {"krl evaluate", "krl agent train", "krl agent study", "krl kernel figures", "krl expert plot"}
    assert expected <= commands
    assert [command for command, action in options if action.type is not process_count] == []


@pytest.mark.parametrize("text", ["0", "-3"])
def test_fewer_than_one_process_is_a_one_line_usage_error(capsys, text):
    with pytest.raises(SystemExit) as stop:
        main(["evaluate", "--controller", "expert", "--course", "flat", "--workers", text])
    assert stop.value.code == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and f"at least 1, got {text}" in error, error


def test_more_processes_than_cores_are_capped_with_a_note(capsys):
    cores = usable_cores()
    assert process_count(str(cores)) == cores and capsys.readouterr().err == ""
    assert process_count("1000") == cores
    note = capsys.readouterr().err
    assert note.count("\n") == 1 and f"capped at the {cores} usable cores" in note, note
    args = build_parser().parse_args(["agent", "train", "--out", "run", "--workers", "1000"])
    assert args.workers == cores


def test_a_process_count_that_is_no_integer_is_a_usage_error():
    with pytest.raises(argparse.ArgumentTypeError, match="expected an integer, got 'two'"):
        process_count("two")
