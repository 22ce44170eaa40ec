"""The call-free elementary functions of the vectorised kernels against numpy's libm."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from capsule_env._fastmath import fast_cos_2pi, fast_exp, fast_log, fast_tanh_nonneg

FUNCS = {"exp": fast_exp, "log": fast_log, "cos_2pi": fast_cos_2pi, "tanh": fast_tanh_nonneg}


@njit(cache=True)
def _apply_loop(code, x):
    """A loop over the array (vectorised by LLVM) and the same call one element at a time."""
    out = np.empty_like(x)
    for k in range(x.size):
        if code == 0:
            out[k] = fast_exp(x[k])
        elif code == 1:
            out[k] = fast_log(x[k])
        elif code == 2:
            out[k] = fast_cos_2pi(x[k])
        else:
            out[k] = fast_tanh_nonneg(x[k])
    return out


def apply(name: str, x: np.ndarray) -> np.ndarray:
    return _apply_loop(list(FUNCS).index(name), np.ascontiguousarray(x, dtype=float))


RNG = np.random.default_rng(0)


def test_exp_relative_error_below_1e_15():
    x = np.r_[RNG.uniform(-700.0, 700.0, 20000), RNG.uniform(-1.0, 1.0, 20000), 0.0, -0.0]
    rel = np.abs(apply("exp", x) / np.exp(x) - 1.0)
    assert rel.max() < 1e-15
    assert apply("exp", np.array([0.0]))[0] == 1.0


def test_exp_clamps_outside_the_double_range():
    got = apply("exp", np.array([-1e4, 1e4]))
    assert got[0] >= 0.0 and got[0] < 1e-300
    assert np.isfinite(got[1]) and got[1] > 1e307


def test_log_error_over_the_normal_range():
    x = np.r_[10.0 ** RNG.uniform(-300, 300, 20000), RNG.uniform(0.0, 1.0, 20000), 1.0]
    got = apply("log", x)
    want = np.log(x)
    assert np.max(np.abs(got - want) / np.maximum(1.0, np.abs(want))) < 1e-15
    assert apply("log", np.array([1.0]))[0] == 0.0


def test_cos_2pi_error_and_symmetry():
    u = np.r_[RNG.uniform(-3.0, 3.0, 40000), 0.0, 0.25, 0.5, 1.0]
    got = apply("cos_2pi", u)
    # reference: libm's cos of the exactly reduced argument (2 pi u itself would carry a
    # rounding error of ~1e-15 at |u| = 3)
    assert np.max(np.abs(got - np.cos(2.0 * np.pi * (u - np.round(u))))) < 1e-15
    assert got[-4] == 1.0 and got[-2] == -1.0
    np.testing.assert_array_equal(apply("cos_2pi", -u), got)


def test_tanh_absolute_error_for_nonnegative_arguments():
    x = np.r_[RNG.uniform(0.0, 40.0, 20000), 10.0 ** RNG.uniform(-12, 0, 20000), 0.0, 400.0]
    got = apply("tanh", x)
    assert np.max(np.abs(got - np.tanh(x))) < 1e-15
    assert got[-2] == 0.0 and got[-1] == 1.0


@pytest.mark.parametrize("name", list(FUNCS))
def test_vectorised_and_scalar_evaluation_give_the_same_bits(name):
    # The kernels rely on it: a vehicle must get the same result in a SIMD lane as in the
    # loop's scalar remainder, so a batch of one and a batch of thousands agree bit for bit.
    x = {
        "exp": RNG.uniform(-50.0, 50.0, 1003),
        "log": RNG.uniform(1e-6, 10.0, 1003),
        "cos_2pi": RNG.uniform(-2.0, 2.0, 1003),
        "tanh": RNG.uniform(0.0, 5.0, 1003),
    }[name]
    batch = apply(name, x)
    one_by_one = np.array([apply(name, x[k : k + 1])[0] for k in range(0, x.size, 97)])
    np.testing.assert_array_equal(batch[::97], one_by_one)
