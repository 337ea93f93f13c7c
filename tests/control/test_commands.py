"""Command generator (thesis Section 4.2.2, Algorithm 2): hand-worked ticks, limits, wrap, timing, errors."""

import math

import numpy as np
import pytest

from krl.control.commands import CommandGenerator, CommandParams, next_command, wrap_angle
from krl.util.timing import COMMAND_PERIOD_STEPS

ZERO = np.zeros(3)
FAR_AHEAD = np.array([100.0, 0.0])
ORIGIN = np.zeros(2)


def test_defaults():
    p = CommandParams()
    assert (p.max_speed, p.rate_limit, p.yaw_gain, p.d_min) == (0.5, 0.005, 0.3, 0.5)
    np.testing.assert_array_equal(p.low, [-0.5, -0.3, -0.5])
    np.testing.assert_array_equal(p.high, [0.5, 0.3, 0.5])
    assert COMMAND_PERIOD_STEPS == 10


# --- one tick of GENERATE_COMMANDS -------------------------------------------------------------------------


def test_first_tick_straight_ahead_is_exactly_the_rate_limit():
    np.testing.assert_array_equal(next_command(FAR_AHEAD, ORIGIN, 0.0, ZERO), [0.005, 0.0, 0.0])


def test_rate_limit_accumulates_and_small_errors_are_reached_in_one_tick():
    cmd = ZERO
    for _ in range(10):
        cmd = next_command(FAR_AHEAD, ORIGIN, 0.0, cmd)
    np.testing.assert_allclose(cmd, [0.05, 0.0, 0.0], atol=1e-15)  # 10 x 0.005
    # Raw command [D, 0, 0] with D = 0.6 m: from 0.598 the remaining 0.002 < 0.005 is taken at once.
    p = CommandParams(max_speed=1.0, vx_range=(-1.0, 1.0))
    np.testing.assert_allclose(next_command([0.6, 0.0], ORIGIN, 0.0, [0.598, 0.0, 0.0], p), [0.6, 0, 0])


def test_each_component_is_rate_limited_down_as_well_as_up():
    # Target 1 m to the left: raw = [cos(pi/2), sin(pi/2), 0.3 * pi/2] = [0, 1, 0.471]
    cmd = next_command([0.0, 1.0], ORIGIN, 0.0, [0.2, -0.1, -0.2])
    np.testing.assert_allclose(cmd, [0.195, -0.095, -0.195], atol=1e-15)


def test_planar_speed_cap():
    # Already at 0.5 m/s straight ahead: +0.005 gives 0.505, capped back to 0.5.
    np.testing.assert_allclose(next_command(FAR_AHEAD, ORIGIN, 0.0, [0.5, 0.0, 0.0]), [0.5, 0.0, 0.0])
    # Far target at 45 deg, previous (0.4, 0.3, 0): rate limit -> (0.405, 0.305, 0.005);
    # |(0.405, 0.305)| = sqrt(0.25705) = 0.50700 > 0.5 -> scale both by 0.5 / 0.50700 -> (0.39941, 0.30079);
    # then the v_y range clips 0.30079 to 0.3. The yaw rate (0.005 rad/s) is not in the norm.
    cmd = next_command([100.0, 100.0], ORIGIN, 0.0, [0.4, 0.3, 0.0])
    scale = 0.5 / math.sqrt(0.405**2 + 0.305**2)
    np.testing.assert_allclose(cmd, [0.405 * scale, 0.3, 0.005], atol=1e-12)
    assert cmd[0] == pytest.approx(0.39941, abs=1e-5)


def test_range_clip():
    p = CommandParams(max_speed=10.0, vx_range=(-0.1, 0.1), yaw_rate_range=(-0.2, 0.2))
    cmd = next_command([100.0, 1.0], ORIGIN, 0.0, [0.1, 0.0, 0.2], p)
    assert cmd[0] == 0.1  # 0.105 clipped
    # heading error atan2(1, 100) = 0.01 rad -> raw 0.003: the rate limit moves 0.2 down to 0.195
    assert cmd[2] == pytest.approx(0.195, abs=1e-15)
    cmd = next_command([-1.0, 1.0], ORIGIN, 0.0, [0.0, 0.0, 0.2], p)
    assert cmd[2] == 0.2  # raw 0.3 * 3pi/4 = 0.707: 0.205 clipped to 0.2


def test_heading_wrap_behind_left_turns_left():
    # Target behind-left at (-1, 1): theta = atan2(1, -1) = 3pi/4; raw = [-1, 1, 0.3 * 3pi/4].
    np.testing.assert_allclose(next_command([-1.0, 1.0], ORIGIN, 0.0, ZERO), [-0.005, 0.005, 0.005])
    # Same target with the robot facing -3pi/4: 3pi/4 - (-3pi/4) = 3pi/2 wraps to -pi/2 (turn right).
    cmd = next_command([-1.0, 1.0], ORIGIN, -0.75 * math.pi, ZERO)
    np.testing.assert_allclose(cmd, [0.0, -0.005, -0.005], atol=1e-12)
    # Facing +3pi/4 + 2 pi turns is the same as facing 3pi/4: target dead ahead, no yaw.
    cmd = next_command([-1.0, 1.0], ORIGIN, 0.75 * math.pi + 4 * math.pi, ZERO)
    np.testing.assert_allclose(cmd, [0.005, 0.0, 0.0], atol=1e-12)
    # Exactly behind: theta = pi, and (-pi, pi] makes it a left turn.
    assert next_command([-1.0, 0.0], ORIGIN, 0.0, ZERO)[2] == 0.005
    assert next_command([-1.0, -0.0], ORIGIN, 0.0, ZERO)[2] == 0.005


def test_wrap_angle():
    pi = math.pi
    np.testing.assert_allclose(
        wrap_angle([0.0, pi, -pi, 3 * pi, 2 * pi, -pi / 2, 1.5 * pi]), [0, pi, pi, pi, 0, -pi / 2, -pi / 2]
    )
    w = wrap_angle(np.linspace(-20, 20, 1001))
    assert np.all((w > -pi) & (w <= pi))


def test_target_at_the_base_commands_no_motion():
    # D = 0: no direction, theta := 0, raw = 0 -> decay by the rate limit
    np.testing.assert_allclose(next_command(ORIGIN, ORIGIN, 1.0, [0.1, 0.0, 0.1]), [0.095, 0.0, 0.095])


def test_batched_inputs_match_single_calls():
    rng = np.random.default_rng(1)
    target = rng.uniform(-3, 3, (5, 2))
    base = rng.uniform(-3, 3, (5, 2))
    yaw = rng.uniform(-4, 4, 5)
    prev = rng.uniform(-0.3, 0.3, (5, 3))
    out = next_command(target, base, yaw, prev)
    assert out.shape == (5, 3)
    for i in range(5):
        np.testing.assert_allclose(out[i], next_command(target[i], base[i], yaw[i], prev[i]))
    assert next_command(target, ORIGIN, 0.0, ZERO).shape == (5, 3)  # broadcasting


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (([1.0, 0.0, 0.0], ORIGIN, 0.0, ZERO), "target_xy"),
        ((FAR_AHEAD, [0.0], 0.0, ZERO), "base_xy"),
        ((FAR_AHEAD, ORIGIN, 0.0, [0.0, 0.0]), "previous_cmd"),
        ((FAR_AHEAD, [np.nan, 0.0], 0.0, ZERO), "base_xy"),
        ((FAR_AHEAD, ORIGIN, np.inf, ZERO), "yaw"),
        ((np.ones((3, 2)), np.ones((4, 2)), 0.0, ZERO), "broadcast"),
        ((FAR_AHEAD, ORIGIN, 0.0, ZERO, "params"), "CommandParams"),
    ],
)
def test_next_command_rejects_bad_inputs(args, match):
    with pytest.raises(ValueError, match=match):
        next_command(*args)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"vx_range": (0.5, -0.5)}, "vx_range"),
        ({"vy_range": (0.1,)}, "vy_range"),
        ({"yaw_rate_range": (0.0, math.nan)}, "yaw_rate_range"),
        ({"d_min": -0.1}, "d_min"),
        ({"max_speed": 0.0}, "max_speed"),
        ({"max_speed": math.inf}, "max_speed"),
        ({"rate_limit": 0.0}, "rate_limit"),
        ({"yaw_gain": -0.3}, "yaw_gain"),
        ({"yaw_gain": "0.3"}, "yaw_gain"),
    ],
)
def test_params_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        CommandParams(**kwargs)


# --- stateful generator -------------------------------------------------------------------------------------


def test_generator_updates_at_20hz_and_holds_in_between():
    gen = CommandGenerator(target_xy=FAR_AHEAD)
    outs = np.array([gen.step(ORIGIN, 0.0) for _ in range(25)])
    np.testing.assert_array_equal(outs[0], [0.005, 0.0, 0.0])  # the first call is a tick
    np.testing.assert_array_equal(outs[:10], np.tile(outs[0], (10, 1)))  # held for 10 control steps
    np.testing.assert_allclose(outs[10:20], np.tile([0.01, 0.0, 0.0], (10, 1)))
    np.testing.assert_allclose(outs[20:], np.tile([0.015, 0.0, 0.0], (5, 1)))
    assert gen.step_count == 25
    np.testing.assert_array_equal(gen.command, outs[-1])
    assert not gen.reached and gen.distance == 100.0


def test_generator_reached_flag_and_ramp_down():
    gen = CommandGenerator(target_xy=[1.0, 0.0])
    gen.step([0.5, 0.0], 0.0)  # distance exactly d_min: not reached (reached means dist < d_min)
    assert gen.distance == 0.5 and not gen.reached
    np.testing.assert_allclose(gen.command, [0.005, 0.0, 0.0])
    for _ in range(9):
        gen.step([0.6, 0.0], 0.0)  # reached between ticks: flag at once, command held
    assert gen.reached and gen.distance == pytest.approx(0.4)
    np.testing.assert_allclose(gen.command, [0.005, 0.0, 0.0])
    gen.step([0.6, 0.0], 0.0)  # next tick: ramps to zero at the rate limit instead of jumping
    np.testing.assert_allclose(gen.command, ZERO, atol=1e-15)


def test_generator_ramps_down_from_speed_once_reached():
    gen = CommandGenerator(target_xy=FAR_AHEAD)
    for _ in range(100):  # 10 ticks -> 0.05 m/s
        gen.step(ORIGIN, 0.0)
    gen.set_target([0.1, 0.0])  # command kept: moves on at the rate limit
    np.testing.assert_allclose(gen.command, [0.05, 0.0, 0.0])
    assert math.isnan(gen.distance) and not gen.reached
    cmd = gen.step(ORIGIN, 0.0)
    assert gen.reached
    np.testing.assert_allclose(cmd, [0.045, 0.0, 0.0])


def test_generator_without_target_and_reset():
    gen = CommandGenerator()
    assert gen.target is None
    np.testing.assert_array_equal(gen.step(ORIGIN, 0.0), ZERO)
    assert not gen.reached and math.isnan(gen.distance)
    gen.set_target([0.0, 5.0])
    for _ in range(11):
        gen.step(ORIGIN, 0.0)
    assert gen.command[1] > 0.0
    gen.reset()
    assert gen.target is None and gen.step_count == 0
    np.testing.assert_array_equal(gen.command, ZERO)
    gen.reset([3.0, 4.0])
    np.testing.assert_array_equal(gen.target, [3.0, 4.0])
    gen(ORIGIN, 0.0)  # __call__ is step
    assert gen.distance == 5.0


def test_generator_period_and_returns_copies():
    gen = CommandGenerator(CommandParams(), FAR_AHEAD, period_steps=1)
    a = gen.step(ORIGIN, 0.0)
    b = gen.step(ORIGIN, 0.0)
    np.testing.assert_allclose([a[0], b[0]], [0.005, 0.01])
    a[0] = 99.0
    gen.command[0] = 99.0
    assert gen.command[0] == pytest.approx(0.01)


def test_generator_rejects_bad_inputs():
    gen = CommandGenerator(target_xy=FAR_AHEAD)
    with pytest.raises(ValueError, match="base_xy"):
        gen.step([0.0, 0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="base_xy"):
        gen.step(np.zeros((1, 2)), 0.0)
    with pytest.raises(ValueError, match="yaw"):
        gen.step(ORIGIN, math.nan)
    with pytest.raises(ValueError, match="target_xy"):
        gen.set_target([[1.0, 2.0]])
    with pytest.raises(ValueError, match="target_xy"):
        gen.set_target([1.0, math.inf])
    with pytest.raises(ValueError, match="period_steps"):
        CommandGenerator(period_steps=0)
    with pytest.raises(ValueError, match="CommandParams"):
        CommandGenerator(params={"max_speed": 1.0})  # type: ignore[arg-type]


def test_generator_ticks_are_next_command_bit_for_bit():
    """The generator's one-robot tick (Python floats) gives exactly the bits of next_command on arrays:
    random targets near and far (the speed cap), on the base (D = 0), previous commands at and past the
    limits, and the ramp to zero once a target is reached."""
    rng = np.random.default_rng(7)
    params = CommandParams(max_speed=0.4)
    for k in range(3000):
        base = rng.uniform(-5, 5, 2)
        target = base.copy() if k % 50 == 0 else base + rng.normal(0, 0.3 if k % 3 else 20.0, 2)
        yaw = float(rng.uniform(-4, 4))
        previous = rng.uniform(-0.7, 0.7, 3) * (rng.random(3) < 0.8)
        gen = CommandGenerator(params, target, period_steps=1)
        gen._command = previous.copy()
        got = gen.step(base, yaw)
        if gen.reached:
            ramp = previous + np.clip(-previous, -params.rate_limit, params.rate_limit)
            speed = np.hypot(ramp[0], ramp[1])
            ramp[:2] *= np.where(speed > params.max_speed, params.max_speed / speed, 1.0)
            expected = np.clip(ramp, params.low, params.high)
        else:
            expected = next_command(target, base, yaw, previous, params)
        assert got.view(np.int64).tolist() == expected.view(np.int64).tolist(), (k, got, expected)
