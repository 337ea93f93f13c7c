"""`krl kernel eval`'s scoring: the validation split of the training data, and where the error is."""

import numpy as np
import pytest

from krl.kernel.model import NetworkConfig
from krl.kernel.scoring import error_breakdown, score
from krl.kernel.train import TrainConfig, train_kernel


def test_validation_score_reproduces_the_training_runs_figure(tmp_path, synthetic_dataset):
    dataset = synthetic_dataset()
    dataset["time"] = np.arange(len(dataset["target_index"])) * 0.005
    config = TrainConfig(network=NetworkConfig(hidden=(16,)), epochs=2, batch_size=64, threads=1)
    trained = train_kernel(dataset, config, tmp_path / "run", progress=False, tensorboard=False)
    result = score(trained.kernel, dataset, validation_only=True, breakdown=True)
    assert result["val_l1"] == pytest.approx(trained.val_l1, rel=1e-5)
    assert result["targets"] == 4  # 20 % of the 20 targets
    assert sum(row["rows"] for row in result["breakdown"]["by_time_since_target"]) == pytest.approx(1.0)
    everything = score(trained.kernel, dataset)
    assert everything["targets"] == 20 and everything["rows"] == len(dataset["target_index"])

    dataset.content_hash = "another"
    with pytest.raises(ValueError, match="trained on dataset"):
        score(trained.kernel, dataset, validation_only=True)


def test_breakdown_hand_worked():
    error = np.repeat([1.0, 2.0, 3.0, 4.0], 12).reshape(4, 4, 3)
    columns = {
        "target_index": np.array([0, 0, 1, 1]),
        "time": np.array([0.0, 0.6, 1.0, 3.5]),  # since the target started: 0, 0.6, 0, 2.5 s
        "ride_height": np.array([0.25, 0.25, 0.20, 0.20]),
        "step_height": np.array([0.08, 0.08, 0.18, 0.18]),  # clearance 0.17, 0.17, 0.02, 0.02 m
        "stance": np.array([[True, False, False, True]] * 4),
    }
    result = error_breakdown(error, columns)
    assert result["stance_l1"] == result["swing_l1"] == 2.5
    assert result["by_time_since_target"] == [
        {"bin": "[0, 0.5) s", "rows": 0.5, "l1": 2.0},
        {"bin": "[0.5, 1) s", "rows": 0.25, "l1": 2.0},
        {"bin": "[2, inf) s", "rows": 0.25, "l1": 4.0},
    ]
    assert result["by_swing_clearance"] == [
        {"bin": "[-inf, 0.04) m", "rows": 0.5, "l1": 3.5},
        {"bin": "[0.1, inf) m", "rows": 0.5, "l1": 1.5},
    ]


def test_validation_needs_the_training_data(capsys):
    from krl.cli import main

    assert main(["kernel", "eval", "--validation"]) == 2
    assert "--validation needs --data" in capsys.readouterr().err
