"""Fixtures of the evaluation's tests."""

from __future__ import annotations

import pytest

TINY_COURSE = """
format = 1
name = "tiny"
time_limit = 0.1
d_min = 0.5
waypoints = [[3.0, 0.0]]
starts = [[0.0, 0.0, 0.0]]

[terrain]
name = "flat"
"""
"""A course of one start and 0.1 s on flat ground: a run is over at once."""


@pytest.fixture
def tiny(tmp_path):
    """The path of :data:`TINY_COURSE` written as a course file."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_COURSE)
    return path
