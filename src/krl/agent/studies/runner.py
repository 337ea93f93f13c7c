"""Running an agent study on Optuna: each trial one ``krl agent train`` run, any number of processes on
any number of machines sharing one study through its storage.

The study lives in an Optuna storage given by URL: a SQLite file for one machine, PostgreSQL (or MySQL)
for many. Every process runs :func:`work` against it, and they share the trials:

* A **list** study's trials (variant x seed) and a search's confirming runs (best trial x seed) are
  *planned*: enqueued once (by whichever process comes first) and popped by one process each. A search's
  trials are drawn by the sampler (random, as the thesis; TPE on request) until the study holds its
  number of them.
* **Exactly once.** A trial that finds an earlier trial of the same plan entry (or, in a search, one that
  finds the study already full) is a *surplus* trial: marked failed with ``surplus`` set, before training
  anything, and left out of every count and report. Two processes that pop at once therefore never train
  one entry twice.
* **Never lost.** A process heart-beats its running trial; a trial whose process died (SIGKILL, a lost
  machine) stops beating, and any process of the study marks it failed after the grace period and
  enqueues it again (Optuna's ``RetryHeartbeatStaleTrialCallback``); processes with nothing left to start
  wait while other processes' trials run, so that they can take such a trial over. A retried trial
  resumes from its run folder's last checkpoint when it runs on the machine that had it. A trial stopped
  by Ctrl-C or SIGTERM (every study process turns SIGTERM into a ``KeyboardInterrupt``) is queued again
  at once, whether it was training (checkpointed first) or still being set up.
* **Finished is final.** A finished trial (complete, pruned or failed with an error) is never run again.

A trial stores what the report needs in the storage itself (user attributes: the final targets reached
and success rate, the learning curve, env steps, wall time), so the report can be written on any machine.
Its run folder stays under ``OUT/trials/<stage>/<entry>`` on the machine that trained it.
"""

from __future__ import annotations

import json
import os
import socket
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from krl.agent.sb3_adapter import logged_value
from krl.agent.studies.designs import StudyDesign, merged
from krl.util.optuna_storage import HEARTBEAT, check_study_database, check_url, masked, study_storage

SEARCH, CONFIRM, LIST = "search", "confirm", "list"
"""A study's stages: a search's random trials and its confirming runs; a list study's runs."""

FINAL_FRACTION: float = 0.2
"""A trial's final targets reached and success rate are the means over the rollouts logged in the last
this-fraction of its env steps (at least its last rollout)."""


class StudyError(RuntimeError):
    """A study that cannot be run as asked (another budget than the stored one, an unknown name); one line."""


class SurplusTrial(Exception):
    """Raised inside a trial that must not train (module docstring); Optuna records it as failed."""


class TrialError(Exception):
    """A trial whose training failed (its message is the trial's ``error``); Optuna records it as failed
    and the process goes on with the next trial."""


@dataclass(frozen=True)
class StudySettings:
    """How one study is run: its budget and seeds (the thesis's unless cut down), and how trials train."""

    budget: int
    """Env steps per trial (a search's trials, a list study's runs)."""
    seeds: tuple[int, ...]
    trials: int = 0
    """A search's trials."""
    top: int = 0
    """A search's best trials trained again from every seed."""
    confirm_budget: int = 0
    """Env steps of each confirming run."""
    sampler: str = "random"
    """``random`` (the thesis's) or ``tpe``."""
    pruner: str = "median"
    """``median``, ``halving`` (successive halving) or ``none``: stops a search trial whose learning curve
    falls behind (ours; the thesis ran every trial to its budget)."""
    workers: int = 2
    """Environment worker processes of each training."""
    num_envs: int | None = None
    """Environments per worker (None: the config's)."""
    shared: Any = None
    """Settings every trial shares on top of the study's base (a nested table, as a ``--config`` file);
    a trial's own variant or drawn settings still win. None: none."""

    @classmethod
    def of(cls, design: StudyDesign, **given: Any) -> StudySettings:
        """The design's thesis settings with the ``given`` ones (None: not given) in their place."""
        for key in ("trials", "top"):  # recorded by the study: a bad one would be locked in
            if given.get(key) is not None and given[key] < 1:
                raise StudyError(f"--{key} must be at least 1, got {given[key]}")
        thesis = cls(design.budget, design.seeds, design.trials, design.top, design.confirm_budget)
        return replace(thesis, **{key: value for key, value in given.items() if value is not None})

    def __post_init__(self) -> None:
        if self.budget < 1 or (self.top and self.confirm_budget < 1):
            raise StudyError("the budget must be at least 1 env step per trial")
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise StudyError(f"seeds must be distinct and at least one, got {list(self.seeds)}")
        if self.sampler not in ("random", "tpe") or self.pruner not in ("median", "halving", "none"):
            raise StudyError(f"unknown sampler {self.sampler!r} or pruner {self.pruner!r}")
        if self.workers < 1 or (self.num_envs is not None and self.num_envs < 1):  # every trial would fail
            raise StudyError(
                f"--workers and --num-envs must be at least 1, got {self.workers} and {self.num_envs}"
            )

    def stored(self) -> dict[str, Any]:
        """What a study records of its settings and refuses to change (not how its trials train)."""
        data = asdict(self)
        for key in ("workers", "num_envs"):
            data.pop(key)
        data["seeds"] = list(self.seeds)
        data["shared"] = json.loads(json.dumps(self.shared or {}))
        return data


def stored_settings(design: StudyDesign, url: str) -> StudySettings | None:
    """The settings the study ``design`` in storage ``url`` was started with (how its trials train aside);
    None if it has not been started there. Creates nothing."""
    import optuna

    check_url(url)  # before a missing file says "not started": a SQLite URL may name no file at all
    if url.startswith("sqlite:///") and not Path(url.removeprefix("sqlite:///")).exists():
        return None
    check_study_database(url)  # Optuna would create its tables in a foreign file
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    try:
        study = optuna.load_study(study_name=design.name, storage=study_storage(url))
    except KeyError:
        return None
    stored = study.user_attrs.get("settings")
    if stored is None:
        return None
    return StudySettings(**{**stored, "seeds": tuple(stored["seeds"]), "shared": stored["shared"] or None})


def _pruner_settings(name: str, budget: int) -> dict[str, int]:
    """The keyword arguments of :func:`pruner`'s Optuna pruner, for trials of ``budget`` env steps."""
    if name == "median":
        return {"n_startup_trials": 5, "n_warmup_steps": budget // 5}
    if name == "halving":
        return {"min_resource": budget // 8, "reduction_factor": 4}
    return {}


def pruner(name: str, budget: int):
    """The Optuna pruner ``--pruner name`` stands for, for trials of ``budget`` env steps: the median rule
    after 5 trials and 20 % of the budget, successive halving from an eighth of it, or none."""
    import optuna

    settings = _pruner_settings(name, budget)
    if name == "median":
        return optuna.pruners.MedianPruner(**settings)
    if name == "halving":
        return optuna.pruners.SuccessiveHalvingPruner(**settings)
    return optuna.pruners.NopPruner()


def pruner_rule(name: str, budget: int) -> str:
    """:func:`pruner`'s rule in words, for reports."""
    settings = _pruner_settings(name, budget)
    if name == "median":
        return (
            f"below the earlier trials' median, after {settings['n_startup_trials']} trials and "
            f"{settings['n_warmup_steps']:.3g} env steps"
        )
    if name == "halving":
        return (
            f"successive halving, rungs from {settings['min_resource']:.3g} env steps, reduction factor "
            f"{settings['reduction_factor']}"
        )
    return "none"


def open_stage(
    design: StudyDesign, settings: StudySettings, stage: str, url: str, heartbeat: float = HEARTBEAT
):
    """The Optuna study of one stage (``NAME`` or ``NAME:confirm``), created or loaded; refuses one
    created with other settings."""
    import optuna

    optuna.logging.set_verbosity(optuna.logging.ERROR)  # trials are logged here, one line each
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    sampler = (
        optuna.samplers.TPESampler(seed=settings.seeds[0])
        if settings.sampler == "tpe"
        else optuna.samplers.RandomSampler(seed=None)
    )
    study = optuna.create_study(
        study_name=design.name if stage != CONFIRM else f"{design.name}:confirm",
        storage=study_storage(url, heartbeat, retries=3),
        direction="maximize",
        sampler=sampler,
        pruner=pruner(settings.pruner if stage == SEARCH else "none", settings.budget),
        load_if_exists=True,
    )
    stored = study.user_attrs.get("settings")
    if stored is None:
        study.set_user_attr("settings", settings.stored())
    elif stored != settings.stored():
        changed = sorted(key for key, value in settings.stored().items() if stored.get(key) != value)
        raise StudyError(
            f"study {design.name} in {masked(url)} was started with other settings ({', '.join(changed)}: "
            f"{', '.join(f'{key} {stored.get(key)!r}' for key in changed)}); give the same, or another --out"
        )
    return study


# --- planned trials ---------------------------------------------------------------------------------


def plan_entries(
    design: StudyDesign, settings: StudySettings, stage: str, best: Sequence[Any] = ()
) -> list[dict]:
    """The planned trials of a list study or of a search's confirming runs (``best``: the search's best
    frozen trials), each ``{"key", "params", "overrides", "seed"}``."""
    entries = []
    if stage == LIST:
        for variant in design.variants:
            for seed in settings.seeds:
                params = {"variant": variant.name, "seed": seed}
                entries.append({"key": f"{variant.name}-seed{seed}", "params": params})
    else:
        for trial in best:
            for seed in settings.seeds:
                params = {"candidate": trial.number, "seed": seed}
                entries.append({"key": f"trial{trial.number}-seed{seed}", "params": params})
    return entries


def enqueue(study, entries: Sequence[dict[str, Any]]) -> None:
    """Enqueue every planned entry the study does not hold yet (each process may call it: a duplicate that
    slips through two processes' race is a surplus trial, never a second training)."""
    for entry in entries:
        study.enqueue_trial(entry["params"], user_attrs={"key": entry["key"]}, skip_if_exists=True)


def is_surplus(trial, others: Sequence[Any], limit: int | None) -> bool:
    """Whether ``trial`` must not train: an earlier trial holds its entry (:func:`run_entry_name`: a plan
    key, or the search trial a retry continues) and is waiting, running or finished but not failed; or it
    is a fresh draw (no plan key, no retry) and the study already holds ``limit`` entries (a search), or
    draws none at all (``limit`` None: a list study, whose queue ran dry)."""
    from optuna.trial import TrialState

    earlier = [t for t in others if t.number < trial.number and not t.user_attrs.get("surplus")]
    name = run_entry_name(trial)
    if any(run_entry_name(t) == name and t.state != TrialState.FAIL for t in earlier):
        return True
    if trial.user_attrs.get("key") is not None or "failed_trial" in trial.system_attrs:
        return False
    return limit is None or len(entries(earlier)) >= limit


def entries(trials: Sequence[Any]) -> set[str]:
    """The entries (:func:`run_entry_name`) the trials stand for: a retried or interrupted trial and its
    retries are one entry."""
    return {run_entry_name(t) for t in trials if not t.user_attrs.get("surplus")}


def run_entry_name(trial) -> str:
    """The run folder's name of a trial: its plan key, or (a search trial) the number of the trial it
    retries, so that a retried trial resumes its original's folder."""
    key = trial.user_attrs.get("key")
    if key is not None:
        return key
    original = trial.system_attrs.get("failed_trial", trial.number)
    return f"trial{original}"


def trial_config(design: StudyDesign, settings: StudySettings, overrides: dict[str, Any], budget: int):
    """The AgentConfig of one trial: the study's base, the settings every trial shares, the trial's own
    overrides, the budget."""
    from krl.agent.config import AgentConfig

    table = merged(design.base, settings.shared or {}, overrides, {"total_steps": budget})
    return AgentConfig.from_json(table, f"study {design.name}")


def final_metrics(run: Path) -> dict[str, Any]:
    """A finished (or pruned) trial's record from its run folder: final targets reached and success rate
    (:data:`FINAL_FRACTION`), env steps, and its learning curve (env steps, targets, success, episode
    reward per rollout)."""
    import numpy as np

    from krl.agent.curves import STEPS_COLUMN, read_progress

    progress = read_progress(run)
    steps = np.asarray(progress[STEPS_COLUMN])
    targets = np.asarray(progress["episode/targets_reached"])
    success = np.asarray(progress["episode/success_rate"])
    reward = np.asarray(progress["episode/reward"])
    if steps.size == 0:
        raise StudyError(f"run {run} logged no rollout with an ended episode")
    last = steps >= steps[-1] * (1 - FINAL_FRACTION)

    def number(value: float) -> float | None:
        return round(float(value), 4) if np.isfinite(value) else None

    return {
        "targets_reached": float(np.nanmean(targets[last])),
        "success_rate": float(np.nanmean(success[last])) if np.isfinite(success[last]).any() else None,
        "curve": [
            [int(s), number(t), number(r), number(w)]
            for s, t, r, w in zip(steps, targets, success, reward, strict=True)
        ],
    }


# --- one trial ----------------------------------------------------------------------------------------


class PruningReport(BaseCallback):
    """SB3 callback of a search trial: reports each rollout's targets reached to Optuna (the learning curve
    a pruner reads) and ends the training when the pruner says so (``pruned``)."""

    def __init__(self, trial) -> None:
        super().__init__()
        self.trial = trial
        self.pruned = False

    def _on_rollout_end(self) -> None:
        value = logged_value(self, "episode/targets_reached")
        if value is not None:
            self.trial.report(float(value), step=int(self.num_timesteps))
            self.pruned = self.trial.should_prune()

    def _on_step(self) -> bool:
        return not self.pruned


def run_trial(
    trial,
    design: StudyDesign,
    settings: StudySettings,
    stage: str,
    out: Path,
    candidates: dict[int, dict[str, Any]] | None = None,
    log: Callable[[str], None] = print,
    progress: bool = False,
) -> float:
    """Train one trial (Optuna objective; ``progress``: the training's progress bar) and return its final
    targets reached; raises :class:`SurplusTrial` for a trial that must not train, ``optuna.TrialPruned``
    for a pruned one. Ctrl-C or SIGTERM (a ``KeyboardInterrupt``) at any moment after the trial was popped
    queues it again (a training checkpoints first), unless it was found surplus."""
    try:
        return _train_trial(trial, design, settings, stage, out, candidates, log, progress)
    except KeyboardInterrupt:
        if not trial.user_attrs.get("surplus"):
            _requeue(trial, _stored(trial))  # stopped, not finished: the next process resumes it
        raise


def _stored(trial, trials: Sequence[Any] | None = None):
    """The stored (frozen) trial of a running one, its system attributes, from ``trials`` (default: the
    study's now)."""
    trials = trial.study.get_trials(deepcopy=False) if trials is None else trials
    return next(t for t in trials if t.number == trial.number)


def _train_trial(
    trial,
    design: StudyDesign,
    settings: StudySettings,
    stage: str,
    out: Path,
    candidates: dict[int, dict[str, Any]] | None,
    log: Callable[[str], None],
    progress: bool,
) -> float:
    """:func:`run_trial`'s work."""
    import optuna

    from krl.agent.train import train

    others = trial.study.get_trials(deepcopy=False)
    me = _stored(trial, others)
    if is_surplus(me, others, settings.trials if stage == SEARCH else None):
        trial.set_user_attr("surplus", True)
        raise SurplusTrial(f"trial {trial.number} has nothing left to train")
    if stage == SEARCH:
        overrides, seed, budget = dict(design.space(trial)), settings.seeds[0], settings.budget
    elif stage == LIST:
        name = trial.suggest_categorical("variant", [v.name for v in design.variants])
        seed = trial.suggest_categorical("seed", list(settings.seeds))
        overrides, budget = (
            dict(next(v for v in design.variants if v.name == name).overrides),
            settings.budget,
        )
    else:
        candidate = trial.suggest_categorical("candidate", sorted(candidates or {}))
        seed = trial.suggest_categorical("seed", list(settings.seeds))
        overrides, budget = (candidates or {})[candidate], settings.confirm_budget
    folder = out / "trials" / stage / run_entry_name(me)
    trial.set_user_attr("worker", f"{socket.gethostname()}:{os.getpid()}")  # who trains it, for status
    report = PruningReport(trial) if stage == SEARCH else None
    try:
        summary = train(
            folder,
            trial_config(design, settings, overrides, budget),
            seed,
            progress=progress,
            log=log,
            workers=settings.workers,
            num_envs=settings.num_envs,
            callbacks=[report] if report is not None else [],
        )
        record = final_metrics(folder)
    except Exception as error:  # a failed training fails its trial, not the study
        message = f"{type(error).__name__}: {error}"
        trial.set_user_attr("error", message)
        log(f"{design.name} {stage} {folder.name}: failed: {message}")
        raise TrialError(f"trial {trial.number} ({folder.name}) failed: {message}") from None
    record.update(env_steps=summary["env_steps"], wall_seconds=summary["wall_seconds"], seed=seed)
    record["overrides"] = overrides
    for key, value in record.items():
        trial.set_user_attr(key, value)
    pruned = report is not None and report.pruned
    log(
        f"{design.name} {stage} {folder.name}: {record['targets_reached']:.2f} targets reached, success "
        f"{record['success_rate']}, {record['env_steps']} env steps" + (" (pruned)" if pruned else "")
    )
    if pruned:
        raise optuna.TrialPruned()
    return record["targets_reached"]


def _requeue(trial, stored) -> None:
    """Enqueue an interrupted trial again, as Optuna's heartbeat retry does (same parameters and plan key,
    ``failed_trial`` naming the first of its line; ``stored``: its stored frozen trial), so that its entry
    is not lost."""
    import optuna

    original = stored.system_attrs.get("failed_trial", trial.number)
    trial.study.add_trial(
        optuna.trial.create_trial(
            state=optuna.trial.TrialState.WAITING,
            params=trial.params,
            distributions=trial.distributions,
            user_attrs=trial.user_attrs,
            system_attrs={"failed_trial": original},
        )
    )


# --- the work loop ------------------------------------------------------------------------------------


def _states(study, *states) -> list:
    return [t for t in study.get_trials(deepcopy=False, states=states) if not t.user_attrs.get("surplus")]


def _run_queue(study, objective, wait: float) -> None:
    """Run the study's waiting trials one at a time until none is waiting and none runs elsewhere (a
    running one may still go stale and come back as a waiting retry)."""
    from optuna.storages import fail_stale_trials
    from optuna.trial import TrialState

    while True:
        fail_stale_trials(study)
        if _states(study, TrialState.WAITING):
            study.optimize(objective, n_trials=1, catch=(SurplusTrial, TrialError), gc_after_trial=True)
        elif _states(study, TrialState.RUNNING):
            time.sleep(wait)
        else:
            return


def _run_search(study, objective, settings: StudySettings, wait: float) -> None:
    """Draw and run search trials until the study holds ``settings.trials`` live ones, then wait for the
    running ones (and run any retried one)."""
    from optuna.storages import fail_stale_trials
    from optuna.trial import TrialState

    while True:
        fail_stale_trials(study)
        drawn = entries(study.get_trials(deepcopy=False))
        if len(drawn) < settings.trials or _states(study, TrialState.WAITING):
            study.optimize(objective, n_trials=1, catch=(SurplusTrial, TrialError), gc_after_trial=True)
        elif _states(study, TrialState.RUNNING):
            time.sleep(wait)
        else:
            return


def best_trials(study, top: int) -> list:
    """The ``top`` complete trials of highest final targets reached (ties: the earlier trial)."""
    from optuna.trial import TrialState

    complete = _states(study, TrialState.COMPLETE)
    return sorted(complete, key=lambda t: (-t.value, t.number))[:top]


def work(
    design: StudyDesign,
    settings: StudySettings,
    out: Path,
    url: str,
    heartbeat: float = HEARTBEAT,
    log: Callable[[str], None] = print,
    progress: bool = False,
) -> None:
    """Run the study's trials in this process until none is left to start or running anywhere (module
    docstring); any number of processes may run it at once on one storage. ``log`` gets a line per trial,
    ``progress`` shows each training's progress bar."""
    out.mkdir(parents=True, exist_ok=True)

    def objective(stage: str, candidates: dict[int, dict[str, Any]] | None = None):
        return lambda trial: run_trial(trial, design, settings, stage, out, candidates, log, progress)

    if design.is_search:
        study = open_stage(design, settings, SEARCH, url, heartbeat)
        _run_search(study, objective(SEARCH), settings, heartbeat)
        best = best_trials(study, settings.top)
        if not best:
            return
        confirm = open_stage(design, settings, CONFIRM, url, heartbeat)
        enqueue(confirm, plan_entries(design, settings, CONFIRM, best))
        candidates = {t.number: t.user_attrs["overrides"] for t in best}
        _run_queue(confirm, objective(CONFIRM, candidates), heartbeat)
    else:
        study = open_stage(design, settings, LIST, url, heartbeat)
        enqueue(study, plan_entries(design, settings, LIST))
        _run_queue(study, objective(LIST), heartbeat)
