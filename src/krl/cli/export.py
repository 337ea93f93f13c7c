"""``krl export``: the kernel and the agent's policy as ONNX, with their JSON contract.

A kernel-only export refuses a folder that holds a ``policy.onnx`` of an earlier export (its contract would
not list it); delete that file or choose another ``--out`` (:mod:`krl.apps.export`).
"""

from __future__ import annotations

import argparse

from krl.cli.common import SHIPPED_AGENTS, SHIPPED_KERNELS, CliError, emit


def run_export(args: argparse.Namespace) -> int:
    """Export what the options name and print the files written."""
    from krl.apps.export import export

    try:
        written = export(args.out, policy=args.policy, kernel=args.kernel)
    except ImportError as error:  # the optional export extra is not installed: one line, not a traceback
        raise CliError(str(error)) from None
    emit(written, args.json)
    return 0


def register(subparsers) -> None:
    """Add ``krl export`` to the main parser's subcommands."""
    p = subparsers.add_parser(
        "export",
        help="the kernel and the agent's policy as ONNX, with a JSON contract (needs the export extra)",
    )
    p.add_argument(
        "--out",
        required=True,
        help="output folder; a kernel-only export refuses one that holds a policy.onnx (delete it first)",
    )
    p.add_argument(
        "--policy",
        help=f"shipped agent ({SHIPPED_AGENTS}; also agent:NAME, NAME@SEED), a seed group or a policy file; "
        "its kernel is exported with it",
    )
    p.add_argument(
        "--kernel",
        help=f"shipped kernel ({SHIPPED_KERNELS}) or a kernel file (default: the policy's, or base)",
    )
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run_export)
