"""Expert data collection (thesis Section 4.2.6.2): the MPC expert walks to random targets; every 200 Hz
control step becomes one row of :mod:`krl.data.schema`.

The collection is split into *episodes* of ``targets_per_episode`` consecutive targets. Each episode starts
from a standing reset at the terrain's spawn with a fresh simulator and expert, and draws its targets (and,
in ``ext`` mode, its step/ride heights) from ``np.random.default_rng([seed, episode])``, so an episode's
rows do not depend on what ran before it. A finished episode is written atomically as one Parquet part
file and then listed in ``manifest.json`` (also written atomically); re-running the same collection on the
same directory resumes after the last finished episode. ``docs/data.md`` has the layout and the reasoning.

Modes:

- ``base``: fixed expert settings (the kernel-base data).
- ``ext``: before each target, one of the two heights is redrawn, step height ~ U(0.05, 0.18) m or ride
  height ~ U(0.18, 0.28) m (each with probability 1/2), and the other is set to the expert's nominal
  value; applied with :meth:`MPCExpert.set_heights` (kernel-ext). ``ext_heights="both"`` redraws both
  every target instead (krl's first ext data), which also visits low-body/high-step combinations
  where the swing apex comes within a few centimetres of the hips and the expert's steps turn erratic
  (docs/kernel.md, "kernel-ext's loss").
- ``dyn2``: a standing reset at the spawn before every target, which is drawn around the spawn
  (kernel-dyn2).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from krl.control.commands import CommandParams
from krl.control.expert import RIDE_HEIGHT_RANGE, STEP_HEIGHT_RANGE, ExpertParams, MPCExpert
from krl.control.gait import normalised_phase
from krl.control.mpc import MPCError
from krl.data.columns import input_columns
from krl.data.schema import FIELDS, canonical_json
from krl.data.storage import directory_lock, open_dataset, write_manifest, write_part
from krl.sim.robot import SimulationUnstableError
from krl.task import TARGET_DISTANCE, TARGET_TIME_LIMIT, random_targets
from krl.task.runner import Runner, StepRecord
from krl.util.progress import progress_bar
from krl.util.timing import CONTROL_DT

MODES: tuple[str, ...] = ("base", "ext", "dyn2")
"""Collection modes (see the module docstring)."""

EXT_HEIGHTS: tuple[str, ...] = ("one", "both")
"""``ext`` mode: redraw one of the two heights per target (the thesis's "step height or ride height"),
or both."""


# --- configuration ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class CollectConfig:
    """What to collect. Everything except ``targets`` must match when a collection is resumed."""

    targets: int = 500
    """Total number of targets (the thesis's 500)."""
    mode: str = "base"
    """One of :data:`MODES`."""
    targets_per_episode: int = 10
    """Targets per episode (one part file, the unit of resumption); the last episode may have fewer."""
    target_time_limit: float = TARGET_TIME_LIMIT
    """Time allowed to reach one target before it is skipped [s]."""
    seed: int = 0
    """Seed of the terrain and of every episode's draws (``default_rng([seed, episode])``)."""
    expert: ExpertParams = field(default_factory=ExpertParams)
    """The expert's settings (in ``ext`` mode its step and ride heights are redrawn per target)."""
    terrain: str = "flat"
    """Terrain name (:data:`krl.sim.terrains.TERRAIN_NAMES`)."""
    terrain_params: Mapping[str, Any] | None = None
    """Terrain parameter overrides."""
    command: CommandParams = field(default_factory=CommandParams)
    """Command generator parameters (Algorithm 2)."""
    target_distance: tuple[float, float] = TARGET_DISTANCE
    """Target distance range (low, high) [m]; tests use short distances."""
    step_height_range: tuple[float, float] = STEP_HEIGHT_RANGE
    """``ext`` mode: step height ~ U(range) [m] (thesis 4.2.6.5)."""
    ride_height_range: tuple[float, float] = RIDE_HEIGHT_RANGE
    """``ext`` mode: ride height ~ U(range) [m] (thesis 4.2.6.5)."""
    ext_heights: str = "one"
    """``ext`` mode: which heights each target redraws (one of :data:`EXT_HEIGHTS`)."""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown collection mode {self.mode!r}; modes: {', '.join(MODES)}")
        if self.ext_heights not in EXT_HEIGHTS:
            raise ValueError(f"ext_heights must be one of {', '.join(EXT_HEIGHTS)}, got {self.ext_heights!r}")
        for name in ("targets", "targets_per_episode", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(f"{name} must be an integer, got {value!r}")
        if self.targets < 1:
            raise ValueError(f"targets must be >= 1, got {self.targets}")
        if self.targets_per_episode < 1:
            raise ValueError(f"targets_per_episode must be >= 1, got {self.targets_per_episode}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        if not (np.isfinite(self.target_time_limit) and self.target_time_limit > 0):
            raise ValueError(f"target_time_limit must be > 0 s, got {self.target_time_limit}")
        low, high = (float(v) for v in self.target_distance)
        if not (np.isfinite(high) and 0 < low <= high):
            raise ValueError(f"target distance must satisfy 0 < low <= high, got {self.target_distance}")
        object.__setattr__(self, "target_distance", (low, high))
        for name, allowed in (
            ("step_height_range", STEP_HEIGHT_RANGE),
            ("ride_height_range", RIDE_HEIGHT_RANGE),
        ):
            low, high = (float(v) for v in getattr(self, name))
            if not allowed[0] <= low <= high <= allowed[1]:
                raise ValueError(f"{name} must lie within {allowed} with low <= high, got ({low}, {high})")
            object.__setattr__(self, name, (low, high))
        if self.terrain_params is not None:
            object.__setattr__(self, "terrain_params", dict(self.terrain_params))

    @property
    def num_episodes(self) -> int:
        return -(-self.targets // self.targets_per_episode)

    def episode_targets(self, episode: int) -> int:
        """Number of targets of ``episode`` (all full except possibly the last)."""
        return min(self.targets_per_episode, self.targets - episode * self.targets_per_episode)

    def settings(self, terrain) -> dict[str, Any]:
        """The settings that define the data (everything but ``targets``), JSON-ready; ``terrain`` is the
        built :class:`krl.sim.terrains.Terrain` (its resolved parameters are recorded)."""
        settings = {
            "mode": self.mode,
            "seed": int(self.seed),
            "targets_per_episode": int(self.targets_per_episode),
            "target_time_limit": float(self.target_time_limit),
            "target_distance": list(self.target_distance),
            "step_height_range": list(self.step_height_range),
            "ride_height_range": list(self.ride_height_range),
            "expert": dataclasses.asdict(self.expert),
            "terrain": {"name": terrain.name, "params": dict(terrain.params)},
            "spawn_xy": [float(v) for v in terrain.spawn_xy],
            "command": dataclasses.asdict(self.command),
            "control_dt": CONTROL_DT,
        }
        if self.mode == "ext":
            settings["ext_heights"] = self.ext_heights
        return json.loads(canonical_json(settings))  # tuples -> lists, numpy scalars -> numbers


# --- recording -------------------------------------------------------------------------------------


class _EpisodeRecorder:
    """Collects the rows of one episode into growing numpy buffers (one per field)."""

    def __init__(self, expert: MPCExpert, episode: int, capacity: int = 8192) -> None:
        self.expert = expert
        self.episode = episode
        self.rows = 0
        self.buffers = {f.name: np.zeros((capacity, *f.shape), dtype=f.dtype) for f in FIELDS}
        self.target_index = -1
        self.target_xy = np.zeros(2)
        self.new_segment = True

    def _grow(self) -> None:
        for name, buffer in self.buffers.items():
            bigger = np.zeros((2 * len(buffer), *buffer.shape[1:]), dtype=buffer.dtype)
            bigger[: len(buffer)] = buffer
            self.buffers[name] = bigger

    def on_step(self, record: StepRecord) -> None:
        n = self.rows
        if n == len(self.buffers["time"]):
            self._grow()
        buf = self.buffers
        before, after = record.before, record.after
        expert = self.expert
        last = expert.last
        params = expert.params
        # the phases the action used: act() advances the gait clock before deciding
        phases = expert.gait.phases
        normalised = normalised_phase(phases, expert.gait.params.swing_ratio)
        # the kernel's inputs, built as every controller that feeds a kernel builds them
        for name, column in input_columns(
            before, record.command, normalised, params.step_height, params.ride_height
        ).items():
            buf[name][n] = column[0]
        buf["ddq"][n] = (after.joint_vel - before.joint_vel) / CONTROL_DT
        buf["phase"][n] = phases
        buf["stance"][n] = last.stance
        buf["foot_pos"][n] = before.foot_pos_base.reshape(-1)
        buf["foot_ref"][n] = last.foot_targets.reshape(-1)
        buf["foot_pos_next"][n] = after.foot_pos_base.reshape(-1)
        buf["stance_duration"][n] = params.stance_duration
        buf["episode"][n] = self.episode
        buf["target_index"][n] = self.target_index
        buf["time"][n] = n * CONTROL_DT
        buf["time_since_reset"][n] = before.time
        buf["new_segment"][n] = self.new_segment
        buf["base_pos"][n] = before.base_pos
        buf["rpy"][n] = before.rpy
        buf["target_xy"][n] = self.target_xy
        buf["fell"][n] = after.fallen
        self.new_segment = False
        self.rows = n + 1

    def columns(self) -> dict[str, np.ndarray]:
        return {name: buffer[: self.rows] for name, buffer in self.buffers.items()}


@dataclass
class EpisodeStats:
    """Counts of one episode."""

    episode: int
    targets: int = 0
    targets_reached: int = 0
    falls: int = 0
    timeouts: int = 0
    unstable: int = 0
    """Targets abandoned because the physics diverged or the MPC's QP failed (then reset like a fall)."""
    rows: int = 0


def collect_episode(
    built,
    config: CollectConfig,
    episode: int,
    on_target: Callable[[EpisodeStats], None] | None = None,
) -> tuple[dict[str, np.ndarray], EpisodeStats]:
    """Run one episode and return its rows (numpy arrays by field name) and counts.

    Deterministic: a fresh simulator and expert, draws from ``default_rng([seed, episode])``. For each
    target, in order, the generator draws its distance and direction (:func:`krl.task.runner.random_targets`,
    one target at a time, so a prefix of the draws never depends on the count), then a step height and
    a ride height (drawn in every mode, used in ``ext``), so every mode sees the same draw sequence.
    """
    from krl.sim.robot import A1Sim

    sim = A1Sim(built)
    expert = MPCExpert(config.expert)
    recorder = _EpisodeRecorder(expert, episode)
    runner = Runner(sim, expert, config.command, on_step=recorder.on_step)
    rng = np.random.default_rng([config.seed, episode])
    spawn = np.asarray(sim.terrain.spawn_xy, dtype=float)
    stats = EpisodeStats(episode=episode)
    need_reset = True
    anchor = spawn
    for k in range(config.episode_targets(episode)):
        if config.mode == "dyn2":
            need_reset = True
        if need_reset:
            anchor = spawn
        target = random_targets(rng, 1, (float(anchor[0]), float(anchor[1])), config.target_distance)[0]
        step_height = float(rng.uniform(*config.step_height_range))
        ride_height = float(rng.uniform(*config.ride_height_range))
        if config.mode == "ext":
            if config.ext_heights == "one":
                if rng.integers(2):
                    step_height = config.expert.step_height
                else:
                    ride_height = config.expert.ride_height
            expert.set_heights(step_height=step_height, ride_height=ride_height)
        recorder.target_index = episode * config.targets_per_episode + k
        recorder.target_xy = target
        if need_reset:
            recorder.new_segment = True
        stats.targets += 1
        try:
            result = runner.walk_to(target[None], config.target_time_limit, reset=need_reset)
        except (SimulationUnstableError, MPCError):
            stats.unstable += 1
            need_reset = True
        else:
            if result.fell:
                stats.falls += 1
                need_reset = True
            elif result.timed_out:
                stats.timeouts += 1
                need_reset = True
            else:
                stats.targets_reached += 1
                anchor = target
                need_reset = False
        if on_target is not None:
            on_target(stats)
    stats.rows = recorder.rows
    return recorder.columns(), stats


# --- the collection --------------------------------------------------------------------------------


@dataclass
class CollectSummary:
    """Outcome of :func:`collect_dataset`: dataset totals and what this call added."""

    path: str
    rows: int
    targets: int
    """Targets attempted in the whole dataset."""
    targets_reached: int
    falls: int
    timeouts: int
    unstable: int
    episodes: int
    sim_seconds: float
    """Simulated time of the whole dataset [s]."""
    wall_seconds: float
    """Wall time of this call [s]."""
    episodes_collected: int
    """Episodes collected by this call (the rest were resumed)."""
    rows_collected: int
    """Rows collected by this call."""
    content_hash: str

    def as_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["sim_seconds"] = round(self.sim_seconds, 3)
        out["wall_seconds"] = round(self.wall_seconds, 3)
        collected_sim = self.rows_collected * CONTROL_DT
        out["rows_per_second"] = round(self.rows_collected / max(self.wall_seconds, 1e-9), 1)
        out["real_time_factor"] = round(collected_sim / max(self.wall_seconds, 1e-9), 2)
        return out


def collect_dataset(
    out: str | Path,
    config: CollectConfig,
    *,
    progress: bool = False,
    on_episode: Callable[[dict[str, Any]], None] | None = None,
) -> CollectSummary:
    """Collect (or resume collecting) an expert dataset into the directory ``out``.

    Finished episodes already listed in ``out/manifest.json`` are kept; the others are collected and each
    is written atomically when it finishes (:mod:`krl.data.storage`). Settings that differ from the
    existing dataset's raise :class:`krl.data.storage.SettingsMismatchError`. ``on_episode`` is called
    with each new part's manifest entry after the manifest lists it. An interruption (Ctrl-C) loses only
    the episode in progress.
    """
    from krl.sim.model import build_model

    start = time.perf_counter()
    directory = Path(out)
    if directory.exists() and not directory.is_dir():
        raise ValueError(f"{directory} exists and is not a directory")
    built = build_model(config.terrain, config.terrain_params, config.seed)
    settings = config.settings(built.terrain)
    directory.mkdir(parents=True, exist_ok=True)
    rows_collected = 0
    collected = 0
    with directory_lock(directory):
        manifest = open_dataset(directory, config, settings)
        done = {int(p["episode"]) for p in manifest["parts"]}
        todo = [e for e in range(config.num_episodes) if e not in done]
        total = sum(config.episode_targets(e) for e in todo)
        with progress_bar(progress, unit="targets", status=True) as bar:
            task = bar.add_task("collecting", total=total, status="")
            counts = {"falls": 0, "timeouts": 0}
            for episode in todo:
                bar.update(task, description=f"episode {episode + 1}/{config.num_episodes}")

                def on_target(stats: EpisodeStats) -> None:
                    falls = counts["falls"] + stats.falls + stats.unstable
                    timeouts = counts["timeouts"] + stats.timeouts
                    bar.update(task, advance=1, status=f"falls {falls} timeouts {timeouts}")

                columns, stats = collect_episode(built, config, episode, on_target)
                part = write_part(directory, columns, dataclasses.asdict(stats), manifest["metadata"])
                manifest["parts"].append(part)
                write_manifest(directory, manifest)
                counts["falls"] += stats.falls + stats.unstable
                counts["timeouts"] += stats.timeouts
                rows_collected += stats.rows
                collected += 1
                if on_episode is not None:
                    on_episode(part)
    totals = manifest["totals"]
    return CollectSummary(
        path=str(directory),
        rows=totals["rows"],
        targets=totals["targets"],
        targets_reached=totals["targets_reached"],
        falls=totals["falls"],
        timeouts=totals["timeouts"],
        unstable=totals["unstable"],
        episodes=totals["episodes"],
        sim_seconds=totals["rows"] * CONTROL_DT,
        wall_seconds=time.perf_counter() - start,
        episodes_collected=collected,
        rows_collected=rows_collected,
        content_hash=manifest["content_hash"],
    )


__all__ = [
    "EXT_HEIGHTS",
    "MODES",
    "CollectConfig",
    "CollectSummary",
    "EpisodeStats",
    "collect_dataset",
    "collect_episode",
]
