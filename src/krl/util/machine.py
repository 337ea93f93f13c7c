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
from pathlib import Path
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


def numpy_blas() -> list[dict[str, Any]]:
    """NumPy's BLAS, as threadpoolctl sees it: ``library`` (``openblas``, ``mkl``...), ``version`` and
    ``architecture`` (the kernels OpenBLAS picked for this CPU; None where the library does not say).

    Only NumPy's, so that the answer does not depend on what else the process has loaded (SciPy brings its
    own OpenBLAS): the BLAS libraries under NumPy's own folders (a wheel's ``numpy.libs``), else those of the
    kind NumPy was built with (a system or conda BLAS), else every one loaded; empty where threadpoolctl
    sees none (Apple's Accelerate)."""
    import numpy as np
    from threadpoolctl import threadpool_info

    package = Path(np.__file__).resolve().parent
    loaded = sorted(
        (info for info in threadpool_info() if info.get("user_api") == "blas"),
        key=lambda info: info["filepath"],
    )
    own = [
        info
        for info in loaded
        if Path(info["filepath"]).resolve().parent in (package, package.parent / "numpy.libs")
    ]
    config = getattr(np.__config__, "CONFIG", {})  # NumPy >= 1.26
    built = str(config.get("Build Dependencies", {}).get("blas", {}).get("name", ""))
    kind = [info for info in loaded if info.get("internal_api") and info["internal_api"] in built]
    return [
        {
            "library": info.get("internal_api"),
            "version": info.get("version"),
            "architecture": info.get("architecture"),
        }
        for info in own or kind or loaded
    ]


@functools.cache
def machine() -> dict[str, Any]:
    """This process's arithmetic: ``{"cpu", "arch", "blas", "numpy", "mujoco", "python"}`` (plain JSON), the
    same in every process of one machine and installation whatever else it has loaded. Computed once per
    process."""
    import mujoco
    import numpy as np

    return {
        "cpu": cpu_model(),
        "arch": platform.machine(),
        "blas": numpy_blas(),
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
        "python": platform.python_version(),
    }
