"""Offscreen rendering (PNG frames, videos) with MuJoCo's renderer.

Headless machines need a software OpenGL: install Debian's ``libosmesa6`` and set ``MUJOCO_GL=osmesa``
(krl sets it when no display is present and nothing else was chosen). ``docs/sim.md`` has the details.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np


def has_display() -> bool:
    """Whether an X11 or Wayland display is available for interactive windows."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def ensure_offscreen_backend() -> None:
    """Pick OSMesa for ``MUJOCO_GL`` on a machine without a display, unless the user chose a backend.

    Must run before ``mujoco`` is first imported: ``import krl`` does it.
    """
    if "MUJOCO_GL" not in os.environ and not has_display():
        os.environ["MUJOCO_GL"] = "osmesa"
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")


class RenderError(RuntimeError):
    """Offscreen rendering is not available (no OpenGL backend)."""


@dataclass(frozen=True)
class CameraView:
    """A camera that tracks the trunk, or looks at a fixed point."""

    distance: float = 1.6
    """Distance from the tracked point [m]."""
    azimuth: float = 135.0
    """Horizontal angle [deg] (MuJoCo convention)."""
    elevation: float = -20.0
    """Vertical angle [deg]; negative looks down."""
    lookat: tuple[float, float, float] | None = None
    """World point [m] to look at instead of tracking the trunk (a course overview)."""


class FrameRenderer:
    """Renders RGB frames of a model, with a camera tracking the robot's trunk.

    Args:
        model: the compiled ``MjModel``.
        width, height: image size [px].
        view: camera placement.
    """

    def __init__(self, model, width: int = 640, height: int = 480, view: CameraView | None = None) -> None:
        ensure_offscreen_backend()
        import mujoco

        if width <= 0 or height <= 0:
            raise ValueError(f"image size must be positive, got {width}x{height}")
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
        try:
            self._renderer = mujoco.Renderer(model, height=height, width=width)
        except Exception as error:  # the GL backends raise several unrelated types
            backend = os.environ.get("MUJOCO_GL", "default")
            raise RenderError(
                f"offscreen rendering unavailable (MUJOCO_GL={backend}): {error}; "
                "on Debian/Ubuntu install libosmesa6 and set MUJOCO_GL=osmesa"
            ) from error
        view = view or CameraView()
        self._camera = mujoco.MjvCamera()
        if view.lookat is None:
            self._camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            self._camera.trackbodyid = model.body("trunk").id
        else:
            self._camera.type = mujoco.mjtCamera.mjCAMERA_FREE
            self._camera.lookat[:] = view.lookat
        self._camera.distance = view.distance
        self._camera.azimuth = view.azimuth
        self._camera.elevation = view.elevation

    def render(self, data) -> np.ndarray:
        """RGB image of the current state. Shape: (height, width, 3), uint8."""
        self._renderer.update_scene(data, camera=self._camera)
        return self._renderer.render().copy()

    def close(self) -> None:
        """Release the OpenGL context."""
        self._renderer.close()

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an RGB image atomically (temporary file, then rename). Returns the path."""
    from PIL import Image

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.tmp")
    Image.fromarray(image).save(temporary, format="PNG")
    os.replace(temporary, path)
    return path
