"""Benchmarks behind ``krl bench``: each returns a JSON-ready dict measured against a same-run baseline."""
