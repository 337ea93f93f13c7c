"""The kernel's result tables (thesis Tables 4.3, 4.4 and 4.5), each a set of resumable training runs.

* ``variants`` (Table 4.4): every variant trained with each seed; mean ± std of the best validation L1.
  base, ind and dyn1 train on the base dataset, ext on the ext dataset, dyn2 on the dyn2 dataset
  (collected with a reset after each target, ``krl collect --mode dyn2``).
* ``data-size`` (Table 4.5): kernel-base trained on 10 … 400 of the training targets, one fixed
  validation set, each size with each seed.
* ``stance`` (Table 4.3): kernel-base with the thesis's manually tuned settings on datasets collected
  at stance durations 0.3, 0.25 and 0.2 s.

Rows of ``data-size`` and ``stance`` also count how many of their kernels walk (reach every one of a
few random waypoints without falling, for each of two waypoint seeds): the thesis's "functional".

Each run trains in ``RUNS/<study>/<run>`` with :func:`krl.kernel.train.train_kernel`, so an interrupted
study resumes where it stopped and finished runs are not redone. The tables (Markdown, CSV, JSON, the
thesis's numbers beside ours and the command that made them) go to ``OUT/<study>.*``.
"""

from __future__ import annotations

import csv
import io
import json
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from krl.kernel.model import NetworkConfig
from krl.kernel.train import TrainConfig, train_kernel
from krl.util.output import write_atomic

STUDIES: tuple[str, ...] = ("variants", "data-size", "stance")

THESIS_VARIANTS = {  # Table 4.4: mean, std of the validation loss
    "base": (6.2e-4, 6.9e-6),
    "ind": (7.2e-4, 4.9e-6),
    "ext": (7.1e-4, 1e-5),
    "dyn1": (3.1e-4, 6.1e-6),
    "dyn2": (2.5e-4, 5.6e-6),
}
THESIS_DATA_SIZE = {10: 1e-3, 25: 9.1e-4, 50: 8.4e-4, 100: 7.7e-4, 200: 6.7e-4, 400: 6.2e-4}  # Table 4.5
THESIS_STANCE = {0.3: (5.9e-3, False), 0.25: (2e-3, False), 0.2: (1.6e-3, True)}  # Table 4.3

TABLE_4_3_SETTINGS = dict(
    network=NetworkConfig(hidden=(256, 256, 256), activation="tanh", dropout=0.2, batch_norm=True),
    learning_rate=0.001,
    lr_decay=0.8,
    batch_size=100,
)
"""The manually tuned hyper-parameters under Table 4.3."""


@dataclass(frozen=True)
class StudyRun:
    """One training run of a study."""

    name: str
    data: str
    config: TrainConfig
    row: dict[str, Any]
    """The table row this run belongs to (e.g. {"variant": "ext"})."""


VARIANT_DATA: dict[str, str] = {"base": "base", "ind": "base", "dyn1": "base", "ext": "ext", "dyn2": "dyn2"}
"""The dataset each variant of Table 4.4 trains on."""


def plan_variants(
    data: dict[str, str],
    seeds: Sequence[int],
    base: TrainConfig,
    variants: Sequence[str] = tuple(VARIANT_DATA),
) -> list[StudyRun]:
    """Runs of Table 4.4 for ``variants``. ``data`` maps ``base``/``ext``/``dyn2`` to dataset
    directories; a variant whose dataset is not given is left out."""
    runs = []
    for variant, source in VARIANT_DATA.items():
        if source not in data or variant not in variants:
            continue
        for seed in seeds:
            config = replace(base, variant=variant, seed=seed)
            runs.append(StudyRun(f"{variant}-seed{seed}", data[source], config, {"variant": variant}))
    return runs


def plan_data_size(
    data: str, sizes: Sequence[int], seeds: Sequence[int], base: TrainConfig
) -> list[StudyRun]:
    """Runs of Table 4.5 (the validation split is ``base.split_seed`` for all of them)."""
    return [
        StudyRun(
            f"targets{size}-seed{seed}",
            data,
            replace(base, variant="base", seed=seed, max_train_targets=size),
            {"targets": size},
        )
        for size in sizes
        for seed in seeds
    ]


def plan_stance(data: dict[float, str], seeds: Sequence[int], base: TrainConfig) -> list[StudyRun]:
    """Runs of Table 4.3: one dataset per stance duration [s], Table 4.3's hyper-parameters."""
    return [
        StudyRun(
            f"stance{stance:g}-seed{seed}",
            path,
            replace(base, variant="base", seed=seed, **TABLE_4_3_SETTINGS),
            {"stance_duration": stance},
        )
        for stance, path in sorted(data.items(), reverse=True)
        for seed in seeds
    ]


def execute(runs: Sequence[StudyRun], runs_dir: Path, progress: bool = True) -> list[dict[str, Any]]:
    """Train every run (resuming unfinished ones); return one record per run."""
    from krl.data.reader import load_dataset

    datasets: dict[str, Any] = {}
    records = []
    for run in runs:
        if run.data not in datasets:
            datasets[run.data] = load_dataset(run.data)
        result = train_kernel(
            datasets[run.data], run.config, runs_dir / run.name, progress=progress, tensorboard=False
        )
        records.append(_record(run, result.kernel_path, result.kernel.metadata))
    return records


def finished(runs: Sequence[StudyRun], runs_dir: Path) -> tuple[list[dict[str, Any]], list[str]]:
    """Records of the runs that have finished training (a kernel written by a run with these settings on
    this data), without training anything; and the names of the others."""
    from krl.data.reader import read_manifest
    from krl.kernel.model import load_kernel
    from krl.kernel.train import CONFIG_NAME, KERNEL_NAME, run_hash

    hashes: dict[str, str] = {}
    records, missing = [], []
    for run in runs:
        if run.data not in hashes:
            hashes[run.data] = read_manifest(Path(run.data))["content_hash"]
        directory = runs_dir / run.name
        try:
            saved = json.loads((directory / CONFIG_NAME).read_text())
        except (OSError, ValueError):
            saved = {}
        kernel_path = directory / KERNEL_NAME
        if saved.get("run_hash") != run_hash(run.config, hashes[run.data]) or not kernel_path.exists():
            missing.append(run.name)
            continue
        records.append(_record(run, kernel_path, load_kernel(kernel_path).metadata))
    return records, missing


def _record(run: StudyRun, kernel_path: Path, metadata: dict[str, Any]) -> dict[str, Any]:
    return {
        **run.row,
        "run": run.name,
        "seed": run.config.seed,
        "val_l1": metadata["val_l1"],
        "epochs_run": metadata["epochs_run"],
        "train_seconds": metadata["train_seconds"],
        "kernel": str(kernel_path),
    }


WALK_SEEDS: tuple[int, ...] = (1, 2)
"""Seeds of the random waypoints on which a study's kernels are asked to walk."""


def functional(kernel_path: str, seeds: Sequence[int] = WALK_SEEDS, targets: int = 5) -> bool:
    """Whether the kernel walks: it reaches all ``targets`` random waypoints without falling, every seed."""
    import numpy as np

    from krl.kernel.controller import KernelController
    from krl.kernel.model import load_kernel
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim
    from krl.task import random_targets
    from krl.task.runner import Runner

    kernel = load_kernel(kernel_path)
    for seed in seeds:
        runner = Runner(A1Sim(build_model("flat")), KernelController(kernel))
        result = runner.walk_to(random_targets(np.random.default_rng(seed), targets))
        if result.fell or result.targets_reached < targets:
            return False
    return True


def add_walking(
    rows: list[dict[str, Any]], records: Sequence[dict[str, Any]], key: str, targets: int
) -> list[dict[str, Any]]:
    """Add ``walking``: how many of a row's kernels (one per seed) are :func:`functional` with
    ``targets`` waypoints (the thesis's "functional locomotion" column, counted over seeds)."""
    for row in rows:
        kernels = [r["kernel"] for r in records if r[key] == row[key]]
        row["walking"] = sum(functional(path, targets=targets) for path in kernels)
    return rows


def summarise(records: Sequence[dict[str, Any]], key: str) -> list[dict[str, Any]]:
    """Mean and standard deviation of ``val_l1`` per value of ``key`` (in first-seen order)."""
    groups: dict[Any, list[dict[str, Any]]] = {}
    for record in records:
        groups.setdefault(record[key], []).append(record)
    rows = []
    for value, group in groups.items():
        losses = [r["val_l1"] for r in group]
        rows.append(
            {
                key: value,
                "val_l1_mean": statistics.fmean(losses),
                "val_l1_std": statistics.stdev(losses) if len(losses) > 1 else 0.0,
                "runs": len(group),
                "epochs": max(r["epochs_run"] for r in group),
                "train_seconds_mean": statistics.fmean(r["train_seconds"] for r in group),
            }
        )
    return rows


def write_table(
    study: str,
    rows: list[dict[str, Any]],
    records: list[dict[str, Any]],
    out: Path,
    command: str,
    unfinished: Sequence[str] = (),
) -> Path:
    """Write ``OUT/<study>.md``, ``.csv`` and ``.json``; returns the Markdown path. ``unfinished``: the
    planned runs left out because they had not finished (``--finished-only``)."""
    columns = list(rows[0])
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns)
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / f"{study}.csv", buffer.getvalue())
    write_atomic(
        out / f"{study}.json",
        json.dumps(
            {"rows": rows, "runs": records, "unfinished": list(unfinished), "command": command}, indent=2
        ),
    )
    header = "| " + " | ".join(columns) + " |\n| " + " | ".join("---" for _ in columns) + " |\n"
    lines = ["| " + " | ".join(_format(row[c]) for c in columns) + " |" for row in rows]
    text = f"# Kernel study: {study}\n\nMade by:\n\n    {command}\n\n" + header + "\n".join(lines) + "\n"
    if unfinished:
        text += f"\nNot finished when this table was written: {', '.join(unfinished)}.\n"
    path = out / f"{study}.md"
    write_atomic(path, text)
    return path


def _format(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1e-2 or abs(value) >= 1e3 else f"{value:.3f}"
    return str(value)


def thesis_columns(study: str, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Add the thesis's figures beside ours."""
    for row in rows:
        if study == "variants":
            mean, std = THESIS_VARIANTS[row["variant"]]
            row["thesis_mean"], row["thesis_std"] = mean, std
        elif study == "data-size":
            row["thesis_mean"] = THESIS_DATA_SIZE.get(row["targets"])
        elif study == "stance":
            mean, walks = THESIS_STANCE.get(row["stance_duration"], (None, None))
            row["thesis_mean"], row["thesis_functional"] = mean, walks
    return rows


@dataclass(frozen=True)
class StudyRequest:
    """One ``krl kernel study``.

    Attributes:
        study: one of :data:`STUDIES`.
        seeds: training seeds; every planned setting trains once per seed.
        train: the training settings every run starts from (epochs, threads).
        runs: where the training runs go (``runs/<study>/<run>``, resumable).
        out: where the tables go (``out/<study>.*``).
        command: the command line written into the tables.
        datasets: ``variants``: the dataset per kind (``base``, ``ext``, ``dyn2``; at least one);
            ``data-size``: ``{"base": path}``.
        variants: ``variants``: which of :data:`VARIANT_DATA` to train.
        sizes: ``data-size``: the training target counts.
        stance_data: ``stance``: a dataset per stance duration [s].
        finished_only: train nothing; table the finished runs and list the others.
        walk_targets: ``data-size``, ``stance``: count the kernels that walk to this many waypoints (0: skip).
        progress: show the training's progress bars.
    """

    study: str
    seeds: tuple[int, ...]
    train: TrainConfig
    runs: Path
    out: Path
    command: str
    datasets: dict[str, str] = field(default_factory=dict)
    variants: tuple[str, ...] = tuple(VARIANT_DATA)
    sizes: tuple[int, ...] = tuple(THESIS_DATA_SIZE)
    stance_data: dict[float, str] = field(default_factory=dict)
    finished_only: bool = False
    walk_targets: int = 5
    progress: bool = True


def plan(request: StudyRequest) -> tuple[list[StudyRun], str]:
    """The study's runs and the row key that groups them.

    Raises:
        ValueError: the study lacks a dataset it needs, or names an unknown variant (one line).
    """
    if request.study == "variants":
        if not request.datasets:
            raise ValueError("variants needs at least one of --data-base, --data-ext, --data-dyn2")
        unknown = sorted(set(request.variants) - set(VARIANT_DATA))
        if unknown or not request.variants:
            raise ValueError(
                f"--variants: unknown variant(s) {', '.join(unknown) or '(none given)'}; "
                f"known: {', '.join(VARIANT_DATA)}"
            )
        return plan_variants(request.datasets, request.seeds, request.train, request.variants), "variant"
    if request.study == "data-size":
        if "base" not in request.datasets:
            raise ValueError("data-size needs --data (a base dataset)")
        base = request.datasets["base"]
        return plan_data_size(base, request.sizes, request.seeds, request.train), "targets"
    if not request.stance_data:
        raise ValueError("stance needs --data-stance TAU=DIR (one per stance duration)")
    return plan_stance(request.stance_data, request.seeds, request.train), "stance_duration"


def run_study(request: StudyRequest) -> dict[str, Any]:
    """Train (or, ``finished_only``, gather) the study's runs and write its tables. Returns ``study``,
    ``table`` (the Markdown path), ``rows`` and ``unfinished`` (the runs left out).

    Raises:
        ValueError: from :func:`plan`, or ``finished_only`` and no run has finished.
    """
    runs, key = plan(request)
    runs_dir = request.runs / request.study
    if request.finished_only:
        records, missing = finished(runs, runs_dir)
        if not records:
            raise ValueError(f"no run of this study has finished in {runs_dir}")
    else:
        records, missing = execute(runs, runs_dir, progress=request.progress), []
    rows = thesis_columns(request.study, summarise(records, key))
    if request.study != "variants" and request.walk_targets > 0:
        add_walking(rows, records, key, request.walk_targets)
    path = write_table(request.study, rows, records, request.out, request.command, missing)
    return {"study": request.study, "table": str(path), "rows": rows, "unfinished": missing}
