"""Kernel features, labels, split, file format, NumPy inference, training with resume."""

import numpy as np
import pytest
import torch

from krl.kernel.features import (
    features_from_columns,
    input_names,
    labels_from_columns,
    split_by_target,
    stack_history,
)
from krl.kernel.fitting import build_network, export_weights
from krl.kernel.model import Kernel, KernelFileError, NetworkConfig, load_kernel
from krl.kernel.train import TrainConfig, train_kernel


def test_feature_layouts_hand_worked(columns):
    c = columns()
    base = features_from_columns("base", c)
    np.testing.assert_allclose(
        base[2], np.r_[c["v_cmd"][2], c["yaw_cmd"][2], c["normalised_phase"][2]], rtol=1e-6
    )
    assert features_from_columns("ext", c).shape == (6, 9)
    assert features_from_columns("dyn1", c).shape == (6, 43)
    assert features_from_columns("dyn2", c).shape == (6, 215)
    ind = features_from_columns("ind", c)
    assert ind.shape == (24, 8)
    np.testing.assert_allclose(ind[4 * 2 + 1, 3], c["normalised_phase"][2, 1], rtol=1e-6)  # step 2, leg FL
    np.testing.assert_array_equal(ind[4 * 2 + 1, 4:], [0, 1, 0, 0])
    for variant in ("base", "ind", "ext", "dyn1", "dyn2"):
        assert len(input_names(variant)) == features_from_columns(variant, c).shape[1]


def test_history_restarts_at_segment_boundaries():
    x = np.arange(6, dtype=float)[:, None]
    stacked = stack_history(x, np.array([True, False, False, True, False, False]), history=3)
    np.testing.assert_array_equal(stacked[:, 0], [0, 0, 0, 3, 3, 3])
    np.testing.assert_array_equal(stacked[:, 1], [0, 0, 1, 3, 3, 4])
    np.testing.assert_array_equal(stacked[:, 2], [0, 1, 2, 3, 4, 5])


def test_labels_are_swing_targets_and_realised_stance_positions(columns):
    labels = labels_from_columns("base", columns()).reshape(-1, 4, 3)
    np.testing.assert_array_equal(labels[:, [0, 3]], 2.0)  # stance: p'
    np.testing.assert_array_equal(labels[:, [1, 2]], 1.0)  # swing: p_ref
    assert labels_from_columns("ind", columns()).shape == (24, 3)


def test_split_keeps_targets_whole_and_is_seeded():
    target = np.repeat(np.arange(50), 7)
    validation = split_by_target(target, 0.2, seed=3)
    assert validation.sum() == 10 * 7
    for t in range(50):
        assert validation[target == t].all() or not validation[target == t].any()
    np.testing.assert_array_equal(validation, split_by_target(target, 0.2, seed=3))
    with pytest.raises(ValueError, match="at least 2 targets"):
        split_by_target(np.zeros(5), 0.2, 0)


@pytest.mark.parametrize("batch_norm", [False, True])
def test_numpy_inference_matches_torch_and_survives_a_round_trip(tmp_path, batch_norm):
    config = TrainConfig(network=NetworkConfig(hidden=(16, 8), batch_norm=batch_norm, activation="tanh"))
    torch.manual_seed(0)
    net = build_network(config, 7, 12)
    if batch_norm:  # give the running statistics non-trivial values
        net.train()
        net(torch.randn(64, 7) * 3 + 1)
    net.eval()
    kernel = Kernel(
        "base",
        config.network,
        export_weights(net),
        np.zeros(7),
        np.ones(7),
        np.zeros(12),
        np.ones(12),
        {"note": "test"},
    )
    x = np.random.default_rng(1).normal(size=(5, 7))
    with torch.no_grad():
        expected = net(torch.from_numpy(x.astype(np.float32))).numpy()
    np.testing.assert_allclose(kernel.predict(x), expected, atol=1e-5)
    loaded = load_kernel(kernel.save(tmp_path / "k.npz"))
    np.testing.assert_allclose(loaded.predict(x), expected, atol=1e-5)
    assert loaded.metadata == {"note": "test"}
    with pytest.raises(ValueError, match="expects 7 inputs"):
        loaded.predict(np.zeros(3))


def test_corrupt_and_mismatched_kernel_files(tmp_path):
    missing = tmp_path / "none.npz"
    with pytest.raises(KernelFileError, match="not found"):
        load_kernel(missing)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip file at all")
    with pytest.raises(KernelFileError, match="corrupt"):
        load_kernel(junk)
    config = NetworkConfig(hidden=(4,))
    weights = [np.zeros((4, 9)), np.zeros(4), np.zeros((12, 4)), np.zeros(12)]  # 9 inputs: ext, not base
    kernel = Kernel("base", config, weights, np.zeros(9), np.ones(9), np.zeros(12), np.ones(12), {})
    path = kernel.save(tmp_path / "wrong.npz")
    with pytest.raises(KernelFileError, match="kernel-base must map 7 inputs"):
        load_kernel(path)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:200])
    with pytest.raises(KernelFileError):
        load_kernel(truncated)


def test_training_learns_and_resumes_exactly(tmp_path, synthetic_dataset):
    dataset = synthetic_dataset()
    config = TrainConfig(
        network=NetworkConfig(hidden=(32, 32)), epochs=4, patience=10, batch_size=64, threads=1
    )
    full = train_kernel(dataset, config, tmp_path / "full", progress=False, tensorboard=False)
    assert full.history[-1]["val_l1"] < full.history[0]["val_l1"]
    assert full.epochs_run == 4

    def stop_after_second(epoch, _):
        if epoch == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_kernel(
            dataset,
            config,
            tmp_path / "resumed",
            progress=False,
            tensorboard=False,
            on_epoch=stop_after_second,
        )
    resumed = train_kernel(dataset, config, tmp_path / "resumed", progress=False, tensorboard=False)
    assert [h["val_l1"] for h in resumed.history] == [h["val_l1"] for h in full.history]
    for a, b in zip(resumed.kernel.weights, full.kernel.weights, strict=True):
        np.testing.assert_array_equal(a, b)
    other = TrainConfig(network=NetworkConfig(hidden=(32, 32)), epochs=5, batch_size=64)
    with pytest.raises(ValueError, match="other settings"):
        train_kernel(dataset, other, tmp_path / "resumed", progress=False, tensorboard=False)


def test_a_kernel_file_whose_layers_do_not_chain_says_so(tmp_path):
    config = NetworkConfig(hidden=(4,))
    weights = [np.zeros((4, 7)), np.zeros(4), np.zeros((12, 5)), np.zeros(12)]  # 4 hidden units, W2 takes 5
    kernel = Kernel("base", config, weights, np.zeros(7), np.ones(7), np.zeros(12), np.ones(12), {})
    path = kernel.save(tmp_path / "unchained.npz")
    with pytest.raises(KernelFileError) as info:
        load_kernel(path)
    message = str(info.value)
    assert "layer 2" in message and "takes 5 inputs" in message and "gives 4" in message
    assert "number of weight arrays" not in message
    short = Kernel("base", config, weights[:3], np.zeros(7), np.ones(7), np.zeros(12), np.ones(12), {})
    with pytest.raises(KernelFileError, match="3 weight arrays, a 1-hidden-layer network has 4"):
        load_kernel(short.save(tmp_path / "short.npz"))


def test_a_failed_training_run_leaves_its_out_folder_usable(tmp_path, synthetic_dataset):
    config = TrainConfig(network=NetworkConfig(hidden=(8,)), epochs=1, batch_size=64, threads=1)
    one_target = synthetic_dataset(targets=1)
    one_target.content_hash = "one-target"
    out = tmp_path / "run"
    with pytest.raises(ValueError, match="need at least 2 targets"):
        train_kernel(one_target, config, out, progress=False, tensorboard=False)
    assert not out.exists()
    result = train_kernel(synthetic_dataset(), config, out, progress=False, tensorboard=False)
    assert result.kernel_path.exists()


@pytest.mark.parametrize(
    "content",
    [b"not a checkpoint", "truncated", "a list"],
)
def test_a_corrupt_checkpoint_is_one_line_naming_the_file(tmp_path, synthetic_dataset, content):
    dataset = synthetic_dataset(targets=4, per_target=20)
    config = TrainConfig(network=NetworkConfig(hidden=(8,)), epochs=2, batch_size=64, threads=1)

    def stop(epoch, _):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_kernel(dataset, config, tmp_path, progress=False, tensorboard=False, on_epoch=stop)
    checkpoint = tmp_path / "checkpoint.pt"
    if content == "truncated":
        checkpoint.write_bytes(checkpoint.read_bytes()[:300])
    elif content == "a list":
        torch.save([1, 2], checkpoint)
    else:
        checkpoint.write_bytes(content)
    with pytest.raises(ValueError) as info:
        train_kernel(dataset, config, tmp_path, progress=False, tensorboard=False)
    message = str(info.value)
    assert str(checkpoint) in message and "\n" not in message and "weights_only" not in message


def test_training_that_diverges_is_one_line(tmp_path, synthetic_dataset):
    dataset = synthetic_dataset(targets=4, per_target=20)
    dataset["foot_ref"] = dataset["foot_ref"] * np.inf  # labels no network can fit
    dataset["foot_pos_next"] = dataset["foot_ref"]
    config = TrainConfig(network=NetworkConfig(hidden=(8,)), epochs=2, batch_size=64, threads=1)
    with np.errstate(invalid="ignore"), pytest.raises(ValueError, match=r"epoch 0: .* not finite") as info:
        train_kernel(dataset, config, tmp_path, progress=False, tensorboard=False)
    assert "\n" not in str(info.value)
