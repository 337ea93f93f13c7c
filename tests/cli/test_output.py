"""What every ``--json`` prints is strict JSON: a non-finite number is null, never NaN or Infinity."""

import json
import math

from krl.cli.common import emit, print_json_summary


def strict_loads(text: str):
    def refuse(constant: str):
        raise AssertionError(f"not strict JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def test_emit_prints_non_finite_numbers_as_null(capsys):
    emit({"val_l1": math.nan, "fits": [1.5, math.inf], "nested": {"low": -math.inf, "ok": 2}}, True)
    assert strict_loads(capsys.readouterr().out) == {
        "val_l1": None,
        "fits": [1.5, None],
        "nested": {"low": None, "ok": 2},
    }
    emit({"val_l1": math.nan}, False)  # text keeps what Python prints
    assert capsys.readouterr().out == "val_l1: nan\n"


def test_figure_summaries_print_non_finite_numbers_as_null(capsys):
    summary = {"figures": {"velocity": {"png": "v.png", "table": {"slope": math.nan}}}}
    print_json_summary(summary, lambda table: {"slope": table["slope"]})
    assert strict_loads(capsys.readouterr().out)["figures"]["velocity"] == {"png": "v.png", "slope": None}
