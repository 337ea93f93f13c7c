"""Course files: the shipped ones load, bad ones fail with one line naming the problem."""

from pathlib import Path

import numpy as np
import pytest

from krl.eval.courses import SHIPPED_COURSES, THESIS_COURSES, CourseError, load_course

GOOD = """
format = 1
name = "mine"
time_limit = 30.0
d_min = 0.5
waypoints = [[2.0, 0.0], [2.0, 2.0]]
starts = [[0.0, 0.0, 0.0]]

[terrain]
name = "flat"
"""


@pytest.mark.parametrize("name", SHIPPED_COURSES)
def test_shipped_courses_load(name):
    course = load_course(name)
    assert course.name == name and course.terrain == name.removesuffix("-hard")
    assert len(course.waypoints) == 5 and len(course.starts) == 4
    assert course.d_min == 0.5 and course.time_limit > 0
    model = course.build()
    assert model.terrain.name == course.terrain


def test_thesis_courses_and_their_inclines():
    assert set(THESIS_COURSES) < set(SHIPPED_COURSES)
    assert load_course("sinusoid").terrain_params["max_incline"] == 0.2
    assert load_course("stairs").terrain_params["step_height"] == 0.04
    assert load_course("tabletop").terrain_params["max_tilt"] == 0.087
    assert load_course("seesaw").terrain_params["max_tilt"] == 0.1


def test_the_harder_courses_change_one_setting_each():
    changed = {
        "stairs": "step_height",
        "tabletop": "max_tilt",
        "seesaw": "max_tilt",
        "sinusoid": "max_incline",
    }
    for name, key in changed.items():
        thesis, hard = load_course(name), load_course(f"{name}-hard")
        assert hard.terrain_params[key] > thesis.terrain_params[key]
        others = set(hard.terrain_params) - {key, "height"}  # the harder table-top stands higher
        assert {k: hard.terrain_params[k] for k in others} == {
            k: thesis.terrain_params.get(k) for k in others
        }
        assert hard.waypoints == thesis.waypoints and hard.starts == thesis.starts


def test_a_users_file_loads_and_its_fingerprint_follows_its_content(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(GOOD)
    course = load_course(path)
    assert course.waypoints == ((2.0, 0.0), (2.0, 2.0)) and course.terrain_seed == 0
    path.write_text(GOOD.replace("[2.0, 2.0]", "[2.0, 2.5]"))
    assert load_course(path).fingerprint != course.fingerprint


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("format = 1", "format = 7", "format 7 is not supported"),
        ("d_min = 0.5", "d_min = -1", "d_min must be a number > 0"),
        ("time_limit = 30.0", "", "missing key"),
        ("[[2.0, 0.0], [2.0, 2.0]]", "[[2.0, 0.0], [2.0]]", r"waypoints\[1\] must be 2 finite numbers"),
        ("[[0.0, 0.0, 0.0]]", "[]", "starts must be a non-empty list"),
        ('name = "flat"', 'name = "lava"', "terrain: unknown terrain 'lava'"),
        ('name = "flat"', 'name = "flat"\nparams = { bumps = 3 }', "terrain: .*bumps"),
        ("d_min = 0.5", "d_min = 0.5\nspeed = 3", "unknown key"),
        ("[[0.0, 0.0, 0.0]]", "[[1.8, 0.0, 0.0]]", r"starts\[0\] is within d_min"),
        ("[2.0, 2.0]]", "[1e12, 2.0]]", r"waypoints\[1\] = \(1e\+12, 2\) m lies outside .* \[-100, 100\]"),
        ("[[0.0, 0.0, 0.0]]", "[[0.0, -150.0, 0.0]]", r"starts\[0\] = \(0, -150\) m lies outside"),
    ],
)
def test_bad_course_files(tmp_path, old, new, message):
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new))
    with pytest.raises(CourseError, match=message) as info:
        load_course(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_a_course_on_a_height_field_stays_on_the_field(tmp_path):
    path = tmp_path / "off.toml"
    path.write_text(GOOD.replace('name = "flat"', 'name = "sinusoid"'))
    load_course(path)
    path.write_text(GOOD.replace('name = "flat"', 'name = "sinusoid"').replace("[2.0, 0.0],", "[20.0, 0.0],"))
    with pytest.raises(CourseError, match=r"waypoints\[0\] = \(20, 0\) m lies outside .*\[-12.5, 12.5\]"):
        load_course(path)


def test_unknown_course_name_and_broken_toml(tmp_path):
    with pytest.raises(CourseError, match=r"unknown course 'moon'.*flat"):
        load_course("moon")
    path = tmp_path / "broken.toml"
    path.write_text("format = = 1")
    with pytest.raises(CourseError, match="not a valid TOML file"):
        load_course(path)


def _largest_excursion(course, tracking_lag):
    """Largest |x| or |y| of the commanded paths from every start [m]."""
    return max(abs(course.commanded_path(i, tracking_lag)[:, :2]).max() for i in range(len(course.starts)))


def test_the_commanded_path_walks_the_course_as_an_ideal_follower(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(GOOD)
    course = load_course(path)
    poses = course.commanded_path(0)
    assert poses.shape[1] == 3 and (poses[0] == course.starts[0]).all()
    last = poses[-1, :2]
    # the walk ends once the last waypoint is within D_min, well before the time limit
    assert abs(((last - course.waypoints[-1]) ** 2).sum() ** 0.5 - course.d_min) < 0.01
    assert len(poses) * 0.005 < course.time_limit
    lagging = course.commanded_path(0, tracking_lag=0.5)
    assert len(lagging) > len(poses)
    with pytest.raises(ValueError, match="tracking_lag"):
        course.commanded_path(0, tracking_lag=-1.0)


def test_the_table_tops_commanded_paths_stay_on_the_plate():
    """A course that steers an ideal follower off the plate tests the command ramp, not the controller."""
    course = load_course("tabletop")
    half = course.build().terrain.landmarks["corner_max"][0]
    for lag in (0.0, 0.3):
        assert _largest_excursion(course, lag) < half - 0.5
    old = load_course(Path(__file__).parents[2] / "examples" / "courses" / "tabletop-3m.toml")
    assert _largest_excursion(old, 0.0) > old.build().terrain.landmarks["corner_max"][0]


def _largest_side_excursion(course, lags=(0.0, 0.1, 0.2, 0.3)) -> float:
    """Largest |y| of the commanded paths from every start while over the stairs (x within 0.3 m of them)."""
    marks = course.build().terrain.landmarks
    low, high = marks["first_riser"][0] - 0.3, marks["stairs_end"][0] + 0.3
    largest = 0.0
    for start in range(len(course.starts)):
        for lag in lags:
            path = course.commanded_path(start, lag)
            over = (path[:, 0] > low) & (path[:, 0] < high)
            largest = max(largest, float(np.abs(path[over, 1]).max()))
    return largest


def test_the_stairs_commanded_paths_stay_on_the_stairs():
    """The 3 m stairs shipped until the stairs diagnosis steered a lagging follower off the landing's side."""
    course = load_course("stairs")
    assert _largest_side_excursion(course) < 0.5 * course.terrain_params["width"] - 0.6
    old = load_course(Path(__file__).parents[2] / "examples" / "courses" / "stairs-3m.toml")
    assert _largest_side_excursion(old) > 0.5 * 3.0
