"""The held-out choice in one call: what ``krl agent heldout`` does once its options are parsed.

Every policy file walks its held-out episodes (:mod:`krl.analysis.agent.heldout`); the candidates' seed
groups are compared (:func:`~krl.analysis.agent.heldout.choose`); the choice is held against a baseline
label on these episodes (it must beat it by more than one episode) and, where a second environment is
given, on that environment's episodes too (it must be no worse there by more than one episode); then the
tables, the choice (or the verdict that it does not stand) and the chosen seeds' copies into a seed group
are written. Everything a request gets wrong is refused (:class:`HeldoutError`, one line naming the option)
before an episode is walked or a file written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from krl.agent.config import AgentConfig, AgentConfigError, EnvConfig
from krl.agent.process_vec_env import WorkerError
from krl.analysis.agent.heldout import (
    against_baseline,
    check_candidates,
    choose,
    group_rows,
    policy_record,
    write_choice,
    write_verdict,
)
from krl.analysis.agent.heldout_request import MAX_EPISODES, HeldoutError, HeldoutRequest, PolicyGroups
from krl.analysis.agent.heldout_tables import write_tables
from krl.analysis.agent.seed_group import check_seeded, copy_into_group, group_copies
from krl.util.parallel import usable_cores


def check_request(request: HeldoutRequest) -> int:
    """Raise :class:`HeldoutError` for options that do not fit together; returns the worker count."""
    if request.episodes < 1:
        raise HeldoutError(f"--episodes must be at least 1, got {request.episodes}")
    if request.episodes > MAX_EPISODES:  # each batch of episodes is built at once: see HELDOUT_BATCH
        raise HeldoutError(f"--episodes must be at most {MAX_EPISODES}, got {request.episodes}")
    workers = usable_cores() if request.workers is None else request.workers
    if workers < 1:
        raise HeldoutError(f"--workers must be at least 1, got {workers}")
    labels, candidates, baseline = list(request.groups), request.candidates, request.baseline
    if request.seed_group and not candidates:
        raise HeldoutError("--seed-group needs --choose: it receives the chosen label's policies")
    if request.baseline_env and not baseline:
        raise HeldoutError("--baseline-env needs --baseline: the label the choice is held against there")
    if baseline and not candidates:
        raise HeldoutError("--baseline needs --choose: it is the label the choice must beat")
    if baseline and baseline not in labels:
        raise HeldoutError(f"--baseline {baseline!r} is no --policy label (labels: {', '.join(labels)})")
    if baseline in candidates:
        raise HeldoutError(f"--baseline {baseline!r} is also a --choose candidate")
    try:
        check_candidates(labels, list(candidates))
        for label in candidates if request.seed_group else ():
            check_seeded(label, request.groups[label], request.seed_group)
    except ValueError as error:
        raise HeldoutError(str(error)) from None
    return workers


def load_env(path: str | None, option: str) -> EnvConfig | None:
    """The env section of the agent config file ``path`` (None for None); a :class:`HeldoutError` names
    ``option``."""
    if path is None:
        return None
    try:
        return AgentConfig.load(path).env
    except AgentConfigError as error:
        raise HeldoutError(f"{option} {path}: {error}") from None


def walk(groups: PolicyGroups, out: Path, episodes: int, workers: int, env: EnvConfig | None, bar) -> dict:
    """Every policy file of ``groups`` on its held-out episodes (in ``env``, None: its own), its record read
    or written under ``out/<label>/``, one ``bar`` task over all; ``{label: [(seed, record)]}``."""
    records: dict[str, list] = {}
    task = bar.add_task(f"held-out episodes ({out.name})", total=episodes * sum(map(len, groups.values())))
    for label, files in groups.items():
        records[label] = []
        for seed, path in files:
            record_path = out / label / ("policy.json" if seed is None else f"seed{seed}.json")
            try:
                record = policy_record(path, record_path, episodes, workers, lambda: bar.advance(task), env)
            except WorkerError as error:
                raise HeldoutError(
                    f"{error}; the same command goes on from the policies already walked"
                ) from None
            records[label].append((seed, record))
    return records


def _hold_against_baseline(
    request: HeldoutRequest, rows, choice, workers: int, baseline_env: EnvConfig | None, bar
) -> None:
    """Add ``choice["baseline"]``: how the chosen label stands against the baseline on these episodes
    and, with ``baseline_env``, on that environment's (walked and tabled under ``out/baseline-env``)."""
    chosen, baseline = choice["chosen"], request.baseline
    checks = {"these episodes": against_baseline(rows, chosen, baseline, True)}
    if baseline_env is not None:
        pair = {label: request.groups[label] for label in (chosen, baseline)}
        out = request.out / "baseline-env"
        again = walk(pair, out, request.episodes, workers, baseline_env, bar)
        rows_again = group_rows(again)
        write_tables(rows_again, again, out, None, request.baseline_env)
        checks[f"`{request.baseline_env}`'s episodes"] = against_baseline(rows_again, chosen, baseline, False)
    stands = all(check["holds"] for check in checks.values())
    choice["baseline"] = {"label": baseline, "checks": checks, "stands": stands}


def run_heldout(request: HeldoutRequest, bar) -> dict[str, Any]:
    """Walk, choose, hold against the baseline and write, as the module says; ``bar`` is a
    :func:`krl.util.progress.progress_bar`. Returns ``rows`` (:func:`group_rows`), ``written`` (the paths by
    kind) and, with candidates, ``choice``.

    Raises:
        HeldoutError: the request does not fit together, a config file or a worker fails, or the chosen
            policies cannot go into the seed group; written before the error stays consistent, and the same
            request goes on from the records already walked.
    """
    workers = check_request(request)
    env, baseline_env = load_env(request.env, "--env"), load_env(request.baseline_env, "--baseline-env")
    records = walk(request.groups, request.out, request.episodes, workers, env, bar)
    rows = group_rows(records)
    choice = choose(rows, list(request.candidates)) if request.candidates else None
    if choice and request.baseline:
        _hold_against_baseline(request, rows, choice, workers, baseline_env, bar)
    chosen = choice["chosen"] if choice and choice.get("baseline", {}).get("stands", True) else None
    try:
        copies = None  # checked before anything is written
        if request.seed_group and chosen:
            copies = group_copies(chosen, request.groups[chosen], request.seed_group)
        written = write_tables(rows, records, request.out, choice, request.env)
        if chosen:
            written |= write_choice(choice, request.groups[chosen], request.out)
            if copies is not None:
                written["seed_group"] = copy_into_group(copies)
        elif choice:  # the choice does not stand against the baseline: recorded, nothing to train from
            written["choice"] = write_verdict(choice, request.out)
    except ValueError as error:
        raise HeldoutError(str(error)) from None
    return {"rows": rows, "written": written} | ({"choice": choice} if choice else {})
