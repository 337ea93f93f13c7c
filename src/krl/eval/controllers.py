"""The controllers an evaluation can score, named by a short spec string.

| spec | controller |
| --- | --- |
| ``expert`` | the MPC expert, τ_stance 0.2 s |
| ``expert:stance=0.3`` | the expert with another stance duration [s] (also ``step=``, ``ride=`` [m]) |
| ``kernel`` | the shipped kernel-base |
| ``kernel:ext`` | a shipped kernel by name |
| ``kernel:PATH`` | a kernel file (``krl kernel train`` output) |
| ``agent`` | the shipped residual agent agent-rp (kernel + PPO residuals), one policy per training seed |
| ``agent:base`` | a shipped agent by name (``base``, ``gait``, ``gait-ground``, ``robust``) |
| ``agent:rp@215`` | one seed of a seed group (label ``agent-rp-seed215``) |
| ``agent:PATH`` | a policy file (``krl agent train`` output) or a seed group (per-seed files or runs) |
| ``gait:capture=1,rate=2`` | kernel-ext driven by a scripted rule after pushes (:mod:`krl.agent.scripted`) |

Each kind is one entry of :data:`CONTROLLER_KINDS` (parse, build, report title), so a new kind joins by
adding one. A :class:`ControllerSpec` is plain data, so worker processes rebuild the controller from it;
the files it is built from are named with their SHA-256, so stored results are tied to the files'
content, not their paths. Every controller implements :class:`krl.control.types.Controller`, so one
runner scores them all.

Labels name results (``OUT/<label>/...``), so two different controllers must never share one. The
expert's is made of its options; a shipped model's is its name (``kernel-base``, ``agent-rp``, the names
``krl report`` sets beside the thesis's rows); a user's file's is its name (``kernel:runs/mine.npz`` is
``kernel-mine``; a file named ``kernel.npz``, what ``krl kernel train`` writes, takes its folder's name),
and where that name is a shipped model's, the first :data:`LABEL_HASH_DIGITS` hex digits of the file's
SHA-256 follow (``kernel:X/kernel-base.npz`` is ``kernel-base-3fa2c1``), so a user's file never takes a
shipped model's results or its row in the report; a byte-identical copy of the shipped model it is named
after is that model, label included (``agent:runs/agent-robust``, the run folders agent-robust's shipped
files were copied from).

A controller is known by its kind, options and files' content (:attr:`ControllerSpec.identity`), not by
its files' paths: one file given several ways in one call (``agent``, ``agent:rp``,
``agent:PATH/agent-rp.npz``, or a byte-identical copy of it) is one controller, evaluated once under the
label of the first spelling (:func:`distinct_controllers`). Two files of different content that still share
a label in one call are refused there.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from krl.util.hashing import file_sha256

LABEL_HASH_DIGITS: int = 6
"""Hex digits of a user file's SHA-256 in its label when its name is a shipped model's (16.7 million
values; two files that share them are refused by :func:`distinct_controllers`, not mixed)."""


class ControllerSpecError(ValueError):
    """An unknown controller, a bad option, or a missing model file."""


@dataclass(frozen=True)
class Artifact:
    """A file a controller is built from."""

    path: str
    """Absolute path."""
    sha256: str
    """SHA-256 of the file's content."""
    seed: int | None = None
    """The training seed this file belongs to (per-seed policies), or None."""

    @classmethod
    def of(cls, path: Path, seed: int | None = None) -> Artifact:
        return cls(str(path.resolve()), file_sha256(path), seed)


def _files_hash(artifacts: Sequence[Artifact]) -> str:
    """SHA-256 naming files' content: the one file's, or the hash of every file's seed and hash."""
    if len(artifacts) == 1:
        return artifacts[0].sha256
    joined = "\n".join(f"{a.seed}:{a.sha256}" for a in artifacts)
    return hashlib.sha256(joined.encode()).hexdigest()


@dataclass(frozen=True)
class ControllerSpec:
    """What to build in each run."""

    kind: str
    """A key of :data:`CONTROLLER_KINDS`."""
    label: str
    """A file-name-safe name for results (``expert-stance0.2``, ``kernel-base``, ``agent-rp``)."""
    options: tuple[tuple[str, Any], ...] = ()
    """Keyword options of the controller's constructor."""
    artifacts: tuple[Artifact, ...] = ()
    """The files the controller is built from (a kernel; a policy, or one policy per seed)."""

    @property
    def seeded(self) -> bool:
        """Whether runs differ by seed: one artifact per training seed, each run using its seed's."""
        return any(artifact.seed is not None for artifact in self.artifacts)

    @property
    def seeds(self) -> tuple[int, ...]:
        """The training seeds of per-seed artifacts (empty for other controllers)."""
        return tuple(a.seed for a in self.artifacts if a.seed is not None)

    @property
    def identity(self) -> tuple[Any, ...]:
        """What makes two specs one controller: kind, options and the files' content with their seeds (not
        the files' paths, nor the label)."""
        return (self.kind, self.options, tuple((a.seed, a.sha256) for a in self.artifacts))

    @property
    def content_hash(self) -> str | None:
        """SHA-256 naming the artifacts' content: the one file's, or the hash of every file's hash."""
        return _files_hash(self.artifacts) if self.artifacts else None

    def artifact(self, seed: int | None = None) -> Artifact:
        """The file for a run of ``seed``: the only one of a controller that is not seeded; a seeded
        controller's first seed's where ``seed`` is None (one robot driven outside an evaluation: the viewer,
        the demo)."""
        if not self.seeded or seed is None:
            return self.artifacts[0]
        for candidate in self.artifacts:
            if candidate.seed == seed:
                return candidate
        known = ", ".join(map(str, self.seeds))
        raise ControllerSpecError(f"controller {self.label}: no policy for seed {seed} (has seeds {known})")

    @property
    def driven_label(self) -> str:
        """The label of what :meth:`build` drives without a seed: a seeded controller's first seed's
        (``agent-rp-seed150``), any other's own label."""
        return f"{self.label}-seed{self.seeds[0]}" if self.seeded else self.label

    def build(self, seed: int | None = None):
        """A fresh controller for one run (``seed`` selects the per-seed artifact of seeded controllers)."""
        return CONTROLLER_KINDS[self.kind].build(self, seed)

    @property
    def batched(self) -> bool:
        """Whether the kind drives many robots as one controller (:meth:`build_batch`), which pays to walk
        its runs in batches."""
        return CONTROLLER_KINDS[self.kind].build_batch is not None

    def build_batch(self, seed: int | None, num_robots: int):
        """The controller of ``num_robots`` robots that batched evaluation steps (:mod:`krl.eval.batch`):
        the kind's own batched one (the agents'), else one fresh :meth:`build` per run
        (:class:`RobotControllers`)."""
        batched = CONTROLLER_KINDS[self.kind].build_batch
        if batched is not None:
            return batched(self, seed, num_robots)
        return RobotControllers(lambda: self.build(seed), num_robots)

    @property
    def title(self) -> str:
        """What reports call this controller."""
        return CONTROLLER_KINDS[self.kind].title

    def describe(self, seed: int | None = None) -> dict[str, Any]:
        """JSON-ready description of what a run of training seed ``seed`` is built from, stored with every
        result. A seeded controller's run names its own seed's file alone, so a group that gains or loses
        a seed keeps the records of the others; without ``seed`` it names the whole group and its seeds."""
        one_seed = self.seeded and seed is not None
        description = {
            "kind": self.kind,
            "label": self.label,
            "options": dict(self.options),
            "model_sha256": self.artifact(seed).sha256 if one_seed else self.content_hash,
        }
        if self.seeded and not one_seed:
            description["seeds"] = list(self.seeds)
        return description

    def described_as(self, stored: dict[str, Any], seed: int | None) -> bool:
        """Whether a stored description is this controller's for a run of ``seed``: :meth:`describe`'s, or
        the form records of a seed group had before they named one seed's file (the whole group's hash and
        its seeds), which matches where this group's files of those seeds hash the same."""
        if stored == self.describe(seed):
            return True
        legacy = isinstance(stored, dict) and isinstance(stored.get("seeds"), list)
        if not (legacy and self.seeded and seed is not None):
            return False
        then = {**stored, "model_sha256": None, "seeds": None}
        if then != {**self.describe(seed), "model_sha256": None, "seeds": None}:
            return False
        try:
            files = [self.artifact(s) for s in stored["seeds"]]
        except ControllerSpecError:
            return False
        return seed in stored["seeds"] and stored["model_sha256"] == _files_hash(files)


@dataclass(frozen=True)
class ControllerKind:
    """One kind of controller: how a spec's text after ``kind:`` is parsed and how a run builds it."""

    parse: Callable[[str, str], ControllerSpec]
    """``(whole spec text, text after the colon) -> spec``; raises :class:`ControllerSpecError`."""
    build: Callable[[ControllerSpec, int | None], Any]
    """``(spec, run seed) -> controller``."""
    title: str
    """Name in reports."""
    build_batch: Callable[[ControllerSpec, int | None, int], Any] | None = None
    """``(spec, run seed, N) -> a controller of N robots`` with ``reset(index, state)`` and ``act(states,
    commands, rows)`` (:class:`RobotControllers`'); None: N single controllers."""


class RobotControllers:
    """N single-robot controllers (:class:`krl.control.types.Controller`) as one controller of N robots:
    robot ``i``'s is built fresh for each run it starts, and acts on its own state.

    Args:
        build: makes a fresh controller.
        num_robots: N.
    """

    def __init__(self, build: Callable[[], Any], num_robots: int) -> None:
        self.build = build
        self.controllers: list[Any] = [None] * num_robots

    def reset(self, index: int, state) -> None:
        """Start robot ``index``'s new run from ``state`` with a fresh controller."""
        self.controllers[index] = self.build()
        self.controllers[index].reset(state)

    def act(self, states, commands: np.ndarray, rows: np.ndarray):
        """The joint command of every robot (arrays of shape (N, 12); the robots outside ``rows`` stand, at
        Table 4.2's gains) and the robots of ``rows`` whose controller gave up (an ``MPCError``), with the
        error."""
        from krl.control.mpc import MPCError
        from krl.control.types import JointCommand
        from krl.robots.a1.constants import KD, KP, STANDING_JOINT_ANGLES

        n = len(self.controllers)
        parts = [
            np.tile(STANDING_JOINT_ANGLES, (n, 1)),
            np.tile(KP, (n, 1)),
            np.tile(KD, (n, 1)),
            np.zeros((n, 12)),
        ]
        given = [False] * 4
        failed: dict[int, Exception] = {}
        for index in rows.tolist():
            try:
                command = self.controllers[index].act(states.row(index), commands[index].copy())
            except MPCError as error:
                failed[index] = error
                continue
            for k, value in enumerate(command):
                if value is not None:
                    parts[k][index] = value
                    given[k] = True
        kp, kd = (parts[1], parts[2]) if given[1] or given[2] else (None, None)
        return JointCommand(parts[0], kp, kd, parts[3] if given[3] else None), failed


def _number_options(text: str, kind: str, rest: str, known: tuple[str, ...]) -> dict[str, float]:
    """The ``key=VALUE,...`` options after a controller's kind, each a finite number and one of ``known``;
    ControllerSpecError (one line naming ``text``) otherwise."""
    options: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in rest.split(","))):
        key, sep, value = item.partition("=")
        if not sep or key not in known:
            raise ControllerSpecError(
                f"controller {text!r}: {kind} options are "
                f"{', '.join(k + '=VALUE' for k in known)}, got {item!r}"
            )
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not math.isfinite(number):
            raise ControllerSpecError(f"controller {text!r}: {key} must be a number, got {value!r}")
        options[key] = number
    return options


# --- expert ----------------------------------------------------------------------------------------

_EXPERT_OPTIONS = {"stance": "stance_duration", "step": "step_height", "ride": "ride_height"}


def _parse_expert(text: str, rest: str) -> ControllerSpec:
    from krl.control.expert import ExpertParams

    options: dict[str, float] = {"stance_duration": ExpertParams.stance_duration}
    for key, number in _number_options(text, "expert", rest, tuple(_EXPERT_OPTIONS)).items():
        options[_EXPERT_OPTIONS[key]] = number
    try:
        ExpertParams(**options)
    except ValueError as error:
        raise ControllerSpecError(f"controller {text!r}: {error}") from None
    label = f"expert-stance{options['stance_duration']:g}" + "".join(
        f"-{key.split('_')[0]}{value:g}" for key, value in sorted(options.items()) if key != "stance_duration"
    )
    return ControllerSpec("expert", label, tuple(sorted(options.items())))


def _build_expert(spec: ControllerSpec, seed: int | None):
    from krl.control.expert import ExpertParams, MPCExpert

    return MPCExpert(ExpertParams(**dict(spec.options)))


# --- kernel ----------------------------------------------------------------------------------------


def _parse_kernel(text: str, rest: str) -> ControllerSpec:
    from krl.kernel.model import KernelFileError, load_kernel
    from krl.kernel.registry import SHIPPED_MODELS, resolve_model

    model = rest.strip() or "base"
    path = resolve_model(model)
    if not path.is_file():
        raise ControllerSpecError(
            f"controller {text!r}: no kernel file {str(path)!r} (shipped: {', '.join(SHIPPED_MODELS)})"
        )
    try:
        load_kernel(path)
    except KernelFileError as error:
        raise ControllerSpecError(f"controller {text!r}: {error}") from None
    artifact = Artifact.of(path)
    if model in SHIPPED_MODELS:
        return ControllerSpec("kernel", f"kernel-{model}", (), (artifact,))
    # `krl kernel train` writes OUT/kernel.npz: its folder names the run
    name = path.stem if path.stem != "kernel" else path.resolve().parent.name
    label = _user_label(
        "kernel",
        name.removeprefix("kernel-"),
        SHIPPED_MODELS,
        artifact.sha256,
        lambda shipped: file_sha256(resolve_model(shipped)),
    )
    return ControllerSpec("kernel", label, (), (artifact,))


def _build_kernel(spec: ControllerSpec, seed: int | None):
    from krl.kernel.controller import KernelController
    from krl.kernel.model import load_kernel

    return KernelController(load_kernel(spec.artifact().path), **dict(spec.options))


def _build_kernel_batch(spec: ControllerSpec, seed: int | None, num_robots: int):
    from krl.agent.controller import KernelBatchController
    from krl.agent.residual import BATCHABLE_VARIANTS
    from krl.kernel.model import load_kernel

    kernel = load_kernel(spec.artifact().path)
    if spec.options or kernel.variant not in BATCHABLE_VARIANTS:  # another gait or heights; kernel-dyn2
        return RobotControllers(lambda: _build_kernel(spec, seed), num_robots)
    return KernelBatchController(kernel, num_robots)


# --- agent -----------------------------------------------------------------------------------------


def _parse_agent(text: str, rest: str) -> ControllerSpec:
    from krl.agent.policy import SHIPPED_POLICIES, PolicyFileError, policy_artifacts

    try:
        name, files = policy_artifacts(rest.strip())
    except PolicyFileError as error:
        raise ControllerSpecError(f"controller {text!r}: {error}") from None
    artifacts = tuple(Artifact.of(path, seed) for seed, path in files)
    spec = ControllerSpec("agent", f"agent-{name}", (), artifacts)
    if (rest.strip() or "rp").partition("@")[0] in SHIPPED_POLICIES:
        return spec

    def shipped_hash(shipped: str) -> str:
        return _files_hash([Artifact.of(path, seed) for seed, path in policy_artifacts(shipped)[1]])

    return replace(
        spec, label=_user_label("agent", name, SHIPPED_POLICIES, spec.content_hash or "", shipped_hash)
    )


def _build_agent_batch(spec: ControllerSpec, seed: int | None, num_robots: int):
    from krl.agent.controller import AgentBatchController
    from krl.agent.policy import load_policy

    return AgentBatchController(load_policy(spec.artifact(seed).path, check_kernel=False), num_robots)


def _build_agent(spec: ControllerSpec, seed: int | None):
    from krl.agent.controller import AgentController
    from krl.agent.policy import load_policy

    # AgentController checks the policy's kernel file itself: hash it once per run, not twice
    return AgentController(load_policy(spec.artifact(seed).path, check_kernel=False))


# --- gait: a scripted rule driving kernel-ext's gait (krl.agent.scripted) ---------------------------------

_GAIT_OPTIONS = ("capture", "rate", "ride", "step", "threshold", "hold", "alpha")


def _parse_gait(text: str, rest: str) -> ControllerSpec:
    from krl.agent.scripted import GaitRule, ScriptedGait

    options = _number_options(text, "gait", rest, _GAIT_OPTIONS)
    try:
        ScriptedGait(GaitRule(**options))
    except ValueError as error:
        raise ControllerSpecError(f"controller {text!r}: {error}") from None
    label = "gait" + "".join(f"-{key}{value:g}" for key, value in sorted(options.items()))
    return ControllerSpec("gait", label, tuple(sorted(options.items())))


def _build_gait(spec: ControllerSpec, seed: int | None):
    from krl.agent.scripted import GaitRule, ScriptedGait

    return ScriptedGait(GaitRule(**dict(spec.options)))


def _user_label(
    kind: str, name: str, shipped: tuple[str, ...], sha256: str, shipped_sha256: Callable[[str], str]
) -> str:
    """The label of a user's file (or seed group) named ``name`` whose content hashes to ``sha256`` (module
    docstring): ``KIND-NAME``, or ``KIND-NAME-HASH`` where NAME is one of the ``shipped`` models' names and
    the content is not that model's (``shipped_sha256(NAME)``)."""
    if name not in shipped or shipped_sha256(name) == sha256:
        return f"{kind}-{name}"
    return f"{kind}-{name}-{sha256[:LABEL_HASH_DIGITS]}"


def distinct_controllers(specs: Sequence[ControllerSpec]) -> list[ControllerSpec]:
    """The specs without repeats, in order: specs of one :attr:`ControllerSpec.identity` (``kernel`` and
    ``kernel:base``; ``agent`` and ``agent:PATH/agent-rp.npz``, or a byte-identical copy) are one
    controller, kept under its first spec's label. Two different controllers of one label are a
    :class:`ControllerSpecError`, since results are stored by label."""
    kept: dict[tuple[Any, ...], ControllerSpec] = {}
    labels: dict[str, ControllerSpec] = {}
    for spec in specs:
        if spec.identity in kept:
            continue
        other = labels.setdefault(spec.label, spec)
        if other is not spec:
            raise ControllerSpecError(
                f"two different controllers are labelled {spec.label!r} ({_origin(other)} and "
                f"{_origin(spec)}); results are stored by label, so give one of them another name"
            )
        kept[spec.identity] = spec
    return list(kept.values())


def _origin(spec: ControllerSpec) -> str:
    """What a controller is made from, for messages: its files, or its options."""
    return ", ".join(a.path for a in spec.artifacts) or f"options {dict(spec.options)}"


CONTROLLER_KINDS: dict[str, ControllerKind] = {
    "expert": ControllerKind(_parse_expert, _build_expert, "MPC"),
    "kernel": ControllerKind(_parse_kernel, _build_kernel, "Kernel", _build_kernel_batch),
    "agent": ControllerKind(_parse_agent, _build_agent, "Agent", _build_agent_batch),
    "gait": ControllerKind(_parse_gait, _build_gait, "Scripted gait"),
}
"""Every kind of controller ``krl evaluate`` knows, by the name before the colon of a spec."""


def parse_controller(text: str) -> ControllerSpec:
    """Parse a spec string (module docstring); raises :class:`ControllerSpecError` with one line."""
    kind, _, rest = text.partition(":")
    entry = CONTROLLER_KINDS.get(kind.strip())
    if entry is None:
        raise ControllerSpecError(
            f"unknown controller {text!r}; known: {', '.join(CONTROLLER_KINDS)} (see --help)"
        )
    return entry.parse(text, rest)
