"""Kernel studies: planning, resumable execution, tables with the thesis's numbers."""

import json

import pytest

from krl.cli import main
from krl.data.collect import CollectConfig, collect_dataset
from krl.kernel import studies
from krl.kernel.studies import plan_variants, summarise
from krl.kernel.train import TrainConfig
from krl.util.thesis import THESIS_SEEDS


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "base"
    collect_dataset(path, CollectConfig(targets=6, targets_per_episode=6, target_distance=(0.6, 0.8)))
    return path


def test_variants_plan_uses_each_variants_dataset():
    runs = plan_variants({"base": "B", "ext": "E"}, seeds=(1, 2), base=TrainConfig())
    by_variant = {(r.config.variant, r.config.seed): r.data for r in runs}
    assert by_variant == {
        ("base", 1): "B",
        ("base", 2): "B",
        ("ind", 1): "B",
        ("ind", 2): "B",
        ("dyn1", 1): "B",
        ("dyn1", 2): "B",
        ("ext", 1): "E",
        ("ext", 2): "E",
    }
    assert THESIS_SEEDS == (150, 215, 345, 556)


def test_variants_plan_can_pick_variants(capsys):
    runs = plan_variants({"base": "B", "ext": "E"}, seeds=(1,), base=TrainConfig(), variants=("ind", "ext"))
    assert [r.name for r in runs] == ["ind-seed1", "ext-seed1"]
    assert main(["kernel", "study", "variants", "--data-base", "B", "--variants", "base,big"]) == 2
    assert "unknown variant(s) big" in capsys.readouterr().err


def test_summary_mean_and_std():
    records = [
        {"k": 1, "val_l1": 1.0, "epochs_run": 2, "train_seconds": 1.0},
        {"k": 1, "val_l1": 3.0, "epochs_run": 2, "train_seconds": 3.0},
    ]
    (row,) = summarise(records, "k")
    assert row["val_l1_mean"] == 2.0 and row["val_l1_std"] == pytest.approx(1.4142135, rel=1e-6)


def test_walking_counts_each_rows_kernels(monkeypatch):
    walks = {"a1": True, "a2": False, "b1": True, "b2": True}
    asked = []

    def fake_functional(path, targets):
        asked.append((path, targets))
        return walks[path]

    monkeypatch.setattr(studies, "functional", fake_functional)
    records = [{"k": path[0], "kernel": path} for path in walks]
    rows = studies.add_walking([{"k": "a"}, {"k": "b"}], records, "k", targets=3)
    assert [row["walking"] for row in rows] == [1, 2]
    assert asked == [(path, 3) for path in walks]


def test_data_size_study_writes_its_table_and_resumes(tmp_path, small_dataset, capsys):
    argv = [
        "kernel",
        "study",
        "data-size",
        "--data",
        str(small_dataset),
        "--sizes",
        "2,3",
        "--seeds",
        "1,2",
        "--epochs",
        "1",
        "--out",
        str(tmp_path / "tables"),
        "--runs",
        str(tmp_path / "runs"),
        "--quiet",
        "--threads",
        "1",
        "--walk-targets",
        "0",
        "--json",
    ]
    assert main(argv) == 0
    first = json.loads(capsys.readouterr().out)
    assert [row["targets"] for row in first["rows"]] == [2, 3]
    assert all(row["runs"] == 2 and row["val_l1_mean"] > 0 for row in first["rows"])
    assert first["rows"][0]["thesis_mean"] is None  # the thesis has no 2-target row
    assert "walking" not in first["rows"][0]  # --walk-targets 0
    table = (tmp_path / "tables" / "data-size.md").read_text()
    assert "krl kernel study data-size" in table
    assert main(argv) == 0  # every run is finished: nothing is retrained, the numbers are the same
    again = json.loads(capsys.readouterr().out)
    assert again["rows"] == first["rows"]
    sizes = argv.index("--sizes") + 1
    partial = [*argv[:sizes], "2,3,4", *argv[sizes + 1 :], "--finished-only"]
    assert main(partial) == 0  # the 4-target runs were never trained: left out and listed
    table = json.loads(capsys.readouterr().out)
    assert table["rows"] == first["rows"] and table["unfinished"] == ["targets4-seed1", "targets4-seed2"]
    assert (
        "Not finished when this table was written: targets4-seed1"
        in (tmp_path / "tables" / "data-size.md").read_text()
    )
    assert not (tmp_path / "runs" / "data-size" / "targets4-seed1").exists()


def test_study_needs_its_data(capsys):
    assert main(["kernel", "study", "variants"]) == 2
    assert "--data-base" in capsys.readouterr().err
    assert main(["kernel", "study", "stance", "--data-stance", "x"]) == 2
    assert "TAU=DIR" in capsys.readouterr().err
