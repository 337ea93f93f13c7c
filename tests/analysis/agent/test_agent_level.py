"""Fig. 4.22's measure (krl agent study level-base): roll and pitch of the trunk, on hand-made runs; the slope
course it walks is on its ramp."""

import numpy as np
import pytest

from krl.analysis.agent.level import level_table, write_level_report
from krl.cli import main
from krl.eval.courses import load_course


def run(policy, course, roll, pitch, fell=False):
    metrics = {"targets_reached": 2, "targets": 2, "fell": fell}
    time = np.arange(len(roll)) * 0.005
    angles = {"roll": np.array(roll), "pitch": np.array(pitch)}
    return {"policy": policy, "course": course, "time": time, **angles, "metrics": metrics}


def test_the_table_gives_rms_and_largest_angles(tmp_path):
    runs = [
        run("agent-base", "slope", [0.1, -0.2], [0.0, 0.3], fell=True),
        run("agent-rp", "slope", [0, 0], [0, 0]),
    ]
    rows = level_table(runs)
    assert rows[0]["roll_rms"] == pytest.approx(0.1581, abs=1e-4) and rows[0]["roll_max"] == 0.2
    assert rows[0]["pitch_rms"] == pytest.approx(0.2121, abs=1e-4) and rows[0]["fell"]
    written = write_level_report(runs, tmp_path, "krl agent study level-base")
    assert [p.rsplit("/", 1)[1] for p in written] == ["level-base.md", "level-base.csv", "level-base.png"]
    assert (
        "| agent-base | slope | 0.158 | 0.212 | 0.200 | 0.300 | 2/2 | yes |"
        in (tmp_path / "level-base.md").read_text()
    )


def test_the_slope_course_climbs_the_ramp_to_the_plateau():
    course = load_course("slope")
    terrain = course.build().terrain
    x = np.array([course.starts[0][0], 2.5, course.waypoints[0][0], course.waypoints[1][0]])
    heights = terrain.height(x, np.zeros(4))
    assert heights[0] == pytest.approx(0.0, abs=1e-3) and heights[-1] == pytest.approx(0.0, abs=1e-3)
    assert heights[2] == pytest.approx(3.0 * np.tan(0.15), abs=1e-3)  # the plateau
    assert 0 < heights[1] < heights[2]


def test_level_base_refuses_a_missing_policy_in_one_line(tmp_path, capsys):
    argv = [
        "agent",
        "study",
        "level-base",
        "--policy",
        f"x={tmp_path / 'none.npz'}",
        "--report-out",
        str(tmp_path),
    ]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "none.npz" in error and error.count("\n") == 1


@pytest.mark.parametrize(
    ("command", "output"),
    [(["agent", "study", "level-base"], "--report-out"), (["agent", "stairs"], "--out")],
)
def test_policy_labels_are_checked_alike_by_every_command(tmp_path, capsys, command, output):
    """level-base and stairs read ``--policy [LABEL=]POLICY`` as heldout does: a label given twice, or not
    a folder name, is refused in one line before anything is walked or written."""
    for policies, message in [
        (["a=rp", "a=base"], "the label 'a' is given twice"),
        (["../x=rp"], "a label is letters, digits"),
    ]:
        argv = [*command, *(f"--policy={p}" for p in policies), output, str(tmp_path / "out")]
        assert main(argv) == 2
        error = capsys.readouterr().err
        assert message in error and error.count("\n") == 1
        assert not (tmp_path / "out").exists()
