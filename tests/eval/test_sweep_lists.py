"""Sweep list options (``--frictions``, ``--magnitudes``) are checked whole before any run starts."""

import pytest

from krl.cli import main
from krl.eval.episodes import FrictionSweep, PushSweep
from krl.sim.pushes import MAX_PUSH_FORCE
from krl.sim.terrains import MAX_GROUND_FRICTION


def test_a_push_above_the_largest_is_refused_by_the_sweep():
    assert MAX_PUSH_FORCE == 5000.0  # the messages below name it
    with pytest.raises(ValueError, match=r"from 0 to 5000 N, got 5001"):
        PushSweep(magnitudes=(300.0, 5001.0))
    assert PushSweep(magnitudes=(MAX_PUSH_FORCE,)).magnitudes == (5000.0,)  # the bound itself is valid


def test_a_friction_above_the_grounds_range_is_refused_by_the_sweep():
    assert MAX_GROUND_FRICTION == 5.0  # the message below names it
    with pytest.raises(ValueError, match=r"friction 6 is out of range: 0 < μ <= 5"):
        FrictionSweep(frictions=(1.0, 6.0))
    assert FrictionSweep(frictions=(MAX_GROUND_FRICTION,)).frictions == (5.0,)  # the bound itself is valid


@pytest.mark.parametrize(
    "options, message",
    [
        (["--friction-sweep", "--frictions", "1,6"], "--frictions: 6 is out of range: 0 < μ <= 5"),
        (["--friction-sweep", "--frictions", "1,-0.5"], "--frictions: -0.5 is out of range: 0 < μ <= 5"),
        (
            ["--push-sweep", "--magnitudes", "300,-50"],
            "push magnitude must be a finite number from 0 to 5000 N",
        ),
        # issue 61: 1e30 N flooded the terminal with MuJoCo's warnings
        (["--push-sweep", "--magnitudes", "300,1e30"], "from 0 to 5000 N, got 1e+30"),
    ],
)
def test_a_bad_value_late_in_a_sweep_list_is_refused_before_any_run(tmp_path, tiny, capsys, options, message):
    # before the fix, --frictions 1,6 ran (and stored) the μ = 1 runs, then failed on μ = 6
    out = tmp_path / "out"
    argv = ["evaluate", "--controller", "expert", "--friction-course", str(tiny), *options]
    assert main([*argv, "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert not out.exists()
