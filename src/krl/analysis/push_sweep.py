"""What a push sweep's records say beyond ``krl report``: which pushes some controller survives, and where
on the trunk the pushes that beat a controller land.

:func:`push_sweep_markdown` reads a ``krl evaluate --push-sweep`` results folder into two tables, which
``krl analyze push-sweep`` prints or writes: the headroom (:mod:`krl.analysis.push_headroom`) and the
success by face struck (:mod:`krl.analysis.push_faces`). docs/agent-robust.md ("What limits agent-robust")
reads them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from krl.analysis.push_faces import DEFAULT_BANDS, face_markdown, face_rows
from krl.analysis.push_headroom import headroom_markdown, headroom_rows, push_outcomes
from krl.eval.report import collect


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
