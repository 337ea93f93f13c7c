"""Agent configs laid together (``AgentConfig.load_layers``, ``krl agent config``): tables merge key by key,
anything else replaces; an invalid result names the layer that made it so; a failed command writes
nothing; the pipeline's layers over agent-gait-ground's recipe are the study's configs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from krl.agent.config import AgentConfig, AgentConfigError, lay_over
from krl.apps.reproduce.robust import LAYERS
from krl.cli import main

ROOT = Path(__file__).resolve().parents[2]
GROUND_RECIPE = ROOT / "training" / "agent-gait-ground-seed345" / "config.json"


def _write(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data))
    return path


def test_tables_merge_key_by_key_and_anything_else_replaces():
    base = {"env": {"push_magnitude": [100, 350], "pushes": True}, "ppo": {"n_epochs": 5}, "num_envs": 8}
    layer = {"env": {"push_magnitude": [100, 900]}, "num_envs": 16}
    assert lay_over(base, layer) == {
        "env": {"push_magnitude": [100, 900], "pushes": True},
        "ppo": {"n_epochs": 5},
        "num_envs": 16,
    }
    assert lay_over({"env": {"reward": {"terms": 1}}}, {"env": {"reward": "base"}}) == {
        "env": {"reward": "base"}
    }
    assert base["env"]["push_magnitude"] == [100, 350]  # the base is not changed


def test_later_layers_win_and_the_result_is_checked(tmp_path):
    recipe = _write(tmp_path / "recipe.json", {"env": {"push_magnitude": [100, 600]}, "num_envs": 8})
    symmetry = _write(tmp_path / "symmetry.json", {"ppo": {"symmetry": "loss"}})
    curriculum = _write(
        tmp_path / "curriculum.json", {"env": {"push_curriculum": True, "push_curriculum_max": 800}}
    )
    config = AgentConfig.load_layers([recipe, symmetry, curriculum])
    assert config.ppo.symmetry == "loss" and config.num_envs == 8
    assert config.env.push_curriculum and config.env.push_curriculum_max == 800
    assert tuple(config.env.push_magnitude) == (100, 600)
    # 800 N is past the default pushes' 350 N but within the recipe's: checked on the whole, not the layer
    assert AgentConfig.load_layers([recipe, curriculum]).env.push_curriculum_max == 800


def test_an_invalid_layer_is_named(tmp_path):
    recipe = _write(tmp_path / "recipe.json", {"env": {"push_magnitude": [100, 600]}})
    typo = _write(tmp_path / "typo.json", {"ppo": {"symetry": "loss"}})
    with pytest.raises(AgentConfigError, match=r"typo\.json\.ppo: unknown setting 'symetry'"):
        AgentConfig.load_layers([recipe, typo])
    too_far = _write(tmp_path / "far.json", {"env": {"push_curriculum": True, "push_curriculum_max": 5000}})
    with pytest.raises(AgentConfigError, match=r"far\.json\.env: push_curriculum_max"):
        AgentConfig.load_layers([recipe, too_far])
    with pytest.raises(AgentConfigError, match="cannot read agent config"):
        AgentConfig.load_layers([recipe, tmp_path / "missing.json"])


def test_the_command_writes_the_whole_config_or_nothing(tmp_path, capsys):
    recipe = _write(tmp_path / "recipe.json", {"num_envs": 8})
    out = tmp_path / "out.json"
    assert (
        main(
            [
                "agent",
                "config",
                str(recipe),
                str(_write(tmp_path / "l.json", {"num_envs": 4})),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    written = json.loads(out.read_text())
    assert written == AgentConfig.from_json({"num_envs": 4}).to_json()
    capsys.readouterr()
    bad = _write(tmp_path / "bad.json", {"num_envs": 0})
    assert main(["agent", "config", str(recipe), str(bad), "--out", str(out)]) == 2
    assert "bad.json" in capsys.readouterr().err.strip().splitlines()[-1]
    assert json.loads(out.read_text()) == written  # the earlier file is intact
    assert main(["agent", "config", str(recipe)]) == 0  # printed, as JSON
    assert json.loads(capsys.readouterr().out)["num_envs"] == 8


@pytest.mark.parametrize(
    ("example", "layers"),
    [
        ("gait-ground-augment", ["augment"]),
        ("gait-ground-loss", ["loss"]),
        ("gait-ground-curriculum", ["curriculum"]),
        ("broad-pushes", ["broad-pushes"]),
    ],
)
def test_the_pipelines_layers_make_the_studys_configs(tmp_path, example, layers):
    """examples/robust's configs (what agent-robust.sh trained and walked) are agent-gait-ground's recipe with
    the reproduce pipeline's layers over it, and the shipped agent-robust's is the recipe with loss and the
    curriculum."""
    paths = [GROUND_RECIPE, *(_write(tmp_path / f"{name}.json", LAYERS[name]) for name in layers)]
    expected = AgentConfig.load(ROOT / "examples" / "robust" / f"{example}.json")
    assert AgentConfig.load_layers(paths) == expected


def test_agent_robusts_recipe_is_the_ground_recipe_with_loss_and_the_curriculum(tmp_path):
    paths = [
        GROUND_RECIPE,
        *(_write(tmp_path / f"{name}.json", LAYERS[name]) for name in ("loss", "curriculum")),
    ]
    chosen = ROOT / "training" / "robust" / "heldout-robust" / "chosen-config.json"
    assert AgentConfig.load_layers(paths) == AgentConfig.load(chosen)
