"""Figures and traces of the residual agent (the stairs diagnosis of docs/agent.md)."""
