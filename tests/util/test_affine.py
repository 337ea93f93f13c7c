"""The row-stable dense layer: a row's result is the one-row product's, whatever rows are beside it."""

import numpy as np
import pytest

from krl.util.affine import affine


@pytest.mark.parametrize(("size_in", "size_out"), [(7, 256), (256, 256), (54, 128), (128, 12)])
def test_a_row_is_computed_as_if_alone(size_in, size_out):
    rng = np.random.default_rng(size_in)
    weight, bias = rng.normal(size=(size_out, size_in)), rng.normal(size=size_out)
    rows = rng.normal(size=(16, size_in))
    alone = np.concatenate([affine(rows[k : k + 1], weight, bias) for k in range(len(rows))])
    for count in (2, 3, 5, 16):
        np.testing.assert_array_equal(affine(rows[:count], weight, bias, rowwise=True), alone[:count])
    np.testing.assert_allclose(affine(rows, weight, bias), alone, rtol=1e-12, atol=1e-12)
