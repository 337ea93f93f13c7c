"""Every ``krl`` command the README and docs/cli.md show parses with today's parser, and runs, smoke-sized
(so the pages cannot rot).

Each command runs in-process (``krl.cli.main``) with the options of its entry in :data:`SMOKE` appended:
argparse keeps the last value of a repeated option, so ``krl collect --out data/base --targets 500`` plus
``--targets 1`` collects one target. A README command without an entry fails the test, so a new README
line cannot go untested. A command runs in its own copy of a workspace (:func:`workspace`) that holds the
inputs the README's commands name, made small by krl's own commands: ``data/base`` (an expert dataset),
``runs/kernel-base`` and ``runs/studies/variants/ind-seed150`` (one-epoch kernels), ``runs/agent-rp`` (a
tiny agent), ``runs/eval`` (an evaluation for ``krl report``), ``runs/push`` (a one-push sweep for ``krl
analyze push-sweep``), ``mine.toml`` (a one-waypoint course), ``study-tiny.json`` (tiny trials for ``krl
agent study``) and ``loss.json`` (a config change for ``krl agent config``).
"""

from __future__ import annotations

import contextlib
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from krl.cli import build_parser, main
from krl.sim.render import rendering_problem

README = Path(__file__).resolve().parents[1] / "README.md"
PAGES: tuple[Path, ...] = (README, README.with_name("docs") / "cli.md")
"""The pages whose commands run: the README and the reference of the ``krl`` command."""

RENDER, WINDOW = "render", "window"
"""What a command needs beyond Python: offscreen rendering (libOSMesa), or a window (run under Xvfb)."""

SMOKE: dict[str, tuple[str, str | None]] = {
    # README command: (options appended to it, what it needs). An empty string: it is small already.
    "krl demo": ("--course mine.toml --workers 1 --quiet", None),  # without rendering: no video, a note
    "krl demo --controller agent:gait --controller agent --out demo-gait": (
        "--course mine.toml --workers 1 --quiet",
        None,
    ),
    "krl reproduce --quick --dry-run": ("", None),
    "krl export --out onnx/ --policy rp": ("", None),
    "krl terrains": ("", None),
    "krl render --terrain seesaw --out seesaw.png": ("--width 64 --height 48 --settle 0", RENDER),
    "krl view --controller agent --course stairs": ("--duration 0.5", WINDOW),
    "krl bench sim --json": ("--steps 20 --repeats 1", None),
    "krl bench mpc --json": ("--seconds 0.5", None),
    "krl bench evaluate --json": ("--controller kernel --course mine.toml --push-attempts 0", None),
    # the tiny agent's PPO: its training measurement is three 128-step rollouts (the default's are 4000)
    "krl bench agent --json": (
        "--num-envs 1 --steps 10 --repeats 1 --train-steps 1 --config agent-tiny.json",
        None,
    ),
    "krl expert run --targets 10 --seed 1 --json": ("--targets 1 --target-time-limit 1", None),
    "krl expert run --command 0.5,0,0 --duration 8 --video walk.mp4": (
        "--duration 2.1 --video-size 160x120",
        RENDER,
    ),
    "krl expert plot all --out figures/": ("--quick --duration 2.1 --workers 1", None),
    "krl collect --out data/base --targets 500": ("--out data/smoke --targets 1 --quiet", None),
    "krl kernel train --data data/base --out runs/kernel-base": (
        "--out runs/kernel-smoke --epochs 1 --threads 1 --no-tensorboard --quiet",
        None,
    ),
    "krl kernel eval --json": ("--targets 1", None),
    "krl kernel eval --model runs/kernel-base/kernel.npz --data data/base --validation --breakdown": (
        "",
        None,
    ),
    "krl kernel run --targets 10 --json": ("--targets 1 --target-time-limit 1", None),
    "krl kernel run --model ext --ride-height 0.2 --command 0.3,0,0 --duration 8": ("--duration 2.2", None),
    "krl kernel tune --data data/base --out runs/tune --trials 50": (
        "--trials 1 --epochs 1 --threads 1 --quiet",
        None,
    ),
    "krl kernel study data-size --data data/base": (
        "--sizes 1 --seeds 150 --epochs 1 --walk-targets 1 --threads 1 --quiet",
        None,
    ),
    "krl kernel run --model runs/studies/variants/ind-seed150/kernel.npz --gait walk --targets 5": (
        "--targets 1 --target-time-limit 1",
        None,
    ),
    "krl kernel figures all --out figures/kernel": ("--quick --workers 1", None),
    "krl agent train --out runs/agent-rp --seed 150": ("--steps 768 --quiet", None),  # resumes the tiny one
    "krl agent curves runs/agent-rp --out figures/agent": ("", None),
    "krl agent info --policy runs/agent-rp/policy.npz": ("", None),
    "krl agent study ppo-search --trials 20 --budget 1000000": (
        "--trials 1 --top 1 --seeds 7 --budget 256 --confirm-budget 256 --config study-tiny.json --workers 1 "
        "--jobs 1 --quiet",
        None,
    ),
    "krl agent rhythm --json": ("--rates 1.5 --terrain flat --seconds 2.5", None),
    "krl agent push --magnitude 600 --direction left --out figures/push": ("--controller kernel", None),
    "krl agent heldout --policy runs/agent-rp/policy.npz --out runs/heldout": (
        "--episodes 2 --workers 1 --quiet",
        None,
    ),
    "krl agent run --targets 5 --json": ("--targets 1 --target-time-limit 1", None),
    "krl agent run --policy runs/agent-rp/policy.npz --terrain heightfield --video agent.mp4": (
        "--targets 1 --target-time-limit 0.3 --video-size 160x120",
        RENDER,
    ),
    "krl render --course stairs --out stairs-course.png": ("--width 64 --height 48 --settle 0", RENDER),
    "krl evaluate --controller expert --controller kernel --controller agent": (
        "--course mine.toml --seeds 150 --workers 1 --quiet",
        None,
    ),
    "krl evaluate --controller expert:stance=0.3 --course mine.toml --video videos/": (
        "--workers 1 --quiet",
        RENDER,
    ),
    "krl evaluate --controller kernel --push-sweep": (
        "--magnitudes 250 --attempts 1 --workers 1 --quiet",
        None,
    ),
    "krl evaluate --controller kernel --friction-sweep": (
        "--frictions 0.5 --friction-course mine.toml --workers 1 --quiet",
        None,
    ),
    "krl evaluate --controller kernel --stair-sweep": ("--risers 4 --workers 1 --quiet", None),
    "krl report": ("", None),
    "krl agent digest --json": ("--envs 1 --steps 5", None),
    "krl agent config runs/agent-rp/config.json loss.json --out my.json": ("", None),
    "krl agent snapshot runs/agent-rp --out committed": ("", None),
    "krl convert-results runs/eval": ("", None),
    "krl compare-results runs/eval runs/eval": ("", None),
    "krl analyze push-sweep runs/push": ("", None),
    "krl analyze mirror": ("--kernel base --command 0.3,0,0 --duration 0.5", None),
    "krl demo --controller agent:robust": ("--course mine.toml --workers 1 --no-video --quiet", None),
    "krl evaluate --controller agent --controller expert --out evaluations/mine": (
        "--course mine.toml --seeds 150 --workers 1 --quiet",
        None,
    ),
    "krl evaluate --controller agent --push-sweep --attempts 50 --out evaluations/mine": (
        "--magnitudes 250 --attempts 1 --workers 1 --quiet",
        None,
    ),
    "krl report --results evaluations/mine --out report/": ("--results runs/eval", None),
    "krl agent train --out runs/my-agent --seed 150": ("--config agent-tiny.json --steps 256 --quiet", None),
}

MINE_TOML = """\
format = 1
name = "mine"
description = "One waypoint 0.6 m ahead on flat ground (the README's smoke test)."
time_limit = 6.0
d_min = 0.5
waypoints = [[0.6, 0.0]]
starts = [[0.0, 0.0, 0.0]]

[terrain]
name = "flat"
seed = 0
"""

TINY_AGENT = (
    '{"ppo": {"rollout_steps": 256, "batch_size": 128, "n_epochs": 1, "shared": [16], "actor": [16], '
    '"critic": [8]}, "num_envs": 2, "workers": 1, "total_steps": 512, "checkpoint_every": 256, '
    '"env": {"episode_time": 0.5}}'
)
"""The README's agent: a tiny network, and half-second episodes (its held-out episodes end at once)."""

TINY_STUDY = (
    '{"ppo": {"rollout_steps": 128, "batch_size": 64, "n_epochs": 1, "shared": [16], "actor": [16], '
    '"critic": [8]}, "num_envs": 2, "checkpoint_every": 256, "env": {"episode_time": 0.5}}'
)
"""Settings every trial of the README's study shares: a tiny network, and half-second episodes so that some
end within its 256 steps."""

WORKSPACE_COMMANDS = (
    "collect --out data/base --targets 3 --targets-per-episode 1 --quiet",
    "kernel train --data data/base --out runs/kernel-base --epochs 1 --threads 1 --no-tensorboard --quiet",
    "kernel train --data data/base --variant ind --out runs/studies/variants/ind-seed150 --epochs 1 "
    "--threads 1 --no-tensorboard --quiet",
    "agent train --out runs/agent-rp --seed 150 --config agent-tiny.json --quiet",
    "evaluate --controller kernel --course mine.toml --workers 1 --quiet",
    "evaluate --controller kernel --push-sweep --magnitudes 400 --attempts 1 --workers 1 --quiet "
    "--out runs/push",
)
"""The ``krl`` commands that make the workspace's inputs (after the files :func:`workspace` writes)."""


def readme_commands() -> list[str]:
    """The ``krl …`` commands the README and the command reference (:data:`PAGES`) show, each once: those
    of their shell blocks (comments dropped, ``&&`` chains split) and the code spans of their tables."""
    commands = []
    for page in PAGES:
        in_block = False
        for line in page.read_text().splitlines():
            if line.startswith("```"):
                in_block = line.strip() == "```bash"
                continue
            if in_block:
                parts = [part.strip() for part in line.split("#")[0].split("&&")]
            elif line.startswith("|"):
                parts = re.findall(r"`(krl [^`]+)`", line)
            else:
                continue
            commands += [part for part in parts if part.startswith("krl ")]
    return list(dict.fromkeys(commands))


def missing_need(need: str | None) -> str | None:
    """Why a command needing ``need`` cannot run here (None: it can)."""
    if need == RENDER:
        return rendering_problem()  # a failed GL start is remembered, so asking again is safe
    if need == WINDOW and shutil.which("xvfb-run") is None:
        return "needs xvfb-run (apt-get install xvfb) for a window"
    return None


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """A folder with the inputs the README's commands read (module docstring), made by krl's commands."""
    folder = tmp_path_factory.mktemp("readme")
    (folder / "mine.toml").write_text(MINE_TOML)
    (folder / "agent-tiny.json").write_text(TINY_AGENT)
    (folder / "study-tiny.json").write_text(TINY_STUDY)
    (folder / "loss.json").write_text('{"ppo": {"symmetry": "loss"}}')
    with contextlib.chdir(folder):
        for command in WORKSPACE_COMMANDS:
            assert main(shlex.split(command)) == 0, command
    return folder


def test_the_readme_shows_commands():
    commands = readme_commands()
    assert "krl demo" in commands and len(commands) > 30


def test_every_readme_command_has_a_smoke_size():
    commands = readme_commands()
    assert [c for c in commands if c not in SMOKE] == [], "add each new README command to SMOKE"
    assert [c for c in SMOKE if c not in commands] == [], "SMOKE names commands the README no longer shows"


@pytest.mark.parametrize("command", readme_commands())
def test_every_readme_command_parses(command):
    build_parser().parse_args(shlex.split(command)[1:])


@pytest.mark.parametrize("command", readme_commands())
def test_every_readme_command_runs(command, workspace, tmp_path, monkeypatch):
    assert command in SMOKE, f"{command!r} has no smoke-size entry in SMOKE"
    options, need = SMOKE[command]
    problem = missing_need(need)
    if problem is not None:
        pytest.skip(problem)
    cwd = tmp_path / "workspace"
    shutil.copytree(workspace, cwd)
    monkeypatch.chdir(cwd)
    argv = shlex.split(command)[1:] + shlex.split(options)
    if need == WINDOW:  # MuJoCo's viewer needs GLFW on a display: a virtual one
        done = subprocess.run(
            ["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable, "-m", "krl.cli", *argv],
            env={**os.environ, "MUJOCO_GL": "glfw"},
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == 0, done.stderr
    else:
        assert main(argv) == 0


WRITTEN: tuple[str, ...] = (
    "demo/path.png",
    "demo-gait/metrics.md",
    "onnx/contract.json",
    "data/base/manifest.json",
    "figures/agent/curves.png",
    "videos/run.mp4",
    "walk.mp4",
    "seesaw.png",
    "report/evaluation.md",
    "evaluations/mine/summary.json",
    "runs/agent-rp/policy.npz",
)
"""Files the commands of the README and docs/cli.md write into the working folder (their ``--out``)."""


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_what_the_commands_write_is_ignored_by_git():
    root = README.parent
    if not (root / ".git").exists():
        pytest.skip("not a git checkout")
    result = subprocess.run(
        ["git", "check-ignore", "--no-index", *WRITTEN], cwd=root, capture_output=True, text=True
    )
    assert sorted(result.stdout.split()) == sorted(WRITTEN)
