"""MP4 videos of runs: rendered offscreen while the simulation steps (:class:`VideoRecorder`), or logged as
joint positions while it steps and rendered afterwards (:class:`FrameLog`, :func:`write_video`), where the
filming should show its progress apart from the walk."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from krl.sim.batch import pose_for_drawing
from krl.sim.render import CameraView, FrameRenderer
from krl.sim.robot import A1Sim

VIDEO_FPS: int = 30
"""Frames per second of simulated time in krl's videos."""


class FrameClock:
    """When a frame is due: every ``1 / fps`` s of simulated time, the first at 0."""

    def __init__(self, fps: int) -> None:
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self._period = 1.0 / fps
        self._next = 0.0

    def due(self, time: float) -> bool:
        """Whether a frame is due at simulated ``time`` [s]; if so, the next one is a period later."""
        if time + 1e-9 < self._next:
            return False
        self._next += self._period
        return True


class FrameLog:
    """Call :meth:`capture` after every control step; keeps the simulator's ``qpos`` at ``fps`` of simulated
    time, the frames :func:`write_video` renders later."""

    def __init__(self, sim: A1Sim, fps: int = VIDEO_FPS) -> None:
        self.sim, self._clock = sim, FrameClock(fps)
        self.qpos: list[np.ndarray] = []
        """One ``MjData.qpos`` per frame. Shape of each: (model.nq,)."""

    def capture(self) -> None:
        """Keep a frame if one is due at the simulator's current time."""
        if self._clock.due(self.sim.time):
            self.qpos.append(self.sim.data.qpos.copy())


def write_video(
    model,
    qpos: Sequence[np.ndarray],
    path: str | Path,
    fps: int = VIDEO_FPS,
    width: int = 640,
    height: int = 480,
    on_frame: Callable[[int], None] | None = None,
) -> Path:
    """Render one frame per ``qpos`` (of ``model``, the one they were logged in) into an MP4 at ``path``,
    written beside it and moved into place when complete; ``on_frame(i)`` hears each frame rendered."""
    import imageio.v2 as imageio
    import mujoco

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.stem}.tmp{path.suffix}")
    data = mujoco.MjData(model)
    with FrameRenderer(model, width, height) as renderer:
        writer = imageio.get_writer(temporary, fps=fps, macro_block_size=1)
        try:
            for index, frame in enumerate(qpos):
                pose_for_drawing(model, data, frame)
                writer.append_data(renderer.render(data))
                if on_frame is not None:
                    on_frame(index)
        finally:
            writer.close()
    os.replace(temporary, path)
    return path


class VideoRecorder:
    """Call :meth:`capture` after every control step; frames are taken at ``fps`` of simulated time.

    The video is written to a temporary file beside ``path`` and renamed on :meth:`close`, so an
    interrupted run never leaves a truncated file under the requested name.
    """

    def __init__(
        self,
        sim: A1Sim,
        path: str | Path,
        fps: int = VIDEO_FPS,
        width: int = 640,
        height: int = 480,
        view: CameraView | None = None,
    ) -> None:
        import imageio.v2 as imageio

        self._clock = FrameClock(fps)  # refuses fps <= 0 before a file is made
        self.sim = sim
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._temporary = self.path.with_name(f".{self.path.stem}.tmp{self.path.suffix}")
        self._renderer = FrameRenderer(sim.model, width, height, view)
        self._writer = imageio.get_writer(self._temporary, fps=fps, macro_block_size=1)
        self.frames = 0

    def capture(self) -> None:
        """Append a frame if one is due at the simulator's current time."""
        if self._clock.due(self.sim.time):
            self._writer.append_data(self._renderer.render(self.sim.data))
            self.frames += 1

    def close(self) -> Path:
        """Finish the file and move it into place. Returns its path."""
        self._writer.close()
        self._renderer.close()
        os.replace(self._temporary, self.path)
        return self.path
