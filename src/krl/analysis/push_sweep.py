"""What a push sweep's records say beyond ``krl report``: which pushes some controller survives, and where
on the trunk the pushes that beat a controller land.

``python -m krl.analysis.push_sweep RESULTS [--controller LABEL ...] [--band LOW:HIGH ...] [--out FILE]``
reads a ``krl evaluate --push-sweep`` results folder and prints (or writes atomically) two tables: the
headroom (:mod:`krl.analysis.push_headroom`) and the success by face struck
(:mod:`krl.analysis.push_faces`). docs/agent-robust.md ("What limits agent-robust") reads them.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from krl.analysis.push_faces import DEFAULT_BANDS, face_markdown, face_rows, parse_band
from krl.analysis.push_headroom import headroom_markdown, headroom_rows, push_outcomes
from krl.eval.report import collect
from krl.util.output import write_atomic


def push_sweep_markdown(
    results: Path,
    controllers: Sequence[str] | None = None,
    bands: Sequence[tuple[float, float]] = DEFAULT_BANDS,
    seeds: Sequence[int] | None = None,
) -> str:
    """Both tables of the results folder ``results`` for ``controllers`` (labels; default every one), of
    the training seeds ``seeds`` alone where given (controllers without seeds, such as the expert, kept).

    Raises:
        OSError: no such results folder.
        ValueError: a label not in it, or records the analyses refuse (their functions say which).
    """
    found = collect(results)
    if seeds is not None:
        kept = (*seeds, None)
        found = {
            label: {group: [r for r in records if r.get("seed") in kept] for group, records in groups.items()}
            for label, groups in found.items()
        }
    labels = list(controllers or found)
    for label in labels:
        if label not in found:
            raise ValueError(f"--controller {label!r}: not in {results} (labels: {', '.join(found)})")
    headroom = headroom_markdown(headroom_rows(push_outcomes(found), labels), labels)
    faces = face_markdown(face_rows(found, labels, bands))
    only = "" if seeds is None else f" (seeds {', '.join(map(str, seeds))})"
    return f"# The push sweep's records: {results}{only}\n\n{headroom}\n{faces}"


def _seeds(text: str) -> list[int]:
    """``--seeds``'s value as training seeds; a one-line ValueError for anything but integers."""
    try:
        return [int(seed) for seed in text.split(",")]
    except ValueError:
        raise ValueError(f"--seeds {text!r}: expected SEED,SEED,... (integers)") from None


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m krl.analysis.push_sweep", description=__doc__.splitlines()[0]
    )
    parser.add_argument("results", type=Path, help="a krl evaluate --out folder with push-sweep records")
    parser.add_argument("--controller", action="append", help="a controller label (default: every one)")
    parser.add_argument(
        "--band",
        action="append",
        help="a force band LOW:HIGH [N] of the faces table, repeat (default: 350:600 and 650:900)",
    )
    parser.add_argument(
        "--seeds", help="SEED,SEED,...: read these training seeds' records only (default all)"
    )
    parser.add_argument("--out", type=Path, help="write the tables here instead of printing them")
    args = parser.parse_args(argv)
    try:
        bands = [parse_band(text) for text in args.band] if args.band else DEFAULT_BANDS
        seeds = _seeds(args.seeds) if args.seeds else None
        text = push_sweep_markdown(args.results, args.controller, bands, seeds)
    except (OSError, ValueError) as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")
    if args.out:
        write_atomic(args.out, text)
    else:
        print(text, end="")


if __name__ == "__main__":
    main()
