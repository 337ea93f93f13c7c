"""``krl export``: the kernel and the agent's policy as ONNX, with their JSON contract."""

from __future__ import annotations

import argparse

from krl.cli.common import emit


def run_export(args: argparse.Namespace) -> int:
    from krl.apps.export import export

    emit(export(args.out, policy=args.policy, kernel=args.kernel), args.json)
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export",
        help="the kernel and the agent's policy as ONNX, with a JSON contract (needs the export extra)",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--policy", help="shipped agent (rp, base) or a policy file; its kernel is exported with it"
    )
    p.add_argument(
        "--kernel", help="shipped kernel (base, ext) or a kernel file (default: the policy's, or base)"
    )
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run_export)
