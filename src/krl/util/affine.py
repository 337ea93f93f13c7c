"""The dense layer of krl's NumPy networks (the kernel, the exported policy), with a row-stable mode.

BLAS sums ``x @ W.T`` for a one-row ``x`` and for a many-row ``x`` in different orders, so a row's result
can differ in its last bits with the rows computed beside it. A robot walked alone and the same robot
walked in a batch must make the same steps (the walk is chaotic: a last-bit difference grows into another
run), so batched evaluation computes every row as a batch of one row (``rowwise=True``).
``tests/test_bit_exactness.py`` holds the networks made of it, and the state readout, to that rule.
"""

from __future__ import annotations

import numpy as np


def affine(x: np.ndarray, weight: np.ndarray, bias: np.ndarray, rowwise: bool = False) -> np.ndarray:
    """``x @ weight.T + bias``. Shapes: x (N, in) (or (in,)), weight (out, in), bias (out,) -> (N, out).

    ``rowwise``: each row of a 2-D ``x`` is multiplied alone, exactly as a one-row ``x`` is, so the result
    of a row does not depend on the other rows: ``x`` as a stack of one-row matrices, which NumPy's matmul
    hands to BLAS one at a time (slower than one product of all rows; tests/util/test_affine.py).
    """
    if not rowwise or x.ndim != 2 or len(x) == 1:
        return x @ weight.T + bias
    return (x[:, None, :] @ weight.T)[:, 0, :] + bias
