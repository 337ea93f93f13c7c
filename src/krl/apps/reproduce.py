"""``krl reproduce``: every table and figure of ``docs/results`` and ``docs/figures`` from nothing.

The pipeline is a list of :class:`Step`: ``krl`` commands in order (expert data -> kernels -> kernel
studies and figures -> agent -> evaluation -> report), each with the wall time it took on the 2-core
development machine (``docs/reproduce.md``). A finished step leaves a marker
(``RUNS/.reproduce/<step>.json``, holding its command), so running ``krl reproduce`` again skips what is
done and resumes the step that was interrupted (every long command it runs resumes by itself). With
``--quick`` every step is cut down (tens of waypoints, a few epochs, a short agent training, one push per
magnitude) into ``RUNS/quick``, whose documents go to ``RUNS/quick/docs``: the same pipeline in well under
an hour here, never touching ``docs/``.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from krl.util.output import write_atomic


@dataclass(frozen=True)
class Step:
    """One command of the pipeline."""

    name: str
    """File-name-safe name (the marker's)."""
    argv: tuple[str, ...]
    """The ``krl`` command's arguments."""
    minutes: float
    """Wall time it took (full) or should take (quick) on the 2-core development machine [min]."""
    makes: str
    """What it writes, for the plan."""
    config: tuple[str, str] | None = None
    """``(path, JSON text)`` of a config file the command reads, written just before it runs."""

    @property
    def command(self) -> str:
        return "krl " + " ".join(self.argv)


COURSES: tuple[str, ...] = ("tabletop", "seesaw", "stairs", "sinusoid", "flat")
SEEDS = "150,215,345,556"


def plan(runs: Path, docs: Path, quick: bool = False) -> list[Step]:
    """The steps, in order, for the run folder ``runs`` and the documents folder ``docs``."""
    if quick:
        runs, docs = runs / "quick", runs / "quick" / "docs"
    r, d = str(runs), str(docs)
    q = quick
    data = {name: f"{r}/data/{name}" for name in ("base", "ext", "dyn2", "s0.3", "s0.25", "s0.2")}
    steps = [
        Step(
            "collect-base",
            ("collect", "--out", data["base"], "--targets", "40" if q else "500", "--seed", "0", "--quiet"),
            1.5 if q else 14,
            "expert data, stance 0.2 s",
        ),
        Step(
            "collect-ext",
            (
                "collect",
                "--out",
                data["ext"],
                "--mode",
                "ext",
                "--targets",
                "20" if q else "500",
                "--seed",
                "1",
                "--quiet",
            ),
            1 if q else 19,
            "kernel-ext's data",
        ),
        Step(
            "collect-dyn2",
            (
                "collect",
                "--out",
                data["dyn2"],
                "--mode",
                "dyn2",
                "--targets",
                "20" if q else "500",
                "--seed",
                "2",
                "--quiet",
            ),
            1 if q else 16,
            "kernel-dyn2's data",
        ),
    ]
    for tau in ("0.3", "0.25", "0.2"):
        steps.append(
            Step(
                f"collect-stance{tau}",
                (
                    "collect",
                    "--out",
                    data[f"s{tau}"],
                    "--targets",
                    "12" if q else "100",
                    "--seed",
                    "3",
                    "--stance-duration",
                    tau,
                    "--quiet",
                ),
                0.5 if q else 4,
                f"Table 4.3's data, τ {tau} s",
            )
        )
    epochs = ("--epochs", "3") if q else ()
    steps += [
        Step(
            "kernel-base",
            (
                "kernel",
                "train",
                "--data",
                data["base"],
                "--out",
                f"{r}/kernel-base",
                "--threads",
                "1",
                *epochs,
                "--quiet",
            ),
            1 if q else 13,
            "kernel-base",
        ),
        Step(
            "kernel-ext",
            (
                "kernel",
                "train",
                "--data",
                data["ext"],
                "--variant",
                "ext",
                "--out",
                f"{r}/kernel-ext",
                "--threads",
                "1",
                *epochs,
                "--quiet",
            ),
            1 if q else 19,
            "kernel-ext",
        ),
    ]
    study = (
        "--runs",
        f"{r}/studies",
        "--threads",
        "1",
        "--seeds",
        "150" if q else SEEDS,
        "--epochs",
        "2" if q else "10",
        "--walk-targets",
        "1" if q else "5",
        "--quiet",
    )
    steps += [
        Step(
            "study-variants",
            (
                "kernel",
                "study",
                "variants",
                "--data-base",
                data["base"],
                "--data-ext",
                data["ext"],
                "--data-dyn2",
                data["dyn2"],
                "--out",
                f"{d}/results/kernel",
                *study,
            ),
            4 if q else 200,
            "Table 4.4",
        ),
        Step(
            "study-data-size",
            (
                "kernel",
                "study",
                "data-size",
                "--data",
                data["base"],
                "--out",
                f"{d}/results/kernel",
                *(("--sizes", "10,25") if q else ()),
                *study,
            ),
            2 if q else 120,
            "Table 4.5",
        ),
        Step(
            "study-stance",
            (
                "kernel",
                "study",
                "stance",
                *(a for tau in ("0.3", "0.25", "0.2") for a in ("--data-stance", f"{tau}={data['s' + tau]}")),
                "--out",
                f"{d}/results/kernel",
                *study,
            ),
            2 if q else 60,
            "Table 4.3",
        ),
        Step(
            "tune",
            (
                "kernel",
                "tune",
                "--data",
                data["base"],
                "--out",
                f"{r}/tune",
                "--trials",
                "2" if q else "8",
                "--threads",
                "1",
                *(("--epochs", "2") if q else ()),
                "--quiet",
            ),
            2 if q else 25,
            "Optuna trials (trials.csv)",
        ),
        Step(
            "expert-figures",
            (
                "expert",
                "plot",
                "all",
                "--out",
                f"{d}/figures/expert",
                "--seed",
                "0",
                *(("--quick",) if q else ()),
            ),
            2 if q else 15,
            "Figs. 4.8, 4.15 (MPC), A.2, A.3",
        ),
        Step(
            "kernel-figures",
            (
                "kernel",
                "figures",
                "all",
                "--out",
                f"{d}/figures/kernel",
                "--model",
                f"{r}/kernel-base/kernel.npz",
                "--ext-model",
                f"{r}/kernel-ext/kernel.npz",
                "--ind-model",
                f"{r}/studies/variants/ind-seed150/kernel.npz",
                *(("--quick",) if q else ()),
            ),
            2 if q else 15,
            "Figs. 4.9-4.13, 4.15",
        ),
    ]
    steps += [
        Step(
            f"course-{name}",
            ("render", "--course", name, "--out", f"{d}/figures/courses/{name}.png"),
            0.1,
            f"picture of the {name} course",
        )
        for name in COURSES
    ]
    agent = f"{r}/agent-rp-seed150"
    config: dict = {"residual": {"kernel": f"{r}/kernel-base/kernel.npz"}}
    if q:
        config.update(
            total_steps=20000,
            checkpoint_every=10000,
            num_envs=4,
            ppo={"rollout_steps": 4000, "batch_size": 1000, "n_epochs": 3},
        )
    # agent-base (Table 4.8's reward without the roll and pitch term) as shipped: 50 environments per worker
    base_config: dict = {**config, "env": {"reward": "base"}}
    if not q:
        base_config.update(num_envs=50, checkpoint_every=1_000_000)
    base_agent = f"{r}/agent-base-seed150"
    for name, out, settings, minutes in (
        ("agent-rp", agent, config, 120),
        ("agent-base", base_agent, base_config, 74),
    ):
        config_path = f"{r}/{name}.json"
        steps.append(
            Step(
                name,
                ("agent", "train", "--out", out, "--seed", "150", "--config", config_path, "--quiet"),
                4 if q else minutes,
                f"{name} (seed 150)",
                config=(config_path, json.dumps(settings, indent=2) + "\n"),
            )
        )
    evaluate = ("--workers", "2", "--out", f"{r}/eval", "--quiet")
    kernel = f"kernel:{r}/kernel-base/kernel.npz"
    policy = f"agent:{agent}/policy.npz"
    courses = ("--course", "thesis", "--course", "flat")
    # 50 attempts per magnitude, as docs/results: the thesis's 10 leave each rate's interval ±0.3 wide
    pushes = ("--push-sweep", "--attempts", "1" if q else "50")
    steps += [
        Step(
            "evaluate-courses",
            (
                "evaluate",
                "--controller",
                "expert",
                "--controller",
                "expert:stance=0.3",
                "--controller",
                kernel,
                "--controller",
                policy,
                "--controller",
                f"agent:{base_agent}/policy.npz",
                *courses,
                *evaluate,
            ),
            6 if q else 14,
            "Tables 5.1-5.4 runs",
        ),
        Step(
            "evaluate-pushes",
            (
                "evaluate",
                "--controller",
                "expert",
                "--controller",
                kernel,
                "--controller",
                policy,
                *pushes,
                *evaluate,
            ),
            2 if q else 90,
            "Table 5.5 runs",
        ),
        Step("report", ("report", "--results", f"{r}/eval", "--out", f"{d}/results"), 0.2, "Tables 5.1-5.5"),
        Step(
            "agent-curves", ("agent", "curves", agent, "--out", f"{d}/figures/agent"), 0.1, "training curves"
        ),
    ]
    return steps


def _marker(runs: Path, quick: bool, step: Step) -> Path:
    return (runs / "quick" if quick else runs) / ".reproduce" / f"{step.name}.json"


def is_done(runs: Path, quick: bool, step: Step) -> bool:
    """Whether ``step`` finished (its marker exists and records the same command)."""
    marker = _marker(runs, quick, step)
    try:
        return json.loads(marker.read_text()).get("argv") == list(step.argv)
    except (OSError, ValueError):
        return False


def describe(steps: Sequence[Step], runs: Path, quick: bool) -> list[str]:
    """The plan as text lines: per step whether it is done, its estimated time and its command."""
    lines = []
    left = 0.0
    for number, step in enumerate(steps, start=1):
        done = is_done(runs, quick, step)
        left += 0.0 if done else step.minutes
        status = "done" if done else f"~{step.minutes:g} min"
        lines.append(f"{number:2d}. {step.name:18s} {status:>10s}  {step.makes}\n      {step.command}")
    lines.append(f"left: about {left:.0f} min ({left / 60:.1f} h) on a 2-core machine")
    return lines


def reproduce(
    runs: Path, docs: Path, quick: bool, run: Callable[[list[str]], int], log=print, dry_run: bool = False
) -> int:
    """Print the plan, then run each step that is not done with ``run(argv) -> exit status``; stops at
    the first failing step (its exit status), returns 0 when everything is done."""
    steps = plan(runs, docs, quick)
    for line in describe(steps, runs, quick):
        log(line)
    if dry_run:
        return 0
    for number, step in enumerate(steps, start=1):
        if is_done(runs, quick, step):
            continue
        log(f"[{number}/{len(steps)}] {step.name}: {step.command}")
        if step.config is not None:
            write_atomic(Path(step.config[0]), step.config[1])
        status = run(list(step.argv))
        if status != 0:
            log(f"step {step.name} failed (exit status {status}); fix it and run krl reproduce to resume")
            return status
        write_atomic(_marker(runs, quick, step), json.dumps({"argv": list(step.argv)}) + "\n")
    log("everything is reproduced")
    return 0
