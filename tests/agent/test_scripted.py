"""The scripted gait rule (``gait:`` controllers): what it drives while the robot is carried, its latch, and
its spec's one-line errors."""

from dataclasses import replace

import numpy as np
import pytest

from krl.agent.scripted import GaitRule, ScriptedGait
from krl.eval.controllers import ControllerSpecError, parse_controller
from krl.sim.model import build_model
from krl.sim.robot import A1Sim


def carried_state(velocity, time=1.0):
    state = A1Sim(build_model("flat")).reset()
    return replace(state, time=time, lin_vel_base=np.array([*velocity, 0.0]))


def test_while_carried_the_rule_steers_towards_the_velocity_and_drives_clock_and_ride():
    controller = ScriptedGait(GaitRule(capture=0.5, rate=1.5, ride=0.2, alpha=1.0))
    command = np.array([0.3, 0.0, 0.0])
    controller.reset(carried_state((0.3, 0.0)))
    controller.act(carried_state((0.3, 0.0)), command)  # walking as commanded: nominal
    np.testing.assert_allclose(controller.residual.gait_inputs[0], [0, 0, 0, 0.08, 0.25, 1.0])
    controller.act(carried_state((0.1, 0.8), time=1.1), command)  # error (-0.2, 0.8): carried
    np.testing.assert_allclose(controller.residual.gait_inputs[0], [-0.1, 0.3, 0, 0.08, 0.2, 1.5])
    controller.act(carried_state((0.1, 0.8), time=1.2), command)
    np.testing.assert_allclose(controller.residual.kernel_command[0], [0.2, 0.3, 0.0])  # 0.4 clipped


def test_the_rule_rests_after_hold_until_the_robot_is_no_longer_carried():
    controller = ScriptedGait(GaitRule(capture=1.0, hold=0.5))
    assert [controller._carried(t, 1.0) for t in (0.0, 0.3, 0.5, 0.6, 0.7)] == [
        True,
        True,
        True,
        False,
        False,
    ]
    assert controller._carried(0.8, 0.1) is False and controller._carried(0.9, 1.0) is True


def test_a_gait_spec_names_its_options_and_refuses_bad_ones_in_one_line():
    spec = parse_controller("gait:capture=1,rate=2,ride=0.18,alpha=1")
    assert spec.label == "gait-alpha1-capture1-rate2-ride0.18" and not spec.artifacts
    assert isinstance(spec.build(), ScriptedGait)
    for text, message in (
        ("gait:foo=1", "gait options are capture=VALUE"),
        ("gait:rate=9", "clock_rate value 9.0 lies outside"),
        ("gait:ride=0.06", r"ride height value 0.06 lies outside the drive's range \[0.18, 0.28\]"),
        ("gait:step=0.25", r"step height value 0.25 lies outside the drive's range \[0.05, 0.18\]"),
        ("gait:ride=x", "ride must be a number"),
        ("gait:hold=0", "hold must be a number > 0"),
    ):
        with pytest.raises(ControllerSpecError, match=message):
            parse_controller(text)
