"""Programs built from everything below: the demo, the live viewer, ONNX export and the reproduction plan.

Nothing below imports this package; only :mod:`krl.cli` does.
"""
