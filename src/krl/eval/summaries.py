"""Summaries of ``krl evaluate`` records: a course's row (Tables 5.1-5.4), the push sweep's (Table 5.5) and
its push directions, the friction sweep's, each pooled over a seed group's runs or per training seed.

Pure functions of the records (:func:`krl.eval.records.read_runs`), shared by ``krl evaluate --json`` and
``krl report``.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from typing import Any

import numpy as np

from krl.util.rounding import readable


def _mean_std(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (n - 1, as the thesis's tables); std 0 for a single value."""
    mean = statistics.fmean(values)
    return mean, (statistics.stdev(values) if len(values) > 1 else 0.0)


def _counts_as_fall(metrics: dict[str, Any]) -> bool:
    """A fall, or a run that ended with an error (diverging simulation, MPC failure)."""
    return bool(metrics["fell"] or metrics["error"] is not None)


def summarise_course(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Mean ± std over a course's runs: reward per step, waypoints reached; success and fall rates.

    A run that ended with an error (diverging simulation, MPC failure) counts as a fall.
    """
    metrics = [r["metrics"] for r in records]
    if not metrics:
        raise ValueError("no runs to summarise")
    reward = _mean_std([m["reward_per_step"] for m in metrics])
    targets = _mean_std([m["targets_reached"] for m in metrics])
    distance = _mean_std([m["distance_walked"] for m in metrics])
    finish_times = [m["time_to_finish"] for m in metrics if m["time_to_finish"] is not None]
    return {
        "runs": len(metrics),
        "targets": metrics[0]["targets"],
        "reward_per_step_mean": reward[0],
        "reward_per_step_std": reward[1],
        "targets_reached_mean": targets[0],
        "targets_reached_std": targets[1],
        "success_rate": sum(m["success"] for m in metrics) / len(metrics),
        "fall_rate": sum(_counts_as_fall(m) for m in metrics) / len(metrics),
        "error_runs": sum(m["error"] is not None for m in metrics),
        "time_to_finish_mean": statistics.fmean(finish_times) if finish_times else None,
        "distance_walked_mean": distance[0],
        "distance_walked_std": distance[1],
    }


SUCCESS_CONFIDENCE_Z = 1.959963984540054
"""Standard-normal quantile of the success rates' two-sided 95 % intervals."""


def success_interval(successes: int, attempts: int) -> tuple[float, float]:
    """Wilson score interval (95 %) of a success rate measured as ``successes`` of ``attempts``.

    It stays inside [0, 1] and is not empty at 0 or 1 successes (10 of 10 gives 0.72-1.00), unlike the
    normal approximation. Used for the push sweep, whose rates come from few attempts per magnitude.
    """
    if not 0 <= successes <= attempts or attempts < 1:
        raise ValueError(f"need 0 <= successes <= attempts >= 1, got {successes} of {attempts}")
    z2 = SUCCESS_CONFIDENCE_Z**2
    rate = successes / attempts
    centre = (rate + z2 / (2 * attempts)) / (1 + z2 / attempts)
    half = SUCCESS_CONFIDENCE_Z * math.sqrt(rate * (1 - rate) / attempts + z2 / (4 * attempts**2))
    half /= 1 + z2 / attempts
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == attempts else min(1.0, centre + half)
    return low, high


def difference_interval(
    successes_a: int, attempts_a: int, successes_b: int, attempts_b: int
) -> tuple[float, float]:
    """95 % interval of the difference of two success rates, p_a - p_b (``successes_a`` of ``attempts_a``
    against ``successes_b`` of ``attempts_b``): Newcombe's hybrid score interval (Newcombe 1998, *Statistics
    in Medicine* 17:873-890, method 10), built from each rate's Wilson score interval (l, u)
    (:func:`success_interval`)::

        low  = (p_a - p_b) - sqrt((p_a - l_a)² + (u_b - p_b)²)
        high = (p_a - p_b) + sqrt((u_a - p_a)² + (p_b - l_b)²)

    It stays inside [-1, 1] and keeps its coverage with few attempts and rates near 0 or 1, where the normal
    approximation does not. It takes every attempt as independent of the others.
    """
    p_a, p_b = successes_a / max(attempts_a, 1), successes_b / max(attempts_b, 1)
    low_a, high_a = success_interval(successes_a, attempts_a)
    low_b, high_b = success_interval(successes_b, attempts_b)
    difference = p_a - p_b
    low = difference - math.hypot(p_a - low_a, high_b - p_b)
    high = difference + math.hypot(high_a - p_a, p_b - low_b)
    return max(-1.0, low), min(1.0, high)


BOOTSTRAP_RESAMPLES = 2000
"""Resamples of :func:`cluster_difference_interval`'s bootstrap."""


def cluster_difference_interval(
    clusters_a: Sequence[tuple[int, int]], clusters_b: Sequence[tuple[int, int]]
) -> tuple[float, float]:
    """95 % percentile bootstrap interval of the difference of two success rates, p_a - p_b, whose runs come
    in clusters: ``clusters_a`` and ``clusters_b`` hold one (successes, runs) pair per cluster, runs >= 1.

    Made for the push sweep, whose attempt ``a`` draws the same push (time, point, direction) at every force
    and for every seed: a cluster is one distinct push with all its runs, which share the push and so are not
    independent. The bootstrap resamples the clusters of a with replacement (as many as it has) and,
    independently, those of b; a resample's rate is its clusters' successes summed over their runs summed.
    The interval (low, high) is the 2.5 and 97.5 percentiles of p_a - p_b over :data:`BOOTSTRAP_RESAMPLES`
    resamples, a difference of rates within [-1, 1]. So it reflects how many distinct pushes there are,
    where :func:`difference_interval` counts every run. The generator is seeded (``default_rng(0)``): the
    same clusters give the same interval. A side with fewer than 2 clusters has no spread to resample, which
    says nothing of the difference: the interval is then the whole range, (-1.0, 1.0).
    """
    if len(clusters_a) < 2 or len(clusters_b) < 2:
        return -1.0, 1.0
    rng = np.random.default_rng(0)
    rates = []
    for clusters in (clusters_a, clusters_b):
        successes, runs = np.asarray(clusters, dtype=np.int64).T
        if np.any(runs < 1) or np.any(successes < 0) or np.any(successes > runs):
            raise ValueError(f"need 0 <= successes <= runs >= 1 in every cluster, got {clusters}")
        drawn = rng.integers(len(runs), size=(BOOTSTRAP_RESAMPLES, len(runs)))  # (resamples, clusters)
        rates.append(successes[drawn].sum(axis=1) / runs[drawn].sum(axis=1))
    low, high = np.percentile(rates[0] - rates[1], [2.5, 97.5])
    return float(low), float(high)


PUSH_DIRECTIONS: tuple[str, ...] = ("forward", "left", "backward", "right")
"""Quarters of the push's horizontal direction, relative to the base's heading when the push starts
(:func:`push_direction`): each spans 90° centred on its name (``forward``: the force's azimuth within ±45°
of it)."""

QUARTER = math.pi / 2
"""The angle [rad] of one quarter of :data:`PUSH_DIRECTIONS`: quarter k is centred on k·QUARTER from the
heading, counter-clockwise (forward, left, backward, right)."""


def push_direction(record: dict[str, Any]) -> str:
    """Which of :data:`PUSH_DIRECTIONS` a push attempt's force (its horizontal part) points to, relative to
    the base's heading when the push started (``push_heading``); for a record without it (written before
    krl recorded it, or a run that ended before the push), relative to the direction of the sweep's target."""
    metrics = record["metrics"]
    force = metrics["push"]["force"]
    heading = metrics.get("push_heading")
    if heading is None:
        target = record["sweep"]["target"]
        heading = math.atan2(target[1], target[0])
    relative = math.atan2(force[1], force[0]) - heading
    quarter = round(relative / QUARTER) % len(PUSH_DIRECTIONS)
    return PUSH_DIRECTIONS[quarter]


def _success(group: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Attempts, success rate and its 95 % interval (:func:`success_interval`) of a group of runs."""
    successes = sum(bool(r["metrics"]["success"]) for r in group)
    low, high = success_interval(successes, len(group))
    return {
        "attempts": len(group),
        "success_rate": successes / len(group),
        "success_low": low,
        "success_high": high,
    }


def summarise_push_directions(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per push direction (:func:`push_direction`), over every magnitude of the sweep: attempts,
    success rate and its 95 % interval. Shows which pushes a controller fails, which the per-magnitude
    rates, each of a mix of directions, do not."""
    by_direction: dict[str, list[dict[str, Any]]] = {}
    for record in records:
        by_direction.setdefault(push_direction(record), []).append(record)
    return [
        {"direction": direction, **_success(by_direction[direction])}
        for direction in PUSH_DIRECTIONS
        if direction in by_direction
    ]


def push_draws(records: Sequence[dict[str, Any]]) -> str:
    """How the push attempts' directions were drawn (``krl evaluate --push-directions``): ``uniform``,
    ``balanced``, or both joined by ``+``; a record made before the option existed is ``uniform``."""
    return "+".join(sorted({r["sweep"].get("directions", "uniform") for r in records}))


def summarise_push_left_right(records: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """Left push success minus right (:func:`push_direction`'s quarters) over ``records``: each side's
    attempts and success rate, the difference and its 95 % interval (:func:`difference_interval`), and how the
    directions were drawn (:func:`push_draws`); then each side's distinct pushes (``left_pushes``,
    ``right_pushes``: its attempt indices, each met at every force and by every seed) and the difference's
    95 % interval that resamples them (``difference_low_pushes``, ``difference_high_pushes``:
    :func:`cluster_difference_interval`). None where a side has no attempt."""
    pushes: dict[str, dict[int, list[int]]] = {"left": {}, "right": {}}  # {attempt: [successes, runs]}
    for record in records:
        direction = push_direction(record)
        if direction in pushes:
            counts = pushes[direction].setdefault(record["attempt"], [0, 0])
            counts[0] += bool(record["metrics"]["success"])
            counts[1] += 1
    if not (pushes["left"] and pushes["right"]):
        return None
    clusters = {side: [(s, n) for s, n in found.values()] for side, found in pushes.items()}
    (left, n_left), (right, n_right) = (
        (sum(s for s, _ in side), sum(n for _, n in side)) for side in clusters.values()
    )
    low, high = difference_interval(left, n_left, right, n_right)
    low_pushes, high_pushes = cluster_difference_interval(clusters["left"], clusters["right"])
    return {
        "directions": push_draws(records),
        "left_attempts": n_left,
        "left_successes": left,
        "left_success_rate": left / n_left,
        "right_attempts": n_right,
        "right_successes": right,
        "right_success_rate": right / n_right,
        "difference": left / n_left - right / n_right,
        "difference_low": low,
        "difference_high": high,
        "left_pushes": len(clusters["left"]),
        "right_pushes": len(clusters["right"]),
        "difference_low_pushes": low_pushes,
        "difference_high_pushes": high_pushes,
    }


def summarise_push(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per magnitude: success rate with its 95 % interval (:func:`success_interval`), fall rate,
    mean impulse [N·s] and Δv [m/s] of the pushes. Records of several training seeds are pooled (with equal
    attempts per seed, the rate is the mean of the seeds' rates); their rows add ``seeds`` and
    ``success_rate_seed_std``, the sample std of the seeds' rates."""
    by_magnitude: dict[float, list[dict[str, Any]]] = {}
    for record in records:
        by_magnitude.setdefault(float(record["magnitude"]), []).append(record)
    rows = []
    for magnitude in sorted(by_magnitude):
        group = by_magnitude[magnitude]
        row = {
            "magnitude": magnitude,
            **_success(group),
            "fall_rate": sum(_counts_as_fall(r["metrics"]) for r in group) / len(group),
            "impulse": statistics.fmean(r["metrics"]["push"]["impulse"] for r in group),
            "delta_v": statistics.fmean(r["metrics"]["push"]["delta_v"] for r in group),
        }
        seeds = by_seed(group)
        if len(seeds) > 1:
            rates = [_success(runs)["success_rate"] for runs in seeds.values()]
            row.update(seeds=len(seeds), success_rate_seed_std=_mean_std(rates)[1])
        rows.append(row)
    return rows


def by_seed(records: Sequence[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """The records of a seed group's runs by training seed, in seed order (empty for runs of one policy)."""
    groups: dict[int, list[dict[str, Any]]] = {}
    for record in records:
        if record.get("seed") is not None:
            groups.setdefault(record["seed"], []).append(record)
    return dict(sorted(groups.items()))


def summarise_push_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """:func:`summarise_push` of each training seed's attempts, each row with its ``seed``."""
    return [{"seed": seed, **row} for seed, runs in by_seed(records).items() for row in summarise_push(runs)]


def summarise_course_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per training seed of a course's runs: runs, waypoints reached (mean), success and fall rate."""
    rows = []
    for seed, runs in by_seed(records).items():
        summary = summarise_course(runs)
        keep = ("runs", "targets", "targets_reached_mean", "success_rate", "fall_rate")
        rows.append({"seed": seed, **{key: summary[key] for key in keep}})
    return rows


def summarise_friction(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (course, μ) of the friction sweep, courses in the records' order and μ falling: runs,
    success rate with its 95 % interval (:func:`success_interval`), fall rate (errors count as falls) and
    waypoints reached (mean). Records of several training seeds are pooled; their rows add ``seeds`` and
    ``success_rate_seed_std``, the sample std of the seeds' rates."""
    groups: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for record in records:
        groups.setdefault((record["course"], float(record["friction"])), []).append(record)
    courses = list(dict.fromkeys(course for course, _ in groups))
    order = sorted(groups, key=lambda key: (courses.index(key[0]), -key[1]))
    return [{"course": course, "friction": mu, **_runs_row(groups[course, mu])} for course, mu in order]


def _runs_row(group: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """A sweep row's figures over ``group``'s runs: runs, success rate with its 95 % interval, fall rate
    (errors count as falls), waypoints reached (mean); for several training seeds pooled also ``seeds`` and
    ``success_rate_seed_std``, the sample std of the seeds' rates."""
    success = _success(group)
    row = {
        "runs": success.pop("attempts"),
        **success,
        "fall_rate": sum(_counts_as_fall(r["metrics"]) for r in group) / len(group),
        "targets_reached_mean": statistics.fmean(r["metrics"]["targets_reached"] for r in group),
    }
    seeds = by_seed(group)
    if len(seeds) > 1:
        rates = [_success(runs)["success_rate"] for runs in seeds.values()]
        row.update(seeds=len(seeds), success_rate_seed_std=_mean_std(rates)[1])
    return row


def summarise_friction_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """:func:`summarise_friction` of each training seed's runs, each row with its ``seed``."""
    return [
        {"seed": seed, **row} for seed, runs in by_seed(records).items() for row in summarise_friction(runs)
    ]


def summarise_stairs(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (riser, direction) of the stair sweep, risers rising, up before down: ``riser`` [m],
    ``direction``, ``trained_risers`` (the policy's training range [m], or None), ``in_training`` (whether
    the riser lies in it; None without one), and :func:`_runs_row`'s figures. Seeds pooled as
    :func:`summarise_friction`'s."""
    groups: dict[tuple[float, str], list[dict[str, Any]]] = {}
    for record in records:
        groups.setdefault((float(record["stair"]["riser"]), record["stair"]["direction"]), []).append(record)
    rows = []
    for riser, direction in sorted(groups, key=lambda key: (key[0], key[1] != "up")):
        group = groups[riser, direction]
        ranges = [r["stair"]["trained_risers"] for r in group if r["stair"]["trained_risers"] is not None]
        trained = [min(low for low, _ in ranges), max(high for _, high in ranges)] if ranges else None
        inside = None if trained is None else bool(trained[0] - 1e-9 <= riser <= trained[1] + 1e-9)
        rows.append(
            {"riser": riser, "direction": direction, "trained_risers": trained, "in_training": inside}
            | _runs_row(group)
        )
    return rows


def summarise_stairs_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """:func:`summarise_stairs` of each training seed's runs, each row with its ``seed``."""
    return [
        {"seed": seed, **row} for seed, runs in by_seed(records).items() for row in summarise_stairs(runs)
    ]


SUMMARY_FIELDS: dict[str, str] = {
    "results": "the results folder (--out)",
    "runs": "the runs this call asked for",
    "ran": "of those, run now",
    "stored": "of those, read from --out, stored by an earlier call (resumed)",
    "shared": "of those, copied from a run of the same controller under another label (one policy file "
    "given two ways runs once)",
    "push_sweep": "the push sweep's settings",
    "controllers": "per controller label: per course runs, targets, reward per step, waypoints reached and "
    "distance walked [m] (mean, std), success and fall rates (errors count as falls), error runs, mean "
    "time to finish [s]; push: per magnitude [N] attempts, success rate with its 95 % interval "
    "(success_low, success_high), fall rate, impulse [N·s], delta_v [m/s]; push_directions, push_left_right; "
    "friction: per course and μ; stair_sweep: per riser [m] and direction (up, down) runs, success_rate, "
    "fall_rate, in_training (the riser inside the policy's training range); *_by_seed: the same per "
    "training seed; wall_seconds: compute time of the controller's runs",
}
"""The fields of ``krl evaluate``'s summary (:func:`evaluation_summary`), as its ``--help`` lists them."""


def evaluation_summary(
    entries: dict[str, dict[str, Any]],
    runs: int,
    counts: dict[str, int],
    out: str,
    push_sweep: dict[str, Any] | None,
) -> dict[str, Any]:
    """``krl evaluate``'s summary (fields: :data:`SUMMARY_FIELDS`), rounded as a person reads it
    (:func:`krl.util.rounding.readable`): ``entries`` {label: :func:`controller_entry`}, ``runs`` of the
    call, ``counts`` by how their record came ({ran, stored, shared}), ``push_sweep`` the sweep's settings or
    None."""
    summary: dict[str, Any] = {"results": out, "runs": runs, **counts, "controllers": {}}
    if push_sweep is not None:
        summary["push_sweep"] = push_sweep
    summary["controllers"] = entries
    return readable(summary)


def controller_entry(
    records: Sequence[dict[str, Any]],
    courses: Sequence[str],
    seeded: bool,
    push: bool,
    friction: bool,
    stairs: bool = False,
) -> dict[str, Any]:
    """One controller's part of :func:`evaluation_summary`: its ``records`` summarised per course (of
    ``courses``), for the push, friction and stair sweeps where they ran, each also per training seed for a
    ``seeded`` controller, and the wall time of its runs."""
    entry: dict[str, Any] = {}
    for course in courses:
        runs = [r for r in records if r.get("course") == course and "friction" not in r and "stair" not in r]
        entry[course] = summarise_course(runs)
        if seeded:
            entry[course]["by_seed"] = summarise_course_by_seed(runs)
    if push:
        pushes = [r for r in records if "magnitude" in r]
        entry["push"] = summarise_push(pushes)
        if seeded:
            entry["push_by_seed"] = summarise_push_by_seed(pushes)
        entry["push_directions"] = summarise_push_directions(pushes)
        entry["push_left_right"] = summarise_push_left_right(pushes)
    if friction:
        grounds = [r for r in records if "friction" in r]
        entry["friction"] = summarise_friction(grounds)
        if seeded:
            entry["friction_by_seed"] = summarise_friction_by_seed(grounds)
    if stairs:
        flights = [r for r in records if "stair" in r]
        entry["stair_sweep"] = summarise_stairs(flights)
        if seeded:
            entry["stair_sweep_by_seed"] = summarise_stairs_by_seed(flights)
    entry["wall_seconds"] = sum(r["metrics"]["wall_seconds"] for r in records)
    return entry
