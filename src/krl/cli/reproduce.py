"""``krl reproduce``: every table and figure of docs/ from nothing, resumable (``docs/reproduce.md``)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from krl.cli.common import parse_ints


def run_step(argv: list[str]) -> int:
    """Run one step as its own ``krl`` process (a fresh interpreter per step, its own progress bars)."""
    return subprocess.call([sys.executable, "-m", "krl.cli", *argv])


def run_reproduce(args: argparse.Namespace) -> int:
    from krl.apps.reproduce import reproduce

    seeds = None if args.seeds is None else parse_ints(args.seeds, "--seeds")
    return reproduce(
        Path(args.runs), Path(args.docs), args.quick, run_step, dry_run=args.dry_run, seeds=seeds
    )


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reproduce", help="regenerate every table and figure of docs/ from nothing (resumable; --quick)"
    )
    p.add_argument("--runs", default="runs/reproduce", help="where data, kernels, agents and results go")
    p.add_argument(
        "--docs", default="docs", help="where the tables and figures go (with --quick: RUNS/quick/docs)"
    )
    p.add_argument("--quick", action="store_true", help="a cut-down pipeline (about 75 min here)")
    p.add_argument(
        "--seeds",
        help="training seeds of the agents and the kernel studies (default: the thesis's 150,215,345,556; "
        "with --quick: 150)",
    )
    p.add_argument("--dry-run", action="store_true", help="print the plan and what is done, run nothing")
    p.set_defaults(func=run_reproduce)
