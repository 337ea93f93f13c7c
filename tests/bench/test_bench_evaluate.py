"""krl bench evaluate walks the courses it is given and sets their steps against bare MuJoCo's."""

from __future__ import annotations

import json

import pytest

from krl.cli import main

SHORT = """
format = 1
name = "short"
time_limit = 0.5
d_min = 0.5
waypoints = [[3.0, 0.0]]
starts = [[0.0, 0.0, 0.0], [0.0, 0.3, 0.5]]

[terrain]
name = "flat"
"""


def test_bench_evaluate_measures_the_courses_it_walks(tmp_path, capsys):
    course = tmp_path / "short.toml"
    course.write_text(SHORT)
    argv = ["bench", "evaluate", "--controller", "kernel", "--course", str(course), "--push-attempts", "0"]
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["controller"] == "kernel-base" and result["control_steps"] == {"short": 2 * 100}
    assert result["eval_steps_per_s"] > 0 and result["bare_steps_per_s"] > 0
    assert result["eval_ratio"] == round(result["eval_steps_per_s"] / result["bare_steps_per_s"], 3)
    assert result["push_runs"] == 0 and result["push_sweep_seconds"] is None
    bare_step = 1 / result["bare_steps_per_s"]  # kernel-base's network bounds the ratio below 1
    assert result["network_us_per_step"] > 0
    ceiling = bare_step / (bare_step + result["network_us_per_step"] * 1e-6)
    assert result["ratio_ceiling"] == pytest.approx(ceiling, abs=2e-3) and result["ratio_ceiling"] < 1
    assert main(["bench", "evaluate", "--controller", "nonsense", "--course", str(course)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nonsense" in err
