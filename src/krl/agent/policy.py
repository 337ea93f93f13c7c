"""The residual agent's policy file: weights, observation normaliser and metadata, with NumPy inference.

A policy file is one ``.npz`` of plain arrays plus a JSON header, loaded with ``allow_pickle=False``, so
loading never executes code and evaluation workers need no torch. It holds the actor's part of the
trained PPO network (the shared layers, the actor's layers and the action layer; tanh activations), the
running mean and variance of the observations it was trained on, and a header with the agent's whole
configuration (:class:`krl.agent.config.AgentConfig`), the observation layout, the SHA-256 of the kernel
it was trained with, and how it was trained (env steps, wall time, seed, software versions). The
deterministic action is the Gaussian's mean, clipped to [-1, 1]. Stable-Baselines3's own checkpoints
are kept for resuming training only.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.config import AgentConfig, AgentConfigError
from krl.agent.observation import layout, observation_size
from krl.agent.shipped import SHIPPED_POLICIES
from krl.util.affine import affine
from krl.util.hashing import file_sha256
from krl.util.output import npz_bytes, write_atomic

FILE_FORMAT = "krl-policy"
FILE_VERSION = 1


class PolicyFileError(ValueError):
    """A policy file is missing, corrupt, of another format, or does not match its kernel; one line."""


@dataclass
class Policy:
    """A trained residual policy: call :meth:`act` with raw observations."""

    config: AgentConfig
    layers: list[tuple[np.ndarray, np.ndarray]]
    """(W (out, in), b (out,)) of every layer from the observation to the action, in order; tanh after
    each but the last."""
    obs_mean: np.ndarray
    """Running mean of the observations. Shape: (D,)."""
    obs_var: np.ndarray
    """Running variance of the observations. Shape: (D,)."""
    obs_clip: float
    """Normalised observations are clipped to ±obs_clip."""
    obs_epsilon: float
    """Added to the variance before the square root."""
    metadata: dict[str, Any]
    """The header: ``kernel_sha256``, ``training`` (steps, wall_seconds, seed), ``software``, ``layout``."""

    @property
    def observation_size(self) -> int:
        return len(self.obs_mean)

    def normalise(self, observation: np.ndarray) -> np.ndarray:
        """Observations as the network saw them in training. Shapes: (N, D) -> (N, D)."""
        scaled = (observation - self.obs_mean) / np.sqrt(self.obs_var + self.obs_epsilon)
        return np.clip(scaled, -self.obs_clip, self.obs_clip)

    def act(self, observation: np.ndarray, rowwise: bool = False) -> np.ndarray:
        """Deterministic actions in [-1, 1] from raw observations. Shapes: (N, D) -> (N, 12). ``rowwise``:
        every robot's action computed as if alone (:func:`krl.util.affine.affine`)."""
        x = np.asarray(observation, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.observation_size:
            raise ValueError(
                f"the policy expects observations of shape (N, {self.observation_size}), got {x.shape}"
            )
        x = self.normalise(x)
        for index, (weight, bias) in enumerate(self.layers):
            x = affine(x, weight, bias, rowwise)
            if index < len(self.layers) - 1:
                x = np.tanh(x)
        return np.clip(x, -1.0, 1.0)

    def save(self, path: str | Path) -> Path:
        """Write the policy atomically to ``path`` (``.npz``)."""
        path = Path(path)
        header = {
            "format": FILE_FORMAT,
            "version": FILE_VERSION,
            "config": self.config.to_json(),
            "num_layers": len(self.layers),
            "obs_clip": self.obs_clip,
            "obs_epsilon": self.obs_epsilon,
            **self.metadata,
            "layout": layout(self.config.observation.features, self.config.observation.scan),
        }
        arrays: dict[str, np.ndarray] = {"obs_mean": self.obs_mean, "obs_var": self.obs_var}
        for index, (weight, bias) in enumerate(self.layers):
            arrays[f"W{index}"] = weight.astype(np.float32)
            arrays[f"b{index}"] = bias.astype(np.float32)
        arrays["header"] = np.array(json.dumps(header, sort_keys=True))
        write_atomic(path, npz_bytes(arrays))
        return path


def load_policy(path: str | Path, kernel_path: str | Path | None = None, check_kernel: bool = True) -> Policy:
    """Load a policy file, checking its format, shapes and observation layout, and (``check_kernel``)
    that its kernel (``kernel_path``, default the one its config names) is the file it was trained with."""
    path = Path(path)
    if not path.is_file():
        raise PolicyFileError(f"policy file not found: {path}")
    if not zipfile.is_zipfile(path):  # NumPy would read it as a pickle and advise allow_pickle
        raise PolicyFileError(f"{path} is not a krl policy (.npz) file")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
        header = json.loads(str(arrays["header"]))
    except ValueError as error:
        if "allow_pickle" in str(error):  # an archive of pickled objects: never a policy file
            raise PolicyFileError(f"{path} is not a krl policy (.npz) file") from None
        raise PolicyFileError(f"policy file {path} is corrupt or not a policy: {error}") from None
    except (OSError, KeyError, zipfile.BadZipFile, EOFError) as error:
        raise PolicyFileError(f"policy file {path} is corrupt or not a policy: {error}") from None
    if not isinstance(header, dict) or header.get("format") != FILE_FORMAT:
        raise PolicyFileError(f"{path} is not a krl policy file")
    if header.get("version") != FILE_VERSION:
        raise PolicyFileError(
            f"{path} has policy file version {header.get('version')}, expected {FILE_VERSION}"
        )
    try:
        config = AgentConfig.from_json(header["config"], f"{path} config")
        layers = [
            (arrays[f"W{i}"].astype(np.float64), arrays[f"b{i}"].astype(np.float64))
            for i in range(int(header["num_layers"]))
        ]
        policy = Policy(
            config=config,
            layers=layers,
            obs_mean=arrays["obs_mean"].astype(np.float64),
            obs_var=arrays["obs_var"].astype(np.float64),
            obs_clip=float(header["obs_clip"]),
            obs_epsilon=float(header["obs_epsilon"]),
            metadata={k: header[k] for k in ("kernel_sha256", "training", "software") if k in header},
        )
    except AgentConfigError as error:
        raise PolicyFileError(str(error)) from None
    except (KeyError, TypeError, ValueError) as error:
        raise PolicyFileError(f"policy file {path} is inconsistent: {error!r}") from None
    _check(policy, header, path)
    if check_kernel:
        check_kernel_file(policy, kernel_path, path)
    return policy


def _check(policy: Policy, header: dict[str, Any], path: Path) -> None:
    expected = observation_size(policy.config.observation.features, policy.config.observation.scan)
    if header.get("layout") != layout(policy.config.observation.features, policy.config.observation.scan):
        raise PolicyFileError(
            f"policy file {path}: its observation layout does not match its configured features"
        )
    width = expected
    if len(policy.obs_mean) != expected or len(policy.obs_var) != expected:
        raise PolicyFileError(
            f"policy file {path}: observation normaliser has {len(policy.obs_mean)} entries, "
            f"the observation has {expected}"
        )
    for index, (weight, bias) in enumerate(policy.layers):
        if weight.ndim != 2 or weight.shape[1] != width or bias.shape != (weight.shape[0],):
            raise PolicyFileError(
                f"policy file {path}: layer {index} has shape {weight.shape}; its input must be {width} wide"
            )
        width = weight.shape[0]
    actions = policy.config.residual.action_size
    if width != actions:
        raise PolicyFileError(f"policy file {path}: the last layer gives {width} actions, expected {actions}")
    arrays = [policy.obs_mean, policy.obs_var, *(a for layer in policy.layers for a in layer)]
    if not all(np.isfinite(a).all() for a in arrays) or np.any(policy.obs_var < 0):
        raise PolicyFileError(f"policy file {path}: non-finite weights or a negative variance")


def check_kernel_file(policy: Policy, kernel_path: str | Path | None, source: str | Path) -> Path:
    """The kernel file of ``policy`` (``kernel_path``, or the one its config names), checked to be the file
    it was trained with (by SHA-256). Returns its path."""
    from krl.kernel.registry import resolve_model

    path = Path(kernel_path) if kernel_path is not None else resolve_model(policy.config.residual.kernel)
    if not path.is_file():
        raise PolicyFileError(f"policy {source}: its kernel file {path} is missing")
    recorded = policy.metadata.get("kernel_sha256")
    actual = file_sha256(path)
    if recorded != actual:
        raise PolicyFileError(
            f"policy {source} was trained with the kernel of SHA-256 {str(recorded)[:12]}…, but {path} has "
            f"{actual[:12]}…: not the kernel this policy corrects"
        )
    return path


def shipped_policy_dir() -> Path:
    return Path(str(files("krl.agent") / "policies"))


RECIPE_FIELDS: tuple[str, ...] = ("residual", "env", "observation", "ppo", "num_envs")
"""The parts of :class:`AgentConfig` that every policy of one seed group must share: a group is one recipe
trained from several seeds, not a mix of recipes."""


def policy_artifacts(text: str) -> tuple[str, list[tuple[int | None, Path]]]:
    """Resolve ``agent:TEXT``: a shipped name (default ``rp``), a policy file, or a seed group, optionally
    narrowed to one of its seeds with ``@SEED`` (``rp@215``, ``runs/agent-rp@345``).

    A seed group is a folder of per-seed policy files (``seed150.npz``, ...) or of run folders each holding a
    ``policy.npz`` (what ``krl agent train`` writes), or a pattern in the path's last part matching such
    files or run folders (a study variant's runs: ``trials/list/heights-seed*``, label ``heights``); every
    file records its training seed and all share
    one recipe (:data:`RECIPE_FIELDS`). Returns ``(label name, [(seed or None, path), ...])``: per-seed files
    carry their seed; one file, or one seed picked with ``@``, carries None (its name ends ``-seedS``).

    Raises :class:`PolicyFileError` (one line) when nothing usable is found, or the seed is not in the group.
    """
    base, at, seed_text = (text or "rp").rpartition("@")
    if not at:
        base, seed_text = seed_text, ""
    name, path = _policy_location(base)
    if path.is_file():
        load_policy(path)
        if seed_text:
            raise PolicyFileError(
                f"{text!r}: {path} is one policy file, not a seed group to pick a seed from"
            )
        return name, [(None, path)]
    group = _seed_group(path)
    if not seed_text:
        return name, sorted(group.items())
    if not seed_text.isdigit() or int(seed_text) not in group:
        raise PolicyFileError(
            f"{text!r}: agent-{name} has no policy for seed {seed_text} (seeds: {', '.join(map(str, group))})"
        )
    return f"{name}-seed{int(seed_text)}", [(None, group[int(seed_text)])]


def one_policy(text: str) -> tuple[str, Path]:
    """The one policy file a single robot runs, for ``TEXT`` as :func:`policy_artifacts` reads it: a seed
    group gives its first seed's file (``rp`` is ``rp@150``). Returns ``(name, path)``."""
    name, files = policy_artifacts(text)
    seed, path = files[0]
    return (name if seed is None else f"{name}-seed{seed}"), path


def _policy_location(text: str) -> tuple[str, Path]:
    """``(label name, path)`` of a shipped name (its folder) or a user's path."""
    if text in SHIPPED_POLICIES:
        return text, shipped_policy_dir() / f"agent-{text}"
    path = Path(text)
    if "*" in path.name:  # a pattern of run folders or files: named by what precedes its seeds
        return path.name.split("*")[0].removesuffix("-seed").removesuffix("-").removeprefix("agent-"), path
    # a run folder's policy.npz takes the folder's name, as a kernel.npz does
    named = path.parent if path.name == "policy.npz" else path
    return (named.stem if named.is_file() else named.name).removeprefix("agent-"), path


def _seed_group(path: Path) -> dict[int, Path]:
    """``{seed: policy file}`` of a seed-group folder, or of the policy files and run folders a pattern in
    the last part of ``path`` matches (``trials/list/heights-seed*``), in seed order (see
    :func:`policy_artifacts`)."""
    if "*" in path.name:
        matches = sorted(path.parent.glob(path.name))
        found = [m if m.is_file() else m / "policy.npz" for m in matches]
        found = [f for f in found if f.suffix == ".npz" and f.is_file()]
        if not found:
            raise PolicyFileError(f"{str(path)!r} matches no policy file and no run folder with a policy.npz")
    elif not path.is_dir():
        raise PolicyFileError(f"no policy file or folder {str(path)!r}")
    else:
        found = sorted(path.glob("*.npz")) or sorted(path.glob("*/policy.npz"))
        if not found:
            raise PolicyFileError(f"policy folder {path} holds no .npz policy files and no run folders")
    group: dict[int, Path] = {}
    recipe: tuple[Path, dict[str, Any]] | None = None
    for candidate in found:
        policy = load_policy(candidate)
        seed = policy.metadata.get("training", {}).get("seed")
        if not isinstance(seed, int):
            raise PolicyFileError(f"policy {candidate} records no training seed (needed in a seed group)")
        if seed in group:
            raise PolicyFileError(f"policy folder {path}: {group[seed]} and {candidate} share seed {seed}")
        settings = {key: value for key, value in policy.config.to_json().items() if key in RECIPE_FIELDS}
        if recipe is not None and settings != recipe[1]:
            differ = sorted(key for key in RECIPE_FIELDS if settings[key] != recipe[1][key])
            raise PolicyFileError(
                f"policy folder {path} mixes recipes: {recipe[0]} and {candidate} differ in "
                f"{', '.join(differ)}"
            )
        recipe = recipe or (candidate, settings)
        group[seed] = candidate
    return dict(sorted(group.items()))
