"""Shared kernel-test data: expert-like columns and a synthetic dataset."""

from typing import ClassVar

import numpy as np
import pytest


def expert_columns(n=6):
    rng = np.random.default_rng(0)
    return {
        "v_cmd": rng.normal(size=(n, 2)),
        "yaw_cmd": rng.normal(size=n),
        "normalised_phase": rng.uniform(0, 2, size=(n, 4)),
        "sine_phase": rng.uniform(-1, 1, size=(n, 4)),
        "step_height": np.full(n, 0.1),
        "ride_height": np.full(n, 0.22),
        "base_lin_vel": rng.normal(size=(n, 3)),
        "base_ang_vel": rng.normal(size=(n, 3)),
        "q": rng.normal(size=(n, 12)),
        "dq": rng.normal(size=(n, 12)),
        "com": rng.normal(size=(n, 3)),
        "projected_gravity": rng.normal(size=(n, 3)),
        "stance": np.tile([True, False, False, True], (n, 1)),
        "foot_ref": np.full((n, 12), 1.0),
        "foot_pos_next": np.full((n, 12), 2.0),
        "new_segment": np.array([True, False, False, True, False, False][:n]),
        "episode": np.zeros(n, int),
        "target_index": np.repeat(np.arange(n // 2), 2),
    }


class FakeDataset(dict):
    """The part of krl.data.reader.Dataset that training uses."""

    content_hash = "fake"
    settings: ClassVar[dict] = {"expert": {"stance_duration": 0.2}}


def make_synthetic_dataset(targets=20, per_target=60):
    """Foot positions as a smooth function of command and phase, like the expert's."""
    rng = np.random.default_rng(5)
    n = targets * per_target
    phase = rng.uniform(0, 2, size=(n, 4))
    v = rng.uniform(-0.5, 0.5, size=(n, 2))
    feet = np.concatenate(
        [0.1 * np.sin(np.pi * phase[:, :, None]) + v[:, None, :1] * 0.2 + np.zeros(3)], axis=0
    )
    c = expert_columns(n)
    c.update(
        v_cmd=v,
        normalised_phase=phase,
        foot_ref=feet.reshape(n, 12),
        foot_pos_next=feet.reshape(n, 12),
        target_index=np.repeat(np.arange(targets), per_target),
        new_segment=np.zeros(n, bool),
    )
    return FakeDataset(c)


@pytest.fixture
def columns():
    """Factory: ``columns(n)`` -> expert-like dataset columns with n rows."""
    return expert_columns


@pytest.fixture
def synthetic_dataset():
    """Factory: ``synthetic_dataset(targets, per_target)`` -> a small dataset training can use."""
    return make_synthetic_dataset
