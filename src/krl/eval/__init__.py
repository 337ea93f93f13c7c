"""Evaluation: courses, the controllers scored on them, metrics, the push sweep and the reports."""
