"""Every ``krl`` command the README shows is a valid command line of today's parser (so it cannot rot)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from krl.cli import build_parser

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_commands() -> list[str]:
    """The ``krl …`` commands of the README's shell blocks (comments dropped, ``&&`` chains split)."""
    commands, in_block = [], False
    for line in README.read_text().splitlines():
        if line.startswith("```"):
            in_block = line.strip() == "```bash"
            continue
        if in_block:
            for part in line.split("#")[0].split("&&"):
                part = part.strip()
                if part.startswith("krl "):
                    commands.append(part)
    return commands


def test_the_readme_shows_commands():
    commands = readme_commands()
    assert "krl demo" in commands and len(commands) > 30


@pytest.mark.parametrize("command", readme_commands())
def test_every_readme_command_parses(command):
    build_parser().parse_args(shlex.split(command)[1:])
