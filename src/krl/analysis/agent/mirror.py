"""How symmetric are the A1 and its kernel? The physics and whole-loop halves of issue 45's mirror check.

:mod:`krl.agent.symmetry` mirrors observations and actions through the base frame's x-z plane. This module
asks whether the simulated robot obeys that mirror:

* **The model** (:mod:`krl.analysis.agent.mirror_model`): every right body, joint and geom against the
  mirror image of its left partner; the only asymmetry is the trunk's inertial frame (Unitree's URDF), and
  :func:`~krl.analysis.agent.mirror_model.symmetric_trunk_model` is the model with it zeroed.
* **The physics** (:func:`physics_mirror_errors`): the robot started in a state and, beside it, in the
  state's mirror image (:func:`mirror_qpos`, :func:`mirror_qvel`), each driven by joint targets and their
  mirror, and the mirror of the first trajectory compared with the second.
* **The whole loop** (:func:`loop_asymmetry`): the kernel walking (the residual agent's action path,
  :class:`krl.agent.residual.ResidualController`, with zero residuals) at a command and, beside it, at the
  command's mirror with the gait clock shifted by half a period (a trot's mirror: FR/RL and FL/RR swap),
  from the same standing start; the figures say how far the second walk is from the mirror of the first.

:func:`mirror_markdown` is what ``krl analyze mirror`` prints: the tables of docs/agent-robust.md ("How
symmetric is the A1 and its kernel?").

Mirror conventions (MuJoCo's free joint, checked by experiment: ``qvel[0:3]`` is the linear velocity in the
world frame, ``qvel[3:6]`` the angular velocity in the body frame): with S = diag(1, -1, 1), a position p
mirrors to S p, a rotation R to S R S, i.e. the quaternion (w, x, y, z) to (w, -x, y, -z); a linear
velocity v to S v and an angular velocity ω to -S ω, in the world and in the body frame alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from krl.agent.config import ResidualConfig
from krl.agent.residual import ResidualController
from krl.agent.symmetry import FEATURE_MIRRORS
from krl.analysis.agent.mirror_model import REFLECTION, model_asymmetries, symmetric_trunk_model
from krl.control.kinematics import inverse_kinematics
from krl.kernel.model import Kernel
from krl.kernel.registry import load_model
from krl.robots.a1.constants import NUM_JOINTS, NUM_LEGS
from krl.sim.backend import make_backend
from krl.sim.model import BuiltModel, build_model
from krl.sim.robot import A1Sim
from krl.util.timing import CONTROL_DT

DEFAULT_COMMANDS: tuple[tuple[float, float, float], ...] = (
    (0.3, 0.0, 0.0),
    (0.3, 0.0, 0.4),
    (0.3, 0.2, 0.0),
    (0.0, 0.0, 0.5),
)
"""Commands (v_x [m/s], v_y [m/s], ω_z [rad/s]) of the whole-loop table; each is walked beside its mirror
(v_x, -v_y, -ω_z). (0.3, 0, 0) is its own mirror: the mirrored walk differs only by its clock's half-period
shift."""

WALK_DURATION: float = 5.0
"""Length of each whole-loop walk [s]."""

WALK_RAMP: float = 1.0
"""Time over which the command rises linearly from zero [s] (as ``krl kernel figures velocity`` ramps)."""

STEADY_FROM: float = 2.0
"""Start of the window the steady figures (mean roll, foot swing) are taken over [s]; with the kernels'
cycle of 1/3 s the window up to :data:`WALK_DURATION` holds whole cycles."""

_PHASE_SLACK = 1e-9
"""Relative slack when checking that the steady window holds whole gait cycles."""


# --- the mirror of the simulator's state ---------------------------------------------------------------

_JOINT_MIRROR = FEATURE_MIRRORS["joint_pos"]
_FEET_MIRROR = FEATURE_MIRRORS["kernel_targets"]


def mirror_joints(q: np.ndarray) -> np.ndarray:
    """Mirror joint angles, rates or targets: legs swapped, abduction negated. Shape: (..., 12)."""
    return _JOINT_MIRROR(np.asarray(q, dtype=float))


def mirror_feet(feet: np.ndarray) -> np.ndarray:
    """Mirror four feet's positions (base or world frame) [m]: legs swapped, y negated. Shape: (..., 4, 3)."""
    feet = np.asarray(feet, dtype=float)
    return _FEET_MIRROR(feet.reshape(*feet.shape[:-2], NUM_LEGS * 3)).reshape(feet.shape)


def mirror_qpos(qpos: np.ndarray) -> np.ndarray:
    """The robot's ``qpos`` mirrored through the world's x-z plane: base y negated, quaternion (w, x, y, z)
    -> (w, -x, y, -z), joints by :func:`mirror_joints`. Shape: (19,) -> (19,) [m, 1, rad]."""
    qpos = np.asarray(qpos, dtype=float)
    mirrored = qpos * np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0, -1.0, *np.ones(NUM_JOINTS)])
    mirrored[7:19] = mirror_joints(qpos[7:19])
    return mirrored


def mirror_qvel(qvel: np.ndarray) -> np.ndarray:
    """The robot's ``qvel`` mirrored: linear velocity (world frame) y negated, angular velocity (body frame)
    x and z negated, joint rates by :func:`mirror_joints`. Shape: (18,) -> (18,) [m/s, rad/s]."""
    qvel = np.asarray(qvel, dtype=float)
    mirrored = qvel * np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0, *np.ones(NUM_JOINTS)])
    mirrored[6:18] = mirror_joints(qvel[6:18])
    return mirrored


def set_state(sim: A1Sim, qpos: np.ndarray, qvel: np.ndarray) -> None:
    """Put ``sim`` in the state (``qpos`` shape (19,), ``qvel`` shape (18,)) after a reset, and recompute
    its kinematics and readout (``mj_forward``); the next :meth:`A1Sim.step` starts from it."""
    sim.reset()
    sim.set_state(qpos, qvel)


# --- the physics -------------------------------------------------------------------------------------


def physics_mirror_errors(
    built: BuiltModel,
    qpos: np.ndarray,
    qvel: np.ndarray,
    targets: np.ndarray,
    horizons: Sequence[int],
) -> dict[int, dict[str, float]]:
    """Drive the robot from (``qpos``, ``qvel``) with ``targets`` and, beside it, from the mirrored state with
    the mirrored targets; compare the mirror of the first trajectory with the second.

    Args:
        built: the model (both robots are simulated on copies of it).
        qpos, qvel: the first robot's start. Shapes: (19,), (18,).
        targets: joint targets of each control step [rad]. Shape: (K, 12).
        horizons: control steps (each ≤ K) after which the errors are taken.

    Returns:
        ``{steps: {"base_pos": [m], "rpy": [rad], "joint_pos": [rad], "qvel": [m/s, rad/s]}}``: the largest
        absolute difference over the coordinates of each, after ``steps`` control steps.
    """
    original, mirrored = A1Sim(built), A1Sim(built)
    set_state(original, qpos, qvel)
    set_state(mirrored, mirror_qpos(qpos), mirror_qvel(qvel))
    errors: dict[int, dict[str, float]] = {}
    for step, target in enumerate(np.asarray(targets, dtype=float), start=1):
        a, b = original.step(target), mirrored.step(mirror_joints(target))
        if step in horizons:
            errors[step] = {
                "base_pos": float(np.abs(REFLECTION @ a.base_pos - b.base_pos).max()),
                "rpy": float(np.abs(a.rpy * [-1.0, 1.0, -1.0] - b.rpy).max()),
                "joint_pos": float(np.abs(mirror_joints(a.joint_pos) - b.joint_pos).max()),
                "qvel": float(np.abs(mirror_qvel(original.data.qvel[:18]) - mirrored.data.qvel[:18]).max()),
            }
    missing = set(horizons) - set(errors)
    if missing:
        raise ValueError(f"horizons {sorted(missing)} lie beyond the {len(targets)} control steps of targets")
    return errors


# --- the whole loop ----------------------------------------------------------------------------------


def mirror_command(command: Sequence[float]) -> np.ndarray:
    """(v_x, v_y, ω_z) -> (v_x, -v_y, -ω_z). Shape: (3,)."""
    return FEATURE_MIRRORS["command"](np.asarray(command, dtype=float))


@dataclass(frozen=True)
class WalkPair:
    """Two walks side by side: robot 0 at a command, robot 1 at its mirror (clock half a period on)."""

    time: np.ndarray
    """Time of each recorded control step [s]. Shape: (T,)."""
    base_pos: np.ndarray
    """Trunk origin, world frame [m]. Shape: (2, T, 3)."""
    rpy: np.ndarray
    """Roll, pitch, yaw (yaw unwrapped) [rad]. Shape: (2, T, 3)."""
    feet: np.ndarray
    """Foot positions, base frame [m]. Shape: (2, T, 4, 3)."""
    phases: np.ndarray
    """The normalised phases the kernel was given (Eq. 4.6). Shape: (2, T, 4)."""
    fallen: np.ndarray
    """Whether each robot fell (the walk stops at the first fall). Shape: (2,), bool."""
    cycle: float
    """The gait's step-cycle duration [s]."""


def walk_pair(
    kernel: Kernel,
    built: BuiltModel,
    command: Sequence[float],
    duration: float = WALK_DURATION,
    ramp: float = WALK_RAMP,
    mirror_targets: bool = False,
) -> WalkPair:
    """The kernel walks ``command`` (robot 0) and its mirror (robot 1) from the same standing start at the
    origin, through the residual agent's action path with zero residuals; robot 1's gait clock starts half a
    step cycle on, so its legs' phases are robot 0's with FR <-> FL and RR <-> RL swapped (a trot's mirror).

    Args:
        kernel: a kernel-base or kernel-ext (their targets depend on the command and the phases only).
        built: the model both robots walk on.
        command: (v_x, v_y, ω_z) [m/s, m/s, rad/s], reached linearly over ``ramp`` [s].
        duration: length of the walk [s].
        mirror_targets: give robot 1 the mirror of robot 0's foot targets instead of its own kernel's, which
            takes the kernel's asymmetry out and leaves the physics'.
    """
    controller = ResidualController(kernel, ResidualConfig(kernel=kernel.variant), num_robots=2)
    batch = make_backend([built, built])
    for index in range(2):
        batch.reset(index, xy=(0.0, 0.0))
    controller.reset()
    cycle = controller.gait.step_duration
    controller.clock[1] = 0.5 * cycle / CONTROL_DT  # [control steps]
    commands = np.array([command, mirror_command(command)], dtype=float)
    zero = np.zeros((2, controller.config.action_size))
    steps = round(duration / CONTROL_DT)
    pos, rpy, feet, phases = (
        np.empty((2, steps, *shape)) for shape in ((3,), (3,), (NUM_LEGS, 3), (NUM_LEGS,))
    )
    states, recorded = batch.states, 0
    for step in range(steps):
        scale = min(1.0, (step + 1) * CONTROL_DT / ramp) if ramp > 0 else 1.0
        controller.prepare(states, scale * commands)
        if mirror_targets:
            q = inverse_kinematics(
                np.stack([controller.kernel_targets[0], mirror_feet(controller.kernel_targets[0])])
            ).q
        else:
            q = controller.joint_targets(zero)
        states = batch.step(q)
        phases[:, step] = controller.normalised_phase
        pos[:, step], rpy[:, step], feet[:, step] = states.base_pos, states.rpy, states.foot_pos_base
        recorded = step + 1
        if states.fallen.any():
            break
    rpy = rpy[:, :recorded]
    rpy[..., 2] = np.unwrap(rpy[..., 2], axis=1)
    return WalkPair(
        time=np.arange(1, recorded + 1) * CONTROL_DT,
        base_pos=pos[:, :recorded],
        rpy=rpy,
        feet=feet[:, :recorded],
        phases=phases[:, :recorded],
        fallen=np.array(states.fallen, dtype=bool),
        cycle=cycle,
    )


_STEADY_FIGURES: tuple[str, ...] = ("roll_a", "roll_b", "roll_diff", "turn_a", "turn_b", "turn_diff")
"""The :func:`pair_figures` taken over the steady window (NaN when a robot fell)."""


def pair_figures(pair: WalkPair, steady_from: float = STEADY_FROM) -> dict[str, float]:
    """How far robot 1's walk is from the mirror of robot 0's. Each ``*_a`` figure is robot 0's, each
    ``*_b`` the mirror image of robot 1's (so a symmetric loop gives a == b), ``*_diff`` is a - b.

    Returns (lengths [m], angles [rad]):
        ``fell``: 1.0 if either fell (the walk stopped there), else 0.0;
        ``max_pos_error``: largest distance between robot 0's trunk and the mirror of robot 1's, over time;
        ``max_rpy_error``: largest difference of roll, pitch or yaw, likewise;
        ``drift_a``, ``drift_b``, ``drift_diff``: lateral position (world y) at the end;
        ``yaw_a``, ``yaw_b``, ``yaw_diff``: yaw at the end;
        ``roll_a``, ``roll_b``, ``roll_diff``: mean roll over the steady window (from ``steady_from`` [s] to
        the end, whole gait cycles);
        ``turn_a``, ``turn_b``, ``turn_diff``: mean yaw rate over the steady window [rad/s] (the yaw
        gained there over its length, free of the start's transient);
        ``swing_fr_a``, ``swing_fr_b``: FR's lateral (base y) peak-to-peak over the steady window in walk 0,
        and FL's in walk 1 (its mirror); ``swing_max_diff``: the largest such difference over the four legs.
    """
    pos_b = pair.base_pos[1] @ REFLECTION
    rpy_b = pair.rpy[1] * [-1.0, 1.0, -1.0]
    feet_b = mirror_feet(pair.feet[1])
    figures = {
        "fell": float(pair.fallen.any()),
        "max_pos_error": float(np.linalg.norm(pair.base_pos[0] - pos_b, axis=1).max()),
        "max_rpy_error": float(np.abs(pair.rpy[0] - rpy_b).max()),
    }
    for name, a, b in (
        ("drift", pair.base_pos[0, -1, 1], pos_b[-1, 1]),
        ("yaw", pair.rpy[0, -1, 2], rpy_b[-1, 2]),
    ):
        figures.update({f"{name}_a": float(a), f"{name}_b": float(b), f"{name}_diff": float(a - b)})
    window = pair.time > steady_from
    cycles = (pair.time[-1] - steady_from) / pair.cycle
    if pair.fallen.any() or not window.any() or abs(cycles - round(cycles)) > _PHASE_SLACK * max(cycles, 1.0):
        nan = float("nan")
        figures.update({k: nan for k in (*_STEADY_FIGURES, "swing_fr_a", "swing_fr_b", "swing_max_diff")})
        return figures
    roll_a, roll_b = pair.rpy[0, window, 0].mean(), rpy_b[window, 0].mean()
    first = int(np.argmax(window)) - 1  # the last step before the window (the window starts after step 0)
    span = pair.time[-1] - pair.time[first]  # [s]
    turn_a = (pair.rpy[0, -1, 2] - pair.rpy[0, first, 2]) / span
    turn_b = (rpy_b[-1, 2] - rpy_b[first, 2]) / span
    swing_a = np.ptp(pair.feet[0, window, :, 1], axis=0)  # (4,) [m]
    swing_b = np.ptp(feet_b[window, :, 1], axis=0)
    figures.update(
        {
            "roll_a": float(roll_a),
            "roll_b": float(roll_b),
            "roll_diff": float(roll_a - roll_b),
            "turn_a": float(turn_a),
            "turn_b": float(turn_b),
            "turn_diff": float(turn_a - turn_b),
            "swing_fr_a": float(swing_a[0]),
            "swing_fr_b": float(swing_b[0]),
            "swing_max_diff": float(np.abs(swing_a - swing_b).max()),
        }
    )
    return figures


def kernel_mirror_error(kernel: Kernel, command: Sequence[float], points: int = 200) -> dict[str, float]:
    """The kernel alone, open loop: its foot targets over one step cycle at ``command`` against the mirror of
    its targets at the mirrored command, half a cycle on (kernel-base and kernel-ext read only the command,
    the phases and, for ext, the nominal heights).

    Returns ``max_error`` (largest |difference| of any foot coordinate [m]), ``max_error_x``, ``_y``, ``_z``
    (per base axis [m]) and ``swing_fr``/``swing_fl`` (FR's lateral peak-to-peak at ``command`` and FL's at
    its mirror, base frame [m]).
    """
    controller = ResidualController(kernel, ResidualConfig(kernel=kernel.variant), num_robots=2 * points)
    cycle_steps = controller.gait.step_duration / CONTROL_DT
    clocks = np.arange(points) / points * cycle_steps
    controller.clock[:] = np.concatenate([clocks, clocks + 0.5 * cycle_steps]) - 1.0  # prepare adds 1
    commands = np.repeat([np.asarray(command, dtype=float), mirror_command(command)], points, axis=0)
    batch = make_backend([build_model("flat")])
    states = batch.states.rows(np.zeros(2 * points, dtype=int))
    controller.prepare(states, commands)
    original, mirrored = controller.kernel_targets[:points], controller.kernel_targets[points:]
    error = np.abs(mirror_feet(original) - mirrored)  # (points, 4, 3) [m]
    return {
        "max_error": float(error.max()),
        **{f"max_error_{axis}": float(error[..., k].max()) for k, axis in enumerate("xyz")},
        "swing_fr": float(np.ptp(original[:, 0, 1])),
        "swing_fl": float(np.ptp(mirrored[:, 1, 1])),
    }


def loop_asymmetry(
    kernel_name: str,
    command: Sequence[float],
    duration: float = WALK_DURATION,
) -> dict[str, dict[str, float]]:
    """The whole-loop figures of one kernel (a shipped name or a file) at one command, three ways:

    ``full``: the kernel and the robot as krl runs them; ``physics``: robot 1 given the mirror of robot 0's
    foot targets (the kernel's asymmetry taken out); ``kernel``: each robot its own kernel on
    :func:`symmetric_trunk_model` (the physics' asymmetry taken out). Each a :func:`pair_figures` dict;
    ``open_loop`` is :func:`kernel_mirror_error`.
    """
    kernel = load_model(kernel_name)
    as_built, symmetric = build_model("flat"), symmetric_trunk_model()
    return {
        "full": pair_figures(walk_pair(kernel, as_built, command, duration)),
        "physics": pair_figures(walk_pair(kernel, as_built, command, duration, mirror_targets=True)),
        "kernel": pair_figures(walk_pair(kernel, symmetric, command, duration)),
        "open_loop": kernel_mirror_error(kernel, command),
    }


# --- the report ---------------------------------------------------------------------------------------


def _milli(value: float) -> str:
    """``value`` [m or rad] in mm or mrad with its sign, one decimal; a dash for NaN (a fallen walk)."""
    return "–" if np.isnan(value) else f"{1000 * value:+.1f}"


LOOP_COLUMNS: tuple[str, ...] = (
    "kernel",
    "command (v_x, v_y, ω_z)",
    "way",
    "fell",
    "max trunk distance [mm]",
    "max rpy difference [mrad]",
    "lateral drift a / b [mm]",
    "end yaw a / b [mrad]",
    "mean roll a / b [mrad]",
    "steady yaw rate a / b [mrad/s]",
    "FR y swing a / b [mm]",
    "largest swing difference [mm]",
    "kernel open loop: max target difference x / y / z, FR / FL y swing [mm]",
)
"""The columns of :func:`loop_table`."""


def _open_loop_cell(open_loop: dict) -> str:
    """:func:`kernel_mirror_error`'s figures as one table cell, in mm."""
    errors = " / ".join(f"{1000 * open_loop[f'max_error_{axis}']:.1f}" for axis in "xyz")
    return f"{errors}, {1000 * open_loop['swing_fr']:.1f} / {1000 * open_loop['swing_fl']:.1f}"


def _loop_row(name: str, command: Sequence[float], way: str, f: dict, open_loop: dict | None) -> str:
    """One Markdown row of :func:`loop_table` from :func:`pair_figures`' ``f`` (and, on the ``full`` row, the
    open-loop figures)."""
    cells = [
        name,
        "({:g}, {:g}, {:g})".format(*command),
        way,
        "yes" if f["fell"] else "no",
        f"{1000 * f['max_pos_error']:.1f}",
        f"{1000 * f['max_rpy_error']:.1f}",
        *(
            f"{_milli(f[f'{k}_a'])} / {_milli(f[f'{k}_b'])}"
            for k in ("drift", "yaw", "roll", "turn", "swing_fr")
        ),
        _milli(f["swing_max_diff"]),
        "" if open_loop is None else _open_loop_cell(open_loop),
    ]
    return "| " + " | ".join(cells) + " |"


def loop_table(
    kernels: Sequence[str], commands: Sequence[Sequence[float]], duration: float = WALK_DURATION
) -> str:
    """The whole-loop table (Markdown, :data:`LOOP_COLUMNS`): per kernel, command and way
    (:func:`loop_asymmetry`), the figures of walk a and of the mirror of walk b, in mm and mrad."""
    lines = ["| " + " | ".join(LOOP_COLUMNS) + " |", "|" + " --- |" * len(LOOP_COLUMNS)]
    for name in kernels:
        for command in commands:
            result = loop_asymmetry(name, command, duration)
            for way in ("full", "physics", "kernel"):
                open_loop = result["open_loop"] if way == "full" else None
                lines.append(_loop_row(name, command, way, result[way], open_loop))
    return "\n".join(lines)


def mirror_markdown(
    kernels: Sequence[str] = ("base", "ext"),
    commands: Sequence[Sequence[float]] = DEFAULT_COMMANDS,
    duration: float = WALK_DURATION,
) -> str:
    """The model's asymmetries (one line each, :func:`~krl.analysis.agent.mirror_model.model_asymmetries`)
    and the whole-loop table (:func:`loop_table`) of ``kernels`` (shipped names or files) at ``commands``
    (v_x, v_y, ω_z) [m/s, m/s, rad/s], each walk ``duration`` [s] long."""
    lines = [
        f"model asymmetry: {asymmetry.element} {asymmetry.quantity}: {asymmetry.difference:.6g}"
        for asymmetry in model_asymmetries(build_model("flat").model)
    ]
    return "\n".join([*lines, loop_table(kernels, commands, duration)]) + "\n"
