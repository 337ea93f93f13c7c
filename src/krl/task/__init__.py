"""The waypoint task: which waypoint the robot walks to, when it counts as reached, and when time is up.

Used by the one episode loop (:mod:`krl.task.episode`) and its one episode record (:mod:`krl.task.record`),
which the runner (:mod:`krl.task.runner`), evaluation (:mod:`krl.eval.episodes`, :mod:`krl.eval.batch`) and
the residual agent's environment (:mod:`krl.agent.env`) all walk and keep, so that "reached" and the reward
cannot disagree.
"""

from krl.task.waypoints import (
    TARGET_DISTANCE,
    TARGET_TIME_LIMIT,
    TaskStatus,
    WaypointTask,
    commanded_path,
    random_targets,
)

__all__ = [
    "TARGET_DISTANCE",
    "TARGET_TIME_LIMIT",
    "TaskStatus",
    "WaypointTask",
    "commanded_path",
    "random_targets",
]
