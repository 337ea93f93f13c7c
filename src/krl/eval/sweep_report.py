"""``krl report``'s sweep sections: the push sweep (Table 5.5, by magnitude and by direction) and the friction
sweep (ours), from the records of ``krl evaluate --push-sweep`` and ``--friction-sweep``.

Each section is rows (dicts, one per controller and magnitude, direction or friction; a seed group's rows
pooled over its seeds, then one per seed), a markdown table of them and a plot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from krl.eval.evaluate import FRICTION_DIR, PUSH_DIR, STAIR_DIR
from krl.eval.summaries import (
    PUSH_DIRECTIONS,
    success_interval,
    summarise_friction,
    summarise_friction_by_seed,
    summarise_push,
    summarise_push_by_seed,
    summarise_push_directions,
    summarise_push_left_right,
    summarise_stairs,
    summarise_stairs_by_seed,
)
from krl.eval.tables import controller_table, rows_csv
from krl.util.output import distinct_colours, figure_bytes, write_atomic
from krl.util.thesis import THESIS_NAMES, THESIS_PUSH_ATTEMPTS, THESIS_PUSH_MAGNITUDES

THESIS_PUSH: dict[str, tuple[float, ...]] = {  # Table 5.5, success rate at 250, 300, ..., 900 N
    "MPC (τ_stance=0.2)": (1, 0.8, 0.9, 0.7, 0.5, 0.3, 0.4, 0.2, 0.4, 0.1, 0.2, 0, 0, 0),
    "Kernel": (1, 1, 1, 0.8, 0.5, 0.3, 0.3, 0, 0, 0, 0, 0, 0, 0),
    "Agent-rp": (1, 1, 1, 1, 0.9, 0.8, 0.9, 0.8, 0.7, 0.4, 0.8, 0.6, 0.3, 0.2),
}


def push_rows(found: dict[str, dict[str, list[dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per (controller, magnitude) of ours (a seed group's pooled over its seeds, then one row per
    (seed, magnitude) with its ``seed``), then the thesis's Table 5.5."""
    rows = []
    for label, groups in found.items():
        if PUSH_DIR in groups:
            for row in summarise_push(groups[PUSH_DIR]):
                rows.append({"source": "krl", "controller": label, **row})
            for row in summarise_push_by_seed(groups[PUSH_DIR]):
                rows.append({"source": "krl", "controller": label, **row})
    for name, rates in THESIS_PUSH.items():
        for magnitude, rate in zip(THESIS_PUSH_MAGNITUDES, rates, strict=True):
            low, high = success_interval(round(rate * THESIS_PUSH_ATTEMPTS), THESIS_PUSH_ATTEMPTS)
            rows.append(
                {
                    "source": "thesis",
                    "controller": name,
                    "magnitude": magnitude,
                    "attempts": THESIS_PUSH_ATTEMPTS,
                    "success_rate": rate,
                    "success_low": low,
                    "success_high": high,
                }
            )
    return rows


PUSH_FORCE_BANDS: tuple[tuple[float, float] | None, ...] = (None, (350.0, 600.0))
"""The forces [N] push success by direction is summarised over: all of the sweep's (None), and 350-600 N,
where lateral pushes fail most and issue #25 sets its lateral target (docs/agent-gait.md)."""


def _band_name(band: tuple[float, float] | None) -> str:
    """``"all"`` or ``"350-600"``: a force band of :data:`PUSH_FORCE_BANDS` in newtons."""
    return "all" if band is None else f"{band[0]:g}-{band[1]:g}"


def _in_band(records: list[dict[str, Any]], band: tuple[float, float] | None) -> list[dict[str, Any]]:
    """The push records whose magnitude [N] lies in ``band`` (low, high), all of them for None."""
    return [record for record in records if band is None or band[0] <= record["magnitude"] <= band[1]]


def push_direction_rows(found: dict[str, dict[str, list[dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per (force band of :data:`PUSH_FORCE_BANDS`, controller, push direction) of ours (the
    thesis has none), ``forces`` naming the band (:func:`_band_name`)."""
    rows = []
    for band in PUSH_FORCE_BANDS:
        for label, groups in found.items():
            records = _in_band(groups.get(PUSH_DIR, []), band)
            rows += [
                {"controller": label, "forces": _band_name(band), **row}
                for row in summarise_push_directions(records)
            ]
    return rows


def push_left_right_rows(found: dict[str, dict[str, list[dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per (force band of :data:`PUSH_FORCE_BANDS`, controller) whose pushes went both left and right:
    left success minus right with its 95 % interval (:func:`krl.eval.summaries.summarise_push_left_right`),
    a seed group's attempts pooled over its seeds; ``forces`` names the band (:func:`_band_name`)."""
    rows = []
    for band in PUSH_FORCE_BANDS:
        for label, groups in found.items():
            records = _in_band(groups.get(PUSH_DIR, []), band)
            row = summarise_push_left_right(records)
            if row is not None:
                rows.append({"controller": label, "forces": _band_name(band), **row})
    return rows


def friction_rows(found: dict[str, dict[str, list[dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per (controller, course, μ) of the friction sweep (a seed group's pooled over its seeds,
    then one row per (seed, course, μ) with its ``seed``); the thesis has none."""
    return _sweep_rows(found, FRICTION_DIR, summarise_friction, summarise_friction_by_seed)


def _sweep_rows(found, group: str, pooled, by_seed) -> list[dict[str, Any]]:
    """Each controller's rows of the sweep whose records are under ``group``: ``pooled(records)``, then
    ``by_seed(records)``, each row with its ``controller``."""
    rows = []
    for label, groups in found.items():
        records = groups.get(group, [])
        rows += [{"controller": label, **row} for row in pooled(records)]
        rows += [{"controller": label, **row} for row in by_seed(records)]
    return rows


def push_markdown(rows: list[dict[str, Any]]) -> str:
    magnitudes = sorted({row["magnitude"] for row in rows})
    controllers: list[tuple[str, str, int | None]] = []
    for row in rows:
        if (row["source"], row["controller"], row.get("seed")) not in controllers:
            controllers.append((row["source"], row["controller"], row.get("seed")))
    header = "| source | controller | " + " | ".join(f"{m:g} N" for m in magnitudes) + " |"
    lines = [
        "### Table 5.5: success rate against push magnitude",
        "",
        header,
        "| --- | --- | " + " | ".join("---" for _ in magnitudes) + " |",
    ]
    for source, controller, seed in controllers:
        mine = {
            r["magnitude"]: r
            for r in rows
            if (r["source"], r["controller"], r.get("seed")) == (source, controller, seed)
        }
        attempts = sorted({r["attempts"] for r in mine.values()})
        # as many decimals as the attempts resolve: 10 attempts move a rate in steps of 0.1
        digits = 1 if all(10 % n == 0 for n in attempts) else 2
        cells = " | ".join(f"{mine[m]['success_rate']:.{digits}f}" if m in mine else "–" for m in magnitudes)
        seeds = max((r.get("seeds", 1) for r in mine.values()), default=1)
        if seed is not None:
            controller = f"{controller} seed {seed}"
        elif seeds > 1:
            controller = f"{controller} (pooled over {seeds} seeds)"
        if attempts != [THESIS_PUSH_ATTEMPTS]:
            controller = f"{controller} ({'/'.join(map(str, attempts))} attempts)"
        lines.append(f"| {source} | {controller} | {cells} |")
    ours = [r for r in rows if r["source"] == "krl"]
    if ours:
        first = ours[0]["controller"]
        impulses = {r["magnitude"]: r for r in ours if r["controller"] == first}
        lines.append(
            "| push | impulse [N·s] | "
            + " | ".join(f"{impulses[m]['impulse']:.2f}" if m in impulses else "–" for m in magnitudes)
            + " |"
        )
        lines.append(
            "| push | Δv [m/s] | "
            + " | ".join(f"{impulses[m]['delta_v']:.2f}" if m in impulses else "–" for m in magnitudes)
            + " |"
        )
    low, high = success_interval(7, THESIS_PUSH_ATTEMPTS)
    lines += [
        "",
        f"Rates of {THESIS_PUSH_ATTEMPTS} attempts unless a row says otherwise. Each rate's 95 % Wilson"
        f" interval is in `push.csv` (`success_low`, `success_high`) and shaded in `push.png`: of"
        f" {THESIS_PUSH_ATTEMPTS} attempts, a rate of 0.7 lies in {low:.2f}-{high:.2f}.",
    ]
    return "\n".join(lines) + "\n"


def push_direction_markdown(rows: list[dict[str, Any]]) -> str:
    """One table per force band of :data:`PUSH_FORCE_BANDS` that has rows (bands none of ``rows`` is in
    are left out): a row per controller, a column per direction."""
    lines = [
        "### Push success by direction",
        "",
        "The force's horizontal direction relative to the walk (origin to target), in quarters of 90°; "
        "success rate (attempts) and 95 % Wilson interval; over every force of the sweep, then over each "
        "band of forces.",
    ]
    for band in PUSH_FORCE_BANDS:
        name = _band_name(band)
        mine = [row for row in rows if row["forces"] == name]
        if not mine:
            continue
        lines += [
            "",
            "All forces:" if band is None else f"Forces {name} N:",
            "",
            *controller_table(
                mine,
                "direction",
                PUSH_DIRECTIONS,
                PUSH_DIRECTIONS,
                lambda r: (
                    f"{r['success_rate']:.2f} ({r['attempts']}), "
                    f"{r['success_low']:.2f}-{r['success_high']:.2f}"
                ),
            ),
        ]
    return "\n".join(lines) + "\n"


def push_left_right_markdown(rows: list[dict[str, Any]]) -> str:
    """A row per controller (named with how its directions were drawn), a column per force band of
    :data:`PUSH_FORCE_BANDS` that has rows: left success minus right (successes/attempts each side), the
    difference's 95 % interval over the attempts, and the distinct pushes left/right with its 95 % interval
    over them."""
    bands = [
        _band_name(band) for band in PUSH_FORCE_BANDS if any(r["forces"] == _band_name(band) for r in rows)
    ]
    draws = {r["controller"]: r["directions"] for r in rows if r["forces"] == "all"}
    named = [
        {**r, "controller": f"{r['controller']} ({draws.get(r['controller'], r['directions'])})"}
        for r in rows
    ]

    def cell(r: dict[str, Any]) -> str:
        sides = f"{r['left_successes']}/{r['left_attempts']} - {r['right_successes']}/{r['right_attempts']}"
        interval = f"{r['difference_low']:+.2f} to {r['difference_high']:+.2f}"
        pushes = (
            f"pushes {r['left_pushes']}/{r['right_pushes']}: "
            f"{r['difference_low_pushes']:+.2f} to {r['difference_high_pushes']:+.2f}"
        )
        return f"{r['difference']:+.2f} ({sides}), {interval}; {pushes}"

    lines = [
        "### Left minus right",
        "",
        "Success of the pushes to the left minus that of the pushes to the right (the quarters above), "
        "(successes/attempts left - right), and the difference's 95 % interval: Newcombe's hybrid score "
        "interval, from the two sides' Wilson intervals. It takes every attempt as independent, though "
        "every force and every seed of a group meets the same pushes (attempt a's time, point and "
        "direction), so it is narrower than the pushes' own spread warrants. After `pushes`, the number of "
        "distinct pushes left/right and a 95 % bootstrap interval that resamples these pushes, each with all "
        "its runs, rather than the attempts: it is the one to read. Beside each controller, how "
        "the directions were drawn: "
        "`uniform` (each side's attempts are random in number) or `balanced` (`krl evaluate "
        "--push-directions balanced`: equal attempts in each quarter, by design).",
        "",
        *controller_table(
            named, "forces", bands, ["all forces" if b == "all" else f"forces {b} N" for b in bands], cell
        ),
    ]
    return "\n".join(lines) + "\n"


def _seeded_rows(rows: list[dict[str, Any]], key: str, value: Any) -> list[dict[str, Any]]:
    """The rows whose ``key`` is ``value``, each a training seed's named so beside its controller."""
    return [
        {**r, "controller": r["controller"] + (f" seed {r['seed']}" if "seed" in r else "")}
        for r in rows
        if r[key] == value
    ]


def friction_markdown(rows: list[dict[str, Any]]) -> str:
    """One table per course: a row per controller (and per training seed), a column per μ, falling."""
    lines = [
        "### Success against ground friction (ours)",
        "",
        "The courses walked from every start with the ground's sliding friction μ (the thesis's ground: "
        "μ = 1). Each cell: success rate / fall rate (runs); the success rates' 95 % Wilson intervals are "
        "in `friction.csv`.",
    ]
    for course in dict.fromkeys(r["course"] for r in rows):
        mine = _seeded_rows(rows, "course", course)
        frictions = sorted({r["friction"] for r in mine}, reverse=True)
        lines += [
            "",
            f"Course `{course}`:",
            "",
            *controller_table(
                mine,
                "friction",
                frictions,
                [f"μ = {mu:g}" for mu in frictions],
                lambda r: f"{r['success_rate']:.2f} / {r['fall_rate']:.2f} ({r['runs']})",
            ),
        ]
    return "\n".join(lines) + "\n"


def plot_push(path: Path, rows: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axis = plt.subplots(figsize=(7, 4))
    colours = _push_colours(rows)
    for source, style in (("krl", "-o"), ("thesis", "--x")):
        for controller in dict.fromkeys(r["controller"] for r in rows if r["source"] == source):
            mine = sorted(
                (
                    r
                    for r in rows
                    if r["source"] == source and r["controller"] == controller and r.get("seed") is None
                ),
                key=lambda r: r["magnitude"],
            )
            magnitudes = [r["magnitude"] for r in mine]
            (line,) = axis.plot(
                magnitudes,
                [r["success_rate"] for r in mine],
                style,
                label=f"{controller} ({source})",
                alpha=0.9,
                color=colours[source, controller],
            )
            if source == "krl":
                low, high = [r["success_low"] for r in mine], [r["success_high"] for r in mine]
                axis.fill_between(magnitudes, low, high, color=line.get_color(), alpha=0.12, linewidth=0)
    axis.set_xlabel("push force [N] (one 1 ms physics step per control step for 0.3 s)")
    axis.set_ylabel("success rate")
    axis.set_ylim(-0.05, 1.05)
    axis.legend(fontsize=7)
    fig.tight_layout()
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)


def _push_colours(rows: list[dict[str, Any]]) -> dict[tuple[str, str], Any]:
    """A colour per (source, controller) of the push rows: every one of ours its own, and a thesis row the
    colour of ours that is the same controller (:data:`THESIS_NAMES`; dashed beside solid), else its own."""
    ours = list(dict.fromkeys(r["controller"] for r in rows if r["source"] == "krl"))
    named = {THESIS_NAMES[label]: label for label in ours if label in THESIS_NAMES}
    theirs = list(dict.fromkeys(r["controller"] for r in rows if r["source"] == "thesis"))
    alone = [name for name in theirs if name not in named]
    palette = distinct_colours(len(ours) + len(alone))
    colours = {("krl", label): palette[index] for index, label in enumerate(ours)}
    colours.update({("thesis", name): colours["krl", label] for name, label in named.items()})
    colours.update({("thesis", name): palette[len(ours) + index] for index, name in enumerate(alone)})
    return colours


def plot_friction(path: Path, rows: list[dict[str, Any]]) -> None:
    """Success rate against ground friction μ, one panel per course, one line per controller (pooled over a
    seed group's seeds), its 95 % Wilson interval shaded."""
    _plot_panels(path, rows, "course", "friction", "course {}", "ground friction μ (thesis: 1)")


def plot_stairs(path: Path, rows: list[dict[str, Any]]) -> None:
    """Success rate against riser height, one panel per direction (up, down), one line per controller
    (pooled over a seed group's seeds), its 95 % Wilson interval shaded."""
    _plot_panels(path, rows, "direction", "riser", "stairs {}", "riser height [m]")


def _plot_panels(path: Path, rows: list[dict[str, Any]], panel: str, x: str, title: str, xlabel: str) -> None:
    """Success rate against ``row[x]``, one panel per value of ``row[panel]`` (titled ``title`` with it), a
    line per controller (the rows without a ``seed``), each 95 % Wilson interval shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = list(dict.fromkeys(r[panel] for r in rows))
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    colours = dict(zip(controllers, distinct_colours(len(controllers)), strict=True))
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.8), sharey=True, squeeze=False)
    for axis, name in zip(axes[0], panels, strict=True):
        pooled = [r for r in rows if r[panel] == name and "seed" not in r]
        for controller in dict.fromkeys(r["controller"] for r in pooled):
            mine = sorted((r for r in pooled if r["controller"] == controller), key=lambda r: r[x])
            xs = [r[x] for r in mine]
            (line,) = axis.plot(
                xs, [r["success_rate"] for r in mine], "-o", label=controller, color=colours[controller]
            )
            low, high = [r["success_low"] for r in mine], [r["success_high"] for r in mine]
            axis.fill_between(xs, low, high, color=line.get_color(), alpha=0.12, linewidth=0)
        axis.set_title(title.format(name))
        axis.set_xlabel(xlabel)
        axis.set_ylim(-0.05, 1.05)
    axes[0][0].set_ylabel("success rate")
    axes[0][-1].legend(fontsize=7)
    fig.tight_layout()
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)


def stair_rows(found: dict[str, dict[str, list[dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per (controller, riser, direction) of the stair sweep (a seed group's pooled over its seeds,
    then one row per (seed, riser, direction) with its ``seed``)."""
    return _sweep_rows(found, STAIR_DIR, summarise_stairs, summarise_stairs_by_seed)


def stairs_markdown(rows: list[dict[str, Any]]) -> str:
    """One table per direction: a row per controller (and per training seed), a column per riser, and the
    risers the controller trained on (the riser's cell marked † where it lies outside them)."""
    lines = [
        "### Success against riser height (ours)",
        "",
        "Straight flights of five risers up onto a landing, or down from it (krl.eval.stair_sweep), from 4 "
        "starts each. Each cell: success rate / fall rate (runs), † where the riser lies outside the risers "
        "the controller's policy trained on (last column; – for a controller trained on none). The success "
        "rates' 95 % Wilson intervals are in `stairs.csv`.",
    ]
    for direction in dict.fromkeys(r["direction"] for r in rows):
        mine = _seeded_rows(rows, "direction", direction)
        risers = sorted({r["riser"] for r in mine})
        trained = {r["controller"]: r["trained_risers"] for r in mine}
        table = controller_table(
            mine,
            "riser",
            risers,
            [f"{riser * 100:g} cm" for riser in risers],
            lambda r: (
                f"{r['success_rate']:.2f} / {r['fall_rate']:.2f} ({r['runs']})"
                + ("†" if r["in_training"] is False else "")
            ),
        )
        table[0] += " trained risers |"
        table[1] += " --- |"
        for index, controller in enumerate(dict.fromkeys(r["controller"] for r in mine), start=2):
            span = trained[controller]
            table[index] += f" {'–' if span is None else f'{span[0] * 100:g}-{span[1] * 100:g} cm'} |"
        lines += ["", f"Stairs {direction}:", "", *table]
    return "\n".join(lines) + "\n"


def write_sweep_sections(
    found: dict[str, dict[str, list[dict[str, Any]]]], out: Path
) -> tuple[list[str], list[str], list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]]]:
    """The push, friction and stair sections of ``evaluation.md`` and their files in ``out``.

    Returns (markdown parts, paths written, push rows with the thesis's, friction rows, stair rows); no
    part where a sweep has no records of ours.
    """
    parts: list[str] = []
    written: list[str] = []
    pushes = push_rows(found)
    if any(r["source"] == "krl" for r in pushes):
        directions = push_direction_rows(found)
        parts += [push_markdown(pushes), "![success against push magnitude](push.png)\n"]
        parts.append(push_direction_markdown(directions))
        write_atomic(out / "push.csv", rows_csv(pushes))
        plot_push(out / "push.png", pushes)
        write_atomic(out / "push-direction.csv", rows_csv(directions))
        written += [str(out / name) for name in ("push.csv", "push.png", "push-direction.csv")]
        sides = push_left_right_rows(found)
        if sides:
            parts.append(push_left_right_markdown(sides))
            write_atomic(out / "push-left-right.csv", rows_csv(sides))
            written.append(str(out / "push-left-right.csv"))
    frictions, stairs = friction_rows(found), stair_rows(found)
    sections = (
        (frictions, friction_markdown, plot_friction, "friction", "success against ground friction"),
        (stairs, stairs_markdown, plot_stairs, "stairs", "success against riser height"),
    )
    for rows, markdown, plot, name, caption in sections:
        if rows:
            parts += [markdown(rows), f"![{caption}]({name}.png)\n"]
            write_atomic(out / f"{name}.csv", rows_csv(rows))
            plot(out / f"{name}.png", rows)
            written += [str(out / f"{name}.csv"), str(out / f"{name}.png")]
    return parts, written, pushes, frictions, stairs
