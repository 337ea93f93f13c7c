"""Numbers as a person reads them: a summary's floats rounded to what the measurement supports.

One rule (:data:`RULE`) for every printed summary: ``krl evaluate``'s and the ``… run`` commands'.
"""

from __future__ import annotations

import math
import re
from typing import Any

RULE = (
    "a time [s] (a field ending in seconds or starting with time_) to 0.1 s; a rate or a share of runs (a "
    "field holding rate, success_low, success_high or difference) to 2 decimals; any other number to 3 "
    "significant digits, never rounding its integer part (a 1025 N push stays 1025)"
)
"""How :func:`readable` rounds, as help texts say it. Integers, booleans, strings and non-finite floats pass
unchanged."""

TIME_KEY = re.compile(r"seconds$|^time_")
"""Keys of times [s], rounded to 0.1 s."""

RATE_KEY = re.compile(r"rate|success_low|success_high|difference")
"""Keys of rates and their intervals (fractions of runs), rounded to 2 decimals."""

SIGNIFICANT_DIGITS = 3
"""Significant digits of any other float."""


def readable(value: Any, key: str = "") -> Any:
    """``value`` (a float, or dicts and lists of them, nested) rounded by the module's rule; ``key`` is the
    name the value is stored under (a list's items take the list's key)."""
    if isinstance(value, dict):
        return {name: readable(item, str(name)) for name, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [readable(item, key) for item in value]
    if not isinstance(value, float) or not math.isfinite(value) or value == 0:
        return value
    if TIME_KEY.search(key):
        return round(value, 1)
    if RATE_KEY.search(key):
        return round(value, 2)
    decimals = SIGNIFICANT_DIGITS - 1 - math.floor(math.log10(abs(value)))
    return round(value, max(0, decimals))
