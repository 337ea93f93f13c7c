"""The fields a stored run's record holds, with their JSON types, checked on every read
(:func:`record_problem`): ``krl report``, ``krl evaluate``'s resumption and the analyses read these fields
without asking, so a record that lacks one or holds another type (``"success": null``, a file holding only
``metrics.success``) is refused in one line naming its file and the field, never half-read.

Every record holds :data:`RUN_FIELDS`; a run of the push sweep (key ``push/...``) also
:data:`PUSH_FIELDS`, one of the friction sweep (``friction/...``) :data:`COURSE_FIELDS` and
:data:`FRICTION_FIELDS`, one of the stair sweep (``stair-sweep/...``) :data:`COURSE_FIELDS` and
:data:`STAIR_FIELDS`, any other (``<course>/...``) :data:`COURSE_FIELDS`. Records written since the first
evaluation (2026-11-22) hold all of them; fields added since (``machine``, ``metrics.ended``,
``metrics.push_heading``) are not required.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

PUSH_DIR = "push"
"""The group of the push sweep's runs (the first part of their key), and their folder in the older layout."""

FRICTION_DIR = "friction"
"""The group of the friction sweep's runs."""

STAIR_DIR = "stair-sweep"
"""The group of the stair sweep's runs."""

_KINDS: dict[str, Callable[[Any], bool]] = {
    "an object": lambda value: isinstance(value, dict),
    "a list": lambda value: isinstance(value, list),
    "a string": lambda value: isinstance(value, str),
    "a boolean": lambda value: isinstance(value, bool),
    "an integer": lambda value: isinstance(value, int) and not isinstance(value, bool),
    "a number": lambda value: isinstance(value, (int, float)) and not isinstance(value, bool),
}
"""What a field may hold, by its name in :data:`RUN_FIELDS` (``... or null``: also null)."""

RUN_FIELDS: dict[str, str] = {
    "controller": "an object",
    "controller.kind": "a string",
    "controller.label": "a string",
    "controller.options": "an object",
    "controller.model_sha256": "a string or null",
    "run": "a string",
    "metrics": "an object",
    "metrics.targets": "an integer",
    "metrics.targets_reached": "an integer",
    "metrics.success": "a boolean",
    "metrics.fell": "a boolean",
    "metrics.timed_out": "a boolean",
    "metrics.error": "a string or null",
    "metrics.steps": "an integer",
    "metrics.reward_total": "a number",
    "metrics.reward_per_step": "a number",
    "metrics.reward_terms": "an object",
    "metrics.time_to_finish": "a number or null",
    "metrics.distance_walked": "a number",
    "metrics.sim_seconds": "a number",
    "metrics.wall_seconds": "a number",
}
"""The fields of every record (dotted: ``metrics.success`` is ``record["metrics"]["success"]``)."""

SEED_FIELD = ("seed", "an integer or null")
"""The training seed of a seed group's run: null (or, in a push record of one policy, absent) otherwise."""

COURSE_FIELDS: dict[str, str] = {
    "course": "a string",
    "course_fingerprint": "a string",
    "start": "an integer",
}
"""The fields of a run on a course (and of the friction sweep's)."""

FRICTION_FIELDS: dict[str, str] = {"friction": "a number"}
"""The friction sweep's run's ground friction μ [-]."""

STAIR_FIELDS: dict[str, str] = {
    "stair": "an object",
    "stair.riser": "a number",
    "stair.direction": "a string",
    "stair.trained_risers": "a list or null",
}
"""The stair sweep's run's flight: riser height [m], direction and the policy's trained risers [m]."""

PUSH_FIELDS: dict[str, str] = {
    "sweep": "an object",
    "magnitude": "a number",
    "attempt": "an integer",
    "metrics.push": "an object",
    "metrics.push.magnitude": "a number",
    "metrics.push.force": "a list",
    "metrics.push.point": "a list",
    "metrics.push.impulse": "a number",
    "metrics.push.delta_v": "a number",
}
"""The fields of a push sweep's attempt."""

_MISSING = object()


def fields_of(run: str) -> dict[str, str]:
    """The fields a record of run key ``run`` (``<group>/<name>``) holds, and what each holds."""
    group = run.partition("/")[0]
    if group == PUSH_DIR:
        return {**RUN_FIELDS, **PUSH_FIELDS}
    if group == FRICTION_DIR:
        return {**RUN_FIELDS, **COURSE_FIELDS, **FRICTION_FIELDS}
    if group == STAIR_DIR:
        return {**RUN_FIELDS, **COURSE_FIELDS, **STAIR_FIELDS}
    return {**RUN_FIELDS, **COURSE_FIELDS}


def record_problem(record: Any) -> str | None:
    """What is wrong with ``record`` as a stored run's record (``field metrics.success is null, not a
    boolean``), or None: it holds every field of :func:`fields_of` its run, each of its kind."""
    if not isinstance(record, dict):
        return f"a record is {_json_name(record)}, not an object"
    run = record.get("run")
    fields = fields_of(run) if isinstance(run, str) else RUN_FIELDS
    name, kind = SEED_FIELD
    if name in record:
        fields = {**fields, name: kind}
    for field, kind in fields.items():
        value: Any = record
        for part in field.split("."):
            value = value.get(part, _MISSING) if isinstance(value, dict) else _MISSING
        if value is _MISSING:
            return f"field {field} is missing"
        allowed = kind.removesuffix(" or null")
        if not (_KINDS[allowed](value) or (value is None and kind.endswith(" or null"))):
            return f"field {field} is {_json_name(value)}, not {kind}"
    return None


def _json_name(value: Any) -> str:
    """``value`` as a message names it: ``null``, ``true``, ``"text"`` or its JSON, cut to 40 characters."""
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."
