"""The names of the kernels krl ships, in a module that imports nothing, so the command line can name them
in its help texts without loading the kernel code."""

SHIPPED_MODELS: tuple[str, ...] = ("base", "ext")
"""Kernels shipped with krl (``src/krl/kernel/models/kernel-<name>.npz``): the thesis's kernel-base and
kernel-ext, whose inputs add the step and ride heights."""
