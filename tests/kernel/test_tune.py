"""Optuna tuning: trials run, the study persists in SQLite and resumes, the best is written."""

import json
import sqlite3

import optuna
import pytest

from krl.kernel.model import NetworkConfig
from krl.kernel.train import TrainConfig
from krl.kernel.tune import NETWORKS, suggest_config, tune


def test_search_space_is_table_a2():
    trial = optuna.trial.FixedTrial(
        {
            "network": "3x128",
            "activation": "tanh",
            "dropout": 0.1,
            "batch_norm": True,
            "learning_rate": 1e-3,
            "lr_decay": 0.8,
            "batch_size": 500,
        }
    )
    config = suggest_config(trial, TrainConfig())
    assert config.network == NetworkConfig(
        hidden=(128, 128, 128), activation="tanh", dropout=0.1, batch_norm=True
    )
    assert (config.learning_rate, config.lr_decay, config.batch_size) == (1e-3, 0.8, 500)
    assert NETWORKS["4x256"] == (256, 256, 256, 256)


def test_tuning_persists_and_resumes(tmp_path, monkeypatch, synthetic_dataset):
    import krl.kernel.tune as tune_module

    # keep trials tiny: whatever is sampled, use a small network
    original = tune_module.suggest_config
    monkeypatch.setattr(
        tune_module,
        "suggest_config",
        lambda trial, base: original(trial, base).__class__(
            **{**original(trial, base).__dict__, "network": NetworkConfig(hidden=(16,)), "batch_size": 256}
        ),
    )
    dataset = synthetic_dataset(targets=10, per_target=40)
    base = TrainConfig(epochs=2, patience=2, threads=1)
    first = tune(dataset, tmp_path, trials=2, base=base, progress=False)
    assert first["trials_completed"] == 2
    second = tune(dataset, tmp_path, trials=1, base=base, progress=False)
    assert second["trials_completed"] == 3  # the same study, resumed from study.db
    best = json.loads((tmp_path / "best.json").read_text())
    assert best["best_value"] == second["best_value"] > 0
    assert (tmp_path / "trials" / "0002" / "kernel.npz").exists()
    rows = (tmp_path / "trials.csv").read_text().splitlines()
    assert rows[0].startswith("number,state,val_l1,seconds,") and "learning_rate" in rows[0]
    assert len(rows) == 4 and all(",COMPLETE," in row for row in rows[1:])
    assert min(float(row.split(",")[2]) for row in rows[1:]) == best["best_value"]


def test_a_bad_storage_is_one_line_with_its_password_masked_before_any_trial(tmp_path, synthetic_dataset):
    """Issue 47's storage checks, for ``krl kernel tune`` too: a foreign SQLite file is not written to, and a
    storage that cannot be opened is named in one line without its password."""
    dataset = synthetic_dataset(targets=2, per_target=10)
    foreign = tmp_path / "foreign.db"
    with sqlite3.connect(foreign) as connection:
        connection.execute("CREATE TABLE things (x)")
    cases = (
        (f"sqlite:///{foreign}", "is not an Optuna study database"),
        (
            "postgresql+nodriver://krl:secret@db/studies",
            "cannot use study storage postgresql+nodriver://krl:***@db",
        ),
    )
    for url, shown in cases:
        with pytest.raises(ValueError) as refused:
            tune(dataset, tmp_path / "out", trials=1, storage=url, progress=False)
        message = str(refused.value)
        assert shown in message and "secret" not in message and "\n" not in message
    assert not (tmp_path / "out" / "trials").exists()
    with sqlite3.connect(foreign) as connection:
        tables = connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()
    assert tables == [("things",)]
