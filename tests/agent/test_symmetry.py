"""The A1's mirror map (krl.agent.symmetry): complete, its own inverse, consistent with the robot."""

import numpy as np
import pytest

from krl.agent.action import DRIVE_PARTS, ActionPart
from krl.agent.config import ResidualConfig, ScanConfig
from krl.agent.observation import FEATURES, feature_size
from krl.agent.symmetry import (
    ACTION_PART_MIRRORS,
    FEATURE_MIRRORS,
    LEG_MIRROR,
    SCAN_FEATURES,
    MirrorError,
    action_mirror,
    observation_mirror,
)
from krl.robots.a1.constants import HIP_OFFSETS, LEG_NAMES, LEG_SIDE


def test_every_feature_and_action_part_has_a_mirror_of_its_size():
    assert set(FEATURE_MIRRORS) | set(SCAN_FEATURES) == set(FEATURES)
    scan = ScanConfig(x_range=(-0.4, 0.6), half_width=0.3, spacing=0.1)
    for name in FEATURES:
        mirror = observation_mirror((name,), scan)
        assert mirror.size == feature_size(name, scan), name
    assert set(ACTION_PART_MIRRORS) == {"residual", *DRIVE_PARTS}


def test_mirroring_twice_is_the_identity_for_every_feature():
    rng = np.random.default_rng(0)
    mirror = observation_mirror(tuple(FEATURES), ScanConfig())
    x = rng.normal(size=(5, mirror.size))
    np.testing.assert_array_equal(mirror(mirror(x)), x)
    assert not np.allclose(mirror(x), x)  # it does something
    np.testing.assert_array_equal(mirror.matrix() @ x[0], mirror(x[0]))


def test_the_leg_swap_matches_the_robot_s_geometry():
    """FR <-> FL and RR <-> RL: each leg's mirror is the leg on the other side at the same x."""
    for leg, other in enumerate(LEG_MIRROR):
        assert LEG_NAMES[leg][0] == LEG_NAMES[other][0]  # front stays front
        assert LEG_SIDE[leg] == -LEG_SIDE[other]
        np.testing.assert_allclose(HIP_OFFSETS[other], HIP_OFFSETS[leg] * [1, -1, 1])


def test_an_unknown_feature_is_refused_in_one_line():
    with pytest.raises(MirrorError, match="'wind'"):
        observation_mirror(("command", "wind"))


def _part(name, low, nominal, high):
    return ActionPart(name, "1", "", low, nominal, high, tuple(str(i) for i in range(len(low))))


def test_an_action_part_whose_range_the_sign_flip_breaks_is_refused():
    asymmetric = _part("steer", (-0.5, -0.2, -0.5), (0.0, 0.0, 0.0), (0.5, 0.3, 0.5))
    with pytest.raises(MirrorError, match=r"steer.*\[-0.2, 0.3\]"):
        action_mirror([asymmetric])
    with pytest.raises(MirrorError, match="'wings'"):
        action_mirror([_part("wings", (-1,), (0,), (1,))])


def test_the_shipped_kernels_action_parts_all_mirror():
    from krl.agent.action import action_parts
    from krl.kernel.model import load_kernel
    from krl.kernel.registry import resolve_model

    config = ResidualConfig(kernel="ext", drive_steer=True, drive_heights=True, drive_rhythm=True)
    parts = action_parts(config, load_kernel(str(resolve_model("ext"))))
    mirror = action_mirror(parts)
    assert mirror.size == config.action_size == 18
    residual = np.arange(12.0) + 1
    mirrored = mirror(np.concatenate([residual, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]]))
    # FR's residual becomes FL's with y negated; steer's v_y and yaw rate negate; heights and rate stay
    np.testing.assert_array_equal(mirrored[:3], [4.0, -5.0, 6.0])
    np.testing.assert_array_equal(mirrored[12:], [0.1, -0.2, -0.3, 0.4, 0.5, 0.6])
