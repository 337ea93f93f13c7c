"""The CLI stays thin and its help complete (issue 47): no function in ``src/krl/cli`` is over 80 lines, and
every option's ``--help`` of every command shows its default where it has one."""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
from pathlib import Path

import krl.cli
from krl.cli import build_parser
from krl.cli.common import HelpFormatter, shows_default

MAX_LINES = 80
"""The longest a function of ``krl.cli`` may be: a command parses, calls one function and prints."""


def _functions(folder: Path):
    """(file, name, lines) of every function and method under ``folder``."""
    for path in sorted(folder.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path.name, node.name, node.end_lineno - node.lineno + 1


def test_no_cli_function_is_over_80_lines():
    folder = Path(krl.cli.__file__).parent
    long = [item for item in _functions(folder) if item[2] > MAX_LINES]
    assert not long, f"functions over {MAX_LINES} lines in krl.cli: {long}"


def _parsers(parser: argparse.ArgumentParser, words: tuple[str, ...] = ("krl",)):
    """(command words, parser) of ``parser`` and every subcommand under it."""
    yield words, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*words, name))


def test_every_option_help_shows_its_default():
    missing, count = [], 0
    for words, parser in _parsers(build_parser()):
        count += 1
        formatter = HelpFormatter(prog=" ".join(words))
        for action in parser._actions:
            if not shows_default(action):
                continue
            text = formatter._expand_help(action) if action.help else ""
            if "default" not in text:
                missing.append((" ".join(words), action.dest))
    assert count > 25  # every command and subcommand was seen
    assert not missing, f"options whose --help does not show their default: {missing}"


def test_evaluate_help_explains_every_summary_field():
    from krl.eval.summaries import SUMMARY_FIELDS

    evaluate = dict(_parsers(build_parser()))[("krl", "evaluate")]
    text = evaluate.format_help()
    assert "(default runs/eval)" in text  # --out
    for field in ("results", "runs", "ran", "stored", "shared", "push_sweep", "controllers"):
        assert field in SUMMARY_FIELDS and f"{field}: " in text


def test_the_parser_is_built_without_pytorch():
    """``krl --help``, ``krl --version`` and every command that trains nothing start in about a second: the
    parser imports no PyTorch (4 s of imports, once the help of ``krl agent heldout`` pulled it in)."""
    code = "import sys; from krl.cli import build_parser; build_parser()\n"
    code += "print(sorted({'torch', 'stable_baselines3'} & set(sys.modules)))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
