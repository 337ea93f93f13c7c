"""What a controller does through one push (``krl agent push``): trunk velocity, ride height, step timing.

:class:`PushProbe` is one attempt of the push sweep made repeatable: the robot walks from the origin to
the sweep's waypoint (3, 0) on flat ground, exactly as ``krl evaluate --push-sweep`` walks it
(:func:`krl.eval.episodes.score_walk`), and one horizontal push of a chosen magnitude and direction hits
the trunk's centre at a chosen time; every controller meets the same push at the same time.
:func:`push_trace` keeps every control step of the run (:data:`TRACE_FIELDS`), and :func:`push_summary`
measures the response: how fast and how far the trunk was carried along the push, how low it sank, when
the first foot came down after the push began, and how the stepping rhythm changed. For an agent that
drives its gait (:mod:`krl.agent.action`) the trace also holds the step height, ride height and clock rate
it chose; for others these are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.action import SATURATED
from krl.control.types import JointCommand
from krl.eval.episodes import PushSweep
from krl.robots.a1.constants import LEG_NAMES, TRUNK_HALF_SIZE
from krl.sim.pushes import Push, check_push_magnitude
from krl.sim.state import RobotState
from krl.util.output import npz_bytes, write_atomic
from krl.util.timing import CONTROL_DT

PROBE_DIRECTIONS: dict[str, tuple[float, float]] = {
    "left": (0.0, 1.0),
    "right": (0.0, -1.0),
    "forward": (1.0, 0.0),
    "backward": (-1.0, 0.0),
}
"""Push directions relative to the walk (the robot walks along +x), as world (x, y) unit vectors."""

PROBE_POINTS: dict[str, tuple[float, float, float]] = {
    "centre": (0.0, 0.0, 0.0),
    "top": (0.0, 0.0, float(TRUNK_HALF_SIZE[2])),
    "bottom": (0.0, 0.0, -float(TRUNK_HALF_SIZE[2])),
}
"""Where the push strikes, trunk frame [m]: the trunk's origin, or the middle of its top or bottom face (the
sweep draws points over the whole surface; docs/agent-robust.md on why the top matters)."""

TRACE_FIELDS: dict[str, str] = {
    "time": "simulated time at the step [s]. Shape: (T,)",
    "base_pos": "trunk position, world [m]. Shape: (T, 3)",
    "velocity": "trunk linear velocity, world [m/s]. Shape: (T, 3)",
    "rpy": "trunk roll, pitch, yaw [rad]. Shape: (T, 3)",
    "foot_contact": "foot touched the ground in the last physics step, FR FL RR RL. Shape: (T, 4)",
    "gait": "the agent's step height [m], ride height [m] and clock rate for the next step; NaN for "
    "controllers without a gait path. Shape: (T, 3)",
    "residual": "the agent's filtered foot residual for the next step, base frame [m], feet FR FL RR RL; NaN "
    "for controllers without one. Shape: (T, 4, 3)",
    "residual_action": "the policy's residual action before the filter, in [-1, 1] (× the residual bound: "
    "metres), feet FR FL RR RL × (x, y, z); NaN for controllers without one. Shape: (T, 12)",
}
"""Every array of a push trace (T control steps; the state the controller saw at the step)."""

RESPONSE_WINDOW: float = 2.0
"""How long after the push's start the response is measured [s]."""

RHYTHM_WINDOW: float = 1.5
"""Stride periods are compared over this long before and after the push's start [s]."""

MIN_SWING: float = 0.05
"""A foot's touchdown counts after at least this long off the ground [s] (contacts flicker in stance)."""

SMOOTHING: float = 0.2
"""The speed along the push is a moving average over this window [s] (a trot's step), less its mean over
the same window before the push, so the gait's own sway and the walk itself are not counted."""

SETTLED: float = 0.1
"""The push's motion has stopped once that speed falls below this [m/s]."""


@dataclass(frozen=True)
class PushProbe:
    """One push, the same for every controller: ``magnitude`` [N] towards ``direction`` (a key of
    :data:`PROBE_DIRECTIONS`), horizontal, at ``point`` (a key of :data:`PROBE_POINTS`), from
    ``start_time`` [s] for ``duration`` [s], applied as the push sweep applies its pushes
    (:mod:`krl.sim.pushes`)."""

    magnitude: float = 600.0
    direction: str = "left"
    start_time: float = 2.55
    """[s]: mid-swing of the trot pair that lifted at 2.50 s (the kernel's clock; the expert's is in step)."""
    duration: float = 0.3
    point: str = "centre"
    sweep: PushSweep = field(default_factory=PushSweep)
    """The walk: the sweep's waypoint, time limit and waypoint threshold."""

    def __post_init__(self) -> None:
        if self.direction not in PROBE_DIRECTIONS:
            known = ", ".join(PROBE_DIRECTIONS)
            raise ValueError(f"unknown push direction {self.direction!r}; known: {known}")
        if self.point not in PROBE_POINTS:
            raise ValueError(f"unknown push point {self.point!r}; known: {', '.join(PROBE_POINTS)}")
        check_push_magnitude(self.magnitude)
        if not 0 <= self.start_time < self.sweep.time_limit:
            raise ValueError(
                f"push start time must lie in [0, {self.sweep.time_limit:g}) s, got {self.start_time}"
            )

    @property
    def unit(self) -> np.ndarray:
        """The push's direction, world. Shape: (3,)."""
        x, y = PROBE_DIRECTIONS[self.direction]
        return np.array([x, y, 0.0])

    def push(self) -> Push:
        """The push (:class:`krl.sim.pushes.Push`): at :attr:`point`, in the push sweep's mode."""
        return Push(
            self.start_time, self.magnitude * self.unit, np.array(PROBE_POINTS[self.point]), self.duration
        )


class StateRecorder:
    """Any :class:`krl.control.types.Controller`, keeping every step's state (:data:`TRACE_FIELDS`)."""

    def __init__(self, controller) -> None:
        self.controller = controller
        self.rows: dict[str, list[np.ndarray]] = {name: [] for name in TRACE_FIELDS}

    def reset(self, state: RobotState) -> None:
        self.controller.reset(state)

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        joint_command = self.controller.act(state, command)
        path = getattr(self.controller, "residual", None)  # an agent's action path
        gait = path.gait_inputs[0, 3:6] if path is not None else np.full(3, np.nan)
        residual = path.residual[0] if path is not None else np.full((len(LEG_NAMES), 3), np.nan)
        values = {
            "time": np.float64(state.time),
            "base_pos": state.base_pos,
            "velocity": state.lin_vel_world,
            "rpy": state.rpy,
            "foot_contact": state.foot_contact,
            "gait": gait,
            "residual": residual,
            "residual_action": self._residual_action(),
        }
        for name, value in values.items():
            self.rows[name].append(np.array(value, copy=True))
        return joint_command

    def _residual_action(self) -> np.ndarray:
        """The residual part of an agent's last action, clipped as its action path clips it. Shape: (12,)."""
        path, action = (
            getattr(self.controller, "residual", None),
            getattr(self.controller, "last_action", None),
        )
        start = 0
        for part in path.parts if path is not None and action is not None else ():
            if part.name == "residual":
                return np.clip(action[start : start + part.size], -1.0, 1.0)
            start += part.size
        return np.full(3 * len(LEG_NAMES), np.nan)

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: np.array(values) for name, values in self.rows.items()}


def push_trace(probe: PushProbe, controller) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Walk ``controller`` through the probe's push. Returns ``(trace, metrics)``: the arrays of
    :data:`TRACE_FIELDS` and the run's metrics (those of a push sweep record)."""
    recorder = StateRecorder(controller)
    metrics = probe.sweep.walk(recorder, probe.push())
    return recorder.arrays(), metrics


def touchdowns(time: np.ndarray, contact: np.ndarray) -> list[np.ndarray]:
    """Per foot, the times [s] at which it came down after at least :data:`MIN_SWING` in the air.

    ``time``: (T,) [s]; ``contact``: (T, 4) bool."""
    times = []
    for foot in range(contact.shape[1]):
        lifted, down = None, []
        for step in range(time.size):
            if not contact[step, foot]:
                lifted = time[step] if lifted is None else lifted
            elif lifted is not None:
                if time[step] - lifted >= MIN_SWING:
                    down.append(time[step])
                lifted = None
        times.append(np.array(down))
    return times


def _stride(downs: list[np.ndarray], low: float, high: float) -> float | None:
    """Mean interval between successive touchdowns of one foot within [low, high) [s]."""
    gaps = [np.diff(d[(d >= low) & (d < high)]) for d in downs]
    gaps = np.concatenate(gaps) if gaps else np.array([])
    return round(float(gaps.mean()), 4) if gaps.size else None


def speed_along(probe: PushProbe, trace: dict[str, np.ndarray]) -> np.ndarray:
    """The trunk's speed along the push [m/s]: a trailing moving average over :data:`SMOOTHING`, less its
    mean over the same window before the push. Shape: (T,)."""
    time, steps = trace["time"], round(SMOOTHING / CONTROL_DT)
    along = np.convolve(trace["velocity"] @ probe.unit, np.ones(steps) / steps, mode="full")[: time.size]
    before = (time >= probe.start_time - SMOOTHING) & (time < probe.start_time)
    return along - (along[before].mean() if before.any() else 0.0)


def _recovery_time(time: np.ndarray, along: np.ndarray, window: np.ndarray, end: float) -> float | None:
    """From the push's ``end`` [s] until ``along`` [m/s] first falls below :data:`SETTLED` within
    ``window``: the push's motion stopped; None if it never does."""
    steps = np.nonzero(window & (time >= end) & (along < SETTLED))[0]
    return round(float(time[steps[0]] - end), 4) if steps.size else None


def push_summary(probe: PushProbe, trace: dict[str, np.ndarray], metrics: dict[str, Any]) -> dict[str, Any]:
    """The response to the push within :data:`RESPONSE_WINDOW` of its start.

    ``peak_speed`` [m/s]: the trunk's largest speed along the push (:data:`SMOOTHING`); ``drift`` [m]: how
    far that speed carried it at most (the walk's own motion taken out);
    ``recovery_time`` [s]: from the push's end until that speed first falls below :data:`SETTLED` (None if
    it never does); ``min_height`` [m] of the trunk; ``peak_roll`` [rad]: its largest roll either way (a
    fall ends the run, so a faller's is the roll it fell at); ``first_touchdown`` [s] after the push began;
    ``touchdowns`` within 1 s of it; ``stride_before`` and ``stride_after`` [s]: a foot's touchdown interval
    over :data:`RHYTHM_WINDOW` before and after it; ``min_ride_height`` [m] and ``max_clock_rate``: the
    gait an agent chose (None for controllers without a gait path); ``peak_residual`` [m]: the largest
    component of an agent's filtered foot residual and ``residual_at_bound``: the share of its residual
    action's components at the bound (|a| >= :data:`krl.agent.action.SATURATED`, before the filter),
    both over the response window (None for controllers without a residual); ``error``: why the run ended
    early (a diverging simulation, an MPC that gave up; None), such a run counting as a fall (``fell``) as
    ``krl evaluate``'s aggregates count it (:mod:`krl.eval.summaries`)."""
    time, start = trace["time"], probe.start_time
    after = (time >= start) & (time < start + RESPONSE_WINDOW)
    along = speed_along(probe, trace)
    carried = np.cumsum(along[after]) * CONTROL_DT  # [m] along the push, less the walk
    recovery = _recovery_time(time, along, after, start + probe.duration)
    downs = touchdowns(time, trace["foot_contact"].astype(bool))
    later = np.concatenate([d[d > start] for d in downs])
    gait = trace["gait"][after]
    driven = bool(np.isfinite(gait).all()) and gait.size > 0
    residual, raw = trace["residual"][after], trace["residual_action"][after]
    if not (np.isfinite(residual).all() and np.isfinite(raw).all()):  # not an agent
        residual, raw = np.zeros(0), np.zeros(0)
    error = metrics.get("error")
    return {
        "fell": bool(metrics["fell"]) or error is not None,
        "success": bool(metrics["success"]),
        "peak_speed": round(float(along[after].max()), 4) if after.any() else None,
        "drift": round(float(carried.max()), 4) if carried.size else None,
        "recovery_time": recovery,
        "min_height": round(float(trace["base_pos"][after, 2].min()), 4) if after.any() else None,
        "peak_roll": round(float(np.abs(trace["rpy"][after, 0]).max()), 4) if after.any() else None,
        "first_touchdown": round(float(later.min() - start), 4) if later.size else None,
        "touchdowns": int(((later >= start) & (later < start + 1.0)).sum()),
        "stride_before": _stride(downs, start - RHYTHM_WINDOW, start),
        "stride_after": _stride(downs, start, start + RHYTHM_WINDOW),
        "min_ride_height": round(float(gait[:, 1].min()), 4) if driven else None,
        "max_clock_rate": round(float(gait[:, 2].max()), 4) if driven else None,
        "peak_residual": round(float(np.abs(residual).max()), 4) if residual.size else None,
        "residual_at_bound": round(float((np.abs(raw) >= SATURATED).mean()), 4) if raw.size else None,
        "error": error,
    }


SUMMARY_COLUMNS: tuple[str, ...] = (
    "controller",
    "fell",
    "success",
    "peak_speed",
    "drift",
    "recovery_time",
    "min_height",
    "peak_roll",
    "first_touchdown",
    "touchdowns",
    "stride_before",
    "stride_after",
    "min_ride_height",
    "max_clock_rate",
    "peak_residual",
    "residual_at_bound",
    "error",
)
"""The columns of ``push-trace.csv``: the controller's label, then :func:`push_summary`'s keys."""


def push_figure(probe: PushProbe, traces: dict[str, dict[str, np.ndarray]]):
    """Speed along the push, trunk height (dashed: an agent's ride height), roll, an agent's clock rate, and
    each controller's foot contacts against time, the push's window shaded; returns the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from krl.analysis.panels import style

    rows = 4 + len(traces)
    ratios = [1.2, 1.0, 1.0, 0.8] + [0.5] * len(traces)
    fig, axes = plt.subplots(rows, 1, figsize=(9, 1.7 * sum(ratios)), sharex=True, height_ratios=ratios)
    for index, (label, trace) in enumerate(traces.items()):
        color, time = f"C{index}", trace["time"]
        axes[0].plot(time, speed_along(probe, trace), color=color, lw=1, label=label)
        axes[1].plot(time, trace["base_pos"][:, 2], color=color, lw=1)
        axes[1].plot(time, trace["gait"][:, 1], color=color, lw=0.8, ls="--")
        axes[2].plot(time, trace["rpy"][:, 0], color=color, lw=1)
        axes[3].plot(time, trace["gait"][:, 2], color=color, lw=1)
        contact_axis = axes[4 + index]
        for foot in range(len(LEG_NAMES)):
            down = trace["foot_contact"][:, foot].astype(bool)
            contact_axis.fill_between(time, foot, foot + 0.8 * down, step="mid", color=color, lw=0)
        ticks = np.arange(len(LEG_NAMES)) + 0.4
        contact_axis.set(yticks=ticks, yticklabels=LEG_NAMES, ylim=(0, len(LEG_NAMES)))
        contact_axis.set_title(f"{label}: feet on the ground", loc="left")
    titles = [
        f"speed along the push [m/s] ({probe.magnitude:g} N {probe.direction}"
        f"{'' if probe.point == 'centre' else f' on the {probe.point}'}, less the walk's)",
        "trunk height [m] (dashed: the agent's ride height)",
        "roll [rad]",
        "an agent's gait clock rate (× the kernel's)",
    ]
    for axis, title in zip(axes[:4], titles, strict=True):
        axis.set_title(title, loc="left")
    for axis in axes:
        axis.axvspan(probe.start_time, probe.start_time + probe.duration, color="0.85", lw=0, zorder=0)
        style(axis)
    axes[0].legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    return fig


def write_push_report(
    probe: PushProbe, runs: dict[str, tuple[dict[str, np.ndarray], dict[str, Any]]], out: Path
) -> dict[str, Any]:
    """``push-trace.png``, ``.json`` (the probe and each controller's summary), ``.csv`` (the summaries) and
    ``.npz`` (every trace, arrays named ``LABEL/FIELD``) in ``out``. Returns the paths and the summaries."""
    import matplotlib.pyplot as plt

    from krl.analysis.common import write_figure

    summaries = [{"controller": label, **push_summary(probe, *run)} for label, run in runs.items()]
    table = {
        "probe": {
            "magnitude": probe.magnitude,
            "direction": probe.direction,
            "start_time": probe.start_time,
            "duration": probe.duration,
            "push": probe.push().summary(),
            "walk": {key: probe.sweep.to_dict()[key] for key in ("target", "time_limit", "d_min")},
        },
        "controllers": summaries,
    }
    fig = push_figure(probe, {label: trace for label, (trace, _) in runs.items()})
    written = write_figure(out, "push-trace", fig, table, SUMMARY_COLUMNS, summaries)
    plt.close(fig)
    arrays = {f"{label}/{name}": value for label, (trace, _) in runs.items() for name, value in trace.items()}
    write_atomic(Path(out) / "push-trace.npz", npz_bytes(arrays))
    return {**written, "npz": str(Path(out) / "push-trace.npz")}
