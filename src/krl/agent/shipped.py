"""The names of the agents krl ships, in a module that imports nothing, so the command line can name them
in its help texts without loading the policy code."""

SHIPPED_POLICIES: tuple[str, ...] = ("rp", "base", "gait", "gait-ground", "robust")
"""Agents krl ships, each a seed group ``src/krl/agent/policies/agent-<name>/seed<S>.npz``: the thesis's
agent-rp and agent-base, and krl's agent-gait, agent-gait-ground (its recipe trained on stepped pyramids
and stronger pushes; docs/agent-gait.md) and agent-robust (agent-gait-ground's recipe with a mirror loss and a
push curriculum; docs/agent-robust.md); ``agent`` alone means ``rp``."""
