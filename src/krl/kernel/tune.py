"""Hyper-parameter search for the kernel with Optuna (thesis 4.2.6.3, Table A.2).

TPE over the thesis's search space, each trial a short training run (10 epochs by default) scored by
its final validation L1 [m]. The study lives in an Optuna storage: a SQLite file by default, so a
search can be stopped and resumed, or any RDB URL (e.g. ``postgresql://…``) shared by several
machines running ``krl kernel tune`` against the same study. Trials left running by a killed process
are detected by Optuna's heartbeat and retried.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from krl.kernel.model import NetworkConfig
from krl.kernel.train import TrainConfig, prepare_data, train_kernel
from krl.util.optuna_storage import check_storage, masked, study_storage
from krl.util.output import write_atomic
from krl.util.thesis import COMPARISON_EPOCHS

NETWORKS: dict[str, tuple[int, ...]] = {
    "2x128": (128, 128),
    "3x128": (128, 128, 128),
    "3x256": (256, 256, 256),
    "4x256": (256, 256, 256, 256),
}
"""Table A.2's network sizes (layers x width)."""

BATCH_SIZES: tuple[int, ...] = (100, 200, 500, 1000, 2000)
LR_DECAYS: tuple[float, ...] = (0.7, 0.8, 0.9)


def suggest_config(trial, base: TrainConfig) -> TrainConfig:
    """Draw one configuration from the Table A.2 search space (Adam fixed)."""
    network = NetworkConfig(
        hidden=NETWORKS[trial.suggest_categorical("network", list(NETWORKS))],
        activation=trial.suggest_categorical("activation", ["tanh", "relu"]),
        dropout=trial.suggest_float("dropout", 0.0, 0.3),
        batch_norm=trial.suggest_categorical("batch_norm", [True, False]),
    )
    return replace(
        base,
        network=network,
        learning_rate=trial.suggest_float("learning_rate", 1e-5, 1e-2, log=True),
        lr_decay=trial.suggest_categorical("lr_decay", list(LR_DECAYS)),
        batch_size=trial.suggest_categorical("batch_size", list(BATCH_SIZES)),
    )


def trials_csv(trials) -> str:
    """One row per Optuna trial: number, state, value (final validation L1 [m]), duration [s] and the
    sampled parameters (full precision: learning rates span three decades)."""
    names = sorted({name for trial in trials for name in trial.params})
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["number", "state", "val_l1", "seconds", *names])
    for trial in trials:
        seconds = trial.duration.total_seconds() if trial.duration is not None else ""
        value = "" if trial.value is None else trial.value
        writer.writerow(
            [trial.number, trial.state.name, value, seconds, *(trial.params.get(n, "") for n in names)]
        )
    return buffer.getvalue()


def tune(
    dataset,
    out_dir: str | Path,
    trials: int,
    base: TrainConfig | None = None,
    storage: str | None = None,
    study_name: str = "kernel",
    seed: int = 0,
    progress: bool = True,
) -> dict[str, Any]:
    """Run ``trials`` more trials of the study (creating or resuming it); return the best so far.

    Each trial trains in ``out_dir/trials/<number>`` (its checkpoint lets a retried trial resume).
    The best trial's parameters are written to ``out_dir/best.json`` and every trial of the study so
    far (all processes') to ``out_dir/trials.csv``. The summary shows ``storage`` with its password masked.

    Raises:
        ValueError: ``trials`` is negative, or the storage cannot be used (one line naming it, password
            masked: :func:`krl.util.optuna_storage.check_storage`), before anything is trained.
    """
    import optuna

    if trials < 0:
        raise ValueError(f"trials must be >= 0, got {trials}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    base = base or TrainConfig(epochs=COMPARISON_EPOCHS, patience=COMPARISON_EPOCHS)
    url = storage or f"sqlite:///{(out / 'study.db').resolve()}"
    check_storage(url)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(
        study_name=study_name,
        storage=study_storage(url),
        direction="minimize",
        sampler=optuna.samplers.TPESampler(seed=seed),
        pruner=optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=2),
        load_if_exists=True,
    )
    data = prepare_data(dataset, base)  # the split does not depend on the searched parameters

    def objective(trial) -> float:
        config = suggest_config(trial, base)

        def report(epoch: int, val_l1: float) -> None:
            trial.report(val_l1, epoch)
            if trial.should_prune():
                raise optuna.TrialPruned()

        result = train_kernel(
            dataset,
            config,
            out / "trials" / f"{trial.number:04d}",
            progress=progress,
            tensorboard=False,
            data=data,
            on_epoch=report,
        )
        return result.history[-1]["val_l1"]

    study.optimize(objective, n_trials=trials, gc_after_trial=True)
    write_atomic(out / "trials.csv", trials_csv(study.trials))
    completed = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    summary: dict[str, Any] = {
        "study": study_name,
        "storage": masked(url),
        "trials_completed": len(completed),
        "trials_pruned": sum(t.state == optuna.trial.TrialState.PRUNED for t in study.trials),
    }
    if completed:
        summary.update(
            best_value=study.best_value, best_params=study.best_params, best_trial=study.best_trial.number
        )
        write_atomic(out / "best.json", json.dumps(summary, indent=2, sort_keys=True))
    return summary
