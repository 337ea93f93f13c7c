"""krl: agile quadruped locomotion by kernel-based residual learning."""

__version__ = "0.1.0"
