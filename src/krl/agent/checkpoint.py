"""A training checkpoint on disk, and reading it back without running code from it.

A checkpoint ``checkpoints/<steps>/`` (written whole by
:class:`krl.agent.callbacks.Checkpointer`, then named in ``checkpoints/latest``; a run keeps its last
:data:`KEPT_CHECKPOINTS`) holds:

* ``model.zip``: SB3's archive (``PPO.save``): the policy's and the optimiser's state dicts and the
  algorithm's fields (JSON, some of them cloudpickled). :func:`read_checkpoint` reads the state dicts
  with ``torch.load(weights_only=True)`` and of the fields only ``_n_updates`` (plain JSON) and
  ``ep_info_buffer`` (the recent episodes, through :func:`restricted_loads`), both through
  :mod:`krl.agent.sb3_adapter`; no other field is read.
* ``normaliser.npz``: the observation and return normaliser (:class:`NormaliserState`), plain arrays read
  with ``np.load(allow_pickle=False)``.
* ``state.json``: ``num_timesteps``, ``wall_seconds``, ``final``.

Nothing read from a run folder runs code: :func:`restricted_loads` builds NumPy arrays, numbers, strings,
lists, dicts and deques, and a plain record in place of each of the few SB3 and NumPy objects a
normaliser pickle holds; any other reference in a pickle is refused with a one-line error. Checkpoints
written before ``normaliser.npz`` hold ``normaliser.pkl`` (SB3's pickle of its ``VecNormalize``) instead,
read the same way, so the committed runs in ``training/`` still resume and start new runs.
"""

from __future__ import annotations

import io
import json
import pickle
import re
import zipfile
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.save_util import load_from_zip_file

from krl.agent.sb3_adapter import saved_episodes_pickle, saved_update_count
from krl.util.output import npz_bytes, write_atomic


class CheckpointError(ValueError):
    """A checkpoint that cannot be read (corrupt, or a pickle that refers to anything but data); one line."""


KEPT_CHECKPOINTS: int = 2
"""The checkpoints a run keeps, its newest ones: a newest one that cannot be read leaves one before it to
resume from."""

NORMALISER_FILE = "normaliser.npz"
"""A checkpoint's normaliser (:class:`NormaliserState`)."""
LEGACY_NORMALISER_FILE = "normaliser.pkl"
"""The normaliser of checkpoints written before :data:`NORMALISER_FILE`: SB3's pickle of its VecNormalize."""


@dataclass(frozen=True)
class NormaliserState:
    """What a checkpoint keeps of SB3's ``VecNormalize``: the running statistics of the observations
    (D numbers each) and of the discounted return (one each), and its settings."""

    obs_mean: np.ndarray
    """Running mean of the raw observations. Shape: (D,)."""
    obs_var: np.ndarray
    """Running variance of the raw observations. Shape: (D,)."""
    obs_count: float
    """Samples behind the observation statistics (SB3 starts it at 1e-4)."""
    return_mean: np.ndarray
    """Running mean of the discounted return. Shape: ()."""
    return_var: np.ndarray
    """Running variance of the discounted return (rewards are divided by its square root). Shape: ()."""
    return_count: float
    """Samples behind the return statistics."""
    clip_obs: float
    """Normalised observations are clipped to ±clip_obs."""
    clip_reward: float
    """Normalised rewards are clipped to ±clip_reward."""
    gamma: float
    """Discount of the return the rewards are scaled by."""
    epsilon: float
    """Added to a variance before its square root."""
    norm_obs: bool
    """Whether observations are normalised."""
    norm_reward: bool
    """Whether rewards are scaled."""

    @classmethod
    def of(cls, env) -> NormaliserState:
        """The state of a ``VecNormalize``."""
        obs, ret = env.obs_rms, env.ret_rms
        settings = {name: getattr(env, name) for name in _NORMALISER_SETTINGS}
        return cls(obs.mean, obs.var, float(obs.count), ret.mean, ret.var, float(ret.count), **settings)

    def restore(self, env, settings: bool = True) -> None:
        """Put the running statistics (and with ``settings`` the settings) into a ``VecNormalize``;
        ValueError if its observations are of another size."""
        if self.obs_mean.shape != env.obs_rms.mean.shape or self.obs_var.shape != self.obs_mean.shape:
            raise ValueError(f"its normaliser is for observations of shape {self.obs_mean.shape}")
        env.obs_rms.mean, env.obs_rms.var, env.obs_rms.count = self.obs_mean, self.obs_var, self.obs_count
        env.ret_rms.mean, env.ret_rms.var = self.return_mean, self.return_var
        env.ret_rms.count = self.return_count
        if settings:
            for name in _NORMALISER_SETTINGS:
                setattr(env, name, getattr(self, name))

    def save(self, path: Path) -> None:
        """Write as a ``.npz`` of plain arrays (one per field)."""
        arrays = {name: np.asarray(getattr(self, name)) for name in self.__dataclass_fields__}
        write_atomic(path, npz_bytes(arrays))

    @classmethod
    def load(cls, path: Path) -> NormaliserState:
        """Read what :meth:`save` wrote (``allow_pickle=False``)."""
        with np.load(path, allow_pickle=False) as arrays:
            values = {name: arrays[name] for name in cls.__dataclass_fields__}
        return cls._typed(values)

    @classmethod
    def _typed(cls, values: dict[str, Any]) -> NormaliserState:
        """The fields from arrays or numbers: the statistics as float64 arrays, the counts and settings as
        the Python numbers and bools VecNormalize keeps them in."""
        typed = {name: np.array(values[name], dtype=np.float64) for name in _NORMALISER_ARRAYS}
        typed.update({name: float(values[name]) for name in _NORMALISER_NUMBERS})
        typed.update({name: bool(values[name]) for name in ("norm_obs", "norm_reward")})
        return cls(**typed)


_NORMALISER_ARRAYS = ("obs_mean", "obs_var", "return_mean", "return_var")
"""The fields of :class:`NormaliserState` that are arrays."""
_NORMALISER_NUMBERS = ("obs_count", "return_count", "clip_obs", "clip_reward", "gamma", "epsilon")
"""The fields of :class:`NormaliserState` that are numbers."""
_NORMALISER_SETTINGS = ("clip_obs", "clip_reward", "gamma", "epsilon", "norm_obs", "norm_reward")
"""The settings of a ``VecNormalize`` that :class:`NormaliserState` keeps (its attribute names)."""


def read_normaliser(checkpoint: Path) -> NormaliserState | None:
    """A checkpoint's normaliser: ``normaliser.npz``, else a ``normaliser.pkl`` of an older checkpoint
    (:func:`_legacy_normaliser`), else None. CheckpointError (one line) if it cannot be read."""
    path, legacy = checkpoint / NORMALISER_FILE, checkpoint / LEGACY_NORMALISER_FILE
    try:
        if path.is_file():
            return NormaliserState.load(path)
        return _legacy_normaliser(legacy.read_bytes()) if legacy.is_file() else None
    except CheckpointError as error:
        raise CheckpointError(f"checkpoint {checkpoint}: {LEGACY_NORMALISER_FILE}: {error}") from None
    except Exception as error:  # NumPy, zipfile and pickle raise many types
        raise _corrupt(checkpoint, error) from None


def _legacy_normaliser(data: bytes) -> NormaliserState:
    """The state in SB3's pickle of its VecNormalize (``normaliser.pkl``), read by
    :func:`restricted_loads`."""
    record = restricted_loads(data)
    if getattr(record, "origin", None) != _VEC_NORMALIZE:
        raise CheckpointError("it is not SB3's VecNormalize")
    state = record.state
    statistics = {"obs": state["obs_rms"].state, "return": state["ret_rms"].state}
    values = {
        f"{kind}_{name}": stats[name]
        for kind, stats in statistics.items()
        for name in ("mean", "var", "count")
    }
    values.update({name: state[name] for name in _NORMALISER_SETTINGS})
    return NormaliserState._typed({name: _value(value) for name, value in values.items()})


class _Record:
    """A stand-in for an object of a pickle: the arguments it was built from and the state it was given
    (nothing of the object's own code runs); ``origin`` names what it stands for."""

    origin = ""

    def __init__(self, *args: Any) -> None:
        self.args = args
        self.state: Any = None

    def __setstate__(self, state: Any) -> None:
        self.state = state


class _DType(_Record):
    """A NumPy dtype of a pickle (``numpy.dtype(name, align, copy)`` + its byte order in the state)."""

    def dtype(self) -> np.dtype:
        """The dtype, if it is one of plain numbers (:data:`_PLAIN_DTYPES`); CheckpointError otherwise."""
        name = self.args[0] if self.args else None
        if name not in _PLAIN_DTYPES:
            raise CheckpointError(f"a pickle holds data of NumPy type {name!r}, not plain numbers")
        order = self.state[1] if isinstance(self.state, tuple) and len(self.state) > 1 else "="
        return np.dtype(name).newbyteorder(order if order in ("<", ">", "=", "|") else "=")


class _Array(_Record):
    """A NumPy array of a pickle (``_reconstruct`` + the state ``(shape, dtype, fortran, bytes)``); the
    array is made from the bytes by :func:`numpy.frombuffer`, never by NumPy's unpickling."""

    value: np.ndarray

    def __setstate__(self, state: Any) -> None:
        shape, dtype, fortran, data = state[-4:]
        if not (isinstance(dtype, _DType) and isinstance(data, bytes | bytearray)):
            raise CheckpointError("a pickle holds an array that is not of plain numbers")
        flat = np.frombuffer(data, dtype=dtype.dtype())
        self.value = flat.reshape(shape, order="F" if fortran else "C").copy()


def _value(item: Any) -> Any:
    """An item of a restricted pickle with its arrays as arrays."""
    return item.value if isinstance(item, _Array) else item


def _scalar(dtype: _DType, data: bytes) -> int | float | bool:
    """A NumPy scalar of a pickle (``numpy._core.multiarray.scalar``) as the Python number it holds."""
    if not (isinstance(dtype, _DType) and isinstance(data, bytes)):
        raise CheckpointError("a pickle holds a NumPy scalar that is not a plain number")
    return np.frombuffer(data, dtype=dtype.dtype())[0].item()


_PLAIN_DTYPES = frozenset(("b1", "i1", "i2", "i4", "i8", "u1", "u2", "u4", "u8", "f2", "f4", "f8"))
"""The NumPy types (dtype codes) an array or scalar of a pickle may have."""

_NUMPY_MULTIARRAY = ("numpy._core.multiarray", "numpy.core.multiarray")
"""NumPy's module of array pickling, by its names in NumPy 2 and 1."""

_VEC_NORMALIZE = "stable_baselines3.common.vec_env.vec_normalize.VecNormalize"

_RECORDED = (
    _VEC_NORMALIZE,
    "stable_baselines3.common.running_mean_std.RunningMeanStd",
    "gymnasium.spaces.box.Box",
    "numpy.random._pickle.__generator_ctor",
    "numpy.random._pickle.__bit_generator_ctor",
    "numpy.random._pcg64.PCG64",
    "numpy.random.bit_generator.__pyx_unpickle_SeedSequence",
    "numpy.random.bit_generator.SeedSequence",
)
"""What SB3's pickle of a VecNormalize refers to (it, its statistics, its spaces and their random
generators): each becomes a :class:`_Record`."""

_CONSTRUCTORS: dict[str, Any] = {
    "collections.deque": deque,
    "numpy.dtype": _DType,
    "numpy.ndarray": _Array,
    **{f"{module}._reconstruct": lambda cls, *args: _Array() for module in _NUMPY_MULTIARRAY},
    **{f"{module}.scalar": _scalar for module in _NUMPY_MULTIARRAY},
}
"""The only callables a pickle may call: a deque, and krl's own readers of NumPy data."""


class _RestrictedUnpickler(pickle.Unpickler):
    """Builds only plain data, :data:`_CONSTRUCTORS` and records of :data:`_RECORDED`."""

    def find_class(self, module: str, name: str) -> Any:
        origin = f"{module}.{name}"
        if origin in _CONSTRUCTORS:
            return _CONSTRUCTORS[origin]
        if origin in _RECORDED:
            return type(name, (_Record,), {"origin": origin})
        raise CheckpointError(f"a pickle refers to {origin}, which krl never reads from a run folder")


def restricted_loads(data: bytes) -> Any:
    """Unpickle ``data`` without running anything it names (module docstring): NumPy arrays become
    :class:`_Array` records (``.value``); CheckpointError for any other reference."""
    return _RestrictedUnpickler(io.BytesIO(data)).load()


@dataclass(frozen=True)
class Checkpoint:
    """A checkpoint as :func:`read_checkpoint` reads it back."""

    folder: Path
    num_timesteps: int
    """Env steps trained when it was saved."""
    wall_seconds: float
    """The run's wall time when it was saved [s]."""
    params: dict[str, dict[str, Any]]
    """SB3's state dicts: ``policy`` (the network) and ``policy.optimizer`` (Adam's state)."""
    n_updates: int
    """PPO's gradient steps so far (SB3's ``_n_updates``, logged as ``train/n_updates``)."""
    episodes: list[dict[str, Any]]
    """SB3's ``ep_info_buffer``: the last (up to 100) episodes' ``info["episode"]``, oldest first."""
    normaliser: NormaliserState | None


def steps_name(steps: int) -> str:
    """``steps`` env steps as the names of checkpoint folders and of a run's log segments
    (``progress.<steps>.csv``) write them: zero-padded, so that names sort as steps."""
    return f"{steps:011d}"


def checkpoint_folders(directory: Path) -> list[Path]:
    """The checkpoint folders in a run's ``checkpoints/`` (named by :func:`steps_name`), newest first; none
    where it does not exist."""
    if not directory.is_dir():
        return []
    pattern = "[0-9]" * len(steps_name(0))
    return sorted((path for path in directory.glob(pattern) if path.is_dir()), reverse=True)


def read_state(checkpoint: Path) -> tuple[int, float]:
    """A checkpoint's env steps and wall seconds (its ``state.json``); CheckpointError if unreadable."""
    try:
        state = json.loads((checkpoint / "state.json").read_text())
        return int(state["num_timesteps"]), float(state["wall_seconds"])
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise _corrupt(checkpoint, error) from None


def read_checkpoint(checkpoint: Path) -> Checkpoint:
    """Read a checkpoint folder without running anything in it (module docstring); CheckpointError
    (one line) if it is incomplete, corrupt, or holds a pickle that refers to anything but data."""
    steps, wall = read_state(checkpoint)
    model = checkpoint / "model.zip"
    if not model.is_file():
        raise CheckpointError(f"checkpoint {checkpoint} has no model.zip")
    try:
        _, stored, _ = load_from_zip_file(model, load_data=False, device="cpu")  # torch weights_only
        params = {name: stored[name] for name in ("policy", "policy.optimizer")}
        with zipfile.ZipFile(model) as archive:
            data = json.loads(archive.read("data"))
        n_updates = saved_update_count(data)
        episodes = list(restricted_loads(saved_episodes_pickle(data)))
        if not all(isinstance(episode, dict) for episode in episodes):
            raise CheckpointError(f"checkpoint {checkpoint}: model.zip's ep_info_buffer holds no episodes")
    except CheckpointError as error:
        raise CheckpointError(f"checkpoint {checkpoint}: model.zip's ep_info_buffer: {error}") from None
    except pickle.UnpicklingError as error:
        raise _refused_weights(checkpoint, error) from None
    except Exception as error:  # zipfile, JSON, base64, pickle and torch raise many types
        raise _corrupt(checkpoint, error) from None
    return Checkpoint(checkpoint, steps, wall, params, n_updates, episodes, read_normaliser(checkpoint))


def _refused_weights(checkpoint: Path, error: pickle.UnpicklingError) -> CheckpointError:
    """The one-line error for a model.zip whose weights ``torch.load(weights_only=True)`` refused: what
    they refer to and that krl refuses it (not PyTorch's advice to load them unsafely), else
    :func:`_corrupt`."""
    if not str(error).startswith("Weights only load failed"):
        return _corrupt(checkpoint, error)
    refused = re.search(r"GLOBAL ([\w.]+)", str(error))
    what = f"refers to {refused.group(1)}" if refused else "holds more than weights"
    return CheckpointError(f"checkpoint {checkpoint}: model.zip {what}, which krl refuses to load")


def _corrupt(checkpoint: Path, error: Exception) -> CheckpointError:
    """The one-line error for a checkpoint that cannot be read."""
    text = str(error).strip()
    return CheckpointError(
        f"checkpoint {checkpoint} is corrupt: {text.splitlines()[0] if text else type(error).__name__}"
    )
