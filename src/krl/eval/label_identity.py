"""What a results folder fixes about each controller label when the label is first written: the controller
(its files' SHA-256 and its options, seed by seed for a seed group) and the content of each course its runs
walked. ``krl report`` pools every run of a label and of a course name into one row, so a later call under
the label with another policy file, or with another course of a stored name, is refused before any run
starts (:func:`check_label`), even where none of its runs is stored yet.

A seed group keeps the records of its other seeds when it gains or loses a seed
(:meth:`krl.eval.controllers.ControllerSpec.describe`): only a seed it still holds must be the same file.
The friction sweep's runs are left to the run-by-run check (:func:`krl.eval.evaluate.check_record`): a
course at a friction μ has a fingerprint of its own.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from krl.eval.controllers import ControllerSpec
from krl.eval.records import EvaluationError, StoredRun

_ADVICE = "use another --out, or delete the old results"


def check_label(
    folder: Path, spec: ControllerSpec, courses: Mapping[str, str], runs: Mapping[str, StoredRun]
) -> None:
    """That every stored run of ``folder`` (``OUT/<label>``; ``runs`` as :func:`krl.eval.records.read_runs`
    gives them) was made by ``spec`` (seed by seed) and, where it walked a course named in ``courses``
    ({course name: fingerprint} of this call), on that course; an :class:`EvaluationError` (one line naming
    the label and both SHA-256) for the first that was not."""
    for stored in runs.values():
        record = stored.record
        problem = _controller_problem(spec, record)
        name = record.get("course")
        if problem is None and "friction" not in record and name in courses:
            fingerprint = record.get("course_fingerprint")
            if fingerprint != courses[name]:
                problem = (
                    f"holds runs of another course {name!r} (fingerprint {fingerprint}; this call's: "
                    f"{courses[name]})"
                )
        if problem is not None:
            raise EvaluationError(f"{folder}: label {spec.label!r} {problem}, in {stored.source}; {_ADVICE}")


def _controller_problem(spec: ControllerSpec, record: dict[str, Any]) -> str | None:
    """How the controller that made ``record`` differs from ``spec`` (None: it is ``spec``'s, or its seed's
    file is one ``spec``'s group no longer holds)."""
    seed = record.get("seed")
    if seed is not None and spec.seeded and seed not in spec.seeds:
        return None
    stored = record["controller"]
    if (seed is not None) == spec.seeded and spec.described_as(stored, seed):
        return None
    now = spec.describe(seed if spec.seeded else None)
    which = "" if seed is None else f"(seed {seed}) "
    if stored.get("model_sha256") != now["model_sha256"]:
        old, new = f"model SHA-256 {stored.get('model_sha256')}", now["model_sha256"]
    else:
        old, new = f"options {stored.get('options')}", now["options"]
    return f"{which}holds runs of another controller ({old}; this call's: {new})"
