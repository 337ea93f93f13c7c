"""``krl agent digest``: a SHA-256 of the residual environment's transitions, to show that a change to the
engine (simulator, controller, task, rewards, pushes, resets) keeps what an agent is trained on.

:func:`transition_digest` steps a :class:`krl.agent.env.ResidualVecEnv` of ``num_envs`` robots for
``steps`` control steps with uniform random actions drawn from ``seed`` (one thread, so BLAS cannot split
a product differently), and hashes, step by step, every number training sees: the observations, each
reward term (float64, before the sum is cast to float32), the dones, and each ended episode's info
(terminal observation, time-limit flag, episode statistics but for its wall time, push verdicts). Random
actions make the robots fall, so resets and new terrains are in the stream; a config with pushes in its
first seconds puts pushes in it too.

The digest is exact: equal on one machine before and after a change means the transitions are
bit-identical there. Another CPU may order a BLAS product differently and give another digest, so digests
are compared on one machine, never against a number recorded elsewhere.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from krl.agent.config import AgentConfig


def _info_bytes(info: dict[str, Any]) -> bytes:
    """An ended episode's or a push verdict's info, as bytes (arrays as their raw float64 bytes)."""
    parts = []
    for key in sorted(info):
        value = info[key]
        if isinstance(value, np.ndarray):
            parts.append(key.encode() + np.ascontiguousarray(value, dtype=np.float64).tobytes())
        elif key == "episode":
            episode = {name: item for name, item in value.items() if name != "t"}  # "t": wall time
            parts.append(key.encode() + json.dumps(episode, sort_keys=True).encode())
        else:
            parts.append(key.encode() + json.dumps(value).encode())
    return b"|".join(parts)


def transition_digest(config: AgentConfig, num_envs: int = 3, steps: int = 2000, seed: int = 0) -> dict:
    """The digest of ``steps`` control steps of ``num_envs`` robots (module docstring), with what the
    stream held: ``{"sha256", "num_envs", "steps", "seed", "episodes", "falls", "push_verdicts"}``."""
    from krl.agent.env import ResidualVecEnv

    digest = hashlib.sha256()
    episodes = falls = verdicts = 0
    with threadpool_limits(1):
        env = ResidualVecEnv(config, num_envs, seed=seed)
        rng = np.random.default_rng(seed)
        observations = env.reset()
        digest.update(np.ascontiguousarray(observations, dtype=np.float64).tobytes())
        for _ in range(steps):
            env.step_async(rng.uniform(-1.0, 1.0, (num_envs, *env.action_space.shape)))
            observations, _, dones, infos = env.step_wait()
            digest.update(np.ascontiguousarray(observations, dtype=np.float64).tobytes())
            for name in sorted(env.batch.last_terms):
                digest.update(name.encode() + np.asarray(env.batch.last_terms[name], np.float64).tobytes())
            digest.update(np.asarray(dones, dtype=bool).tobytes())
            for index, info in enumerate(infos):
                if info:
                    digest.update(str(index).encode() + _info_bytes(info))
                episodes += "episode" in info
                falls += bool(info.get("episode", {}).get("fell"))
                verdicts += "push_survived" in info
        env.close()
    return {
        "sha256": digest.hexdigest(),
        "num_envs": num_envs,
        "steps": steps,
        "seed": seed,
        "episodes": episodes,
        "falls": falls,
        "push_verdicts": verdicts,
    }
