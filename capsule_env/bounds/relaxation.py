"""Quadratic constraints that every force the plant's damper can produce satisfies.

Each constraint is a quadratic form ``q(xi) = xi^T M xi >= 0`` of one force evaluation's local
variables ``xi = (d, c, v, x, 1)``: the force ``F = F0 (d + c)`` split into a rate part ``D =
F0 d`` and an offset ``C = F0 c`` (``F0`` :data:`FORCE_SCALE_N`), the stroke rate ``v`` (m/s)
and the stroke ``x`` (m) it is evaluated at. docs/fair-comparison.md derives each one from the
model's formula (docs/model.md 4.5, 4.6); :func:`model_force_parts` is that formula in numpy,
for the tests that replay rollouts through the constraints.

Bi-exponential model (the ``sim`` plant), with the branch blend ``w(x)`` in [0, 1]::

    F = a S_d(v) + b v + c,   S_d(v) = sign(v) (1 - exp(-d |v|)),
    a, b, c, d = lower + w (upper - lower) of (a0 + a1 i, b0 + b1 i, c0 + c1 i, d),  i in [0, i_max]

``D = a S_d(v) + b v``, ``C = c``. Over every current and blend weight ``a`` lies in
``[a_lo, a_hi]``, ``b`` in ``[b_lo, b_hi]``, ``d`` in ``[d_lo, d_hi]``, ``c`` in ``[c_lo, c_hi]``
(the extremes of a bilinear function of ``(i, w)``: at the corners). The passive linear damper (``F =
c_lin v``) is the special case ``a = 0``, ``b = c_lin``, ``c = 0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from capsule_env.dampers.registry import model_of_code

__all__ = [
    "FORCE_SCALE_N",
    "MAGNITUDE_SPLITS",
    "DamperEnvelope",
    "damper_envelope",
    "constraint_matrices",
    "constraint_names",
    "constraint_values",
    "model_force_parts",
]

#: Forces enter the bound in kN (the local variables' scale).
FORCE_SCALE_N = 1000.0
#: The splits ``e`` of ``|E| <= a_hi + db |v|`` into ``E^2 <= (1 + 1/e) a_hi^2 + (1 + e) db^2 v^2``.
MAGNITUDE_SPLITS = (0.1, 1.0, 10.0)
#: The slopes ``m`` (N s/m) of the offset sectors ``(D - b_lo v)(m v - D) + delta_m >= 0``.
OFFSET_SECTOR_SLOPES = (3e4, 6e4, 1.2e5, 2.5e5)
#: Cells of the grid over which ``delta_m`` is bounded (:func:`offset_sector_constant`).
DELTA_CELLS = 20000
#: Relative slack on the sector's upper slope and absolute slack (kN^2) on every constraint:
#: covers the kernel's fast exp (within 2 ulp of exp) and the rounding of ``v`` itself.
SLOPE_SLACK_REL = 1e-9
ABS_SLACK_KN2 = 1e-12


@dataclass(frozen=True)
class DamperEnvelope:
    """The ranges of one damper's parameters over every current and blend weight (SI units)."""

    a_lo: float
    a_hi: float
    b_lo: float
    b_hi: float
    d_hi: float
    c_lo: float
    c_hi: float
    blend_m: float
    offset_follows_stroke: bool = True

    @property
    def slope_hi(self) -> float:
        """The steepest ``D / v``: ``a_hi d_hi + b_hi`` (``|S_d(v)| <= d |v|``)."""
        return (self.a_hi * self.d_hi + self.b_hi) * (1.0 + SLOPE_SLACK_REL)


def _corners(p: np.ndarray, lo: int, up: int, k0: int, k1: int, i_max: float) -> np.ndarray:
    """``(p0 + p1 i)`` of both branches at ``i = 0`` and ``i_max``: the corners of ``(i, w)``."""
    return np.array([p[o + k0] + p[o + k1] * i for o in (lo, up) for i in (0.0, i_max)])


def damper_envelope(code: int, params: np.ndarray) -> DamperEnvelope:
    """The :class:`DamperEnvelope` of a damper row; ValueError for a model with no relaxation."""
    name = model_of_code(code).name
    p = np.asarray(params, dtype=float)
    if name == "bi_exponential":
        from capsule_env.dampers import bi_exponential as be
        from capsule_env.dampers.base import BRANCH_BLEND, I_MAX

        i_max = float(p[I_MAX])
        lo, up = be.LOWER, be.UPPER
        a = _corners(p, lo, up, be.A0, be.A1, i_max)
        b = _corners(p, lo, up, be.B0, be.B1, i_max)
        c = _corners(p, lo, up, be.C0, be.C1, i_max)
        d_hi = max(p[lo + be.D], p[up + be.D])
        if a.min() < 0.0 or b.min() < 0.0:
            raise ValueError("certified_floor: a Bi-exponential damper with a negative yield "
                             "force or slope at some current has no sector relaxation")  # fmt: skip
        # outside the blend the offset is one branch's: does it have the stroke's sign?
        follows = bool(c[2:].min() > 0.0 and c[:2].max() < 0.0)
        return DamperEnvelope(a.min(), a.max(), b.min(), b.max(), d_hi, c.min(), c.max(),
                              float(p[BRANCH_BLEND]), follows)  # fmt: skip
    if name == "passive":
        slope = float(p[0])
        return DamperEnvelope(0.0, 0.0, slope, slope, 0.0, 0.0, 0.0, 0.0)
    raise ValueError(
        f"certified_floor: no relaxation for the plant damper {name!r}; supported: "
        "bi_exponential (the sim setting), passive"
    )


def constraint_names() -> tuple[str, ...]:
    """The constraints of :func:`constraint_matrices`, in order."""
    mags = tuple(f"rate_part_magnitude_e{e:g}" for e in MAGNITUDE_SPLITS)
    cones = tuple(f"offset_sector_{m:g}" for m in OFFSET_SECTOR_SLOPES)
    return ("sector", "rate_part_above_max_slope", *mags, "offset_band", "offset_sign", *cones)


def offset_sector_constant(env: DamperEnvelope, slope: float) -> float:
    """An upper bound (N^2) on ``(D - b_lo v)(D - m v)`` over every rate part ``D`` the damper
    produces, ``m = slope``: for ``v > 0`` (odd symmetry gives ``v < 0``), ``D`` lies in
    ``[b_lo v, U(v)]``, ``U = a_hi (1 - exp(-d_hi v)) + b_hi v`` increasing, and the product,
    convex in ``D``, is largest at an end: 0 at ``b_lo v``. On a cell ``[v0, v1]`` of a grid
    over ``[0, a_hi / (m - b_hi)]`` (beyond, ``U < m v``) it is at most ``(U(v1) - b_lo v0)
    (U(v1) - m v0)`` where both factors are positive (a rigorous bound, not a sample)."""
    if env.a_hi == 0.0 or slope <= env.b_hi:
        return 0.0 if env.a_hi == 0.0 else math.inf
    v = np.linspace(0.0, env.a_hi / (slope - env.b_hi), DELTA_CELLS + 1)
    upper = env.a_hi * (1.0 - np.exp(-env.d_hi * v)) + env.b_hi * v
    first = upper[1:] - env.b_lo * v[:-1]
    second = upper[1:] - slope * v[:-1]
    return float(np.max(np.where(second > 0.0, first * second, 0.0)) * (1.0 + 1e-9))


def _quad(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The symmetric 5x5 matrix of ``(u . xi)(w . xi)``."""
    m = np.outer(u, w)
    return 0.5 * (m + m.T)


def constraint_matrices(env: DamperEnvelope) -> np.ndarray:
    """(K, 5, 5) matrices ``M_k``, ``xi^T M_k xi >= 0`` for every force the damper can produce
    (``xi = (d, c, v, x, 1)``, forces in kN); order :func:`constraint_names`."""
    f0 = FORCE_SCALE_N
    lo, hi = env.b_lo / f0, env.slope_hi / f0
    a_hi, db = env.a_hi / f0, (env.b_hi - env.b_lo) / f0
    b_hi = env.b_hi / f0
    e_d, e_v, e_1 = np.eye(5)[0], np.eye(5)[2], np.eye(5)[4]
    e_c, e_x = np.eye(5)[1], np.eye(5)[3]
    out = [_quad(e_d - lo * e_v, hi * e_v - e_d)]  # (D - b_lo v)(s_hi v - D) >= 0
    # (D - b_hi v)^2 <= a_hi^2 + db^2 v^2
    out.append(a_hi**2 * _quad(e_1, e_1) + db**2 * _quad(e_v, e_v)
               - _quad(e_d - b_hi * e_v, e_d - b_hi * e_v))  # fmt: skip
    for e in MAGNITUDE_SPLITS:  # (D - b_lo v)^2 <= (1 + 1/e) a_hi^2 + (1 + e) db^2 v^2
        out.append((1.0 + 1.0 / e) * a_hi**2 * _quad(e_1, e_1)
                   + (1.0 + e) * db**2 * _quad(e_v, e_v)
                   - _quad(e_d - lo * e_v, e_d - lo * e_v))  # fmt: skip
    c_lo, c_hi = env.c_lo / f0, env.c_hi / f0
    out.append(_quad(e_c - c_lo * e_1, c_hi * e_1 - e_c))  # c_lo <= C <= c_hi
    c_abs = max(abs(c_lo), abs(c_hi))
    sign = _quad(e_c, e_x) + c_abs * env.blend_m * _quad(e_1, e_1)  # C x >= -|c| blend
    out.append(sign if env.offset_follows_stroke else np.zeros((5, 5)))
    for m in OFFSET_SECTOR_SLOPES:  # (D - b_lo v)(m v - D) + delta_m >= 0
        delta = offset_sector_constant(env, m) / f0**2
        out.append(_quad(e_d - lo * e_v, (m / f0) * e_v - e_d) + delta * _quad(e_1, e_1))
    mats = np.array(out)
    mats[:, 4, 4] += ABS_SLACK_KN2
    return mats


def constraint_values(mats: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """``q_k(xi_s)`` for local variables ``xi`` (N, 5): an (N, K) array."""
    return np.einsum("si,kij,sj->sk", xi, mats, xi)


def model_force_parts(
    code: int, params: np.ndarray, x: np.ndarray, v: np.ndarray, i: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(D, C)`` (N) of the damper's force at strokes ``x``, rates ``v``, currents ``i``
    (clipped to ``[0, i_max]`` as the kernel clips them): the model's formula in numpy."""
    name = model_of_code(code).name
    p = np.asarray(params, dtype=float)
    x, v = np.asarray(x, dtype=float), np.asarray(v, dtype=float)
    if name == "passive":
        return p[0] * v, np.zeros_like(v)
    if name != "bi_exponential":
        raise ValueError(f"model_force_parts: no numpy form for {name!r}")
    from capsule_env.dampers import bi_exponential as be
    from capsule_env.dampers.base import BRANCH_BLEND, I_MAX

    i = np.clip(np.asarray(i, dtype=float), 0.0, p[I_MAX])
    s = np.clip(0.5 + 0.5 * x / p[BRANCH_BLEND], 0.0, 1.0)
    w = s * s * (3.0 - 2.0 * s)

    def par(k: int) -> np.ndarray:
        return p[be.LOWER + k] + w * (p[be.UPPER + k] - p[be.LOWER + k])

    sat = np.sign(v) * (1.0 - np.exp(-par(be.D) * np.abs(v)))
    rate = (par(be.A0) + par(be.A1) * i) * sat + (par(be.B0) + par(be.B1) * i) * v
    return rate, par(be.C0) + par(be.C1) * i
