"""Gait generator (thesis Section 4.2.3, Table 4.1, Eq. 4.1-4.3, 4.6): hand-worked values and properties."""

import dataclasses
import math

import numpy as np
import pytest

from krl.control.gait import (
    GAITS,
    GaitGenerator,
    GaitParams,
    contact_schedule,
    gait_params,
    leg_phases,
    normalised_phase,
    sine_phase,
    stance_mask,
    state_fraction,
)
from krl.robots.a1.constants import LEG_NAMES, NUM_LEGS
from krl.util.timing import CONTROL_DT

FR, FL, RR, RL = (LEG_NAMES.index(n) for n in ("FR", "FL", "RR", "RL"))


# --- parameters and presets ----------------------------------------------------------------------------


def test_table_4_1_presets():
    assert set(GAITS) == {"walk", "trot", "bound"}
    assert GAITS["walk"] == GaitParams((0.0, 0.5, 0.75, 0.25), 0.25, 0.3)
    assert GAITS["trot"] == GaitParams((0.9, 0.4, 0.4, 0.9), 0.4, 0.3)
    assert GAITS["bound"] == GaitParams((0.4, 0.4, 0.9, 0.9), 0.3, 0.1)


@pytest.mark.parametrize(
    ("name", "swing", "step"),
    [
        # Eq. 4.1: tau_swing = tau_stance / (1 - r) * r;  Eq. 4.2: tau_step = tau_stance + tau_swing
        ("walk", 0.3 / 0.75 * 0.25, 0.4),  # 0.1 s swing
        ("trot", 0.3 / 0.6 * 0.4, 0.5),  # 0.2 s swing
        ("bound", 0.1 / 0.7 * 0.3, 1.0 / 7.0),  # 3/70 s swing
    ],
)
def test_durations_eq_4_1_4_2(name, swing, step):
    p = GAITS[name]
    assert p.swing_duration == pytest.approx(swing, abs=1e-12)
    assert p.step_duration == pytest.approx(step, abs=1e-12)


def test_trot_with_shorter_stance_durations():
    p = gait_params("trot", stance_duration=0.2)
    assert p.initial_phases == (0.9, 0.4, 0.4, 0.9)
    assert p.swing_duration == pytest.approx(0.2 / 0.6 * 0.4)  # 0.1333 s
    assert p.step_duration == pytest.approx(1.0 / 3.0)


def test_gait_params_overrides_and_unknown_names():
    p = gait_params("walk", swing_ratio=0.3, initial_phases=[0.1, 0.2, 0.3, 0.4])
    assert p.swing_ratio == 0.3 and p.initial_phases == (0.1, 0.2, 0.3, 0.4)
    assert GAITS["walk"].swing_ratio == 0.25  # the preset is untouched
    with pytest.raises(ValueError, match="known gaits: bound, trot, walk"):
        gait_params("gallop")
    with pytest.raises(ValueError, match="stance_time"):
        gait_params("trot", stance_time=0.2)
    with pytest.raises(ValueError, match="stance_duration"):
        gait_params("trot", stance_duration=-0.2)


def test_presets_are_read_only_and_frozen():
    with pytest.raises(TypeError):
        GAITS["gallop"] = GAITS["trot"]  # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        GAITS["trot"].swing_ratio = 0.5  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"stance_duration": -0.1}, "stance_duration"),
        ({"stance_duration": 0.0}, "stance_duration"),
        ({"stance_duration": math.nan}, "stance_duration"),
        ({"stance_duration": math.inf}, "stance_duration"),
        ({"swing_ratio": 0.0}, "swing_ratio"),
        ({"swing_ratio": 1.0}, "swing_ratio"),
        ({"swing_ratio": 1.2}, "swing_ratio"),
        ({"swing_ratio": math.nan}, "swing_ratio"),
        ({"swing_ratio": "0.4"}, "swing_ratio"),
        ({"initial_phases": (0.9, 0.4, 0.4)}, "initial_phases"),
        ({"initial_phases": ((0.9, 0.4), (0.4, 0.9))}, "initial_phases"),
        ({"initial_phases": (0.9, 0.4, 1.5, 0.9)}, r"initial_phases\[RR\]"),
        ({"initial_phases": (-0.1, 0.4, 0.4, 0.9)}, r"initial_phases\[FR\]"),
        ({"initial_phases": (math.nan, 0.4, 0.4, 0.9)}, r"initial_phases\[FR\]"),
        ({"initial_phases": ("a", 0.4, 0.4, 0.9)}, "initial_phases"),
    ],
)
def test_invalid_params_name_the_field(kwargs, field):
    base = {"initial_phases": (0.9, 0.4, 0.4, 0.9), "swing_ratio": 0.4, "stance_duration": 0.2}
    with pytest.raises(ValueError, match=field):
        GaitParams(**{**base, **kwargs})


# --- hand-worked phases --------------------------------------------------------------------------------


def test_trot_at_50ms_by_hand():
    # tau_swing = 0.2 / 0.6 * 0.4 = 0.1333, tau_step = 0.3333, t / tau_step = 0.15
    p = gait_params("trot", stance_duration=0.2)
    phi = leg_phases(0.05, p)
    # FR, RL: (0.9 + 0.15) mod 1 = 0.05; FL, RR: 0.4 + 0.15 = 0.55
    np.testing.assert_allclose(phi, [0.05, 0.55, 0.55, 0.05], atol=1e-12)
    np.testing.assert_array_equal(stance_mask(phi, p.swing_ratio), [False, True, True, False])
    # swing: 1 + 0.05 / 0.4 = 1.125; stance: (0.55 - 0.4) / 0.6 = 0.25
    np.testing.assert_allclose(normalised_phase(phi, p.swing_ratio), [1.125, 0.25, 0.25, 1.125], atol=1e-12)
    s = math.sin(0.125 * math.pi)  # sin(1.125 pi) = -sin(0.125 pi) = -0.3827
    np.testing.assert_allclose(sine_phase(phi, p.swing_ratio), [-s, 0.5**0.5, 0.5**0.5, -s], atol=1e-12)
    # elapsed fraction: 0.05 / 0.4 = 0.125 of the swing, 0.25 of the stance
    np.testing.assert_allclose(state_fraction(phi, p.swing_ratio), [0.125, 0.25, 0.25, 0.125], atol=1e-12)


def test_walk_boundaries_by_hand():
    p = GAITS["walk"]  # tau_step = 0.4 s, r = 0.25
    # t = 0: theta_FR = 0 is read as phase 1 (the last instant of stance)
    phi0 = leg_phases(0.0, p)
    np.testing.assert_array_equal(phi0, [1.0, 0.5, 0.75, 0.25])
    np.testing.assert_array_equal(stance_mask(phi0, p.swing_ratio), [True, True, True, False])
    # t = 0.1 s -> +0.25: FR 0.25 (= r: still swing, last instant), FL 0.75, RR 1.0 (0 -> 1), RL 0.5
    phi = leg_phases(0.1, p)
    np.testing.assert_array_equal(phi, [0.25, 0.75, 1.0, 0.5])
    np.testing.assert_array_equal(stance_mask(phi, p.swing_ratio), [False, True, True, True])
    np.testing.assert_allclose(normalised_phase(phi, p.swing_ratio), [2.0, 2 / 3, 1.0, 1 / 3], atol=1e-12)


def test_trot_and_bound_coordination():
    t = np.arange(400) * CONTROL_DT
    trot = contact_schedule(t, GAITS["trot"])
    np.testing.assert_array_equal(trot[:, FR], trot[:, RL])
    np.testing.assert_array_equal(trot[:, FL], trot[:, RR])
    bound = contact_schedule(t, GAITS["bound"])
    np.testing.assert_array_equal(bound[:, FR], bound[:, FL])
    np.testing.assert_array_equal(bound[:, RR], bound[:, RL])
    assert not np.array_equal(bound[:, FR], bound[:, RR])


# --- properties ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(GAITS))
def test_phase_properties(name):
    p = GAITS[name]
    rng = np.random.default_rng(0)
    t = np.concatenate([rng.uniform(-5.0, 50.0, 2000), np.arange(1000) * CONTROL_DT])
    phi = leg_phases(t, p)
    assert phi.shape == (t.size, NUM_LEGS)
    assert np.all((phi > 0.0) & (phi <= 1.0))
    norm = normalised_phase(phi, p.swing_ratio)
    swing = ~stance_mask(phi, p.swing_ratio)
    np.testing.assert_array_equal(norm > 1.0, swing)  # > 1 exactly during swing
    assert np.all((norm > 0.0) & (norm <= 2.0))
    frac = state_fraction(phi, p.swing_ratio)
    assert np.all((frac > 0.0) & (frac <= 1.0))
    np.testing.assert_allclose(norm, frac + swing, atol=1e-12)
    sine = sine_phase(phi, p.swing_ratio)
    assert np.all(sine[swing] <= 1e-12) and np.all(sine[~swing] >= -1e-12)


@pytest.mark.parametrize("name", sorted(GAITS))
def test_stance_fraction_of_a_cycle_is_one_minus_swing_ratio(name):
    p = GAITS[name]
    n = 100_000
    t = (np.arange(n) + 0.5) / n * p.step_duration  # one full cycle, midpoint samples
    stance = contact_schedule(t, p)
    np.testing.assert_allclose(stance.mean(axis=0), 1.0 - p.swing_ratio, atol=2.0 / n)


def test_batched_times():
    p = GAITS["trot"]
    t = np.arange(24.0).reshape(2, 3, 4) * 0.013
    phi = leg_phases(t, p)
    sched = contact_schedule(t, p)
    assert phi.shape == (2, 3, 4, NUM_LEGS) and sched.shape == (2, 3, 4, NUM_LEGS)
    assert sched.dtype == bool
    for idx in np.ndindex(t.shape):
        np.testing.assert_array_equal(phi[idx], leg_phases(float(t[idx]), p))
    assert leg_phases(0.3, p).shape == (NUM_LEGS,)
    with pytest.raises(ValueError, match="finite"):
        leg_phases(np.array([0.0, np.nan]), p)


def test_phase_functions_reject_bad_swing_ratio():
    for fn in (normalised_phase, sine_phase, stance_mask, state_fraction):
        with pytest.raises(ValueError, match="swing_ratio"):
            fn(np.array([0.5]), 1.0)


# --- stateful generator ----------------------------------------------------------------------------------


def test_generator_hand_worked_and_readouts():
    gen = GaitGenerator(gait_params("trot", stance_duration=0.2))
    np.testing.assert_allclose(gen.phases, [0.9, 0.4, 0.4, 0.9])
    for _ in range(10):  # 10 x 5 ms = 0.05 s
        phi = gen.step()
    assert gen.step_count == 10 and gen.time == pytest.approx(0.05)
    np.testing.assert_allclose(phi, [0.05, 0.55, 0.55, 0.05], atol=1e-12)
    np.testing.assert_allclose(gen.phases, phi)
    np.testing.assert_allclose(gen.normalised_phases, [1.125, 0.25, 0.25, 1.125], atol=1e-12)
    np.testing.assert_array_equal(gen.stance_mask, [False, True, True, False])
    np.testing.assert_array_equal(gen.swing_mask, [True, False, False, True])
    np.testing.assert_allclose(gen.state_fraction, [0.125, 0.25, 0.25, 0.125], atol=1e-12)
    np.testing.assert_allclose(gen.sine_phases, np.sin(np.pi * gen.normalised_phases))


def test_generator_state_fraction_advances_by_dt_over_duration():
    p = gait_params("trot", stance_duration=0.2)
    gen = GaitGenerator(p)
    prev_frac, prev_stance = gen.state_fraction, gen.stance_mask
    for _ in range(200):
        gen.step()
        frac, stance = gen.state_fraction, gen.stance_mask
        same = stance == prev_stance
        expected = np.where(stance, CONTROL_DT / p.stance_duration, CONTROL_DT / p.swing_duration)
        np.testing.assert_allclose((frac - prev_frac)[same], expected[same], atol=1e-9)
        prev_frac, prev_stance = frac, stance


def test_generator_has_no_drift_and_resets():
    p = gait_params("trot", stance_duration=0.2)  # tau_step = 1/3 s: 200 steps = 1 s = 3 cycles
    gen = GaitGenerator(p)
    for _ in range(20_000):  # 100 s
        gen.step()
    np.testing.assert_allclose(gen.phases, [0.9, 0.4, 0.4, 0.9], atol=1e-12)
    gen.reset()
    assert gen.step_count == 0 and gen.time == 0.0
    np.testing.assert_allclose(gen.phases, [0.9, 0.4, 0.4, 0.9])
    gen.step()
    gen.reset(GAITS["bound"])
    assert gen.params == GAITS["bound"] and gen.step_count == 0
    np.testing.assert_allclose(gen.phases, [0.4, 0.4, 0.9, 0.9])


def test_generator_rejects_bad_arguments():
    with pytest.raises(ValueError, match="GaitParams"):
        GaitGenerator("trot")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="dt"):
        GaitGenerator(GAITS["trot"], dt=0.0)
    with pytest.raises(ValueError, match="GaitParams"):
        GaitGenerator(GAITS["trot"]).reset("walk")  # type: ignore[arg-type]
