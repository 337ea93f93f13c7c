"""Drawing helpers shared by the expert's and the kernel's figures (matplotlib axes in, nothing out)."""

from __future__ import annotations

import math

import numpy as np

VELOCITY_NAMES: dict[str, tuple[str, str]] = {
    "vx": ("forward velocity v_x", "m/s"),
    "vy": ("lateral velocity v_y", "m/s"),
    "wz": ("yaw rate ω_z", "rad/s"),
}
"""(name, unit) of each command component on the velocity panels."""


def style(ax, fontsize: int = 7, grid: bool = True) -> None:
    """Small fonts for a dense panel (title one point larger) and, with ``grid``, a light grid."""
    ax.tick_params(labelsize=fontsize)
    ax.title.set_fontsize(fontsize + 1)
    ax.xaxis.label.set_fontsize(fontsize)
    ax.yaxis.label.set_fontsize(fontsize)
    if grid:
        ax.grid(alpha=0.3)


def shade(ax, t: np.ndarray, mask: np.ndarray, color: str = "0.85", label: str | None = None) -> None:
    """Shade the spans of ``t`` where ``mask`` holds. Shapes: (N,) each."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(int), [0]))))
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    for k, (start, stop) in enumerate(zip(edges[::2], edges[1::2], strict=True)):
        ax.axvspan(
            t[start] - dt / 2,
            t[stop - 1] + dt / 2,
            color=color,
            lw=0,
            zorder=0,
            label=label if k == 0 else None,
        )


def draw_fit_and_axes(ax, fit: dict[str, float], lim: float, name: str, unit: str, label: str) -> None:
    """On a realised-vs-commanded panel: the fitted line over [-lim, lim] (if finite) and the axes'
    labels, limits and title."""
    if math.isfinite(fit["slope"]):
        ax.plot(
            [-lim, lim],
            [fit["offset"] - fit["slope"] * lim, fit["offset"] + fit["slope"] * lim],
            color="C1",
            lw=0.8,
            label=label,
        )
    ax.set(
        xlabel=f"commanded {name} [{unit}]", ylabel=f"realised {name} [{unit}]", xlim=(-lim, lim), title=name
    )
