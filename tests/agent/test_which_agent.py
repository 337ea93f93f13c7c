"""docs/which-agent.md names every shipped agent, and the recipe it links for each is the config that agent's
policies were trained with, seed by seed (a policy file records its config)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from krl.agent.config import AgentConfig
from krl.agent.policy import load_policy, one_policy
from krl.agent.shipped import SHIPPED_POLICIES

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "which-agent.md"
SEEDS: tuple[int, ...] = (150, 215, 345, 556)
"""The thesis's training seeds: every shipped agent holds one policy of each."""


def recipes() -> dict[str, str]:
    """``{name: path}``: each ``### agent-<name>`` section's ``**Recipe:**`` link, relative to the root."""
    found = {}
    for section in PAGE.read_text().split("\n### ")[1:]:
        name = re.match(r"agent-([a-z-]+):", section)
        link = re.search(r"\*\*Recipe:\*\* \[`([^`]+)`\]\(\.\./\1\)", section)
        assert name and link, f"a section of {PAGE.name} without its name or recipe link: {section[:60]!r}"
        found[name.group(1)] = link.group(1)
    return found


def test_the_page_has_one_section_per_shipped_agent():
    assert sorted(recipes()) == sorted(SHIPPED_POLICIES)


@pytest.mark.parametrize("name", SHIPPED_POLICIES)
def test_the_linked_recipe_trained_every_seed_of_the_agent(name):
    recipe = AgentConfig.load(ROOT / recipes()[name])
    trained = {seed: load_policy(one_policy(f"{name}@{seed}")[1]).config for seed in SEEDS}
    assert [seed for seed, config in trained.items() if config != recipe] == []
