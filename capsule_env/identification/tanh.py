"""Identification of the hyperbolic-tangent MR-damper model (docs/model.md 4.4, paper eq. 3).

``F = c v + k x + alpha tanh(beta v + delta sign(x)) + f0`` with ``c, k, alpha, f0`` linear in
current and ``beta, delta`` constant. Variable projection: the linear coefficients by linear
least squares inside a bounded nonlinear search over ``(log beta, delta)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from capsule_env.dampers import TanhDamper, branch_weights
from capsule_env.identification.least_squares import (
    lstsq,
    multistart_least_squares,
    velocity_scale,
)
from capsule_env.identification.loops import Loop, check_int, check_loops, stack_loops

__all__ = ["fit_tanh"]


def _tanh_design(
    sign_x: np.ndarray,
    v: np.ndarray,
    i: np.ndarray,
    x: np.ndarray,
    beta: float,
    delta: float,
    with_current: bool,
) -> np.ndarray:
    """Design matrix of the linear coefficients at fixed ``beta, delta``: columns ``v, x,
    tanh(.), 1`` (each also times ``i`` when ``with_current``)."""
    t = np.tanh(beta * v + delta * sign_x)
    one = np.ones_like(v)
    if with_current:
        return np.column_stack([v, i * v, x, i * x, t, i * t, one, i])
    return np.column_stack([v, x, t, one])


def fit_tanh(loops: Sequence[Loop], starts: int = 3) -> TanhDamper:
    """Identify the hyperbolic-tangent model (docs/model.md 4.4) from force loops.

    ``F = c v + k x + alpha tanh(beta v + delta sign(x)) + f0`` with ``c, k, alpha, f0`` linear in
    current (``p = p_a + p_b i``; with one distinct current the ``_b`` terms are 0) and
    ``beta`` (s/m), ``delta`` (-) constant. Variable projection: the 8 (or 4) linear
    coefficients by linear least squares inside :func:`scipy.optimize.least_squares` over
    ``(log beta, delta)``, started from the best ``starts`` points of a coarse grid; bounds
    ``beta |v|_max`` in [0.01, 1e4] and ``delta`` in [-20, 20].
    """
    loops = check_loops(loops)
    starts = check_int("starts", starts, 1)
    x, v, f, i = stack_loops(loops)
    # the model's sign(x), blended over its branch_blend_m (TanhDamper)
    sign_x = 2.0 * branch_weights(np.ascontiguousarray(x), TanhDamper.branch_blend_m) - 1.0
    with_current = np.unique(i).size > 1
    v_ref = velocity_scale(loops)
    lb = np.array([math.log(0.01 / v_ref), -20.0])
    ub = np.array([math.log(1e4 / v_ref), 20.0])

    def residual(p: np.ndarray) -> np.ndarray:
        phi = _tanh_design(sign_x, v, i, x, math.exp(p[0]), p[1], with_current)
        return lstsq(phi, f)[1]

    grid = [
        np.array([math.log(s / v_ref), dl])
        for s in (0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0)
        for dl in (-1.0, 0.0, 0.5, 1.0, 2.0)
    ]
    best = multistart_least_squares(residual, grid, lb, ub, starts)
    beta, delta = math.exp(best.x[0]), float(best.x[1])
    coef, _ = lstsq(_tanh_design(sign_x, v, i, x, beta, delta, with_current), f)
    if not with_current:
        coef = np.array([coef[0], 0.0, coef[1], 0.0, coef[2], 0.0, coef[3], 0.0])
    names = ("c_a", "c_b", "k_a", "k_b", "alpha_a", "alpha_b", "f0_a", "f0_b")
    values = {n: float(c) for n, c in zip(names, coef)}
    return TanhDamper(beta=beta, delta=delta, max_current_a=max(1.5, float(np.max(i))), **values)
