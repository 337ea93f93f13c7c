"""krl.util.machine names what a machine's floating-point results depend on, as plain JSON."""

from __future__ import annotations

import json

import mujoco
import numpy as np

from krl.util.machine import machine


def test_the_machine_is_plain_json_and_names_its_blas():
    found = machine()
    assert json.loads(json.dumps(found)) == found
    assert found["numpy"] == np.__version__ and found["mujoco"] == mujoco.__version__
    assert found["cpu"] and found["arch"]
    assert found["blas"], "NumPy's BLAS is loaded, so threadpoolctl sees it"
    assert {"library", "version", "architecture"} == set(found["blas"][0])
