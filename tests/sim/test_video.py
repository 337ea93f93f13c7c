"""Videos filmed afterwards (krl.sim.video.FrameLog, write_video): the frames are those filmed live.

Up to lighting: a live frame renders the simulator's MjData after ``A1Sim.step``, which refreshes positions
with ``mj_kinematics`` but leaves the scene light where ``mj_step`` put it, at the step's start; a replayed
frame's ``mj_forward`` puts it at the frame's pose. Measured: 72-228 of 20 736 pixel values differ."""

from __future__ import annotations

import numpy as np
import pytest

from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.model import build_model
from krl.sim.render import FrameRenderer, rendering_problem
from krl.sim.robot import A1Sim
from krl.sim.video import VIDEO_FPS, FrameLog, write_video

pytestmark = pytest.mark.skipif(rendering_problem() is not None, reason=str(rendering_problem()))


def test_a_logged_walk_renders_to_the_frames_filmed_while_it_stepped(tmp_path):
    import mujoco

    sim = A1Sim(build_model("heightfield", seed=3))
    sim.reset()
    log, live = FrameLog(sim), []
    targets = STANDING_JOINT_ANGLES + 0.3 * np.sin(np.arange(12))
    with FrameRenderer(sim.model, 96, 72) as renderer:
        for _ in range(60):  # 0.3 s: ten frames at 30 fps, the first at once
            sim.step(targets)
            before = len(log.qpos)
            log.capture()
            if len(log.qpos) > before:
                live.append(renderer.render(sim.data))
        replay = mujoco.MjData(sim.model)
        replayed = []
        for qpos in log.qpos:
            replay.qpos[:] = qpos
            mujoco.mj_forward(sim.model, replay)
            replayed.append(renderer.render(replay))
    assert len(live) == len(log.qpos) == 10
    for a, b in zip(live, replayed, strict=True):
        difference = np.abs(a.astype(int) - b.astype(int))
        assert np.mean(difference > 0) < 0.02 and difference.mean() < 0.5
    heard = []
    path = write_video(sim.model, log.qpos, tmp_path / "walk.mp4", width=96, height=72, on_frame=heard.append)
    assert heard == list(range(10)) and path.stat().st_size > 0
    assert not list(tmp_path.glob(".*"))  # the temporary file was moved into place
    import imageio.v2 as imageio

    with imageio.get_reader(path) as reader:
        assert reader.count_frames() == 10 and reader.get_meta_data()["fps"] == VIDEO_FPS
