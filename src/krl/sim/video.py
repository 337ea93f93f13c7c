"""MP4 videos of runs, rendered offscreen while the simulation steps."""

from __future__ import annotations

import os
from pathlib import Path

from krl.sim.render import CameraView, FrameRenderer
from krl.sim.robot import A1Sim


class VideoRecorder:
    """Call :meth:`capture` after every control step; frames are taken at ``fps`` of simulated time.

    The video is written to a temporary file beside ``path`` and renamed on :meth:`close`, so an
    interrupted run never leaves a truncated file under the requested name.
    """

    def __init__(
        self,
        sim: A1Sim,
        path: str | Path,
        fps: int = 30,
        width: int = 640,
        height: int = 480,
        view: CameraView | None = None,
    ) -> None:
        import imageio.v2 as imageio

        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.sim = sim
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._temporary = self.path.with_name(f".{self.path.stem}.tmp{self.path.suffix}")
        self._renderer = FrameRenderer(sim.model, width, height, view)
        self._writer = imageio.get_writer(self._temporary, fps=fps, macro_block_size=1)
        self._period = 1.0 / fps
        self._next = 0.0
        self.frames = 0

    def capture(self) -> None:
        """Append a frame if one is due at the simulator's current time."""
        if self.sim.time + 1e-9 >= self._next:
            self._writer.append_data(self._renderer.render(self.sim.data))
            self.frames += 1
            self._next += self._period

    def close(self) -> Path:
        """Finish the file and move it into place. Returns its path."""
        self._writer.close()
        self._renderer.close()
        os.replace(self._temporary, self.path)
        return self.path
