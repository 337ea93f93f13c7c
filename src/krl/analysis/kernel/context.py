"""What every kernel figure shares: the figure list, the thesis's figure numbers, the legs drawn, the run's
settings (:class:`FigureRun`) and the error the driver raises.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from krl.robots.a1.constants import LEG_NAMES


class FigureError(ValueError):
    """A bad ``krl kernel figures`` argument or a missing/unsuitable kernel file (one-line message)."""


FIGURES: tuple[str, ...] = ("trajectories", "command-sweep", "symmetry", "walk-gait", "heights", "velocity")
"""The figures, in the order ``all`` makes them."""

CHOICES: tuple[str, ...] = (*FIGURES, "all")

THESIS_FIGURE: dict[str, str] = {
    "trajectories": "Fig. 4.9",
    "command-sweep": "Fig. 4.10",
    "symmetry": "Fig. 4.11",
    "walk-gait": "Fig. 4.12",
    "heights": "Fig. 4.13",
    "velocity": "Fig. 4.15 (kernel)",
}

FR, RL = LEG_NAMES.index("FR"), LEG_NAMES.index("RL")
"""Indices of the front-right and rear-left legs (a trot's diagonal pair) in :data:`LEG_NAMES` order."""

CSV_DECIMATION: int = 2
"""``trajectories.csv`` and ``walk-gait.csv`` keep every this many control steps (100 Hz)."""


@dataclass(frozen=True)
class FigureRun:
    """One ``krl kernel figures`` run's settings (checked by the driver)."""

    seed: int
    """Seed of the waypoints and of the simulator."""
    quick: bool
    """Tiny runs (tests)."""
    workers: int
    """Processes for the velocity sweep."""
    progress: bool
    """Say on stderr what runs."""

    def say(self, text: str) -> None:
        """Print ``text`` on stderr when :attr:`progress` is on."""
        if self.progress:
            print(text, file=sys.stderr, flush=True)
