"""Constants of the thesis's protocol that more than one part of krl follows (one home for each)."""

from __future__ import annotations

THESIS_SEEDS: tuple[int, ...] = (150, 215, 345, 556)
"""The four seeds used throughout the thesis (Section 4.2.1): training seeds of the kernel studies and
run seeds of the evaluation."""

COMPARISON_EPOCHS: int = 10
"""Training epochs per run when the thesis compares kernels: each tuning trial (Table A.2) and each run
of Tables 4.3-4.5."""

THESIS_PUSH_MAGNITUDES: tuple[float, ...] = tuple(float(m) for m in range(250, 901, 50))
"""Push forces of the robustness sweep, Table 5.5: 250-900 N in steps of 50 [N]."""

THESIS_PUSH_ATTEMPTS: int = 10
"""Attempts per push magnitude in Table 5.5 (Section 5.3: "For each magnitude of force applied, we run 10
attempts")."""

THESIS_NAMES: dict[str, str] = {
    "expert-stance0.3": "MPC (τ_stance=0.3)",
    "expert-stance0.2": "MPC (τ_stance=0.2)",
    "kernel-base": "Kernel",
    "agent-base": "Agent-base",
    "agent-rp": "Agent-rp",
}
"""krl's controller labels -> the thesis's names of the same controllers (the rows of Tables 5.1-5.5)."""

__all__ = [
    "COMPARISON_EPOCHS",
    "THESIS_NAMES",
    "THESIS_PUSH_ATTEMPTS",
    "THESIS_PUSH_MAGNITUDES",
    "THESIS_SEEDS",
]
