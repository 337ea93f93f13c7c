"""``krl view``'s live session: the keyboard pauses, resets, pushes and steers; the waypoints steer."""

from __future__ import annotations

import numpy as np

from krl.apps.viewer import KEY_BACKSPACE, KEY_C, KEY_LEFT, KEY_P, KEY_SPACE, KEY_UP, LiveSession
from krl.cli import main
from krl.eval.courses import load_course
from krl.kernel.controller import KernelController
from krl.kernel.registry import load_model
from krl.sim.robot import A1Sim


def test_keys_pause_push_steer_and_reset():
    course = load_course("flat")
    session = LiveSession(
        A1Sim(course.build()),
        KernelController(load_model("base")),
        course.waypoints,
        course.starts[0],
        course.d_min,
    )
    for _ in range(300):
        session.step()
    assert session.sim.time > 1.4 and np.linalg.norm(session.sim.state.base_pos[:2]) > 0.05
    session.key(KEY_SPACE)
    time_paused = session.sim.time
    session.step()
    assert session.sim.time == time_paused
    session.key(KEY_SPACE)
    session.key(KEY_UP)
    session.key(KEY_UP)
    session.key(KEY_LEFT)
    np.testing.assert_allclose(session.command(), [0.2, 0.0, 0.1])
    session.key(KEY_C)
    assert session.manual is None
    session.key(KEY_P)
    assert session.sim.pending_push is not None and session.messages[-1] == "push of 250 N"
    session.step()
    session.key(KEY_BACKSPACE)
    assert session.sim.time == 0.0 and session.task.index == 0


def test_view_without_a_display_is_one_line(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", "--controller", "kernel", "--course", "stairs"]) == 2
    error = capsys.readouterr().err
    assert error.startswith("krl: error: `krl view` needs a display") and error.count("\n") == 1


def test_the_scan_of_an_agent_that_observes_it_is_marked_on_the_terrain():
    from dataclasses import replace

    import mujoco
    from agent_fakes import make_policy

    from krl.agent.config import AgentConfig
    from krl.agent.controller import AgentController
    from krl.apps.viewer import KEY_H, _mark_points

    config = AgentConfig()
    observation = replace(config.observation, features=(*config.observation.features, "height_scan"))
    policy = make_policy(replace(config, observation=observation))
    course = load_course("stairs")
    session = LiveSession(A1Sim(course.build()), AgentController(policy), course.waypoints, course.starts[0])
    session.step()
    points = session.scan_points()
    assert points.shape == (187, 3)
    terrain = session.sim.terrain
    np.testing.assert_allclose(points[:, 2], terrain.height(points[:, 0], points[:, 1]), atol=1e-9)
    scene = mujoco.MjvScene(session.sim.model, maxgeom=1000)
    _mark_points(scene, points)
    assert scene.ngeom == 187
    np.testing.assert_allclose(scene.geoms[5].pos, points[5], atol=1e-6)
    session.key(KEY_H)
    assert session.scan_points().shape == (0, 3)
    blind = LiveSession(A1Sim(course.build()), KernelController(load_model("base")))
    assert blind.scan_points().shape == (0, 3)
