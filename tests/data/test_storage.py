"""`krl.data.storage` without a simulator: the writer's lock, settings differences, leftovers of an
interrupted write, and a part written durably is the bytes its sha256 names."""

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest

from krl.data.schema import FIELDS, MANIFEST_NAME
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
