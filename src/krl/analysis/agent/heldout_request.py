"""What a held-out comparison is asked to do, and its bounds: light enough for the CLI to build its help
from (no PyTorch); :mod:`krl.analysis.agent.heldout_choice` runs it, :mod:`krl.analysis.agent.heldout` walks
the episodes."""

from __future__ import annotations

import dataclasses
from pathlib import Path

HELDOUT_BATCH: int = 32
"""Episodes walked at once, their environments built together (their memory: benchmarks/README.md,
"Figures behind constants and design choices"): a larger count is
walked in batches of this many, environment ``k`` still seeded
:data:`krl.analysis.agent.heldout.HELDOUT_SEED` ``+ k``, so memory does not grow with the count. A count up
to this (the documented 32) is one batch, walked as it always was."""

MAX_EPISODES: int = 1024
"""The most held-out episodes per policy file: 32 batches, a machine-day of 60 s episodes on a few cores.
What still grows with the count is small: each episode's record and, for a policy that drives its gait,
the driven numbers of every step (:func:`krl.analysis.agent.heldout.drive_usage`; their memory at this
count: benchmarks/README.md)."""

PolicyGroups = dict[str, list[tuple[int | None, Path]]]
"""Policy files by label: ``{label: [(seed or None, path)]}``."""


class HeldoutError(ValueError):
    """A held-out request that cannot run as given; the message is one line and names the option."""


@dataclasses.dataclass(frozen=True)
class HeldoutRequest:
    """One ``krl agent heldout``.

    Attributes:
        groups: the policy files by label.
        out: the output folder (one record per policy file, the tables, the choice).
        episodes: held-out episodes per policy file, 1 to :data:`MAX_EPISODES`.
        workers: environment processes (None: one per usable core).
        candidates: the labels to choose among (empty: no choice, only the tables).
        baseline: a label the choice must beat (None: none).
        env: an agent config file whose env every policy walks instead of its own (None: its own).
        baseline_env: an agent config file on whose env the choice must also be no worse than the baseline.
        seed_group: a seed-group folder that receives the chosen label's policies (None: none).
    """

    groups: PolicyGroups
    out: Path
    episodes: int = 32
    workers: int | None = None
    candidates: tuple[str, ...] = ()
    baseline: str | None = None
    env: str | None = None
    baseline_env: str | None = None
    seed_group: Path | None = None
