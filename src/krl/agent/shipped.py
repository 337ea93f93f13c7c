"""The names of the agents krl ships, in a module that imports nothing, so the command line can name them
in its help texts without loading the policy code."""

SHIPPED_POLICIES: tuple[str, ...] = ("rp", "base", "gait", "gait-ground")
"""Agents krl ships, each a seed group ``src/krl/agent/policies/agent-<name>/seed<S>.npz``: the thesis's
agent-rp and agent-base, and krl's agent-gait and agent-gait-ground (its recipe trained on stepped pyramids
and stronger pushes; docs/agent-gait.md); ``agent`` alone means ``rp``."""
