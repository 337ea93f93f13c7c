"""``heights`` (thesis Fig. 4.13): kernel-ext's FR z over a cycle for several step and ride heights."""

from __future__ import annotations

import numpy as np

from krl.analysis.common import FIG_SIZE, fit_rows
from krl.analysis.kernel.context import FR, THESIS_FIGURE, FigureRun
from krl.analysis.kernel.metrics import CYCLE_POINTS, height_metrics
from krl.analysis.kernel.recording import cycle_inputs, expert_params, kernel_columns, predict_feet
from krl.analysis.panels import shade, style
from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
from krl.robots.a1.constants import FOOT_RADIUS
from krl.util.output import FIG_DPI

HEIGHTS_COMMAND: tuple[float, float, float] = (0.3, 0.0, 0.0)
"""Command of ``heights`` (the thesis does not say; a forward walk inside the training range)."""
STEP_HEIGHTS: tuple[float, ...] = tuple(float(v) for v in np.round(np.linspace(0.05, 0.18, 6), 3))
RIDE_HEIGHTS: tuple[float, ...] = tuple(float(v) for v in np.round(np.linspace(0.18, 0.28, 6), 3))

_CSV_COLUMNS: tuple[str, ...] = (
    "sweep",
    "step_height",
    "ride_height",
    "stance_z",
    "apex_z",
    "clearance",
    "stance_z_expected",
    "apex_z_expected",
    "clearance_expected",
)


def heights_figure(ext_kernel, run: FigureRun):
    """Fig. 4.13 for kernel-ext ``ext_kernel`` (no simulation: the kernel alone).

    Returns ``(table, csv columns, csv rows, matplotlib figure)``.
    """
    stance_duration = expert_params(ext_kernel).stance_duration
    cycle = cycle_inputs("trot", stance_duration)
    rows, curves = _sweep(ext_kernel, cycle, run.quick)
    step_rows = [r for r in rows if r["sweep"] == "step_height"]
    ride_rows = [r for r in rows if r["sweep"] == "ride_height"]
    fits = {
        "clearance_vs_step_height": fit_rows(step_rows, "step_height", "clearance"),
        "apex_vs_step_height": fit_rows(step_rows, "step_height", "apex_z"),
        "stance_z_vs_ride_height": fit_rows(ride_rows, "ride_height", "stance_z"),
        "apex_vs_ride_height": fit_rows(ride_rows, "ride_height", "apex_z"),
    }
    table = {
        "figure": "heights",
        "thesis_figure": THESIS_FIGURE["heights"],
        "quick": run.quick,
        "command": list(HEIGHTS_COMMAND),
        "stance_duration": stance_duration,
        "training_ranges": {"step_height": [0.05, 0.18], "ride_height": [0.18, 0.28]},
        "metric": (
            f"kernel-ext FR z (base frame) over one trot cycle at φ_FR = j/{CYCLE_POINTS}, command "
            f"{HEIGHTS_COMMAND}; stance_z = median z over the stance part, apex_z = max z, clearance = "
            "apex_z − stance_z [m]; expected (the expert's set points): stance_z = −ride + foot radius "
            f"({FOOT_RADIUS:g} m), apex = stance + step height; fits: least squares over the sweep (ideal "
            "slopes: clearance vs step 1, stance_z vs ride −1)"
        ),
        "fits": fits,
        "conditions": rows,
    }
    return table, _CSV_COLUMNS, rows, _draw(cycle, curves, step_rows, ride_rows, fits)


def _sweep(ext_kernel, cycle: dict, quick: bool) -> tuple[list, dict]:
    """Predict the FR z over ``cycle`` at each (step, ride height) of the two sweeps (their ends only with
    ``quick``).

    Returns the CSV rows (the ``step_height`` sweep first) and, per sweep, the curves ``(step, ride, z)``.
    """
    command = np.tile(np.array(HEIGHTS_COMMAND), (CYCLE_POINTS, 1))
    sweeps = {
        "step_height": [(h, NOMINAL_RIDE_HEIGHT) for h in STEP_HEIGHTS],
        "ride_height": [(NOMINAL_STEP_HEIGHT, h) for h in RIDE_HEIGHTS],
    }
    if quick:
        sweeps = {key: values[:: len(values) - 1] for key, values in sweeps.items()}
    rows, curves = [], {}
    for name, settings in sweeps.items():
        curves[name] = []
        for step, ride in settings:
            z = predict_feet(ext_kernel, kernel_columns(command, cycle["normalised"], step, ride))[:, FR, 2]
            rows.append(
                {
                    "sweep": name,
                    "step_height": step,
                    "ride_height": ride,
                    **height_metrics(z, cycle["stance"], step, ride),
                }
            )
            curves[name].append((step, ride, z))
    return rows, curves


def _draw(cycle: dict, curves: dict, step_rows: list, ride_rows: list, fits: dict):
    """The figure: the z curves of each sweep on top, the clearance and stance height against the inputs
    below."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(2, 2)
    for col, name in enumerate(("step_height", "ride_height")):
        _draw_curves(axes[0, col], col, name, cycle, curves[name])
    _draw_responses(axes[1], step_rows, ride_rows, fits)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['heights']}: kernel-ext FR z over one trot cycle, command v_x = "
        f"{HEIGHTS_COMMAND[0]:g} m/s; grey: the training range's end values",
        fontsize=9,
    )
    return fig


def _draw_curves(ax, col: int, name: str, cycle: dict, curves: list) -> None:
    """Panel (a) or (b), sweep ``name``: the FR z over the cycle per setting, coloured by the varied height,
    with the expert's target as a dotted line and the end values underlaid in grey."""
    import matplotlib as mpl

    cmap = mpl.colormaps["viridis"]
    phase = cycle["phase"]
    values = [c[0] if name == "step_height" else c[1] for c in curves]
    norm = mpl.colors.Normalize(min(values), max(values))
    shade(ax, phase, ~cycle["stance"])
    for (step, ride, z), value in zip(curves, values, strict=True):
        color = cmap(norm(value))
        ax.plot(phase, z, color=color, lw=1.3, label=f"{value:.3f} m")
        ground = -ride + FOOT_RADIUS
        target = ground + step if name == "step_height" else ground
        ax.axhline(target, color=color, lw=0.7, ls=":")
    for edge in (min(values), max(values)):
        ax.plot(phase, curves[values.index(edge)][2], color="0.5", lw=3.0, alpha=0.35, zorder=0)
    what = "step height (ride 0.25 m)" if name == "step_height" else "ride height (step 0.08 m)"
    ax.set(
        xlabel="FR phase φ_FR [cycles] (shaded: swing)",
        ylabel="FR z [m]",
        title=f"({'ab'[col]}) varying {what}; dotted: expert's "
        f"{'apex' if name == 'step_height' else 'landing height'}",
    )
    style(ax)
    ax.legend(fontsize=6, loc="upper right", title=name.replace("_", " "), title_fontsize=6)


def _draw_responses(axes, step_rows: list, ride_rows: list, fits: dict) -> None:
    """Panels (c) and (d) on ``axes``: the swing clearance against the step height input and the stance
    height against the ride height input, each beside the expert's set point."""
    ax = axes[0]
    x = [r["step_height"] for r in step_rows]
    ax.plot(x, [r["clearance"] for r in step_rows], "o-", color="C1", label="kernel-ext clearance")
    ax.plot(x, x, "k--", lw=0.8, label="expert set point (= step height)")
    fit = fits["clearance_vs_step_height"]
    ax.set(
        xlabel="step height input [m]",
        ylabel="apex − stance z [m]",
        title=f"(c) swing clearance (fit slope {fit['slope']:.2f}, offset {fit['offset']:+.3f} m)",
    )
    style(ax)
    ax.legend(fontsize=6)
    ax = axes[1]
    x = [r["ride_height"] for r in ride_rows]
    ax.plot(x, [r["stance_z"] for r in ride_rows], "o-", color="C0", label="kernel-ext stance z")
    ax.plot(x, [r["stance_z_expected"] for r in ride_rows], "k--", lw=0.8, label="−ride + foot radius")
    fit = fits["stance_z_vs_ride_height"]
    ax.set(
        xlabel="ride height input [m]",
        ylabel="stance z [m]",
        title=f"(d) stance height (fit slope {fit['slope']:.2f}, offset {fit['offset']:+.3f} m)",
    )
    style(ax)
    ax.legend(fontsize=6)
