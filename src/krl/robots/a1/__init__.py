"""The Unitree A1 model (MJCF) and its constants."""

from importlib.resources import files

MJCF_PATH = files(__package__) / "a1.xml"
"""Path of the packaged A1 MJCF (robot only; terrains are added by :mod:`krl.sim.model`)."""
