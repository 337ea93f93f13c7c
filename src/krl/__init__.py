"""krl: agile quadruped locomotion by kernel-based residual learning.

Importing the package registers the Gymnasium environments (``krl/A1-v0``) and, on a machine without
a display, selects MuJoCo's OSMesa backend for offscreen rendering unless ``MUJOCO_GL`` is set (MuJoCo
reads it when it is first imported, so this has to happen first).
"""

__version__ = "0.1.0"

from krl.sim.render import ensure_offscreen_backend

ensure_offscreen_backend()

from krl.envs import register_envs  # noqa: E402

register_envs()
