"""The kernel figures' metrics (``docs/kernel_figures.md``): L1 per axis, FR/RL symmetry, a foot's
trajectory over a cycle, phantom lifts, heights against the expert's set points, and folding many cycles
into one.
"""

from __future__ import annotations

import math

import numpy as np

from krl.robots.a1.constants import FOOT_RADIUS

AXES: tuple[str, ...] = ("x", "y", "z")
"""Names of the three position components, in array order."""
CYCLE_POINTS: int = 80
"""Samples per gait cycle of the kernel-only sweeps (and bins of the folded expert cycles)."""
LIFT_THRESHOLD: float = 0.02
"""A stance sample counts as a "phantom lift" when the prediction is this much above the label [m]."""


def l1_per_axis(prediction: np.ndarray, label: np.ndarray) -> dict[str, float]:
    """Mean absolute error per axis and overall [m]. Shapes: (..., 3) each."""
    prediction, label = np.asarray(prediction, dtype=float), np.asarray(label, dtype=float)
    if prediction.shape != label.shape or prediction.shape[-1] != 3:
        raise ValueError(f"need two (..., 3) arrays of one shape, got {prediction.shape} and {label.shape}")
    error = np.abs(prediction - label).reshape(-1, 3)
    return {
        "x": float(error[:, 0].mean()),
        "y": float(error[:, 1].mean()),
        "z": float(error[:, 2].mean()),
        "mean": float(error.mean()),
    }


def symmetry_metrics(fr: np.ndarray, rl: np.ndarray) -> dict[str, float]:
    """How far the FR and RL trajectories over one cycle are from the trot's diagonal symmetry.

    Each trajectory is first *normalised* by removing its mean over the cycle (its nominal offset):
    ``p̃ = p − mean_t p``. True symmetry (the thesis's definition) means the lateral trajectories are
    each other's inverse, ``ỹ_FR = −ỹ_RL``, while x and z coincide, ``x̃_FR = x̃_RL``, ``z̃_FR = z̃_RL``.

    Args:
        fr, rl: positions over one cycle at the same instants [m]. Shape: (K, 3) each.

    Returns:
        ``y_asym``: RMS over the cycle of ``ỹ_FR + ỹ_RL`` [m] (0 when symmetric); ``y_asym_rel``: that
        divided by the RMS amplitude ``sqrt((rms(ỹ_FR)² + rms(ỹ_RL)²) / 2)`` (0 inverse, √2 for unrelated
        equal-amplitude motions, 2 identical); ``y_corr``: correlation of ``ỹ_FR`` and ``ỹ_RL``
        (−1 when symmetric); ``y_rms_fr``, ``y_rms_rl`` [m]; ``y_offset_sum``: ``mean y_FR + mean y_RL``
        [m] (0 when the feet are placed mirror-symmetrically); ``x_mismatch``, ``z_mismatch``: RMS of
        ``x̃_FR − x̃_RL`` and ``z̃_FR − z̃_RL`` [m].
    """
    fr, rl = np.asarray(fr, dtype=float), np.asarray(rl, dtype=float)
    if fr.shape != rl.shape or fr.ndim != 2 or fr.shape[1] != 3 or len(fr) < 2:
        raise ValueError(f"need two (K >= 2, 3) arrays of one shape, got {fr.shape} and {rl.shape}")
    a, b = fr - fr.mean(axis=0), rl - rl.mean(axis=0)

    def rms(v: np.ndarray) -> float:
        return float(np.sqrt(np.mean(v**2)))

    amplitude = math.sqrt((rms(a[:, 1]) ** 2 + rms(b[:, 1]) ** 2) / 2)
    denominator = rms(a[:, 1]) * rms(b[:, 1])
    return {
        "y_asym": rms(a[:, 1] + b[:, 1]),
        "y_asym_rel": rms(a[:, 1] + b[:, 1]) / amplitude if amplitude > 0 else float("nan"),
        "y_corr": float(np.mean(a[:, 1] * b[:, 1]) / denominator) if denominator > 0 else float("nan"),
        "y_rms_fr": rms(a[:, 1]),
        "y_rms_rl": rms(b[:, 1]),
        "y_offset_sum": float(fr[:, 1].mean() + rl[:, 1].mean()),
        "x_mismatch": rms(a[:, 0] - b[:, 0]),
        "z_mismatch": rms(a[:, 2] - b[:, 2]),
    }


def fold_cycle(
    phase: np.ndarray, values: np.ndarray, bins: int = CYCLE_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """Average ``values`` over many cycles in ``bins`` equal bins of a leg phase in (0, 1].

    Args:
        phase: phase of each sample [cycles]. Shape: (N,).
        values: the samples. Shape: (N, ...).

    Returns:
        ``(centres, means)``: bin centres ``(j − 0.5) / bins`` and the mean of the samples in each bin
        (NaN for an empty bin). Shapes: (bins,), (bins, ...).
    """
    phase = np.asarray(phase, dtype=float)
    values = np.asarray(values, dtype=float)
    if phase.ndim != 1 or len(values) != len(phase):
        raise ValueError(f"phase must be (N,) and values (N, ...), got {phase.shape} and {values.shape}")
    index = np.clip(np.ceil(phase * bins).astype(int) - 1, 0, bins - 1)
    flat = values.reshape(len(values), -1)
    sums = np.zeros((bins, flat.shape[1]))
    np.add.at(sums, index, flat)
    counts = np.bincount(index, minlength=bins).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / counts[:, None]
    centres = (np.arange(bins) + 0.5) / bins
    return centres, means.reshape((bins, *values.shape[1:]))


def sweep_metrics(feet: np.ndarray) -> dict[str, float]:
    """Shape of one foot's trajectory over a cycle: peak-to-peak and mean per axis, z extremes [m].

    Args:
        feet: positions over one cycle [m]. Shape: (K, 3).
    """
    feet = np.asarray(feet, dtype=float)
    out: dict[str, float] = {}
    for i, axis in enumerate(AXES):
        out[f"{axis}_ptp"] = float(np.ptp(feet[:, i]))
        out[f"{axis}_mean"] = float(feet[:, i].mean())
    out["z_min"], out["z_max"] = float(feet[:, 2].min()), float(feet[:, 2].max())
    return out


def stance_lift_metrics(
    z_prediction: np.ndarray, z_label: np.ndarray, stance: np.ndarray, threshold: float = LIFT_THRESHOLD
) -> dict[str, float]:
    """Does a predicted foot lift when it should stand, and stand when it should swing?

    Args:
        z_prediction, z_label: one foot's z over time [m]. Shape: (N,).
        stance: the gait's stance flag of that foot. Shape: (N,), bool.
        threshold: height difference that counts [m].

    Returns:
        ``phantom_lift_fraction``: fraction of stance samples with ``z_pred > z_label + threshold``;
        ``missed_swing_fraction``: fraction of the swing samples in which the label is above its own
        stance level by more than ``threshold`` (the foot is really up) where the prediction is not
        (``z_pred < stance level + threshold``); ``stance_z_l1``, ``swing_z_l1``: mean |error| of z over
        stance and swing samples [m]. The stance level is the median label z over stance samples.
    """
    zp, zl = np.asarray(z_prediction, dtype=float), np.asarray(z_label, dtype=float)
    stance = np.asarray(stance, dtype=bool)
    if not (zp.shape == zl.shape == stance.shape) or zp.ndim != 1:
        raise ValueError(f"need three (N,) arrays, got {zp.shape}, {zl.shape}, {stance.shape}")
    nan = float("nan")
    out = {"phantom_lift_fraction": nan, "missed_swing_fraction": nan, "stance_z_l1": nan, "swing_z_l1": nan}
    if stance.any():
        out["phantom_lift_fraction"] = float(np.mean(zp[stance] > zl[stance] + threshold))
        out["stance_z_l1"] = float(np.abs(zp[stance] - zl[stance]).mean())
        level = float(np.median(zl[stance]))
        up = ~stance & (zl > level + threshold)
        if up.any():
            out["missed_swing_fraction"] = float(np.mean(zp[up] < level + threshold))
    if (~stance).any():
        out["swing_z_l1"] = float(np.abs(zp[~stance] - zl[~stance]).mean())
    return out


def height_metrics(z: np.ndarray, stance: np.ndarray, step_height: float, ride_height: float) -> dict:
    """FR z over a cycle against the expert's set points (:mod:`krl.control.swing`).

    The expert lands a foot at ``−ride_height + FOOT_RADIUS`` (base frame) and lifts it to an apex
    ``step_height`` above that. Returns ``stance_z`` (median z over stance samples), ``apex_z`` (max z),
    ``clearance`` (= apex_z − stance_z), and the expected ``stance_z_expected``, ``apex_z_expected``,
    ``clearance_expected`` (= step_height) [m].
    """
    z, stance = np.asarray(z, dtype=float), np.asarray(stance, dtype=bool)
    stance_z = float(np.median(z[stance])) if stance.any() else float("nan")
    apex = float(z.max())
    ground = -ride_height + FOOT_RADIUS
    return {
        "stance_z": stance_z,
        "apex_z": apex,
        "clearance": apex - stance_z,
        "stance_z_expected": ground,
        "apex_z_expected": ground + step_height,
        "clearance_expected": float(step_height),
    }
