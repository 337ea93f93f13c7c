"""Assembling a terrain: :func:`add_terrain` (the registry of builders, the shared scene) and
:func:`terrain_param_defaults`.

The scene every terrain shares: a skybox, checker textures, the materials the builders name (``krl_floor``,
``krl_ground``, ``krl_steps``, ``krl_steps_alt``, ``krl_prop``, ``krl_support``), the headlight, a sun, and
the offscreen buffer and free camera defaults.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import mujoco
import numpy as np

from krl.robots.a1.constants import FOOT_FRICTION
from krl.sim.terrains.geoms import set_ground_friction
from krl.sim.terrains.heightfields import (
    build_heightfield,
    build_perlin,
    build_pits,
    build_sinusoid,
    build_slope,
)
from krl.sim.terrains.params import (
    HEIGHTFIELD_MILD_MAX_HEIGHT,
    TERRAIN_NAMES,
    FlatParams,
    HeightfieldParams,
    PerlinParams,
    PitsParams,
    PyramidsParams,
    SeesawParams,
    SinusoidParams,
    SlopeParams,
    StairsParams,
    TabletopParams,
    TerrainError,
    resolve_params,
)
from krl.sim.terrains.primitives import build_flat, build_pyramids, build_seesaw, build_stairs, build_tabletop
from krl.sim.terrains.terrain import Terrain

__all__ = ["add_terrain", "terrain_param_defaults"]


def terrain_param_defaults(name: str) -> dict[str, float | int | None]:
    """Default parameters of a terrain (``None`` marks a value drawn at random when not given)."""
    cls, overrides, _ = _registry(name)
    values = {f.name: f.default for f in dataclasses.fields(cls)}
    values.update(overrides)
    return values


def add_terrain(
    spec: mujoco.MjSpec,
    name: str,
    params: Mapping[str, Any] | None = None,
    rng: np.random.Generator | None = None,
) -> Terrain:
    """Add a terrain (geoms, props, textures, lights) to ``spec``, which already holds the robot.

    Args:
        spec: the spec to extend; call at most once per spec.
        name: one of :data:`TERRAIN_NAMES`.
        params: overrides of the terrain's parameter dataclass fields (unknown keys are rejected).
        rng: source of every random draw; ``None`` means ``np.random.default_rng(0)`` (reproducible).

    Returns:
        The :class:`Terrain`, with ``params`` fully resolved; ``friction`` is among them only where it is
        not the default μ = 1, so the terrains of every record made before krl had the parameter (the
        datasets' settings and hashes, for one) are described as they were.

    Raises:
        TerrainError: unknown name, unknown parameter, out-of-range value, or a spec that already has a
            terrain.
    """
    cls, overrides, builder = _registry(name)
    resolved = resolve_params(name, cls, overrides, params)
    if rng is None:
        rng = np.random.default_rng(0)
    if spec.material("krl_floor") is not None:
        raise TerrainError(f"terrain {name!r}: this spec already has a terrain (add_terrain called twice)")
    _add_scene(spec)
    terrain = builder(spec, name, resolved, rng)
    set_ground_friction(spec, terrain.geom_names, resolved.friction)
    params = {key: value for key, value in terrain.params.items() if key != "friction"}
    if resolved.friction != FOOT_FRICTION:
        params["friction"] = resolved.friction
    return dataclasses.replace(terrain, params=params)


def _registry(name: str) -> tuple[type, dict[str, Any], Callable[..., Terrain]]:
    """Terrain ``name``'s parameter dataclass, its overrides of that class's defaults, and its builder.

    Raises:
        TerrainError: ``name`` is not one of :data:`TERRAIN_NAMES`.
    """
    table: dict[str, tuple[type, dict[str, Any], Callable[..., Terrain]]] = {
        "flat": (FlatParams, {}, build_flat),
        "heightfield": (HeightfieldParams, {}, build_heightfield),
        "heightfield_mild": (
            HeightfieldParams,
            {"max_height": HEIGHTFIELD_MILD_MAX_HEIGHT},
            build_heightfield,
        ),
        "perlin": (PerlinParams, {}, build_perlin),
        "sinusoid": (SinusoidParams, {}, build_sinusoid),
        "slope": (SlopeParams, {}, build_slope),
        "stairs": (StairsParams, {}, build_stairs),
        "pyramids": (PyramidsParams, {}, build_pyramids),
        "pits": (PitsParams, {}, build_pits),
        "tabletop": (TabletopParams, {}, build_tabletop),
        "seesaw": (SeesawParams, {}, build_seesaw),
    }
    if not isinstance(name, str) or name not in table:
        raise TerrainError(f"unknown terrain {name!r}; valid names: {', '.join(TERRAIN_NAMES)}")
    return table[name]


def _add_scene(spec: mujoco.MjSpec) -> None:
    """Skybox, checker textures, materials and lights shared by every terrain."""
    sky = spec.add_texture()
    sky.name = "krl_sky"
    sky.type = mujoco.mjtTexture.mjTEXTURE_SKYBOX
    sky.builtin = mujoco.mjtBuiltin.mjBUILTIN_GRADIENT
    sky.rgb1 = [0.62, 0.76, 0.92]
    sky.rgb2 = [0.1, 0.14, 0.22]
    sky.width = 512
    sky.height = 3072

    def checker(name: str, rgb1: list[float], rgb2: list[float]) -> None:
        tex = spec.add_texture()
        tex.name = name
        tex.type = mujoco.mjtTexture.mjTEXTURE_2D
        tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
        tex.rgb1 = rgb1
        tex.rgb2 = rgb2
        tex.mark = mujoco.mjtMark.mjMARK_EDGE
        tex.markrgb = [0.85, 0.85, 0.85]
        tex.width = 512
        tex.height = 512

    checker("krl_grid", [0.32, 0.36, 0.42], [0.22, 0.26, 0.32])
    checker("krl_grid_warm", [0.55, 0.47, 0.36], [0.45, 0.38, 0.28])

    def material(name: str, texture: str | None, rgba: list[float], repeat: float = 1.0) -> None:
        mat = spec.add_material()
        mat.name = name
        if texture is not None:
            textures = [""] * int(mujoco.mjtTextureRole.mjNTEXROLE)
            textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = texture
            mat.textures = textures
            mat.texuniform = True
            mat.texrepeat = [repeat, repeat]
        mat.rgba = rgba
        mat.reflectance = 0.0

    # texuniform: texrepeat counts textures per metre; one checker texture is 2 x 2 squares -> 0.5 m squares.
    material("krl_floor", "krl_grid", [1, 1, 1, 1], 1.0)
    material("krl_ground", "krl_grid_warm", [1, 1, 1, 1], 1.0)
    material("krl_steps", "krl_grid", [0.85, 0.9, 1.0, 1], 2.0)
    material("krl_steps_alt", "krl_grid", [0.62, 0.7, 0.85, 1], 2.0)
    material("krl_prop", "krl_grid_warm", [1.0, 0.75, 0.45, 1], 2.0)
    material("krl_support", None, [0.45, 0.45, 0.5, 1])

    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]
    spec.visual.headlight.specular = [0.1, 0.1, 0.1]
    spec.visual.global_.offwidth = max(int(spec.visual.global_.offwidth), 1280)
    spec.visual.global_.offheight = max(int(spec.visual.global_.offheight), 960)
    spec.visual.global_.azimuth = 135.0
    spec.visual.global_.elevation = -20.0

    # The sun follows the robot's trunk (position only): a directional light's shadow map covers a region
    # around the light, and a fixed far-away sun gave heavy shadow acne in offscreen (OSMesa) renders.
    trunk = spec.body("trunk")
    sun = (trunk if trunk is not None else spec.worldbody).add_light()
    sun.name = "krl_sun"
    sun.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    if trunk is not None:
        sun.mode = mujoco.mjtCamLight.mjCAMLIGHT_TRACK
    sun.pos = [0.0, 0.0, 1.5]
    sun.dir = list(np.array([0.3, 0.4, -1.0]) / np.linalg.norm([0.3, 0.4, -1.0]))
    sun.diffuse = [0.6, 0.6, 0.6]
    sun.specular = [0.2, 0.2, 0.2]
    sun.castshadow = True
