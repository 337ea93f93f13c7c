"""Raibert swing: phase remapping, the parabola through lift-off, apex and landing, landing points."""

import numpy as np
import pytest

from krl.control.swing import NOMINAL_FOOT_XY, raibert_landing, remap_swing_phase, swing_position
from krl.robots.a1.constants import FOOT_RADIUS


def test_eighty_percent_of_the_path_in_the_first_half():
    assert remap_swing_phase(0.0) == pytest.approx(0.0)
    assert remap_swing_phase(0.5) == pytest.approx(0.8)
    assert remap_swing_phase(1.0) == pytest.approx(1.0)
    s = np.linspace(0, 1, 101)
    assert np.all(np.diff(remap_swing_phase(s)) >= 0)


def test_path_passes_lift_off_apex_and_landing():
    lift_off = np.array([0.1, -0.13, -0.23])
    landing = np.array([0.25, -0.13, -0.23])
    apex = -0.15
    np.testing.assert_allclose(swing_position(0.0, lift_off, landing, apex), lift_off)
    np.testing.assert_allclose(swing_position(1.0, lift_off, landing, apex), landing)
    # the apex is at path fraction 0.5, i.e. swing time s with 0.8 sin(π s) = 0.5
    s_apex = np.arcsin(0.5 / 0.8) / np.pi
    at_apex = swing_position(s_apex, lift_off, landing, apex)
    assert at_apex[2] == pytest.approx(apex)
    assert at_apex[0] == pytest.approx(0.175)


def test_raibert_landing_hand_worked():
    velocity = np.tile([0.4, 0.0, 0.0], (4, 1))
    command = np.tile([0.5, 0.0, 0.0], (4, 1))
    landing = raibert_landing(velocity, command, stance_duration=0.2, ride_height=0.25, gain=0.03)
    # 0.4 * 0.1 = 0.04 ahead, minus 0.03 * (0.5 - 0.4) = 0.003 of feedback
    np.testing.assert_allclose(landing[:, 0], NOMINAL_FOOT_XY[:, 0] + 0.037)
    np.testing.assert_allclose(landing[:, 1], NOMINAL_FOOT_XY[:, 1])
    np.testing.assert_allclose(landing[:, 2], -0.25 + FOOT_RADIUS)
