"""A dataset directory on disk (``docs/data.md``): one Parquet part file per episode plus ``manifest.json``,
each written atomically and durably (:func:`krl.util.output.write_atomic`); a lock file against a second
writer; and opening a directory to collect into: creating its manifest, or checking an existing one against
the collection's settings and plan, and dropping what an interrupted write left behind.

:mod:`krl.data.collect` records the rows; :mod:`krl.data.schema` defines them and :mod:`krl.data.reader`
reads datasets back.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import io
import json
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from krl.data.reader import read_manifest
from krl.data.schema import (
    FORMAT_NAME,
    MANIFEST_NAME,
    PART_PATTERN,
    SCHEMA_VERSION,
    DatasetError,
    columns_description,
    columns_to_table,
    content_hash,
    dataset_hash,
)
from krl.util.hashing import file_sha256
from krl.util.output import write_atomic

LOCK_NAME: str = ".lock"
"""Lock file of a dataset directory while a collection writes it (holds the writer's pid)."""

_DICTIONARY_COLUMNS: tuple[str, ...] = (
    "step_height",
    "ride_height",
    "stance_duration",
    "episode",
    "target_index",
    "target_xy",
)
"""Columns that are constant per target or episode, where Parquet's dictionary encoding pays off."""


class SettingsMismatchError(ValueError):
    """Resuming a dataset with settings different from those it was started with."""


class EpisodePlan(Protocol):
    """How a collection splits its targets into episodes (:class:`krl.data.collect.CollectConfig`)."""

    targets: int
    """Total number of targets."""
    targets_per_episode: int
    """Targets per full episode."""

    @property
    def num_episodes(self) -> int:
        """Number of episodes."""

    def episode_targets(self, episode: int) -> int:
        """Number of targets of ``episode``."""


def write_manifest(directory: Path, manifest: dict[str, Any]) -> None:
    """Sort the parts by episode, recompute the totals and the dataset's content hash, and write
    ``manifest.json`` (atomically and durably)."""
    parts = sorted(manifest["parts"], key=lambda p: p["episode"])
    manifest["parts"] = parts
    manifest["totals"] = {
        key: int(sum(p[key] for p in parts))
        for key in ("rows", "targets", "targets_reached", "falls", "timeouts", "unstable")
    }
    manifest["totals"]["episodes"] = len(parts)
    manifest["content_hash"] = dataset_hash(
        manifest["metadata"]["settings"], (p["content_hash"] for p in parts)
    )
    manifest["updated"] = _now()
    text = json.dumps(manifest, indent=1, sort_keys=False, allow_nan=False) + "\n"
    write_atomic(directory / MANIFEST_NAME, text, durable=True)


def write_part(
    directory: Path, columns: Mapping[str, np.ndarray], counts: Mapping[str, int], metadata: Mapping[str, Any]
) -> dict[str, Any]:
    """Write one episode's part file (atomically and durably); returns its manifest entry.

    Args:
        directory: the dataset directory.
        columns: the episode's rows by field name (:data:`krl.data.schema.FIELDS`).
        counts: ``episode``, ``rows``, ``targets``, ``targets_reached``, ``falls``, ``timeouts``,
            ``unstable`` (an :class:`krl.data.collect.EpisodeStats` as a dict).
        metadata: the dataset's metadata (recorded in the file, without its column list).
    """
    import pyarrow.parquet as pq

    from krl import __version__

    name = PART_PATTERN.format(episode=counts["episode"])
    part = {"file": name}
    for key in ("episode", "rows", "targets", "targets_reached", "falls", "timeouts", "unstable"):
        part[key] = counts[key]
    part["content_hash"] = content_hash(columns)
    file_meta = {
        "dataset": {key: value for key, value in metadata.items() if key != "columns"},
        "part": {**part, "krl_version": __version__, "created": _now()},
    }
    table = columns_to_table(columns, file_meta)
    # Dictionary encoding only where values repeat (it inflates noisy float columns by ~50 %).
    buffer = io.BytesIO()
    pq.write_table(table, buffer, compression="zstd", use_dictionary=list(_DICTIONARY_COLUMNS))
    data = buffer.getvalue()
    write_atomic(directory / name, data, durable=True)
    part["sha256"] = hashlib.sha256(data).hexdigest()
    return part


def _now() -> str:
    """The time now (UTC, ISO 8601, whole seconds)."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


@contextlib.contextmanager
def directory_lock(directory: Path) -> Iterator[None]:
    """Refuse a second writer on the same directory (a stale lock of a dead process is taken over)."""
    path = directory / LOCK_NAME
    for _ in range(2):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                pid = int(path.read_text().strip() or "0")
            except (OSError, ValueError):
                pid = 0
            alive = False
            if pid > 0 and pid != os.getpid():
                try:
                    os.kill(pid, 0)
                    alive = True
                except ProcessLookupError:
                    alive = False
                except PermissionError:
                    alive = True
            if alive:
                raise ValueError(f"{directory}: another collection (pid {pid}) is writing it") from None
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            continue
        with os.fdopen(fd, "w") as handle:
            handle.write(f"{os.getpid()}\n")
        break
    else:
        raise ValueError(f"{directory}: could not take the lock {path}")
    try:
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts as one dict with dotted keys."""
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        for key, item in value.items():
            out.update(_flatten(item, f"{prefix}{key}."))
        return out
    return {prefix[:-1]: value}


def settings_difference(old: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    """``"key old != new"`` for every (dotted, nested) key whose value differs; empty when equal."""
    a, b = _flatten(dict(old)), _flatten(dict(new))
    missing = "(unset)"
    keys = sorted(set(a) | set(b))
    return [
        f"{k} {a.get(k, missing)!r} != {b.get(k, missing)!r}"
        for k in keys
        if a.get(k, missing) != b.get(k, missing)
    ]


def _is_own_file(name: str) -> bool:
    """A temporary file of :func:`krl.util.output.write_atomic` writing a part or the manifest."""
    return name.endswith(".tmp") and name.startswith((".part-", f".{MANIFEST_NAME}."))


def open_dataset(directory: Path, config: EpisodePlan, settings: dict[str, Any]) -> dict[str, Any]:
    """Create the manifest of a new dataset, or check and repair that of an existing one; returns it.

    Leftover temporary files are removed; an existing dataset must have the same ``settings`` and the
    same targets per episode, and each listed part must match its sha256 (a missing part is dropped from
    the manifest, to be collected again).

    Raises:
        SettingsMismatchError: other settings or another split of the targets than the dataset's.
        DatasetError: a listed part that is corrupt or modified.
        ValueError: the directory holds something that is not a krl dataset.
    """
    from krl import __version__

    manifest_path = directory / MANIFEST_NAME
    for entry in directory.iterdir():  # leftovers of an interrupted write
        if _is_own_file(entry.name):
            with contextlib.suppress(FileNotFoundError):
                entry.unlink()
    if not manifest_path.exists():
        others = [e.name for e in directory.iterdir() if e.name != LOCK_NAME]
        if others:
            raise ValueError(
                f"{directory} exists and is not a krl dataset (no {MANIFEST_NAME}); choose a new --out"
            )
        metadata = {
            "schema_version": SCHEMA_VERSION,
            "krl_version": __version__,
            "created": _now(),
            "targets_requested": int(config.targets),
            "settings": settings,
            "columns": columns_description(),
        }
        manifest = {
            "format": FORMAT_NAME,
            "schema_version": SCHEMA_VERSION,
            "metadata": metadata,
            "parts": [],
        }
        write_manifest(directory, manifest)
        return manifest
    manifest = read_manifest(directory)
    difference = settings_difference(manifest["metadata"]["settings"], settings)
    if difference:
        raise SettingsMismatchError(
            f"{manifest_path}: settings differ from the existing dataset ({'; '.join(difference)}); "
            "re-run with the original options or choose a new --out"
        )
    kept = []
    for part in manifest["parts"]:
        episode, path = int(part["episode"]), directory / part["file"]
        if episode >= config.num_episodes or part["targets"] != config.episode_targets(episode):
            planned = config.episode_targets(episode) if episode < config.num_episodes else 0
            raise SettingsMismatchError(
                f"{path}: episode {episode} holds {part['targets']} targets but --targets {config.targets} "
                f"with --targets-per-episode {config.targets_per_episode} plans {planned} for it"
            )
        if not path.exists():
            continue  # lost: collect it again
        if file_sha256(path) != part["sha256"]:
            raise DatasetError(
                f"{path}: sha256 mismatch (corrupt or modified); delete it to collect that episode again"
            )
        kept.append(part)
    changed = len(kept) != len(manifest["parts"])
    manifest["parts"] = kept
    if manifest["metadata"].get("targets_requested") != config.targets:
        manifest["metadata"]["targets_requested"] = int(config.targets)
        changed = True
    if changed:
        write_manifest(directory, manifest)
    return manifest
