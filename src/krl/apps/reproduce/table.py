"""The pipeline's table: a :class:`Row` per step in both modes (full and ``--quick``), made into a
:class:`Step` by filling its placeholders."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar


@dataclass(frozen=True)
class Step:
    """One command of the pipeline."""

    name: str
    """File-name-safe name (the marker's)."""
    argv: tuple[str, ...]
    """The ``krl`` command's arguments."""
    minutes: float
    """Wall time it took (full) or should take (quick) on the 2-core development machine [min]."""
    makes: str
    """What it writes, for the plan."""
    config: tuple[str, str] | None = None
    """``(path, JSON text)`` of a config file the command reads, written just before it runs."""

    @property
    def command(self) -> str:
        return "krl " + " ".join(self.argv)


T = TypeVar("T")

AGENT_SEED_EVALUATION_MINUTES: float = 5.0
"""Wall time of one agent seed's full evaluation on both cores of the development machine [min]: the
thesis's and the harder courses, the default push sweep at 50 attempts per force and the friction sweep.
Measured: benchmarks/README.md, "Wall times of the reproduce pipeline"."""
EXPERT_EVALUATION_MINUTES: float = 35.0
"""Wall time of the MPC expert's full evaluation (the same courses and sweeps) on both cores of the
development machine [min], an upper bound. Measured: benchmarks/README.md, "Wall times of the reproduce
pipeline"."""
AGENT_PUSHES_PER_MINUTE: float = 450.0
"""Push attempts one agent walks per minute on both cores of the development machine. Measured:
benchmarks/README.md, "Wall times of the reproduce pipeline"."""
EXPERT_PUSHES_PER_MINUTE: float = 64.0
"""Push attempts the MPC expert walks per minute on both cores of the development machine. Measured:
benchmarks/README.md, "Wall times of the reproduce pipeline"."""


@dataclass(frozen=True)
class ByMode(Generic[T]):
    """A value that differs between the full pipeline and ``--quick``."""

    full: T
    quick: T

    def pick(self, quick: bool) -> T:
        return self.quick if quick else self.full


Fragment = str | ByMode[str]
"""Part of a command: space-separated template tokens (``{runs}``, ``{data}``, ... filled by
:func:`krl.apps.reproduce.pipeline.places`, ``{config}`` by the row), or one such string per mode ("" for
no tokens)."""


def _pick(value: Any, quick: bool) -> Any:
    """``value`` for the mode: one side of a :class:`ByMode`, anything else as it is."""
    return value.pick(quick) if isinstance(value, ByMode) else value


def _fill(value: Any, places: Mapping[str, str]) -> Any:
    """``value`` (a config: nested dicts) with every string's placeholders filled."""
    if isinstance(value, str):
        return value.format(**places)
    if isinstance(value, dict):
        return {key: _fill(item, places) for key, item in value.items()}
    return value


@dataclass(frozen=True)
class Row:
    """One step of the pipeline's table, in both modes; :meth:`step` makes its :class:`Step`."""

    name: str
    """File-name-safe name (the marker's)."""
    makes: str
    """What it writes, for the plan."""
    minutes: ByMode[float] | float
    """Wall time it took (full) or should take (quick) on the 2-core development machine [min]."""
    argv: tuple[Fragment, ...]
    """The ``krl`` command, as template fragments."""
    config: ByMode[dict[str, Any]] | None = None
    """Settings written as JSON to ``{config}`` (``RUNS/<name>.json``) just before the command runs."""

    def step(self, places: Mapping[str, str], quick: bool) -> Step:
        """This row with its placeholders filled, for the mode."""
        places = {**places, "config": f"{places['runs']}/{self.name}.json"}
        argv = tuple(token.format(**places) for part in self.argv for token in _pick(part, quick).split())
        config = None
        if self.config is not None:
            config = (places["config"], json.dumps(_fill(self.config.pick(quick), places), indent=2) + "\n")
        return Step(self.name, argv, _pick(self.minutes, quick), self.makes, config)


def chosen_seed_rows(group: str, heldout: str, seeds: Sequence[int]) -> tuple[Row, ...]:
    """The trainings of seed group ``group``'s other ``seeds`` into ``RUNS/<group>/seed<S>``, from the
    recipe the held-out choice in ``RUNS/<heldout>`` wrote (``chosen-config.json``)."""
    return tuple(
        Row(
            f"{group}-seed{seed}",
            f"{group} (seed {seed})",
            120,
            (
                f"agent train --out {{runs}}/{group}/seed{seed} --seed {seed}",
                f"--config {{runs}}/{heldout}/chosen-config.json --quiet",
            ),
        )
        for seed in seeds
    )
