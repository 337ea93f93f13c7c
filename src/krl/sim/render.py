"""Offscreen rendering (PNG frames, videos) with MuJoCo's renderer.

Headless machines need a software OpenGL: Debian's ``libosmesa6`` with ``MUJOCO_GL=osmesa`` (krl sets it
when no display is present, nothing else was chosen and the library is installed). Without it, everything
but rendering works, and a command that renders says which library to install. ``docs/sim.md`` has the
details.
"""

from __future__ import annotations

import ctypes.util
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

OSMESA_INSTALL: str = "apt-get install libosmesa6 (with sudo when not root)"
"""How to install the software OpenGL that offscreen rendering needs on Debian/Ubuntu."""


def has_display(environ: Mapping[str, str] | None = None) -> bool:
    """Whether an X11 or Wayland display is available for interactive windows."""
    environ = os.environ if environ is None else environ
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def offscreen_backend(
    environ: Mapping[str, str], find_library: Callable[[str], str | None] = ctypes.util.find_library
) -> dict[str, str]:
    """The environment variables to set for offscreen rendering (empty: leave MuJoCo's choice alone).

    OSMesa is chosen only on a machine without a display, when the user chose no ``MUJOCO_GL``, and when
    ``libOSMesa`` can be found: selecting it without the library would make ``import mujoco`` fail (PyOpenGL
    raises at import), which must not break commands that never render.
    """
    if "MUJOCO_GL" in environ or has_display(environ) or not find_library("OSMesa"):
        return {}
    return {"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": environ.get("PYOPENGL_PLATFORM", "osmesa")}


def ensure_offscreen_backend() -> None:
    """Apply :func:`offscreen_backend` to this process. Must run before ``mujoco`` is first imported:
    ``import krl`` does it."""
    os.environ.update(offscreen_backend(os.environ))


class RenderError(RuntimeError):
    """Offscreen rendering is not available (no OpenGL backend)."""


def _first_line(error: BaseException | str) -> str:
    """The first line of an error's message (its type's name when it has none)."""
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def import_mujoco() -> None:
    """Import ``mujoco`` so that only rendering needs its ``MUJOCO_GL`` backend. MuJoCo imports the backend
    with itself, so one that cannot load (an unknown value, or ``egl``/``osmesa`` without the library) would
    fail every command, ``krl --help`` included: then ``mujoco`` is imported without rendering
    (``MUJOCO_GL=disable``, which this process's children inherit) and the failure is remembered, for
    :class:`FrameRenderer` to raise in one line. :class:`RenderError` if even that import fails."""
    global _backend_failure
    try:
        import mujoco
    except (RuntimeError, ImportError, AttributeError, OSError) as error:
        backend = os.environ.get("MUJOCO_GL", "unset")
        _backend_failure = (
            f"MuJoCo could not load its rendering backend MUJOCO_GL={backend} ({type(error).__name__}: "
            f"{_first_line(error)}); install its library (osmesa: {OSMESA_INSTALL}) or set another MUJOCO_GL"
        )
        os.environ["MUJOCO_GL"] = "disable"
        try:
            import mujoco  # noqa: F401
        except (RuntimeError, ImportError, AttributeError, OSError):
            raise RenderError(_backend_failure) from None


def render_unavailable(error: BaseException | str) -> str:
    """The one-line message of a renderer that could not start."""
    backend = os.environ.get("MUJOCO_GL", "unset")
    first = _first_line(error)
    if not has_display() and not ctypes.util.find_library("OSMesa"):
        return f"offscreen rendering needs the OSMesa library (libOSMesa not found): {OSMESA_INSTALL}"
    return (
        f"offscreen rendering unavailable (MUJOCO_GL={backend}): {first}; on Debian/Ubuntu: {OSMESA_INSTALL}"
    )


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


def aim_camera(camera, model, view: CameraView) -> None:
    """Set a ``mujoco.MjvCamera`` as ``view`` says: tracking the trunk of ``model``, or looking at
    ``view.lookat``, from its distance and angles (offscreen frames and ``krl view``'s window)."""
    import mujoco

    if view.lookat is None:
        camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        camera.trackbodyid = model.body("trunk").id
    else:
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = view.lookat
    camera.distance = view.distance
    camera.azimuth = view.azimuth
    camera.elevation = view.elevation


_backend_failure: str | None = None
"""Why the GL backend failed to start in this process (one line), once it has: MuJoCo's GL backends abort
the interpreter on a second failed start (libc++abi "recursive initialization", found with libOSMesa
missing), so a failure is remembered and never retried."""


class FrameRenderer:
    """Renders RGB frames of a model, with a camera tracking the robot's trunk.

    Args:
        model: the compiled ``MjModel``.
        width, height: image size [px].
        view: camera placement.
    """

    def __init__(self, model, width: int = 640, height: int = 480, view: CameraView | None = None) -> None:
        global _backend_failure
        ensure_offscreen_backend()
        import mujoco

        if width <= 0 or height <= 0:
            raise ValueError(f"image size must be positive, got {width}x{height}")
        if _backend_failure is not None:
            raise RenderError(_backend_failure)
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
        try:
            self._renderer = mujoco.Renderer(model, height=height, width=width)
        except Exception as error:  # the GL backends raise several unrelated types
            _backend_failure = render_unavailable(error)
            raise RenderError(_backend_failure) from error
        self._camera = mujoco.MjvCamera()
        aim_camera(self._camera, model, view or CameraView())

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


def rendering_problem() -> str | None:
    """Why offscreen rendering cannot start here (one line), or None when it can (tried on a tiny model)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body name='trunk'/></worldbody></mujoco>")
    try:
        FrameRenderer(model, 16, 16).close()
    except RenderError as error:
        return str(error)
    return None


def write_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an RGB image atomically (temporary file, then rename). Returns the path."""
    from PIL import Image

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.tmp")
    Image.fromarray(image).save(temporary, format="PNG")
    os.replace(temporary, path)
    return path
