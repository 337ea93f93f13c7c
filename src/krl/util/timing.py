"""Simulation and control rates: the single source of truth for every period in krl.

The physics runs at 1 kHz; the PD law is evaluated by MuJoCo at every physics step. Everything that
decides (gait, kernel, agent, MPC) runs at the 200 Hz control rate, and the command generator of
Algorithm 2 at 20 Hz (thesis Sections 4.2.2-4.2.4).
"""

PHYSICS_DT: float = 0.001
"""Physics step [s] (1 kHz): MuJoCo ``opt.timestep``; the PD law is applied once per physics step."""

SUBSTEPS: int = 5
"""Physics steps per control step."""

CONTROL_DT: float = PHYSICS_DT * SUBSTEPS
"""Control step [s] (200 Hz)."""

COMMAND_PERIOD_STEPS: int = 10
"""Control steps per command-generator tick (20 Hz)."""

COMMAND_DT: float = CONTROL_DT * COMMAND_PERIOD_STEPS
"""Command-generator period [s] (20 Hz)."""
