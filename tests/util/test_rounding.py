"""Summaries rounded to what the measurement supports (issue 47: evaluate printed 17-digit floats)."""

from __future__ import annotations

import math

from krl.util.rounding import readable


def test_times_rates_and_other_numbers_round_by_their_key():
    summary = {
        "wall_seconds": 12.3456,
        "time_to_finish_mean": 23.456,
        "success_rate": 0.9333333333333333,
        "success_low": 0.70181,
        "difference_high": -0.123456,
        "reward_per_step_mean": 0.812345678,
        "magnitude": 1025.0,
        "impulse": 45.678,
        "mean_velocity": [0.49871, -0.0012345],
        "rows": [{"fall_rate": 1 / 3, "friction": 0.35}],
    }
    assert readable(summary) == {
        "wall_seconds": 12.3,
        "time_to_finish_mean": 23.5,
        "success_rate": 0.93,
        "success_low": 0.7,
        "difference_high": -0.12,
        "reward_per_step_mean": 0.812,
        "magnitude": 1025.0,
        "impulse": 45.7,
        "mean_velocity": [0.499, -0.00123],
        "rows": [{"fall_rate": 0.33, "friction": 0.35}],
    }


def test_what_is_not_a_finite_float_passes_unchanged():
    values = {"runs": 3, "fell": True, "label": "x", "time_to_finish_mean": None, "rate": math.inf, "z": 0.0}
    assert readable(values) == values
