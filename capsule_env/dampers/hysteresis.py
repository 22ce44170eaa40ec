"""Closed-form update of the Bouc-Wen hysteretic variable for ``n = 2``.

The Bouc-Wen evolution ``z' = -gamma |w| z |z| - beta w z^2 + A w`` (``w`` the rate of the
deformation ``u`` that drives it) is rate independent: written against the path length of ``u``
it is a Riccati equation with a closed-form solution. Advancing ``z`` over a deformation
increment ``du`` with that solution is exact for monotone ``u`` and unconditionally stable,
which removes the stiffness that makes explicit Runge-Kutta blow up on the Spencer damper
(docs/model.md 4.8: plain RK4 fails above about 2e-4 s; the saturation eigenvalue grows
with ``|w|``).

With ``s = sign(du)``, ``m = |du|`` and ``q = s z``::

    dq/dm = A - (gamma + beta) q^2        while q >= 0   (loading towards saturation)
    dq/dm = A - (beta - gamma) q^2        while q <  0   (unloading, up to q = 0)

Both are solved exactly (tanh, tan or linear forms). Pure functions compiled with numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from capsule_env._fastmath import BORROWED, FAST, fast_exp, fast_log

__all__ = [
    "hysteresis_update",
    "hysteresis_rate",
    "riccati_constants",
    "hysteresis_update_fast",
    "saturation_level",
]


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


# ------------------------------------------------------------------ branch-free form
#: Columns of :func:`riccati_constants`: ``A, 1/A`` and ``r = sqrt(A/p)``, ``1/r``, ``k = sqrt(A
#: p)`` of the loading branch (``p = gamma + beta``), then ``r, 1/r, k, 1/k`` of the unloading
#: branch (``p = beta - gamma``; 1 where it is not positive).
RICCATI_CONSTANT_NAMES = ("a", "inv_a", "r_load", "inv_r_load", "k_load", "r_unload",
                          "inv_r_unload", "k_unload", "inv_k_unload")  # fmt: skip
N_RICCATI_CONSTANTS = len(RICCATI_CONSTANT_NAMES)


def riccati_constants(a_coef: np.ndarray, gamma: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """The constants :func:`hysteresis_update_fast` reads, one row per parameter set
    (:data:`RICCATI_CONSTANT_NAMES`), computed once rather than every step."""
    a, gamma, beta = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (a_coef, gamma, beta))
    load = gamma + beta
    unload = np.where(beta - gamma > 0.0, beta - gamma, 1.0)
    r_l, r_u = np.sqrt(a / load), np.sqrt(a / unload)
    k_l, k_u = np.sqrt(a * load), np.sqrt(a * unload)
    return np.stack((a, 1.0 / a, r_l, 1.0 / r_l, k_l, r_u, 1.0 / r_u, k_u, 1.0 / k_u), axis=1)


@njit(**FAST, **BORROWED)
def hysteresis_update_fast(z0, du, a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u, k_u, inv_k_u,
                           tanh_unload):  # fmt: skip
    """:func:`hysteresis_update` without branches or library calls (so that a loop over
    vehicles vectorises), for ``A > 0``, ``gamma + beta > 0`` and an unloading coefficient
    ``beta - gamma`` that is 0 (``tanh_unload`` False: linear) or positive (True). The constants
    are a row of :func:`riccati_constants`; increments are written as
    ``q + r T (1 - t0^2) / (1 + t0 T)`` (``T = tanh(k m)``, ``t0 = q / r``), so that a zero
    increment returns ``z0`` exactly, with T's own division folded into that one."""
    s = 1.0 if du >= 0.0 else -1.0
    m = abs(du)
    q = s * z0
    if tanh_unload:
        t0u = q * inv_r_u
        eu = fast_exp(-2.0 * k_u * m)  # tanh(k_u m) = (1 - eu) / (1 + eu)
        q_unload = q + r_u * (1.0 - t0u * t0u) * (1.0 - eu) / ((1.0 + eu) + t0u * (1.0 - eu))
        xz = min(max(-t0u, 0.0), 1.0 - 1e-12)
        m_zero = 0.5 * fast_log((1.0 + xz) / (1.0 - xz)) * inv_k_u
    else:
        q_unload = q + a * m
        m_zero = -q * inv_a
    unloading = q < 0.0
    stays = unloading and m <= m_zero
    q_start = 0.0 if unloading else q
    m_load = max(m - m_zero, 0.0) if unloading else m
    t0 = q_start * inv_r_l
    el = fast_exp(-2.0 * k_l * m_load)  # tanh(k_l m) = (1 - el) / (1 + el): one division
    q_load = q_start + r_l * (1.0 - t0 * t0) * (1.0 - el) / ((1.0 + el) + t0 * (1.0 - el))
    return s * (q_unload if stays else q_load)
