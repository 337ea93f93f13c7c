"""Only the simulator backend writes MuJoCo's data: no module of krl outside :data:`OWNERS` assigns into an
``MjData`` array (``data.qpos[...] = …``, ``d.ctrl += …``) or calls a MuJoCo function that steps, resets
or recomputes an ``MjData`` (``mj_step``, ``mj_forward``, ``mj_resetData``, …), read from the source with
``ast``. A renderer or an analysis reads a robot's ``MjData`` through the backend's ``data(i)``; one that
needs a robot in another pose or a bare-MuJoCo timing asks the backend's module for it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import mujoco
import pytest

import krl
from krl.sim.model import build_model

ROOT = Path(krl.__file__).resolve().parent

OWNERS = ("sim/batch.py", "sim/backend.py")
"""The modules (relative to ``src/krl``) that may write ``MjData``: the MuJoCo CPU backend and the seam."""

WRITING_FUNCTIONS = frozenset(
    {
        "mj_step",
        "mj_step1",
        "mj_step2",
        "mj_forward",
        "mj_forwardSkip",
        "mj_inverse",
        "mj_inverseSkip",
        "mj_resetData",
        "mj_resetDataDebug",
        "mj_resetDataKeyframe",
        "mj_resetCtrl",
        "mj_setState",
        "mj_copyData",
        "mj_copyState",
        "mj_kinematics",
        "mj_fwdKinematics",
        "mj_comPos",
        "mj_comVel",
        "mj_fwdPosition",
        "mj_fwdVelocity",
        "mj_fwdActuation",
        "mj_fwdAcceleration",
        "mj_fwdConstraint",
        "mj_Euler",
        "mj_RungeKutta",
        "mj_implicit",
        "mj_collision",
        "mj_camlight",
        "mj_tendon",
        "mj_transmission",
        "mj_crb",
        "mj_makeM",
        "mj_factorM",
        "mj_passive",
        "mj_sensorPos",
        "mj_sensorVel",
        "mj_sensorAcc",
        "mj_energyPos",
        "mj_energyVel",
        "mj_subtreeVel",
        "mj_rnePostConstraint",
        "mj_makeConstraint",
        "mj_projectConstraint",
        "mj_referenceConstraint",
        "mj_setKeyframe",
        "mj_normalizeQuat",
        "rollout",
    }
)
"""MuJoCo functions that write an ``MjData`` they are given (the pipeline and its stages, resets, copies)."""

SHARED_NAMES = frozenset(
    {"time", "model", "energy", "signature", "solver", "timer", "warning", "contact", "userdata"}
)
"""``MjData`` attributes whose names other objects use too (``self.time = …``, an ``MjSpec`` element's
``userdata``): only an assignment into their elements (``d.warning[...] = …``) counts as a write."""


def mjdata_fields() -> frozenset[str]:
    """The names of ``MjData``'s data attributes (arrays and counters), as this MuJoCo has them."""
    data = mujoco.MjData(build_model("flat").model)
    names = (name for name in dir(data) if not name.startswith("_"))
    return frozenset(name for name in names if not callable(getattr(data, name)))


def _written_field(target: ast.expr, fields: frozenset[str]) -> str | None:
    """The ``MjData`` field an assignment target writes (``x.qpos[...]``, ``x.ctrl``), or None. An object's
    own attribute (``self.qpos: list = []``, ``self.contact[rows] = False``) is not ``MjData``'s."""
    subscripted = isinstance(target, ast.Subscript)
    while isinstance(target, ast.Subscript):
        target = target.value
    if not isinstance(target, ast.Attribute) or target.attr not in fields:
        return None
    if isinstance(target.value, ast.Name) and target.value.id == "self":
        return None
    return target.attr if subscripted or target.attr not in SHARED_NAMES else None


def _called(node: ast.Call) -> str | None:
    """The name a call calls (``mujoco.mj_step(…)`` and ``mj_step(…)`` alike: ``mj_step``)."""
    function = node.func
    if isinstance(function, ast.Attribute):
        return function.attr
    if isinstance(function, ast.Name):
        return function.id
    return None


def mjdata_writes(source: str, filename: str, fields: frozenset[str]) -> list[str]:
    """``line: what`` for every write of ``MjData`` in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source, filename)):
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = [leaf for target in node.targets for leaf in _leaves(target)]
        elif isinstance(node, ast.AugAssign | ast.AnnAssign) and node.value is not None:
            targets = [node.target]
        elif isinstance(node, ast.Call) and _called(node) in WRITING_FUNCTIONS:
            found.append(f"{node.lineno}: calls {_called(node)}")
        for target in targets:
            if (field := _written_field(target, fields)) is not None:
                found.append(f"{node.lineno}: writes .{field}")
    return found


def _leaves(target: ast.expr) -> list[ast.expr]:
    """The single targets of an assignment target (tuples unpacked)."""
    if isinstance(target, ast.Tuple | ast.List):
        return [leaf for element in target.elts for leaf in _leaves(element)]
    return [target]


def test_nothing_outside_the_backend_writes_mjdata():
    fields = mjdata_fields()
    offenders = [
        f"{path.relative_to(ROOT)}:{where}"
        for path in sorted(ROOT.rglob("*.py"))
        if path.relative_to(ROOT).as_posix() not in OWNERS
        for where in mjdata_writes(path.read_text(), str(path), fields)
    ]
    assert not offenders, "MjData written outside the simulator backend:\n" + "\n".join(offenders)


@pytest.mark.parametrize(
    "line",
    [
        "data.qpos[:] = frame",
        "sim.data.ctrl[:12] = KP * angles",
        "d.xfrc_applied[trunk, :3] += force",
        "d.qvel = qvel",
        "d.warning[0] = 0",
        "mujoco.mj_step(model, data, nstep=5)",
        "mj_forward(model, data)",
        "mujoco.mj_resetData(model, data)",
        "a, robot.qpos[:] = 1, q",
    ],
)
def test_the_scan_finds_each_kind_of_write(line):
    assert mjdata_writes(line, "<line>", mjdata_fields())


@pytest.mark.parametrize(
    "line",
    [
        "self.time = 0.0",
        "self.contact[rows] = False",
        "hfield.userdata = heights",
        "q = data.qpos[:19].copy()",
        "mujoco.mj_ray(model, data, p, v, None, 1, -1, g)",
    ],
)
def test_the_scan_leaves_reads_alone(line):
    assert not mjdata_writes(line, "<line>", mjdata_fields())
