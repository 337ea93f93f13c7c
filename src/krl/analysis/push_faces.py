"""Where on the trunk a push lands, and whether the robot survives it.

Training and the push sweep alike draw each push's point uniformly over the trunk box's surface (faces
weighted by area, :func:`krl.sim.pushes.random_trunk_point`) and tilt its force up by at most 0.3 rad. A
mostly horizontal force at a point above the centre of mass adds a moment that turns the trunk the way the
force tips the robot over its feet; below it, the moment turns the other way. This module splits a results
folder's push records by the face struck and by the push's direction relative to the walk (sideways: the
quarters left and right of :func:`krl.eval.summaries.push_direction`; along: forward and backward) and
gives each controller's success per force band.

``krl analyze push-sweep`` writes its table.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from krl.eval.evaluate import PUSH_DIR
from krl.eval.summaries import push_direction
from krl.robots.a1.constants import TRUNK_HALF_SIZE

FACES: tuple[str, ...] = ("top", "bottom", "sides", "ends")
"""The trunk box's faces as this module groups them: top (+z), bottom (−z), the left and right sides (±y),
the front and back ends (±x); trunk frame."""

DIRECTIONS: dict[str, tuple[str, ...]] = {"sideways": ("left", "right"), "along": ("forward", "backward")}
"""Push directions relative to the walk, grouped (quarters of :data:`krl.eval.summaries.PUSH_DIRECTIONS`)."""

DEFAULT_BANDS: tuple[tuple[float, float], ...] = ((350.0, 600.0), (650.0, 900.0))
"""Force bands [N]: 350-600 N, where issue 45's left-right target reads, and the forces above it."""


def face_of(point: Sequence[float]) -> str:
    """The face of :data:`FACES` a point on the trunk box's surface (trunk frame [m], shape (3,)) lies on:
    the axis along which it is farthest out relative to the box's half size."""
    axis = int(np.argmax(np.abs(np.asarray(point, dtype=float)) / TRUNK_HALF_SIZE))
    return {2: "top" if point[2] > 0 else "bottom", 1: "sides", 0: "ends"}[axis]


def parse_band(text: str) -> tuple[float, float]:
    """``LOW:HIGH`` [N] as a band, both ends included; a one-line ValueError for anything else."""
    low, _, high = text.partition(":")
    try:
        band = (float(low), float(high))
    except ValueError:
        band = (np.nan, np.nan)
    if not (np.isfinite(band).all() and 0 <= band[0] <= band[1]):
        raise ValueError(f"--band {text!r}: expected LOW:HIGH in newtons with 0 <= LOW <= HIGH")
    return band


def face_rows(
    found: dict[str, dict[str, list[dict[str, Any]]]],
    controllers: Sequence[str],
    bands: Sequence[tuple[float, float]] = DEFAULT_BANDS,
) -> list[dict[str, Any]]:
    """One row per (direction group of :data:`DIRECTIONS`, face of :data:`FACES`) with, per controller and
    band, ``<label>/<low>-<high>/attempts`` and ``.../success_rate`` (None where no attempt fell in it);
    seeds pooled.

    Raises:
        ValueError: a label in ``controllers`` has no push records.
    """
    cells: dict[tuple[str, str, str, int], list[bool]] = {}
    for label in controllers:
        records = found.get(label, {}).get(PUSH_DIR, [])
        if not records:
            raise ValueError(f"--controller {label!r}: no push-sweep records")
        for record in records:
            direction = push_direction(record)
            group = next(name for name, quarters in DIRECTIONS.items() if direction in quarters)
            face = face_of(record["metrics"]["push"]["point"])
            for index, (low, high) in enumerate(bands):
                if low <= float(record["magnitude"]) <= high:
                    cells.setdefault((label, group, face, index), []).append(
                        bool(record["metrics"]["success"])
                    )
    rows = []
    for group in DIRECTIONS:
        for face in FACES:
            row: dict[str, Any] = {"direction": group, "face": face}
            for label in controllers:
                for index, (low, high) in enumerate(bands):
                    outcomes = cells.get((label, group, face, index), [])
                    key = f"{label}/{low:g}-{high:g}"
                    row[f"{key}/attempts"] = len(outcomes)
                    row[f"{key}/success_rate"] = float(np.mean(outcomes)) if outcomes else None
            rows.append(row)
    return rows


def face_markdown(rows: list[dict[str, Any]]) -> str:
    """The rows as a markdown section: a column per controller and band, a cell ``rate (attempts)``."""
    keys = [key.removesuffix("/attempts") for key in rows[0] if key.endswith("/attempts")]
    header = ["direction", "face struck", *(f"{key.replace('/', ', ')} N" for key in keys)]
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for row in rows:
        cells = [row["direction"], row["face"]]
        for key in keys:
            rate, attempts = row[f"{key}/success_rate"], row[f"{key}/attempts"]
            cells.append("–" if rate is None else f"{rate:.2f} ({attempts})")
        lines.append("| " + " | ".join(cells) + " |")
    return (
        "## By the face struck\n\nSuccess rate (attempts) per direction relative to the walk (sideways: left "
        "or right; along: forward or backward) and face of the trunk struck, seeds pooled "
        "(`krl.analysis.push_faces`).\n\n" + "\n".join(lines) + "\n"
    )
