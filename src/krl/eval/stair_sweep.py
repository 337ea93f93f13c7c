"""The stair sweep (ours, issue 60): straight flights up and down of rising risers, scored like a course.

For each riser height a flight is walked **up** (from before its foot onto the landing) and **down** (from
the landing past the far flight's foot), from :data:`STAIR_STARTS_UP` / :data:`STAIR_STARTS_DOWN`, with the
waypoint scoring of every course (success: the waypoint reached in :data:`STAIR_TIME_LIMIT`; fall: the
robot fell). The flights are the ``stairs`` terrain: :data:`STAIR_STEPS` risers of the riser height and
:data:`STAIR_TREAD` deep treads up, a :data:`STAIR_LANDING` m landing, the same risers down, the whole
:data:`STAIR_WIDTH` m wide (wider than the thesis's course needs, so a run measures the climb, not the
path): risers at x = 1.0, 1.3, 1.6, 1.9 and 2.2 m up, the landing from 2.2 to 3.7 m, the far flight down
at 3.7 ... 4.9 m.

:func:`trained_risers` says which risers a policy's training ground held (a terrain curriculum's riser
range, else its stepped pyramids'), so the report can say whether each riser lies inside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from krl.eval.courses import Course

STAIR_SWEEP_RISERS: tuple[float, ...] = (0.04, 0.06, 0.08, 0.10, 0.12, 0.14)
"""Riser heights of the sweep [m]: the thesis's 4 cm stairs to 14 cm."""
STAIR_TREAD: float = 0.3
"""Tread depth [m], as the thesis's stairs."""
STAIR_STEPS: int = 5
"""Risers per flight (the landing is five risers up)."""
STAIR_LANDING: float = 1.5
"""Landing depth [m]."""
STAIR_WIDTH: float = 4.0
"""Width of the flights [m]."""
STAIR_TIME_LIMIT: float = 30.0
"""Time for one flight [s]: the thesis's 4 cm flight takes ~8 s at the command generator's speed."""
STAIR_STARTS_UP: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.0, 0.0),
    (0.0, 0.4, -0.2),
    (0.0, -0.4, 0.2),
    (-0.5, 0.0, 0.0),
)
"""Start poses (x [m], y [m], yaw [rad]) before the flight up."""
STAIR_TARGET_UP: tuple[float, float] = (3.0, 0.0)
"""The waypoint of a flight up: the landing's middle [m]."""
STAIR_STARTS_DOWN: tuple[tuple[float, float, float], ...] = (
    (2.9, 0.0, 0.0),
    (2.9, 0.4, -0.2),
    (2.9, -0.4, 0.2),
    (2.6, 0.0, 0.0),
)
"""Start poses on the landing before the flight down."""
STAIR_TARGET_DOWN: tuple[float, float] = (6.2, 0.0)
"""The waypoint of a flight down: 1.3 m past its foot [m]."""
STAIR_D_MIN: float = 0.5
"""Waypoint threshold [m], the courses'."""
DIRECTIONS: tuple[str, ...] = ("up", "down")


@dataclass(frozen=True)
class StairSweep:
    """The stair sweep: every riser of ``risers`` walked up and down from every start."""

    risers: tuple[float, ...] = STAIR_SWEEP_RISERS
    """Riser heights [m], each in (0, 0.3] and distinct."""

    def __post_init__(self) -> None:
        if not self.risers:
            raise ValueError("the stair sweep needs at least one riser height")
        for riser in self.risers:
            if not 0 < riser <= 0.3:
                raise ValueError(f"riser {riser:g} m is out of range: (0, 0.3] m (in {self.risers})")
        if len(set(self.risers)) != len(self.risers):
            raise ValueError(f"risers must be distinct, got {self.risers}")

    def courses(self) -> list[tuple[float, str, Course]]:
        """``(riser [m], direction, course)`` of every flight, riser by riser, up before down."""
        return [(riser, way, flight(riser, way)) for riser in self.risers for way in DIRECTIONS]


def flight(riser: float, direction: str) -> Course:
    """The course of one flight: ``direction`` ``up`` or ``down`` stairs of ``riser`` [m] risers."""
    up = direction == "up"
    return Course(
        name=f"stairs-{direction}-{round(riser * 100, 1):g}cm",
        description=f"A flight of {STAIR_STEPS} risers of {riser * 100:g} cm {direction} (the stair sweep).",
        terrain="stairs",
        terrain_params={
            "step_height": riser,
            "step_depth": STAIR_TREAD,
            "num_steps": STAIR_STEPS,
            "landing_depth": STAIR_LANDING,
            "width": STAIR_WIDTH,
        },
        terrain_seed=0,
        waypoints=(STAIR_TARGET_UP if up else STAIR_TARGET_DOWN,),
        starts=STAIR_STARTS_UP if up else STAIR_STARTS_DOWN,
        time_limit=STAIR_TIME_LIMIT,
        d_min=STAIR_D_MIN,
    )


def trained_risers(spec: Any, seed: int | None) -> list[float] | None:
    """The riser heights [m] (low, high) a controller's policy trained on: its terrain curriculum's range,
    else its stepped pyramids' where it trained on them; None for a controller without a policy or a
    policy trained without risers."""
    if spec.kind != "agent":
        return None
    from krl.agent.policy import load_policy

    env = load_policy(spec.artifact(seed).path).config.env
    if env.terrain_curriculum is not None:
        return list(env.terrain_curriculum.riser)
    if env.pyramids_probability > 0:
        return list(env.pyramids_step_height)
    return None
