"""External pushes on the trunk: the training perturbations of Section 4.2.9 and scripted pushes.

How a push acts (``docs/pushes.md``). The thesis applies a force of 100-900 N "for 0.3 s". Held for
0.3 s, 900 N would give the 12.5 kg robot about 21 m/s, so the thesis's PyBullet code most likely set
the force once per 200 Hz control step, and PyBullet clears external forces after every 1 kHz physics
step: the force then acts during one physics step in five. krl reproduces that by default
(``mode="control_step"``: the force acts during the first 1 ms physics step of every control step of
the push window), which keeps the thesis's force axis comparable; ``mode="continuous"`` holds it for
the whole window. Every push reports its impulse [N·s] and the velocity change it would give the free
robot [m/s], so results can also be compared on those physical axes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from krl.robots.a1.constants import TOTAL_MASS, TRUNK_HALF_SIZE
from krl.util.timing import CONTROL_DT, PHYSICS_DT, SUBSTEPS

PushMode = Literal["control_step", "continuous"]
PUSH_MODES: tuple[str, ...] = ("control_step", "continuous")

FULL_TURN: tuple[float, float] = (-np.pi, np.pi)
"""The azimuth range [rad] of a push's direction unless told otherwise: every horizontal direction."""

MAX_PUSH_FORCE: float = 5000.0
"""The largest push magnitude a push sweep or probe applies [N]: over five times the thesis's largest
(900 N, Table 5.5); far larger ones only blow the simulation up, under a flood of MuJoCo's warnings."""


def check_push_magnitude(magnitude: float) -> None:
    """ValueError (one line) unless ``magnitude`` [N] is finite and from 0 to :data:`MAX_PUSH_FORCE`."""
    if not (np.isfinite(magnitude) and 0 <= magnitude <= MAX_PUSH_FORCE):
        raise ValueError(
            f"push magnitude must be a finite number from 0 to {MAX_PUSH_FORCE:g} N, got {magnitude}"
        )


@dataclass(frozen=True)
class Push:
    """One push on the trunk.

    The push is active during the control steps ``start_step <= k < start_step + num_steps`` where
    ``start_step = ceil(start_time / CONTROL_DT)`` and ``num_steps = round(duration / CONTROL_DT)``.
    """

    start_time: float
    """Simulation time at which the push starts [s]."""
    force: np.ndarray
    """Force in the world frame [N]. Shape: (3,)."""
    point: np.ndarray
    """Point of application in the trunk (base) frame [m]. Shape: (3,)."""
    duration: float = 0.3
    """Length of the push window [s] (thesis: 0.3 s)."""
    mode: PushMode = "control_step"
    """``control_step``: force during the first physics step of each control step (PyBullet-like);
    ``continuous``: force during every physics step of the window."""

    def __post_init__(self) -> None:
        force = np.asarray(self.force, dtype=float)
        point = np.asarray(self.point, dtype=float)
        if force.shape != (3,) or not np.all(np.isfinite(force)):
            raise ValueError(f"push force must be a finite 3-vector [N], got {self.force!r}")
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise ValueError(f"push point must be a finite 3-vector [m], got {self.point!r}")
        if not (np.isfinite(self.start_time) and self.start_time >= 0):
            raise ValueError(f"push start_time must be >= 0 s, got {self.start_time}")
        if not (np.isfinite(self.duration) and self.duration >= CONTROL_DT):
            raise ValueError(
                f"push duration must be >= one control step ({CONTROL_DT} s), got {self.duration}"
            )
        if self.mode not in PUSH_MODES:
            raise ValueError(f"unknown push mode {self.mode!r}; known: {', '.join(PUSH_MODES)}")
        object.__setattr__(self, "force", force)
        object.__setattr__(self, "point", point)

    @property
    def magnitude(self) -> float:
        """Force magnitude [N]."""
        return float(np.linalg.norm(self.force))

    @property
    def start_step(self) -> int:
        """First control step during which the push acts."""
        return int(np.ceil(self.start_time / CONTROL_DT - 1e-9))

    @property
    def num_steps(self) -> int:
        """Number of control steps in the push window."""
        return round(self.duration / CONTROL_DT)

    @property
    def physics_steps_per_control_step(self) -> int:
        """Physics steps per control step during which the force acts."""
        return 1 if self.mode == "control_step" else SUBSTEPS

    @property
    def applied_seconds(self) -> float:
        """Total time during which the force acts [s]."""
        return self.num_steps * self.physics_steps_per_control_step * PHYSICS_DT

    @property
    def impulse(self) -> np.ndarray:
        """Impulse of the push in the world frame [N·s]. Shape: (3,)."""
        return self.force * self.applied_seconds

    @property
    def delta_v(self) -> float:
        """Speed change the impulse gives the whole robot, ignoring the ground [m/s]."""
        return float(np.linalg.norm(self.impulse) / TOTAL_MASS)

    def active_at(self, step: int) -> bool:
        """Whether the push acts during control step ``step``."""
        return self.start_step <= step < self.start_step + self.num_steps

    def turned(self, yaw: float) -> Push:
        """This push with its force turned about the world's vertical by ``yaw`` [rad]: a force given
        relative to a heading (x forward, y left, z up) put into the world frame for a base of that yaw.
        The point stays in the trunk frame."""
        cos, sin = np.cos(yaw), np.sin(yaw)
        x, y, z = self.force
        return replace(self, force=np.array([cos * x - sin * y, sin * x + cos * y, z]))

    def summary(self) -> dict[str, float | list[float] | str]:
        """A JSON-ready description: magnitude [N], impulse [N·s], delta_v [m/s], and the push itself."""
        return {
            "start_time": self.start_time,
            "duration": self.duration,
            "mode": self.mode,
            "magnitude": self.magnitude,
            "force": self.force.tolist(),
            "point": self.point.tolist(),
            "impulse": float(np.linalg.norm(self.impulse)),
            "delta_v": self.delta_v,
        }


def random_direction(
    rng: np.random.Generator, max_elevation: float, azimuth_range: tuple[float, float] = FULL_TURN
) -> np.ndarray:
    """Unit vector with azimuth ~ U(azimuth_range) (default U(-π, π)) and elevation above horizontal
    ~ U(0, max_elevation) [rad]. Draws the azimuth, then the elevation, one number each, whatever the range.

    Shape: (3,).
    """
    azimuth = rng.uniform(*azimuth_range)
    elevation = rng.uniform(0.0, max_elevation)
    return np.array(
        [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)]
    )


def random_trunk_point(rng: np.random.Generator, top_share: float | None = None) -> np.ndarray:
    """Point on the surface of the trunk box, in the base frame [m]. Shape: (3,).

    A face is drawn with probability proportional to its area, then a point uniformly on it. With
    ``top_share``, the top face (+z) is drawn with that probability instead (its share of the area is
    0.248) and the other five faces share the rest by area; None draws exactly as before the option.
    """
    hx, hy, hz = TRUNK_HALF_SIZE
    face_areas = np.array([hy * hz, hx * hz, hx * hy])  # faces normal to x, y, z (two of each)
    if top_share is not None:
        return _point_with_top_share(rng, top_share, face_areas)
    axis = rng.choice(3, p=face_areas / face_areas.sum())
    point = rng.uniform(-TRUNK_HALF_SIZE, TRUNK_HALF_SIZE)
    point[axis] = TRUNK_HALF_SIZE[axis] * rng.choice((-1.0, 1.0))
    return point


def _point_with_top_share(rng: np.random.Generator, top_share: float, face_areas: np.ndarray) -> np.ndarray:
    """:func:`random_trunk_point` with the top face drawn with probability ``top_share``."""
    point = rng.uniform(-TRUNK_HALF_SIZE, TRUNK_HALF_SIZE)
    if rng.random() < top_share:
        point[2] = TRUNK_HALF_SIZE[2]
        return point
    others = np.array([face_areas[0], face_areas[0], face_areas[1], face_areas[1], face_areas[2]])
    face = rng.choice(5, p=others / others.sum())  # ±x, ±y, -z
    axis, sign = (0, 0, 1, 1, 2)[face], (1.0, -1.0, 1.0, -1.0, -1.0)[face]
    point[axis] = TRUNK_HALF_SIZE[axis] * sign
    return point


@dataclass(frozen=True)
class PushDistribution:
    """Distribution of random pushes (defaults: thesis Section 4.2.9, training perturbations)."""

    interval: tuple[float, float] = (5.0, 8.0)
    """Time between the starts of consecutive pushes ~ U(a, b) [s]."""
    magnitude: tuple[float, float] = (100.0, 350.0)
    """Force magnitude ~ U(a, b) [N]."""
    max_elevation: float = 0.3
    """Direction tilted upward by ~ U(0, max_elevation) [rad] ("slightly upwards"; our choice)."""
    duration: float = 0.3
    """Push window [s]."""
    mode: PushMode = "control_step"
    """How the force is applied across physics steps (see :class:`Push`)."""
    top_share: float | None = None
    """Probability that a push strikes the trunk's top face (:func:`random_trunk_point`); None: points
    uniform over the surface (the top then 0.248 of them)."""

    def __post_init__(self) -> None:
        if self.top_share is not None and not (
            isinstance(self.top_share, (int, float)) and 0 <= self.top_share <= 1
        ):
            raise ValueError(f"push top_share must be in [0, 1] or None, got {self.top_share!r}")
        for name in ("interval", "magnitude"):
            low, high = getattr(self, name)
            if not (0 <= low <= high and np.isfinite(high)):
                raise ValueError(f"push {name} range must satisfy 0 <= low <= high, got {(low, high)}")
        if not 0 <= self.max_elevation < np.pi / 2:
            raise ValueError(f"push max_elevation must be in [0, π/2) rad, got {self.max_elevation}")

    def sample(
        self,
        rng: np.random.Generator,
        start_time: float,
        magnitude: float | None = None,
        azimuth_range: tuple[float, float] = FULL_TURN,
    ) -> Push:
        """Draw one push starting at ``start_time`` [s]; ``magnitude`` [N] fixes the force magnitude,
        ``azimuth_range`` [rad] the range its azimuth is drawn from (:func:`random_direction`)."""
        size = rng.uniform(*self.magnitude) if magnitude is None else float(magnitude)
        return Push(
            start_time=start_time,
            force=size * random_direction(rng, self.max_elevation, azimuth_range),
            point=random_trunk_point(rng, self.top_share),
            duration=self.duration,
            mode=self.mode,
        )


@dataclass
class PushSchedule:
    """Random pushes at random intervals for the whole episode (training perturbations)."""

    distribution: PushDistribution
    rng: np.random.Generator
    pushes: list[Push] = field(default_factory=list)
    """Every push drawn so far, in order."""

    def __post_init__(self) -> None:
        self._next_time = float(self.rng.uniform(*self.distribution.interval))

    def due(self, time: float, heading: float = 0.0) -> Push | None:
        """The push to start at ``time`` [s] if the next push time has come, else None. Call once per
        control step. ``heading``, the base's [rad], is not used: these pushes are drawn in the world frame
        (:class:`krl.task.episode.PushEvents`)."""
        if time + 1e-9 < self._next_time:
            return None
        push = self.distribution.sample(self.rng, start_time=time)
        self.pushes.append(push)
        self._next_time = time + float(self.rng.uniform(*self.distribution.interval))
        return push


@dataclass
class OnePush:
    """A single push (the push sweep's) as push events (:class:`krl.task.episode.PushEvents`): in the world
    frame it is scheduled at the first control step (it acts from its own start on); in the heading frame
    (x forward, y left) it waits for the control step it starts at and is turned then by the base's heading
    (:meth:`Push.turned`)."""

    push: Push
    in_heading_frame: bool = False
    scheduled: bool = False
    """Whether :meth:`due` has given the push out."""

    def due(self, time: float, heading: float) -> Push | None:
        """The push to schedule before the control step starting at ``time`` [s], with the base heading
        ``heading`` [rad] then, or None."""
        if self.scheduled:
            return None
        if self.in_heading_frame and round(time / CONTROL_DT) < self.push.start_step:
            return None
        self.scheduled = True
        return self.push.turned(heading) if self.in_heading_frame else self.push


def scripted_push(
    magnitude: float,
    rng: np.random.Generator,
    window: tuple[float, float],
    distribution: PushDistribution | None = None,
    azimuth_range: tuple[float, float] = FULL_TURN,
) -> Push:
    """A single push of a given magnitude [N] at a random time ~ U(window) [s], random point and direction
    (its azimuth ~ U(azimuth_range) [rad]; the same draws in the same order whatever the range).

    Used by the robustness sweep (thesis Section 5.3).
    """
    check_push_magnitude(magnitude)
    distribution = distribution or PushDistribution()
    start = float(rng.uniform(*window))
    return distribution.sample(rng, start_time=start, magnitude=magnitude, azimuth_range=azimuth_range)
