"""``krl export``: the kernel and the agent's policy as ONNX graphs, with a JSON contract beside them.

The graphs are built from the same NumPy arrays krl's own inference uses (``Kernel.predict``,
``Policy.act``), normalisation included, so a robot or another simulator can run them without krl:

* ``kernel.onnx``: ``features`` (N, n_in) float32 -> ``foot_targets`` (N, 12), the four feet's targets in the
  base frame [m], leg-major (FR, FL, RR, RL) × (x, y, z); kernel-ind maps (4N, 8) -> (4N, 3).
* ``policy.onnx``: ``observation`` (N, D) float32 -> ``action`` (N, A) in [-1, 1] (the deterministic
  action: the Gaussian's mean, clipped); A = 12 for the thesis's residual agent.
* ``contract.json``: the observation's terms in order with slices and units, the kernel's input names, the
  action's parts in order (:mod:`krl.agent.action`: slice, unit, each number's name, the values -1, 0
  and +1 map to, the filter each passes through), the residual bound [m] and the filter's α, the control
  and physics steps, the foot and joint order; for each graph, the SHA-256 of the ONNX file and of the
  krl file it was made from (``source``), and for the policy its seed group and training seed.

An export leaves its folder consistent: every graph is built before the first file is written, the contract
is written last, and a kernel-only export refuses a folder that holds a ``policy.onnx`` (of an earlier
export), which its contract would not list; krl does not delete a file it was not asked to.

``onnx`` and ``onnxruntime`` are an optional extra (``pip install -e ".[export]"``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from krl.util.output import write_atomic

OPSET = 17
"""ONNX opset of the exported graphs."""

KERNEL_FILE = "kernel.onnx"
"""The kernel's graph, in the export folder."""

POLICY_FILE = "policy.onnx"
"""The policy's graph, in the export folder."""

CONTRACT_FILE = "contract.json"
"""The contract, in the export folder."""

DEFAULT_KERNEL = "base"
"""The shipped kernel exported when neither a policy nor a kernel is given."""


def _onnx():
    try:
        import onnx
    except ImportError:
        raise ImportError('krl export needs the onnx package: pip install -e ".[export]"') from None
    return onnx


class _Graph:
    """A small builder of a feed-forward ONNX graph over one input."""

    def __init__(self, input_name: str) -> None:
        self.onnx = _onnx()
        self.nodes: list[Any] = []
        self.constants: list[Any] = []
        self.last = input_name
        self.count = 0

    def _name(self, kind: str) -> str:
        self.count += 1
        return f"{kind}_{self.count}"

    def constant(self, array: np.ndarray) -> str:
        name = self._name("c")
        self.constants.append(self.onnx.numpy_helper.from_array(np.asarray(array, dtype=np.float32), name))
        return name

    def op(self, kind: str, *extra: str, **attributes: Any) -> str:
        out = self._name(kind.lower())
        self.nodes.append(self.onnx.helper.make_node(kind, [self.last, *extra], [out], **attributes))
        self.last = out
        return out

    def linear(self, weight: np.ndarray, bias: np.ndarray) -> None:
        self.op("MatMul", self.constant(np.asarray(weight).T))
        self.op("Add", self.constant(bias))

    def affine(self, scale: np.ndarray, shift: np.ndarray) -> None:
        self.op("Mul", self.constant(scale))
        self.op("Add", self.constant(shift))

    def clip(self, low: float, high: float) -> None:
        self.op("Clip", self.constant(np.array(low)), self.constant(np.array(high)))

    def model(self, input_name: str, width_in: int, output_name: str, width_out: int, doc: str):
        helper = self.onnx.helper
        self.nodes.append(helper.make_node("Identity", [self.last], [output_name]))
        graph = helper.make_graph(
            self.nodes,
            "krl",
            [helper.make_tensor_value_info(input_name, self.onnx.TensorProto.FLOAT, ["N", width_in])],
            [helper.make_tensor_value_info(output_name, self.onnx.TensorProto.FLOAT, ["N", width_out])],
            initializer=self.constants,
        )
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="krl")
        model.doc_string = doc
        self.onnx.checker.check_model(model)
        return model


def kernel_onnx(kernel):
    """The kernel (normalisers, MLP, batch norm folded) as an ONNX model."""
    from krl.kernel.model import BN_EPS

    graph = _Graph("features")
    graph.affine(1.0 / kernel.input_std, -kernel.input_mean / kernel.input_std)
    layers = kernel.layers()
    for index, layer in enumerate(layers):
        graph.linear(layer["W"], layer["b"])
        if index == len(layers) - 1:
            break
        if kernel.network.batch_norm:
            scale = layer["gamma"] / np.sqrt(layer["var"] + BN_EPS)
            graph.affine(scale, layer["beta"] - layer["mean"] * scale)
        graph.op("Relu" if kernel.network.activation == "relu" else "Tanh")
    graph.affine(kernel.output_std, kernel.output_mean)
    return graph.model(
        "features", kernel.input_size, "foot_targets", kernel.output_size, f"krl kernel-{kernel.variant}"
    )


def policy_onnx(policy):
    """The policy (observation normaliser, tanh MLP, action clip) as an ONNX model."""
    graph = _Graph("observation")
    scale = 1.0 / np.sqrt(policy.obs_var + policy.obs_epsilon)
    graph.affine(scale, -policy.obs_mean * scale)
    graph.clip(-policy.obs_clip, policy.obs_clip)
    for index, (weight, bias) in enumerate(policy.layers):
        graph.linear(weight, bias)
        if index < len(policy.layers) - 1:
            graph.op("Tanh")
    graph.clip(-1.0, 1.0)
    actions = policy.config.residual.action_size
    return graph.model("observation", policy.observation_size, "action", actions, "krl residual policy")


def contract(
    kernel,
    kernel_path: Path,
    policy=None,
    policy_path: Path | None = None,
    graphs: dict[str, bytes] | None = None,
    seed_group: str | None = None,
) -> dict[str, Any]:
    """What the exported graphs mean (module docstring). ``graphs``: the ONNX files' bytes by role
    (``kernel``, ``policy``), hashed into the contract; ``seed_group``: the seed group the policy was taken
    from (a shipped agent's name or a folder), None for a policy file named alone."""
    import hashlib

    from krl.agent.observation import layout
    from krl.kernel.features import input_names
    from krl.robots.a1.constants import JOINT_NAMES, LEG_NAMES
    from krl.util.hashing import file_sha256
    from krl.util.timing import COMMAND_DT, CONTROL_DT, PHYSICS_DT

    document: dict[str, Any] = {
        "format": "krl-export",
        "version": 2,
        "control_dt": CONTROL_DT,
        "physics_dt": PHYSICS_DT,
        "command_dt": COMMAND_DT,
        "foot_order": list(LEG_NAMES),
        "joint_order": list(JOINT_NAMES),
        "kernel": {
            "file": KERNEL_FILE,
            "variant": kernel.variant,
            "sha256": hashlib.sha256(graphs["kernel"]).hexdigest() if graphs else None,
            "source": {"file": kernel_path.name, "sha256": file_sha256(kernel_path)},
            "inputs": input_names(kernel.variant),
            "outputs": "foot targets in the base frame [m], leg-major (foot_order) x (x, y, z)",
        },
    }
    if policy is not None:
        document["policy"] = {
            "file": POLICY_FILE,
            "sha256": hashlib.sha256(graphs["policy"]).hexdigest() if graphs else None,
            "source": {"file": policy_path.name, "sha256": file_sha256(policy_path)},
            "seed_group": seed_group,
            "seed": policy.metadata.get("training", {}).get("seed"),
            "observation": [
                {"name": r["name"], "start": r["start"], "stop": r["stop"], "unit": r["unit"]}
                for r in layout(policy.config.observation.features, policy.config.observation.scan)
            ],
            "action": _action_contract(policy.config.residual, kernel),
            "kernel_sha256": policy.metadata.get("kernel_sha256"),
        }
        if "height_scan" in policy.config.observation.features:
            document["policy"]["height_scan"] = _scan_contract(policy.config.observation.scan)
    return document


def _scan_contract(scan) -> dict[str, Any]:
    """How a robot measures ``height_scan`` (a :class:`krl.agent.config.ScanConfig`): the points, the value
    of each and its clip."""
    return {
        "value": "trunk height - terrain height under the point - offset, clipped to [-clip, clip] [m]",
        "frame": "heading frame: origin under the trunk, x forward, y left, turned with the trunk's yaw",
        "points": [[round(x, 9), round(y, 9)] for x, y in scan.points()],
        "offset": scan.offset,
        "clip": scan.clip,
    }


def _action_contract(residual, kernel) -> dict[str, Any]:
    """The action's size, bounds and parts (:mod:`krl.agent.action`) for the contract."""
    from krl.agent.action import describe_parts

    alphas = {"residual": residual.residual_alpha}
    parts = [
        {**part, "filter_alpha": alphas.get(part["name"], residual.gait_alpha)}
        for part in describe_parts(residual, kernel)
    ]
    action: dict[str, Any] = {"size": residual.action_size, "bounds": [-1.0, 1.0], "parts": parts}
    if residual.residuals:
        action["residual_bound_m"] = list(residual.residual_bound)
        action["filter"] = "r_t = alpha * action_t * residual_bound + (1 - alpha) * r_(t-1), r_(-1) = 0"
        action["filter_alpha"] = residual.residual_alpha
    if residual.drives_gait:
        action["drive_filter"] = (
            "d_t = gait_alpha * (value(action_t) - at_0) + (1 - gait_alpha) * d_(t-1), d_(-1) = 0; "
            "value = linear from at_minus_1 through at_0 to at_plus_1; the kernel's command and heights "
            "and the clock rate of the next step are at_0 + d_t"
        )
        action["clock"] = "phase time t_(k+1) = t_k + control_dt * clock rate (1 when not driven)"
    action["then"] = "joint targets = IK(kernel foot targets + r_t), PD at 1/physics_dt (Table 4.2 gains)"
    return action


def _load(policy: str | None, kernel: str | None) -> tuple[Any, Path, Any, Path | None, str | None]:
    """The policy (or None) and the kernel to export, with their files and the policy's seed group:
    ``(kernel, kernel file, policy, policy file, seed group)``. Names of shipped models (``base``, ``ext``;
    ``rp``, ``gait-ground``, also as ``krl evaluate`` spells them: ``agent:gait-ground``) resolve to their
    files; a seed group gives its first seed's (``@SEED`` picks another)."""
    from krl.agent.policy import check_kernel_file, load_policy, policy_artifacts
    from krl.kernel.model import load_kernel
    from krl.kernel.registry import resolve_model

    kernel_file = None if kernel is None else resolve_model(kernel)
    loaded_policy, policy_path, seed_group = None, None, None
    if policy is not None:
        text = policy.removeprefix("agent:")
        name, files = policy_artifacts(text)
        seed, policy_path = files[0]
        if seed is not None:  # a group: its first seed's
            seed_group = name
        elif "@" in text:  # one seed picked from a group
            seed_group = policy_artifacts(text.rpartition("@")[0])[0]
        loaded_policy = load_policy(policy_path, check_kernel=False)
        kernel_path = check_kernel_file(loaded_policy, kernel_file, policy_path)
    else:
        kernel_path = kernel_file or resolve_model(DEFAULT_KERNEL)
    return load_kernel(kernel_path), kernel_path, loaded_policy, policy_path, seed_group


def export(out: str | Path, policy: str | None = None, kernel: str | None = None) -> dict[str, Any]:
    """Write the ONNX files and the contract into ``out``. ``policy``: a shipped agent's name or a policy
    file (its kernel is exported with it); ``kernel``: a shipped kernel's name or a kernel file (the
    policy's, checked by SHA-256; without a policy, default :data:`DEFAULT_KERNEL`).

    Raises ValueError (one line), before anything is written, for a missing or mismatched file, and for a
    kernel-only export into a folder that holds a ``policy.onnx`` (module docstring).
    """
    out = Path(out)
    loaded_kernel, kernel_path, loaded_policy, policy_path, seed_group = _load(policy, kernel)
    if loaded_policy is None and (out / POLICY_FILE).exists():
        raise ValueError(
            f"{out / POLICY_FILE} is left from an earlier export, and this kernel-only export's "
            f"{CONTRACT_FILE} would not list it: delete it or export into another folder"
        )
    outputs = {"kernel": (KERNEL_FILE, kernel_onnx(loaded_kernel).SerializeToString())}
    if loaded_policy is not None:
        outputs["policy"] = (POLICY_FILE, policy_onnx(loaded_policy).SerializeToString())
    graphs = {role: data for role, (_, data) in outputs.items()}
    document = contract(loaded_kernel, kernel_path, loaded_policy, policy_path, graphs, seed_group)
    outputs["contract"] = (CONTRACT_FILE, json.dumps(document, indent=2) + "\n")
    written = {}
    for role, (name, data) in outputs.items():  # the contract last
        write_atomic(out / name, data)
        written[role] = str(out / name)
    return written
