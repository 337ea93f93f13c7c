"""The waypoint task: which waypoint the robot walks to, when it counts as reached, and when time is up.

Used by the runner (:mod:`krl.task.runner`), the episode scorer (:mod:`krl.eval.episodes`) and the residual
agent's environment (:mod:`krl.agent.env`), so that "reached" and the reward cannot disagree.
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
