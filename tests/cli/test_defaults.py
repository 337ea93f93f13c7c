"""The CLI restates no default: options that set a dataclass field default to None, the command fills only
the fields given, and the help shows the dataclass's own default."""

import argparse

import pytest

from krl.cli import build_parser, main
from krl.cli.common import Parser, default_of
from krl.cli.data import collect_config_from_args
from krl.cli.eval import push_sweep_from_args
from krl.cli.kernel import config_from_args
from krl.control.expert import ExpertParams
from krl.data.collect import CollectConfig
from krl.eval.episodes import PushSweep
from krl.kernel.model import NetworkConfig
from krl.kernel.train import TrainConfig
from krl.task import TARGET_TIME_LIMIT

TRAIN_OPTIONS = {
    "--variant": (TrainConfig, "variant"),
    "--epochs": (TrainConfig, "epochs"),
    "--patience": (TrainConfig, "patience"),
    "--lr": (TrainConfig, "learning_rate"),
    "--lr-decay": (TrainConfig, "lr_decay"),
    "--batch-size": (TrainConfig, "batch_size"),
    "--seed": (TrainConfig, "seed"),
    "--hidden": (NetworkConfig, "hidden"),
    "--activation": (NetworkConfig, "activation"),
    "--dropout": (NetworkConfig, "dropout"),
    "--batch-norm": (NetworkConfig, "batch_norm"),
}


def subcommand(*names: str) -> argparse.ArgumentParser:
    parser = build_parser()
    for name in names:
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action.choices[name]
    return parser


def options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {flag: action for action in parser._actions for flag in action.option_strings}


def shown(value) -> str:
    return ",".join(map(str, value)) if isinstance(value, tuple) else str(value)


def test_kernel_train_help_shows_the_defaults_of_train_config(capsys):
    with pytest.raises(SystemExit):
        main(["kernel", "train", "--help"])
    text = " ".join(capsys.readouterr().out.split())  # undo argparse's line wrapping
    found = options(subcommand("kernel", "train"))
    for flag, (owner, field) in TRAIN_OPTIONS.items():
        assert found[flag].default is None, f"{flag} restates a default: {found[flag].default!r}"
        default = shown(default_of(owner, field))
        help_text = " ".join(found[flag].help.split())
        assert f"(default {default})" in help_text, (flag, help_text)
        assert f"(default {default})" in text, flag  # and krl kernel train --help prints it


def test_kernel_train_without_options_trains_train_configs_defaults():
    args = subcommand().parse_args(["kernel", "train", "--data", "d", "--out", "o"])
    assert config_from_args(args) == TrainConfig()
    args = subcommand().parse_args(
        ["kernel", "train", "--data", "d", "--out", "o", "--lr", "0.01", "--no-batch-norm"]
    )
    assert config_from_args(args) == TrainConfig(learning_rate=0.01)
    args = subcommand().parse_args(
        ["kernel", "train", "--data", "d", "--out", "o", "--hidden", "8,4", "--batch-norm"]
    )
    assert config_from_args(args).network == NetworkConfig(hidden=(8, 4), batch_norm=True)


def test_collect_without_options_collects_collect_configs_defaults():
    args = build_parser().parse_args(["collect", "--out", "d"])
    assert collect_config_from_args(args) == CollectConfig(terrain_params={})
    found = options(subcommand("collect"))
    for flag in ("--targets", "--mode", "--ext-heights", "--targets-per-episode", "--target-time-limit"):
        assert found[flag].default is None, flag
    for flag in ("--gait", "--stance-duration", "--step-height", "--ride-height"):
        assert found[flag].default is None, flag
        field = flag.removeprefix("--").replace("-", "_")
        assert f"(default {default_of(ExpertParams, field)})" in found[flag].help


def test_run_and_push_options_restate_no_default():
    found = options(subcommand("expert", "run"))
    assert found["--target-time-limit"].default is None
    assert f"(default {TARGET_TIME_LIMIT:g})" in found["--target-time-limit"].help
    found = options(subcommand("evaluate"))
    for flag in ("--magnitudes", "--attempts", "--push-seed"):
        assert found[flag].default is None, flag
    args = build_parser().parse_args(["evaluate", "--controller", "expert", "--push-sweep"])
    assert push_sweep_from_args(args) == PushSweep()
    args = build_parser().parse_args(["evaluate", "--controller", "expert", "--magnitudes", "100:200:50"])
    assert push_sweep_from_args(args).magnitudes == (100.0, 150.0, 200.0)


def test_evaluate_help_names_every_controller_kind(capsys):
    from krl.eval.controllers import CONTROLLER_KINDS

    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for kind in CONTROLLER_KINDS:
        assert f"{kind}, " in text and f"{kind}:" in text, kind  # the kind and one of its options


@pytest.mark.parametrize("command", [("agent", "run"), ("agent", "heldout"), ("export",), ("evaluate",)])
def test_help_texts_name_every_shipped_agent(command, capsys):
    from krl.agent.policy import SHIPPED_POLICIES

    with pytest.raises(SystemExit):
        main([*command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert ", ".join(SHIPPED_POLICIES) in text, command


@pytest.mark.parametrize("command", [("kernel", "run"), ("kernel", "eval"), ("export",)])
def test_help_texts_name_every_shipped_kernel(command, capsys):
    from krl.kernel.registry import SHIPPED_MODELS

    with pytest.raises(SystemExit):
        main([*command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"({', '.join(SHIPPED_MODELS)})" in text, command


def test_help_and_descriptions_wrap_at_spaces_only(monkeypatch):
    """argparse alone breaks these names after their hyphen at 50 columns (6 and 4 of 8 stay whole)."""
    monkeypatch.setenv("COLUMNS", "50")
    parser = Parser(prog="krl", description="names " + "friction-sweep " * 8)
    parser.add_argument("--policy", help="shipped " + "gait-ground " * 8)
    text = parser.format_help()
    assert text.count("friction-sweep") == 8 and text.count("gait-ground") == 8
