"""krl.util.machine names what a machine's floating-point results depend on, as plain JSON."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from krl.util.machine import machine, numpy_blas


def test_the_machine_is_plain_json_and_names_its_blas():
    found = machine()
    assert json.loads(json.dumps(found)) == found
    assert found["numpy"] == np.__version__ and found["mujoco"] == mujoco.__version__
    assert found["cpu"] and found["arch"]
    assert found["blas"], "NumPy's BLAS is loaded, so threadpoolctl sees it"
    assert {"library", "version", "architecture"} == set(found["blas"][0])


def test_another_blas_in_the_process_changes_nothing():
    before = numpy_blas()
    pytest.importorskip("scipy.linalg")  # SciPy's wheels bring their own OpenBLAS
    assert numpy_blas() == before and len(before) == 1
