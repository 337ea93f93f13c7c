"""Low-pass filter of the residuals (thesis Section 4.2.5, Eq. 4.4): hand-worked values and errors."""

import math

import numpy as np
import pytest

from krl.control.filters import RESIDUAL_ALPHA, LowPassFilter


def test_default_alpha_is_the_thesis_value():
    assert RESIDUAL_ALPHA == 0.1
    assert LowPassFilter((12,)).alpha == 0.1


def test_step_response_by_hand():
    f = LowPassFilter(alpha=0.1, shape=(2,))
    np.testing.assert_array_equal(f.value, [0.0, 0.0])  # zero initial state
    x = np.array([1.0, -2.0])
    np.testing.assert_allclose(f(x), [0.1, -0.2])  # 0.1 * 1 + 0.9 * 0
    np.testing.assert_allclose(f(x), [0.19, -0.38])  # 0.1 + 0.9 * 0.1
    np.testing.assert_allclose(f(x), [0.271, -0.542])  # 0.1 + 0.9 * 0.19
    for _ in range(7):
        y = f(x)
    np.testing.assert_allclose(y, (1 - 0.9**10) * x)  # after n steps: 1 - (1 - alpha)^n


def test_reset_to_a_value_and_broadcast():
    f = LowPassFilter((4, 3), alpha=0.1)
    f.reset(2.0)
    np.testing.assert_allclose(f(np.zeros((4, 3))), np.full((4, 3), 1.8))  # 0.9 * 2
    f.reset([1.0, 2.0, 3.0])  # broadcast over the legs
    np.testing.assert_allclose(f(np.zeros((4, 3))), np.tile([0.9, 1.8, 2.7], (4, 1)))
    f.reset()
    np.testing.assert_array_equal(f.value, np.zeros((4, 3)))


def test_alpha_one_passes_through_and_int_shape():
    f = LowPassFilter(5, alpha=1.0)
    assert f.shape == (5,)
    x = np.arange(5.0)
    np.testing.assert_array_equal(f(x), x)


def test_outputs_are_copies():
    f = LowPassFilter((2,))
    y = f(np.ones(2))
    y[:] = 100.0
    f.value[:] = 100.0
    np.testing.assert_allclose(f.value, [0.1, 0.1])


@pytest.mark.parametrize("alpha", [0.0, -0.1, 1.5, math.nan, math.inf, True, "0.1"])
def test_bad_alpha(alpha):
    with pytest.raises(ValueError, match="alpha"):
        LowPassFilter((3,), alpha=alpha)


def test_bad_inputs():
    f = LowPassFilter((4, 3))
    with pytest.raises(ValueError, match=r"shape \(4, 3\)"):
        f(np.zeros(12))
    with pytest.raises(ValueError, match="finite"):
        f(np.full((4, 3), np.nan))
    with pytest.raises(ValueError, match="broadcast"):
        f.reset(np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        f.reset(np.inf)
    with pytest.raises(ValueError, match="shape"):
        LowPassFilter((-1, 3))
    with pytest.raises(ValueError, match="shape"):
        LowPassFilter("abc")  # type: ignore[arg-type]
    np.testing.assert_array_equal(f.value, np.zeros((4, 3)))  # failed calls leave the state alone
