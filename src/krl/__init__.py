"""krl: agile quadruped locomotion by kernel-based residual learning.

Importing the package registers the Gymnasium environments (``krl/A1-v0``).
"""

__version__ = "0.1.0"

from krl.envs import register_envs

register_envs()
