"""What ``krl expert plot`` runs for each figure: its conditions, and one job per condition
(:mod:`krl.analysis.expert.runs`); a condition shared by two figures is one job.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from krl.analysis.common import velocity_sweep
from krl.analysis.expert.runs import SWEEP_STANCE, HoldJob, Job, WalkJob
from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
from krl.task import TARGET_DISTANCE

FIGURES: tuple[str, ...] = ("com-variance", "ride-height", "step-height", "velocity")
"""The figures, in the order ``all`` makes them."""

CHOICES: tuple[str, ...] = (*FIGURES, "all")

THESIS_FIGURE: dict[str, str] = {
    "com-variance": "Fig. 4.8",
    "ride-height": "Fig. A.2",
    "step-height": "Fig. A.3",
    "velocity": "Fig. 4.15 (MPC)",
}

STANCE_DURATIONS: tuple[float, ...] = (0.3, 0.25, 0.2)
"""τ_stance of Fig. 4.8's panels A, B, C [s]."""
RIDE_HEIGHTS: tuple[float, ...] = (0.18, 0.21, 0.25, 0.28)
"""Ride heights of the Fig. A.2 sweep [m] (the expert's range is 0.18-0.28 m)."""
STEP_HEIGHTS: tuple[float, ...] = (0.05, 0.09, 0.13, 0.18)
"""Step heights of the Fig. A.3 sweep [m] (the expert's range is 0.05-0.18 m)."""

DEFAULT_TARGETS: int = 10
"""Random waypoints per CoM condition (about 95 s of walking)."""
QUICK_TARGETS: int = 1
"""The same with ``quick`` (tests)."""
QUICK_TARGET_DISTANCE: tuple[float, float] = (1.8, 2.0)
"""Range of the distance to that waypoint with ``quick`` [m]."""


@dataclass(frozen=True)
class Settings:
    """One ``krl expert plot`` run's choices (checked by :func:`krl.analysis.expert.driver.make_figures`)."""

    seed: int
    """Seed of the waypoints and of the terrain."""
    targets: int
    """Random waypoints per CoM condition."""
    duration: float
    """Length of each velocity-sweep hold [s]."""
    quick: bool
    """Tiny runs (tests)."""


def _waypoints(settings: Settings) -> tuple[tuple[float, float], ...]:
    from krl.task import random_targets

    distance = QUICK_TARGET_DISTANCE if settings.quick else TARGET_DISTANCE
    points = random_targets(np.random.default_rng(settings.seed), settings.targets, (0.0, 0.0), distance)
    return tuple((float(x), float(y)) for x, y in points)


def _com_conditions(which: str) -> list[tuple[str, dict[str, float]]]:
    """(legend label, expert settings) per condition of a CoM figure."""
    ride, step = NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
    if which == "com-variance":
        return [(f"τ_stance = {s:g} s", {"stance": s, "ride": ride, "step": step}) for s in STANCE_DURATIONS]
    if which == "ride-height":
        return [
            (f"ride height {h:g} m", {"stance": SWEEP_STANCE, "ride": h, "step": step}) for h in RIDE_HEIGHTS
        ]
    return [(f"step height {h:g} m", {"stance": SWEEP_STANCE, "ride": ride, "step": h}) for h in STEP_HEIGHTS]


def plan(which: Sequence[str], settings: Settings) -> dict[str, list[tuple[Any, Job]]]:
    """Per figure: (condition description, job); equal jobs across figures are the same object key."""
    out: dict[str, list[tuple[Any, Job]]] = {}
    waypoints = _waypoints(settings)
    for name in which:
        if name == "velocity":
            out[name] = [
                ((axis, value), HoldJob(command, settings.duration, settings.seed))
                for axis, value, command in velocity_sweep(settings.quick)
            ]
        else:
            out[name] = [
                (
                    (label, cfg),
                    WalkJob(cfg["stance"], cfg["ride"], cfg["step"], settings.seed, waypoints),
                )
                for label, cfg in _com_conditions(name)
            ]
    return out
