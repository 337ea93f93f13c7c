"""krl agent digest: the same transitions give the same SHA-256, and any change to them another."""

from __future__ import annotations

import json
from dataclasses import replace

from krl.agent.config import AgentConfig, EnvConfig
from krl.analysis.agent.transitions import transition_digest
from krl.cli import main

PUSHED = AgentConfig(env=EnvConfig(push_interval=(0.05, 0.1)))
"""Pushes within the test's steps."""


def test_the_digest_is_repeatable_and_sees_a_change_of_the_transitions():
    first = transition_digest(PUSHED, num_envs=2, steps=60)
    assert transition_digest(PUSHED, num_envs=2, steps=60) == first
    assert first["push_verdicts"] > 0  # the pushes are in the stream
    assert transition_digest(PUSHED, num_envs=2, steps=60, seed=1)["sha256"] != first["sha256"]
    stronger = replace(PUSHED, env=replace(PUSHED.env, push_magnitude=(700.0, 800.0)))
    assert transition_digest(stronger, num_envs=2, steps=60)["sha256"] != first["sha256"]


def test_cli_digests_each_config_and_refuses_bad_counts_in_one_line(tmp_path, capsys):
    path = tmp_path / "pushed.json"
    path.write_text(json.dumps(PUSHED.to_json()))
    assert main(["agent", "digest", "--config", str(path), "--envs", "2", "--steps", "60", "--json"]) == 0
    (digest,) = json.loads(capsys.readouterr().out)["digests"]
    assert digest == {"config": str(path), **transition_digest(PUSHED, num_envs=2, steps=60)}
    assert main(["agent", "digest", "--steps", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--steps must be >= 1, got 0" in err
