"""Evaluation courses: a terrain, five waypoints, the start poses, a time limit and D_min, as TOML files.

krl ships the thesis's four courses (Section 5.1: ``tabletop``, ``seesaw``, ``stairs``, ``sinusoid``),
a ``flat`` reference course, two of ours (``slope``, Fig. 4.22's ramps; ``heightfield``, a random
height field, the friction sweep's) and a harder variant of each thesis course (:data:`HARDER_COURSES`)
in ``krl/eval/courses/``; :func:`load_course` takes one of those
names or the path of a user's own file. Every key is checked, and any problem is one :class:`CourseError` line
naming the file and the key. The format is documented in ``docs/evaluation.md``.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

COURSE_FORMAT = 1
"""Version of the course file format."""

SHIPPED_COURSES: tuple[str, ...] = (
    "flat",
    "sinusoid",
    "stairs",
    "tabletop",
    "seesaw",
    "slope",
    "heightfield",
    "tabletop-hard",
    "seesaw-hard",
    "stairs-hard",
    "sinusoid-hard",
)
"""Courses shipped with krl."""

THESIS_COURSES: tuple[str, ...] = ("tabletop", "seesaw", "stairs", "sinusoid")
"""The thesis's four evaluation courses, in the order of Tables 5.1-5.4."""

HARDER_COURSES: tuple[str, ...] = tuple(f"{name}-hard" for name in THESIS_COURSES)
"""Ours, beyond the thesis: each thesis course made harder in one setting (stairs of 6 cm, the table-top
and the seesaw tilting 0.12 rad, the sinusoid's inclines 0.25 rad), the same waypoints and starts."""

PLANE_EXTENT: float = 100.0
"""Half side [m] of the square around the origin that a course must lie in on a terrain whose ground is
an unbounded plane (flat, stairs, table-top, seesaw): as far as the largest height field krl builds reaches
(``half_size`` <= 100 m). On a height-field terrain the course must lie on the field."""

_KEYS = {"format", "name", "description", "time_limit", "d_min", "waypoints", "starts", "terrain"}
_TERRAIN_KEYS = {"name", "seed", "params"}


class CourseError(ValueError):
    """A course file or name that cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class Course:
    """One evaluation course."""

    name: str
    description: str
    terrain: str
    """Terrain name (``krl terrains``)."""
    terrain_params: dict[str, Any]
    """Overrides of the terrain's parameters."""
    terrain_seed: int
    """Seed of the terrain's random draws (the course is the same for every run)."""
    waypoints: tuple[tuple[float, float], ...]
    """World (x, y) of the waypoints, in order [m]. Shape: (N, 2)."""
    starts: tuple[tuple[float, float, float], ...]
    """Start poses (x, y, yaw) [m, m, rad]; every run starts from one of them."""
    time_limit: float
    """Time allowed for the whole course [s]."""
    d_min: float
    """A waypoint is reached when the base is closer than this (planar) [m]."""
    source: str = field(default="", compare=False)
    """Where the course came from (a file path)."""

    def to_dict(self) -> dict[str, Any]:
        """The course's content as plain JSON-ready values (without ``source``)."""
        return {
            "name": self.name,
            "description": self.description,
            "terrain": {"name": self.terrain, "seed": self.terrain_seed, "params": dict(self.terrain_params)},
            "waypoints": [list(w) for w in self.waypoints],
            "starts": [list(s) for s in self.starts],
            "time_limit": self.time_limit,
            "d_min": self.d_min,
        }

    @property
    def fingerprint(self) -> str:
        """SHA-256 of the course's content: results made on a different course never mix."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def build(self, markers: bool = False):
        """Compile the course's model (:class:`krl.sim.model.BuiltModel`); ``markers`` shows the
        waypoints as red posts (for pictures; the dynamics do not change)."""
        from krl.sim.model import build_model

        points = self.waypoints if markers else ()
        return build_model(self.terrain, self.terrain_params, self.terrain_seed, markers=points)

    def commanded_path(self, start: int, tracking_lag: float = 0.0) -> np.ndarray:
        """Where the course's commands lead from start pose ``start`` (an index of :attr:`starts`): the
        path of an ideal command follower (:func:`krl.task.waypoints.commanded_path`), (x, y, yaw)
        [m, m, rad] per control step. Shape: (steps + 1, 3)."""
        from krl.control.commands import CommandParams
        from krl.task import WaypointTask, commanded_path

        task = WaypointTask(
            np.array(self.waypoints),
            replace(CommandParams(), d_min=self.d_min),
            target_time_limit=self.time_limit,
            time_limit=self.time_limit,
        )
        return commanded_path(task, self.starts[start], tracking_lag)


def shipped_course_path(name: str) -> Path:
    """Path of a shipped course file by name."""
    return Path(str(files("krl.eval") / "courses" / f"{name}.toml"))


def load_course(name_or_path: str | Path) -> Course:
    """A shipped course by name, or a course file by path; validated (:class:`CourseError` if not)."""
    text = str(name_or_path)
    if text in SHIPPED_COURSES:
        path = shipped_course_path(text)
    else:
        path = Path(text)
        if not path.is_file():
            raise CourseError(
                f"unknown course {text!r}: not a shipped course ({', '.join(SHIPPED_COURSES)}) "
                "nor an existing file"
            )
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise CourseError(f"{path}: not a valid TOML file ({error})") from None
    return parse_course(data, str(path))


def distinct_courses(courses: Sequence[Course]) -> list[Course]:
    """The courses without repeats (equal content), in order; two different courses of one name are a
    :class:`CourseError`, since results are stored by course name (``OUT/<controller>/<course>/``)."""
    kept: dict[str, Course] = {}
    for course in courses:
        other = kept.setdefault(course.name, course)
        if other.fingerprint != course.fingerprint:
            raise CourseError(
                f"two different courses are named {course.name!r} ({other.source} and {course.source}); "
                "results are stored by course name, so give one another name (its name key)"
            )
    return list(kept.values())


COURSE_SETS: dict[str, tuple[str, ...]] = {
    "thesis": THESIS_COURSES,
    "harder": HARDER_COURSES,
    "all": SHIPPED_COURSES,
}
"""Names that stand for several shipped courses (``krl evaluate --course thesis``)."""


def courses_named(names: Sequence[str]) -> list[Course]:
    """The courses of ``names`` (shipped names, files, or a set of :data:`COURSE_SETS`), each once; two
    different courses of one name are refused (:func:`distinct_courses`)."""
    expanded: list[str] = []
    for name in names:
        expanded += list(COURSE_SETS.get(name, (name,)))
    return distinct_courses([load_course(name) for name in dict.fromkeys(expanded)])


def parse_course(data: dict[str, Any], source: str = "<course>") -> Course:
    """Validate a course's parsed TOML content and build the :class:`Course`."""

    def fail(problem: str) -> CourseError:
        return CourseError(f"{source}: {problem}")

    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise fail(f"unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_KEYS))}")
    missing = sorted(_KEYS - {"description"} - set(data))
    if missing:
        raise fail(f"missing key(s) {', '.join(missing)}")
    if data["format"] != COURSE_FORMAT:
        raise fail(f"format {data['format']!r} is not supported (this krl reads format {COURSE_FORMAT})")
    name = data["name"]
    if not isinstance(name, str) or not name or not name.replace("-", "").replace("_", "").isalnum():
        raise fail(f"name must be a non-empty word (letters, digits, - and _), got {name!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise fail("description must be a string")
    time_limit = _positive(data["time_limit"], "time_limit", fail)
    d_min = _positive(data["d_min"], "d_min", fail)
    waypoints = _rows(data["waypoints"], "waypoints", 2, fail)
    starts = _rows(data["starts"], "starts", 3, fail)

    terrain = data["terrain"]
    if not isinstance(terrain, dict):
        raise fail("terrain must be a table with name, seed and params")
    unknown = sorted(set(terrain) - _TERRAIN_KEYS)
    if unknown:
        raise fail(f"unknown key(s) terrain.{', terrain.'.join(unknown)}; known: name, seed, params")
    if "name" not in terrain:
        raise fail("missing key terrain.name")
    seed = terrain.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise fail(f"terrain.seed must be an integer >= 0, got {seed!r}")
    params = terrain.get("params", {})
    if not isinstance(params, dict):
        raise fail("terrain.params must be a table of terrain parameters")
    course = Course(
        name=name,
        description=description.strip(),
        terrain=str(terrain["name"]),
        terrain_params=dict(params),
        terrain_seed=seed,
        waypoints=tuple((w[0], w[1]) for w in waypoints),
        starts=tuple((s[0], s[1], s[2]) for s in starts),
        time_limit=time_limit,
        d_min=d_min,
        source=source,
    )
    from krl.sim.terrains import TerrainError

    try:
        terrain_built = course.build().terrain
    except TerrainError as error:
        raise fail(f"terrain: {error}") from None
    (x_low, x_high), (y_low, y_high) = terrain_extent(terrain_built)
    for key, points in (("waypoints", course.waypoints), ("starts", course.starts)):
        for index, (x, y, *_) in enumerate(points):
            if not (x_low <= x <= x_high and y_low <= y <= y_high):
                raise fail(
                    f"{key}[{index}] = ({x:g}, {y:g}) m lies outside the {course.terrain} terrain's extent "
                    f"[{x_low:g}, {x_high:g}] x [{y_low:g}, {y_high:g}] m"
                )
    first = course.waypoints[0]
    for index, (x, y, _) in enumerate(course.starts):
        if math.hypot(first[0] - x, first[1] - y) < course.d_min:
            raise fail(f"starts[{index}] is within d_min = {course.d_min} m of the first waypoint")
    return course


def terrain_extent(terrain) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((x_min, x_max), (y_min, y_max))`` [m] a course on ``terrain`` (:class:`krl.sim.terrains.Terrain`)
    must lie in: its height field, or :data:`PLANE_EXTENT` around the origin on a plane."""
    grid = terrain.grid
    if grid is not None:
        return (grid.x0, grid.x1), (grid.y0, grid.y1)
    return (-PLANE_EXTENT, PLANE_EXTENT), (-PLANE_EXTENT, PLANE_EXTENT)


def _positive(value: Any, key: str, fail) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (math.isfinite(value) and value > 0)
    ):
        raise fail(f"{key} must be a number > 0, got {value!r}")
    return float(value)


def _rows(value: Any, key: str, width: int, fail) -> list[list[float]]:
    what = "(x, y)" if width == 2 else "(x, y, yaw)"
    if not isinstance(value, list) or not value:
        raise fail(f"{key} must be a non-empty list of {what} rows")
    rows = []
    for index, row in enumerate(value):
        if (
            not isinstance(row, list)
            or len(row) != width
            or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in row
            )
        ):
            raise fail(f"{key}[{index}] must be {width} finite numbers {what}, got {row!r}")
        rows.append([float(v) for v in row])
    return rows
