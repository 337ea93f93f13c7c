"""Where ``krl evaluate`` keeps its records: a Parquet dataset per controller, in its results folder.

An evaluation's folder ``OUT`` holds one folder per controller label::

    OUT/<label>/part-00000.parquet   runs, a row each (:data:`COLUMNS`), written atomically per batch
    OUT/<label>/commands.txt         the krl evaluate commands that wrote them
    OUT/<label>/<group>/<name>.json  the layout before Parquet (one file per run), still read

A run's *key* is its path under the label without ``.json``: ``<group>/<name>``, the group being a course
name, ``push`` or ``friction`` (``stairs/start0-seed150``, ``push/m400-a12``). A part's ``record`` column
holds each run's record as JSON, as the older layout's file held it (identity, ``run``, ``metrics``, and in
records made since 2026-12-07 the ``machine`` that computed them, :func:`krl.util.machine.machine`);
the other columns repeat a few of its fields for queries (``pyarrow.dataset``, pandas, DuckDB) and are not
read back. The schema metadata names the label and the format and holds the SHA-256 of the records, so a
damaged part, a part of another controller or a half-written one is refused in one line rather than mixed
into results, as is a record without a field its readers need (:mod:`krl.eval.record_schema`); a temporary
file that an interrupted write left behind is removed (its runs run again).

:func:`read_runs` reads both layouts; :class:`RecordWriter` buffers records and writes parts;
:func:`consolidate` merges a label's parts (and, converting an old folder, its JSON files) into one part,
reading it back before anything is removed.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import io
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from krl.eval.record_schema import record_problem
from krl.util.output import write_atomic

PART_FORMAT = 1
"""Version of the part files' layout (:data:`COLUMNS` and metadata)."""

PART_GLOB = "part-*.parquet"
PART_NAME = "part-{index:05d}.parquet"
METADATA_KEY = b"krl.evaluation"
"""Schema metadata key of a part: JSON ``{"format", "label", "runs", "records_sha256"}``."""

COLUMNS: dict[str, str] = {
    "controller": "the controller's label (string)",
    "run": "the run's key, <group>/<name> (string)",
    "group": "a course name, push or friction (string)",
    "seed": "the training seed of a seed group's policy, null for one policy (int64)",
    "success": "every waypoint reached (bool)",
    "fell": "the robot fell (bool)",
    "targets_reached": "waypoints reached (int64)",
    "reward_per_step": "the final reward summed over the run over its control steps (float64)",
    "record": "the whole record as JSON: identity, run and metrics (string); the source of truth",
}
"""A part's columns and what each holds."""

FLUSH_RECORDS = 256
"""A writer writes a part once this many records wait..."""
FLUSH_SECONDS = 60.0
"""...or once the oldest waiting record has waited this long [s]: a killed evaluation loses at most that."""


class EvaluationError(ValueError):
    """Stored results that cannot be used (corrupt, or made by something else); one line. A ValueError:
    whatever refuses bad input in one line refuses these too (``krl analyze``'s readers)."""


def run_order(run: str) -> tuple[str, str]:
    """The order records are listed in: by group, then by the older layout's file name."""
    group, _, name = run.partition("/")
    return group, name + ".json"


@dataclass(frozen=True)
class StoredRun:
    """A stored record and where it is (a part file or a JSON file)."""

    record: dict[str, Any]
    source: Path


def _record_text(record: dict[str, Any]) -> str:
    return json.dumps(record)


def _sha256(texts: Sequence[str]) -> str:
    return hashlib.sha256("\n".join(texts).encode()).hexdigest()


def _table(label: str, records: Sequence[dict[str, Any]]):
    """The ``pyarrow.Table`` of a part holding ``records`` (in the order given) of controller ``label``."""
    import pyarrow as pa

    texts = [_record_text(r) for r in records]
    metrics = [r["metrics"] for r in records]
    meta = {"format": PART_FORMAT, "label": label, "runs": len(records), "records_sha256": _sha256(texts)}
    columns = {
        "controller": pa.array([label] * len(records), pa.string()),
        "run": pa.array([r["run"] for r in records], pa.string()),
        "group": pa.array([r["run"].partition("/")[0] for r in records], pa.string()),
        "seed": pa.array([r.get("seed") for r in records], pa.int64()),
        "success": pa.array([m.get("success") for m in metrics], pa.bool_()),
        "fell": pa.array([m.get("fell") for m in metrics], pa.bool_()),
        "targets_reached": pa.array([m.get("targets_reached") for m in metrics], pa.int64()),
        "reward_per_step": pa.array([m.get("reward_per_step") for m in metrics], pa.float64()),
        "record": pa.array(texts, pa.string()),
    }
    return pa.table(columns).replace_schema_metadata({METADATA_KEY: json.dumps(meta).encode()})


def _run_order_of(record: dict[str, Any]) -> tuple[str, str]:
    return run_order(record["run"])


def _texts(records: Sequence[dict[str, Any]]) -> list[str]:
    """The JSON texts of ``records`` in :func:`run_order`: what two lists of records must share to be one
    (NaN equal to NaN, unlike the records compared as dicts)."""
    return [_record_text(record) for record in sorted(records, key=_run_order_of)]


def _same_table(table, expected) -> bool:
    """Whether two ``pyarrow.Table`` hold the same columns and values, NaN equal to NaN (a record's JSON
    text may hold NaN, which ``Table.equals`` finds unequal to itself)."""
    if table.equals(expected):
        return True
    same_schema = table.schema.equals(expected.schema)
    return same_schema and json.dumps(table.to_pydict()) == json.dumps(expected.to_pydict())


def part_bytes(label: str, records: Sequence[dict[str, Any]]) -> bytes:
    """The Parquet bytes of a part holding ``records`` of controller ``label``, in :func:`run_order`."""
    import pyarrow.parquet as pq

    buffer = io.BytesIO()
    table = _table(label, sorted(records, key=_run_order_of))
    pq.write_table(table, buffer, compression="zstd")
    return buffer.getvalue()


def read_part(path: Path, label: str) -> list[dict[str, Any]]:
    """The records of one part of controller ``label``; :class:`EvaluationError` (one line) for a part that
    is damaged (unreadable, or any column or metadata field not what its records make: every byte that
    the records depend on is checked), of another format or of another controller, or that holds a record
    without a field its readers need (:func:`krl.eval.record_schema.record_problem`)."""
    return _part_records(path, path, label)


def _part_records(source: Path | io.BytesIO, path: Path, label: str) -> list[dict[str, Any]]:
    """:func:`read_part` of the Parquet file or bytes ``source``, named ``path`` in messages."""
    import pyarrow.parquet as pq

    def refuse(reason: str) -> EvaluationError:
        return EvaluationError(f"{path}: damaged record part ({reason}); delete it to redo its runs")

    try:
        table = pq.read_table(source)
        meta = json.loads((table.schema.metadata or {})[METADATA_KEY])
        texts = table.column("record").to_pylist()
        digest = _sha256(texts)
        records = [json.loads(text) for text in texts]
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:  # ArrowInvalid: ValueError
        raise refuse(" ".join(str(error).split())[:160]) from None
    if not isinstance(meta, dict) or set(meta) != {"format", "label", "runs", "records_sha256"}:
        raise refuse(f"metadata fields {sorted(meta) if isinstance(meta, dict) else 'missing'}")
    if len(texts) != meta["runs"] or digest != meta["records_sha256"]:
        raise refuse("its records do not match their SHA-256")
    for record in records:
        problem = record_problem(record)
        if problem is not None:
            run = record.get("run") if isinstance(record, dict) else None
            where = f" (run {run})" if isinstance(run, str) else ""
            raise EvaluationError(f"{path}{where}: {problem}; delete it to redo its runs")
    try:
        consistent = _same_table(table, _table(meta["label"], records))
    except (ValueError, TypeError, OverflowError) as error:  # ArrowInvalid, ArrowTypeError
        raise refuse(" ".join(str(error).split())[:160]) from None
    if not consistent or {record["controller"]["label"] for record in records} - {meta["label"]}:
        raise refuse("its columns or metadata do not match its records")
    if meta["format"] != PART_FORMAT:
        raise EvaluationError(
            f"{path}: record part of format {meta['format']!r}, this krl reads {PART_FORMAT}"
        )
    if meta["label"] != label:
        raise EvaluationError(
            f"{path} holds records of controller {meta['label']!r}, not {label!r}; delete it to redo its runs"
        )
    return records


def read_json_record(path: Path, label: str) -> dict[str, Any]:
    """One record of controller ``label`` in the older layout (a JSON file per run, ``run`` set from its
    path where absent); :class:`EvaluationError` (one line) for a file that is not JSON, that holds a record
    without a field its readers need (:func:`krl.eval.record_schema.record_problem`), or a record of
    another run or controller."""

    def refuse(reason: str) -> EvaluationError:
        return EvaluationError(f"{path}: {reason}; delete it to redo that run")

    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise refuse(f"corrupt result file ({' '.join(str(error).split())[:160]})") from None
    if isinstance(record, dict):
        record.setdefault("run", json_run(path))
    problem = record_problem(record)
    if problem is not None:
        raise refuse(problem)
    if record["run"] != json_run(path):
        raise refuse(f"it holds the record of run {record['run']!r}, not {json_run(path)!r}")
    if record["controller"]["label"] != label:
        raise refuse(f"it holds a record of controller {record['controller']['label']!r}, not {label!r}")
    return record


def json_files(folder: Path) -> list[Path]:
    """A label folder's records in the older layout, ``<group>/<name>.json``."""
    return sorted(path for path in folder.glob("*/*.json") if path.is_file())


def json_run(path: Path) -> str:
    """The run key of an older-layout record file ``OUT/<label>/<group>/<name>.json``: ``<group>/<name>``."""
    return f"{path.parent.name}/{path.stem}"


def part_files(folder: Path) -> list[Path]:
    return sorted(folder.glob(PART_GLOB))


WALL_TIME = "wall_seconds"
"""The metric that differs between two repeats of one run (wall-clock time [s]): every other is fixed by the
run's key (on one machine's arithmetic)."""

MACHINE = "machine"
"""The field of a record that names the machine that computed it: not part of its result."""


VOLATILE: tuple[str, ...] = (f"metrics.{WALL_TIME}", MACHINE)
"""The dotted fields of a record that differ between two repeats of one run (its wall time, its machine),
each with every field under it (``machine.cpu``)."""


def result_of(record: dict[str, Any], volatile: Sequence[str] = VOLATILE) -> dict[str, Any]:
    """``record`` without its ``volatile`` fields: what two repeats of one run must agree on."""

    def kept(value: Any, path: str) -> Any:
        if not isinstance(value, dict):
            return value
        return {k: kept(v, f"{path}{k}.") for k, v in value.items() if f"{path}{k}" not in volatile}

    return kept(record, "")


def read_runs(folder: Path, label: str | None = None) -> dict[str, StoredRun]:
    """Every stored record of one controller (``folder`` = ``OUT/<label>``), by run key, in
    :func:`run_order`: its JSON files' and its parts', oldest first (JSON files, then parts by number).
    A run stored twice is one run, the newer record kept, where the two are equal but for the wall time
    and the machine (:func:`result_of`: a merge cut short; a run redone for its missing video: every run
    is seeded by its key); with any other difference, an :class:`EvaluationError`."""
    label = folder.name if label is None else label
    found: dict[str, StoredRun] = {}

    def add(run: Any, record: dict[str, Any], source: Path) -> None:
        if not isinstance(run, str):
            raise EvaluationError(f"{source}: a record without its run key; delete it to redo that run")
        other = found.get(run)
        if other is not None and result_of(other.record) != result_of(record):
            raise EvaluationError(
                f"run {label} {run} is stored twice with different records ({other.source}, {source}); "
                "delete the one to drop"
            )
        found[run] = StoredRun(record, source)

    for path in json_files(folder):
        add(json_run(path), read_json_record(path, label), path)
    for path in part_files(folder):
        for record in read_part(path, label):
            add(record.get("run"), record, path)
    return dict(sorted(found.items(), key=lambda item: run_order(item[0])))


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``folder`` (``flock`` on the folder itself, released when the process
    dies): one writer at a time picks part names, removes leftovers and merges, so two evaluations of one
    controller into one folder cannot overwrite or drop each other's parts. Not re-entrant."""
    folder.mkdir(parents=True, exist_ok=True)
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)


def remove_leftovers(folder: Path) -> list[Path]:
    """Remove the temporary files that an interrupted part write left in ``folder``; returns them."""
    if not folder.is_dir():
        return []
    with _locked(folder):
        leftovers = sorted(folder.glob(".part-*.parquet.*.tmp"))
        for path in leftovers:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
    return leftovers


def _next_part(folder: Path, label: str, records: Sequence[dict[str, Any]]) -> Path:
    """:func:`write_part` for a caller holding the folder's lock. The part is read back from its bytes before
    they are written: a part the readers would refuse is never written (an :class:`EvaluationError` naming
    the folder and why, nothing written)."""
    taken = [int(path.stem.removeprefix("part-")) for path in part_files(folder) if path.stem[5:].isdigit()]
    path = folder / PART_NAME.format(index=max(taken, default=-1) + 1)
    for record in records:
        problem = record_problem(record)
        if problem is not None:
            raise EvaluationError(f"{folder}: run {record.get('run')}: {problem}; nothing written")
    try:
        data = part_bytes(label, records)
        back = _part_records(io.BytesIO(data), path, label)
    except (ValueError, TypeError, OverflowError) as error:  # ArrowInvalid, EvaluationError: ValueError
        raise EvaluationError(
            f"{folder}: no readable part of these records ({error}); nothing written"
        ) from None
    if _texts(back) != _texts(records):
        raise EvaluationError(f"{folder}: records that do not read back as written; nothing written")
    write_atomic(path, data, durable=True)
    return path


def write_part(folder: Path, label: str, records: Sequence[dict[str, Any]]) -> Path:
    """Write ``records`` as the next part of ``folder`` (atomically and durably); returns its path."""
    with _locked(folder):
        return _next_part(folder, label, records)


def consolidate(folder: Path, label: str | None = None, absorb_json: bool = False) -> dict[str, int]:
    """Merge a controller's parts (with ``absorb_json``, its JSON records too; without, only the JSON files
    that a part holds a newer record of go) into one part, read back and compared before the old parts and
    files are removed, so an interruption loses nothing (a rerun finishes the job). Returns ``{"runs",
    "parts_merged", "json_removed"}``; nothing is written where there is nothing to merge."""
    label = folder.name if label is None else label
    with _locked(folder):
        return _consolidate(folder, label, absorb_json)


def _consolidate(folder: Path, label: str, absorb_json: bool) -> dict[str, int]:
    runs = read_runs(folder, label)
    files = json_files(folder)
    if not absorb_json:  # only those whose run a part holds a newer record of
        files = [path for path in files if runs[json_run(path)].source != path]
    parts = part_files(folder)
    if not files and len(parts) <= 1:
        return {"runs": len(runs), "parts_merged": 0, "json_removed": 0}
    kept = [stored.record for stored in runs.values() if absorb_json or stored.source.suffix == ".parquet"]
    merged = _next_part(folder, label, kept)
    if _texts(read_part(merged, label)) != _texts(kept):
        raise EvaluationError(f"{merged}: the merged part does not read back as written; nothing was removed")
    for path in [*parts, *files]:
        path.unlink()
    for group in {path.parent for path in files}:
        with contextlib.suppress(OSError):  # a folder that still holds something the user put there
            group.rmdir()
    if merged.name != PART_NAME.format(index=0) and not (folder / PART_NAME.format(index=0)).exists():
        merged = merged.rename(folder / PART_NAME.format(index=0))
    return {"runs": len(runs), "parts_merged": len(parts), "json_removed": len(files)}


@dataclass
class RecordWriter:
    """Buffers finished records and writes them as parts of ``OUT/<label>/``: once
    :data:`FLUSH_RECORDS` wait or the oldest has waited :data:`FLUSH_SECONDS`, and on :meth:`flush`."""

    out: Path
    flush_records: int = FLUSH_RECORDS
    flush_seconds: float = FLUSH_SECONDS
    waiting: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    since: float | None = None
    written: set[str] = field(default_factory=set)
    """Labels this writer wrote a part for."""

    def add(self, label: str, record: dict[str, Any]) -> None:
        self.waiting.setdefault(label, []).append(record)
        self.since = time.monotonic() if self.since is None else self.since
        count = sum(len(records) for records in self.waiting.values())
        if count >= self.flush_records or time.monotonic() - self.since >= self.flush_seconds:
            self.flush()

    def flush(self) -> None:
        """Write every waiting record, one part per label."""
        for label, records in self.waiting.items():
            write_part(self.out / label, label, records)
            self.written.add(label)
        self.waiting.clear()
        self.since = None

    def consolidate(self) -> None:
        """Merge each written label's parts into one (:func:`consolidate`)."""
        for label in sorted(self.written):
            consolidate(self.out / label, label)


def labels_in(results: Path) -> list[str]:
    """The controller labels of a results folder: its subfolders."""
    return sorted(path.name for path in results.iterdir() if path.is_dir())


def controller_labels(results: Path, labels: Iterable[str] | None = None) -> list[str]:
    """``labels`` (default: every controller of ``results``, :func:`labels_in`), each checked to have a
    folder there; :class:`EvaluationError` (one line) for a missing results folder or controller."""
    if not results.is_dir():
        raise EvaluationError(f"no results folder {str(results)!r}")
    labels = list(labels or labels_in(results))
    for label in labels:
        if not (results / label).is_dir():
            raise EvaluationError(f"no results for controller {label!r} in {str(results)!r}")
    return labels


def convert(
    results: Path, labels: Iterable[str] | None = None, on_done: Callable[[str], None] | None = None
) -> dict[str, dict[str, int]]:
    """Rewrite an evaluation folder of the older layout as parts, one per controller (:func:`consolidate`
    absorbing the JSON files); returns what each label held and what was merged and removed.
    ``on_done(label)`` is called as each controller is done."""
    converted = {}
    for label in controller_labels(results, labels):
        converted[label] = consolidate(results / label, label, absorb_json=True)
        if on_done is not None:
            on_done(label)
    return converted
