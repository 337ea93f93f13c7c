"""`krl.data.storage` without a simulator: the writer's lock, settings differences, leftovers of an
interrupted write, and a part written durably is the bytes its sha256 names."""

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest

from krl.data.reader import load_dataset
from krl.data.schema import FIELDS, MANIFEST_NAME, DatasetError
from krl.data.storage import (
    LOCK_NAME,
    directory_lock,
    open_dataset,
    settings_difference,
    write_manifest,
    write_part,
)


class Plan:
    """Two episodes of two targets (the :class:`krl.data.storage.EpisodePlan` a CollectConfig is)."""

    targets = 4
    targets_per_episode = 2
    num_episodes = 2

    def episode_targets(self, episode):
        return 2


SETTINGS = {"mode": "base", "seed": 0, "expert": {"stance_duration": 0.2}}


def test_the_lock_refuses_a_live_writer_and_takes_over_a_dead_ones(tmp_path):
    writer = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        (tmp_path / LOCK_NAME).write_text(f"{writer.pid}\n")
        with (
            pytest.raises(ValueError, match=f"another collection \\(pid {writer.pid}\\)"),
            directory_lock(tmp_path),
        ):
            pass
    finally:
        writer.kill()
        writer.wait()
    with directory_lock(tmp_path):  # its writer is gone: a stale lock
        assert (tmp_path / LOCK_NAME).read_text().strip() != str(writer.pid)
    assert not (tmp_path / LOCK_NAME).exists()


def test_settings_difference_names_every_nested_key():
    new = {"mode": "ext", "seed": 0, "expert": {"stance_duration": 0.25}, "extra": 1}
    assert settings_difference(SETTINGS, new) == [
        "expert.stance_duration 0.2 != 0.25",
        "extra '(unset)' != 1",
        "mode 'base' != 'ext'",
    ]
    assert settings_difference(SETTINGS, json.loads(json.dumps(SETTINGS))) == []


def test_open_dataset_creates_a_manifest_and_clears_leftover_temp_files(tmp_path):
    (tmp_path / f".{MANIFEST_NAME}.abc123.tmp").write_text("half")
    (tmp_path / ".part-00000.parquet.abc123.tmp").write_bytes(b"half")
    manifest = open_dataset(tmp_path, Plan(), SETTINGS)
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST_NAME]
    assert manifest["parts"] == [] and manifest["totals"]["episodes"] == 0
    assert json.loads((tmp_path / MANIFEST_NAME).read_text())["metadata"]["settings"] == SETTINGS
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match="is not a krl dataset"):
        open_dataset(foreign, Plan(), SETTINGS)


def test_a_part_is_the_bytes_its_sha256_names_and_the_manifest_counts_it(tmp_path):
    manifest = open_dataset(tmp_path, Plan(), SETTINGS)
    rows = 3
    columns = {f.name: np.zeros((rows, *f.shape), dtype=f.dtype) for f in FIELDS}
    counts = {"episode": 1, "rows": rows, "targets": 2, "targets_reached": 1, "falls": 1, "timeouts": 0}
    part = write_part(tmp_path, columns, {**counts, "unstable": 0}, manifest["metadata"])
    assert part["file"] == "part-00001.parquet"
    assert part["sha256"] == hashlib.sha256((tmp_path / part["file"]).read_bytes()).hexdigest()
    manifest["parts"].append(part)
    write_manifest(tmp_path, manifest)
    assert manifest["totals"] == {
        **{k: v for k, v in counts.items() if k != "episode"},
        "unstable": 0,
        "episodes": 1,
    }
    again = open_dataset(tmp_path, Plan(), SETTINGS)  # resumable: the part is kept
    assert [p["episode"] for p in again["parts"]] == [1]


def write_dataset(directory, episodes):
    """A dataset of the given episodes' columns (``{field: array}`` each), written as collection writes."""
    directory.mkdir()
    manifest = open_dataset(directory, Plan(), SETTINGS)
    for episode, columns in enumerate(episodes):
        rows = len(columns["episode"])
        counts = {"episode": episode, "rows": rows, "targets": 2, "targets_reached": 2, "falls": 0}
        part = write_part(directory, columns, {**counts, "timeouts": 0, "unstable": 0}, manifest["metadata"])
        manifest["parts"].append(part)
    write_manifest(directory, manifest)
    return manifest


def random_columns(rows=10, seed=0):
    rng = np.random.default_rng(seed)
    return {f.name: rng.uniform(-1.0, 1.0, size=(rows, *f.shape)).astype(f.dtype) for f in FIELDS}


def test_non_finite_rows_are_refused_naming_the_part_the_column_and_the_rows(tmp_path, capsys):
    from krl.cli import main

    bad = random_columns(seed=1)
    bad["q"][[2, 7], 4] = np.nan
    bad["q"][7, 5] = np.inf
    write_dataset(tmp_path / "ds", [random_columns(), bad])  # sha256 and content hash match the NaN rows
    with pytest.raises(DatasetError) as info:
        load_dataset(tmp_path / "ds")
    message = str(info.value)
    assert "part-00001.parquet" in message and "column q" in message and "2 of 10 rows" in message
    assert "\n" not in message
    out = tmp_path / "run"
    for argv in (
        ["kernel", "train", "--data", str(tmp_path / "ds"), "--out", str(out), "--quiet"],
        ["kernel", "eval", "--data", str(tmp_path / "ds"), "--json"],
    ):
        assert main(argv) == 2
        captured = capsys.readouterr()
        assert "column q" in captured.err and captured.err.count("\n") == 1 and captured.out == ""
    assert not out.exists()


def test_a_part_whose_rows_differ_from_its_content_hash_is_refused(tmp_path):
    directory = tmp_path / "ds"
    manifest = write_dataset(directory, [random_columns(), random_columns(seed=1)])
    stale = manifest["parts"][1]["content_hash"]
    changed = random_columns(seed=1)
    changed["foot_ref"][3, 0] += 0.01
    rewritten = write_part(
        directory, changed, {**manifest["parts"][1], "unstable": 0}, manifest["metadata"]
    )  # a modified part whose sha256 the manifest was told, but not its content hash
    manifest["parts"][1] = {**rewritten, "content_hash": stale}
    write_manifest(directory, manifest)
    with pytest.raises(DatasetError, match=r"part-00001\.parquet: its rows do not match its content_hash"):
        load_dataset(directory)


def test_a_manifest_whose_content_hash_is_not_its_parts_is_refused(tmp_path):
    directory = tmp_path / "ds"
    write_dataset(directory, [random_columns()])
    path = directory / MANIFEST_NAME
    manifest = json.loads(path.read_text())
    manifest["content_hash"] = "0" * 64
    path.write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match=r"manifest\.json: content_hash .* is not the hash of its parts"):
        load_dataset(directory)


def test_a_consistent_dataset_loads_and_a_column_subset_is_still_checked(tmp_path):
    directory = tmp_path / "ds"
    columns = random_columns()
    write_dataset(directory, [columns])
    ds = load_dataset(directory, columns=["q"])
    np.testing.assert_array_equal(ds["q"], columns["q"])
    columns["dq"][0, 0] = np.nan  # a column that was not asked for
    write_dataset(tmp_path / "nan", [columns])
    with pytest.raises(DatasetError, match="column dq"):
        load_dataset(tmp_path / "nan", columns=["q"])
