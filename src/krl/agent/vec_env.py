"""What Stable-Baselines3 asks of every ``VecEnv``, written once for krl's batched environments.

krl's vectorised environments (:class:`krl.agent.env.ResidualVecEnv` in one process,
:class:`krl.agent.process_vec_env.ProcessVecEnv` over worker processes) hold their N environments as one
batch, not as N environment objects: an attribute is the batch's, no wrapper sits on an environment, and
there is no per-environment method to call. :class:`BatchVecEnv` answers SB3's attribute, wrapper and
method queries accordingly; a subclass implements ``reset``, ``step_async``, ``step_wait``, ``seed`` and
``close``.
"""

from __future__ import annotations

from typing import Any

from stable_baselines3.common.vec_env import VecEnv


class BatchVecEnv(VecEnv):
    """A ``VecEnv`` of N environments held as one batch (see the module docstring)."""

    render_mode = None
    """SB3 asks; frames come from :class:`krl.envs.residual.A1ResidualEnv`."""

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """The batch's attribute, once per index; AttributeError when it has none (SB3's ``has_attr``)."""
        return [getattr(self, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs):
        raise NotImplementedError(f"{type(self).__name__} has no per-environment objects to call methods on")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))
