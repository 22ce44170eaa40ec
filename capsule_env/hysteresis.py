"""Closed-form update of the Bouc-Wen hysteretic variable for ``n = 2``.

The Bouc-Wen evolution ``z' = -gamma |w| z |z| - beta w z^2 + A w`` (``w`` the rate of the
deformation ``u`` that drives it) is rate independent: written against the path length of ``u``
it is a Riccati equation with a closed-form solution. Advancing ``z`` over a deformation
increment ``du`` with that solution is exact for monotone ``u`` and unconditionally stable,
which removes the stiffness that makes explicit Runge-Kutta blow up on the Spencer damper
(MODEL.md 4.1: RK4 diverges at a 5e-4 s step; the saturation eigenvalue grows with ``|w|``).

With ``s = sign(du)``, ``m = |du|`` and ``q = s z``::

    dq/dm = A - (gamma + beta) q^2        while q >= 0   (loading towards saturation)
    dq/dm = A - (beta - gamma) q^2        while q <  0   (unloading, up to q = 0)

Both are solved exactly (tanh, tan or linear forms). Pure functions compiled with numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["hysteresis_update", "hysteresis_rate"]


@njit(cache=True, inline="always")
def _riccati(q0: float, m: float, a_coef: float, p: float) -> float:
    """Solve dq/dm = a_coef - p q^2 from q0 over a path length m >= 0."""
    if p > 0.0:
        r = math.sqrt(a_coef / p)
        t0 = q0 / r
        big_t = math.tanh(math.sqrt(a_coef * p) * m)
        # tanh/coth addition formula: valid for |t0| < 1 and t0 > 1 alike.
        return r * (t0 + big_t) / (1.0 + t0 * big_t)
    if p == 0.0:
        return q0 + a_coef * m
    r = math.sqrt(-a_coef / p)
    return r * math.tan(math.sqrt(-a_coef * p) * m + math.atan(q0 / r))


@njit(cache=True, inline="always")
def _path_to_zero(q0: float, a_coef: float, p: float) -> float:
    """Path length for dq/dm = a_coef - p q^2 to bring q0 < 0 up to 0."""
    if p > 0.0:
        r = math.sqrt(a_coef / p)
        t0 = max(q0 / r, -1.0 + 1e-12)
        return math.atanh(-t0) / math.sqrt(a_coef * p)
    if p == 0.0:
        return -q0 / a_coef
    r = math.sqrt(-a_coef / p)
    return math.atan(-q0 / r) / math.sqrt(-a_coef * p)


@njit(cache=True, inline="always")
def hysteresis_update(z0: float, du: float, a_coef: float, gamma: float, beta: float) -> float:
    """Exact Bouc-Wen (n = 2) hysteretic variable after a monotone deformation increment ``du``.

    Parameters
    ----------
    z0 : hysteretic variable at the start (m, Bouc-Wen's z has units of displacement).
    du : signed deformation increment (m).
    a_coef, gamma, beta : Bouc-Wen A (-), gamma and beta (1/m^2); needs A > 0 and
        gamma >= 0 and gamma + beta > 0 (a bounded loop).
    """
    if du == 0.0:
        return z0
    s = 1.0 if du > 0.0 else -1.0
    m = abs(du)
    q = s * z0
    if q < 0.0:
        m_zero = _path_to_zero(q, a_coef, beta - gamma)
        if m <= m_zero:
            return s * _riccati(q, m, a_coef, beta - gamma)
        m -= m_zero
        q = 0.0
    return s * _riccati(q, m, a_coef, gamma + beta)


@njit(cache=True, inline="always")
def hysteresis_rate(z: float, w: float, a_coef: float, gamma: float, beta: float) -> float:
    """Bouc-Wen rate ``z' = -gamma |w| z |z| - beta w z^2 + A w`` (n = 2)."""
    return -gamma * abs(w) * z * abs(z) - beta * w * z * z + a_coef * w


def saturation_level(a_coef: float, gamma: float, beta: float) -> float:
    """The bound ``|z| -> sqrt(A / (gamma + beta))`` reached under sustained loading."""
    return float(np.sqrt(a_coef / (gamma + beta)))
