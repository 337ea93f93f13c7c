"""The CLI stays thin and its help complete (issue 47): no function in ``src/krl/cli`` is over 80 lines, and
every option's ``--help`` of every command shows its default where it has one. Every tool is a ``krl``
command (issue 61): argparse and script entry points live in ``src/krl/cli`` only."""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
from pathlib import Path

import krl
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


def _script_parts(path: Path) -> list[str]:
    """What makes the module at ``path`` a command line of its own: an argparse import, an ``if __name__ ==
    "__main__"`` block, or its being a ``__main__.py``."""
    tree = ast.parse(path.read_text())
    parts = ["__main__.py"] if path.name == "__main__.py" else []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "argparse" for a in node.names):
            parts.append("imports argparse")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "argparse":
            parts.append("imports argparse")
        elif isinstance(node, ast.Compare) and "__main__" in {
            getattr(item, "value", None) for item in (node.left, *node.comparators)
        }:
            parts.append('an if __name__ == "__main__" block')
    return parts


def test_every_command_line_is_a_krl_command():
    """A module outside ``krl.cli`` that parses arguments or runs as ``python -m`` is a tool that ``krl
    --help`` does not list, docs/cli.md does not show and tests/test_readme.py does not run."""
    package, cli = Path(krl.__file__).parent, Path(krl.cli.__file__).parent
    outside = [path for path in sorted(package.rglob("*.py")) if cli not in path.parents]
    found = {str(path.relative_to(package.parent)): _script_parts(path) for path in outside}
    offenders = {path: parts for path, parts in found.items() if parts}
    assert not offenders, f"command lines outside src/krl/cli (make them krl commands): {offenders}"
    assert _script_parts(cli / "__main__.py") == ["__main__.py"]  # the checker sees the one there is


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
