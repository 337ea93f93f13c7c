"""Renamed config settings (``krl.agent.config.RENAMED_SETTINGS``): a config or policy file saved with a
setting's old name loads with the same value under the new name, a resumed run folder saved so is the same
config, a config is written with the new names only, and a table giving both names is refused in one line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from krl.agent.config import AgentConfig, AgentConfigError
from krl.agent.policy import load_policy
from krl.agent.run_folder import open_run

ROOT = Path(__file__).resolve().parents[2]
OLD_RUN = ROOT / "training" / "robust" / "sym-curriculum-seed150"
"""A run folder whose config.json gives the residuals' α as ``residual.alpha`` (its name before)."""
SHIPPED_POLICY = ROOT / "src" / "krl" / "agent" / "policies" / "agent-rp" / "seed150.npz"


def _old_table(path: Path) -> dict:
    table = json.loads(path.read_text())
    assert "alpha" in table["residual"] and "residual_alpha" not in table["residual"]  # the old name
    return table


def test_an_old_config_loads_with_the_same_values_under_the_new_name():
    table = _old_table(OLD_RUN / "config.json")
    config = AgentConfig.load(OLD_RUN / "config.json")
    assert config.residual.residual_alpha == table["residual"]["alpha"]
    assert config.residual.gait_alpha == table["residual"]["gait_alpha"]
    written = config.to_json()["residual"]
    assert "alpha" not in written and written["residual_alpha"] == table["residual"]["alpha"]
    renamed = {**table, "residual": written}
    assert AgentConfig.from_json(renamed) == config


def test_a_shipped_policy_saved_with_the_old_name_loads_its_value():
    with np.load(SHIPPED_POLICY, allow_pickle=False) as archive:
        saved = json.loads(str(archive["header"]))["config"]["residual"]
    assert "alpha" in saved
    policy = load_policy(SHIPPED_POLICY)
    assert policy.config.residual.residual_alpha == saved["alpha"]


def test_an_old_run_folder_resumes_with_its_own_config(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    for name in ("config.json", "run.json"):
        shutil.copy(OLD_RUN / name, run / name)
    seed = json.loads((run / "run.json").read_text())["seed"]
    stored = AgentConfig.load(run / "config.json")
    for asked in (None, stored, AgentConfig.from_json(stored.to_json())):
        config, _ = open_run(run, asked, seed, None, None, None, "cpu")
        assert config == stored
    assert (run / "config.json").read_text() == (OLD_RUN / "config.json").read_text()  # nothing rewritten


def test_a_new_name_laid_over_an_old_one_replaces_it(tmp_path):
    recipe = tmp_path / "recipe.json"
    recipe.write_text(json.dumps({"residual": {"alpha": 0.2}}))
    layer = tmp_path / "layer.json"
    layer.write_text(json.dumps({"residual": {"residual_alpha": 0.3}}))
    assert AgentConfig.load_layers([recipe, layer]).residual.residual_alpha == 0.3
    assert AgentConfig.load_layers([recipe]).residual.residual_alpha == 0.2


def test_both_names_in_one_table_are_refused_in_one_line(tmp_path):
    both = {"residual": {"alpha": 0.1, "residual_alpha": 0.2}}
    refusal = r"^both\.residual: both 'alpha' and 'residual_alpha'"
    with pytest.raises(AgentConfigError, match=refusal) as caught:
        AgentConfig.from_json(both, "both")
    assert "\n" not in str(caught.value)
    path = tmp_path / "both.json"
    path.write_text(json.dumps(both))
    with pytest.raises(AgentConfigError, match="both 'alpha' and 'residual_alpha'"):
        AgentConfig.load_layers([path])
