"""What a machine's floating-point results depend on, stored with what it computes.

A walk is chaotic: a last-bit difference in one product grows into another run. Two machines whose BLAS
picks different kernels (OpenBLAS's ``Haswell`` against ``SkylakeX``, OpenBLAS against MKL) sum the
networks' products in different orders, so the same run of the same code can end differently on each
(docs/sim.md, "Across machines"). :func:`machine` names what decides that, so that a record says where it
was made and two records that differ can be told apart from a changed result.
"""

from __future__ import annotations

import functools
import platform
from typing import Any


def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo``'s ``model name``; elsewhere what :mod:`platform`
    says, ``unknown`` when nothing does)."""
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.partition(":")[2].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def blas_libraries() -> list[dict[str, Any]]:
    """The BLAS libraries loaded in this process (threadpoolctl): ``library`` (``openblas``, ``mkl``...),
    ``version`` and ``architecture`` (the kernels OpenBLAS picked for this CPU; None where the library does
    not say)."""
    from threadpoolctl import threadpool_info

    return [
        {
            "library": info.get("internal_api"),
            "version": info.get("version"),
            "architecture": info.get("architecture"),
        }
        for info in threadpool_info()
        if info.get("user_api") == "blas"
    ]


@functools.cache
def machine() -> dict[str, Any]:
    """This process's arithmetic: ``{"cpu", "arch", "blas", "numpy", "mujoco", "python"}`` (plain JSON).
    Computed once per process, after NumPy's BLAS is loaded."""
    import mujoco
    import numpy as np

    return {
        "cpu": cpu_model(),
        "arch": platform.machine(),
        "blas": blas_libraries(),
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
        "python": platform.python_version(),
    }
