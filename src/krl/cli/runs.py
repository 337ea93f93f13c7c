"""``krl agent snapshot``: copy run folders of ``krl agent train`` into a folder to commit or carry."""

from __future__ import annotations

import argparse
from pathlib import Path

from krl.cli.common import CliError, emit


def run_snapshot(args: argparse.Namespace) -> int:
    from krl.agent.run_folder import snapshot_runs

    try:
        result = snapshot_runs([Path(run) for run in args.run], Path(args.out))
    except ValueError as error:
        raise CliError(str(error)) from None
    except OSError as error:
        raise CliError(f"cannot snapshot into {args.out}: {error}") from None
    emit(result, args.json)
    return 0


def register(group) -> None:
    """Add ``krl agent snapshot`` to ``krl agent``'s subcommands."""
    p = group.add_parser(
        "snapshot",
        help="copy run folders (config, logs, checkpoints, policy; no TensorBoard events) into OUT/<name>, "
        "to commit or carry to another machine; copied back, krl agent train --out resumes them",
    )
    p.add_argument("run", nargs="+", help="run folders of krl agent train")
    p.add_argument("--out", required=True, help="the folder the copies go into (one subfolder per run)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run_snapshot)
