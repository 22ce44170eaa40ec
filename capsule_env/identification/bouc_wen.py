"""Identification of the Bouc-Wen MR-damper model (docs/model.md 4.3, n = 2) and its loop simulation.

Least squares of the simulated response over all loops at once. The model has a scale
degeneracy (``z -> s z``, ``A -> s A``, ``gamma, beta -> /s``, ``alpha -> /s`` leave the force
unchanged), removed by fixing ``A = 1``: ``z`` is then in metres and saturates at the yield
displacement ``z_y = 1/sqrt(gamma + beta)``. Variable projection: the force is linear in the
damping, stiffness and ``alpha`` coefficients once ``z_y`` and the loop-shape ratio
``(beta - gamma)/(beta + gamma)`` are fixed.

The response is simulated with the exact closed-form ``n = 2`` hysteresis update
(:func:`capsule_env.dampers.hysteresis.hysteresis_update`) on the loop's stroke samples, linear between
samples (exact for a piecewise-monotone stroke, no ODE solver), from ``z = 0`` over one
preceding period of the stroke, so that the fitted part is the steady response
(:class:`BoucWenSequences`, also used by
:func:`~capsule_env.identification.predict.predict_force`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from capsule_env.dampers import BoucWenDamper
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.identification.least_squares import lstsq, multistart_least_squares
from capsule_env.identification.loops import (
    Loop,
    check_int,
    check_loops,
    stack_loops,
    warm_sequence,
)

__all__ = ["BoucWenSequences", "fit_bouc_wen"]


@njit(cache=True)
def _bouc_wen_z(
    x: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    a_coef: float,
    gamma: float,
    beta: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - numba
    """Hysteretic variable along each segment ``x[starts[s]:ends[s]]``, from z = 0 (exact)."""
    for s in range(starts.shape[0]):
        z = 0.0
        prev = x[starts[s]]
        for k in range(starts[s], ends[s]):
            z = hysteresis_update(z, x[k] - prev, a_coef, gamma, beta)
            prev = x[k]
            out[k] = z


class BoucWenSequences:
    """Concatenated warm-up + loop strokes of several loops, for fast repeated simulation.

    Each loop is preceded by its warm-up period
    (:func:`~capsule_env.identification.loops.warm_sequence`); :meth:`z` simulates every
    sequence from ``z = 0`` and returns the hysteretic variable at the loops' own samples only.
    """

    def __init__(self, loops: Sequence[Loop]) -> None:
        parts, starts, ends, scored = [], [], [], []
        offset = 0
        for loop in loops:
            _, x2, _, n_warm = warm_sequence(loop)
            parts.append(x2)
            starts.append(offset)
            ends.append(offset + x2.size)
            scored.append(np.arange(offset + n_warm, offset + x2.size))
            offset += x2.size
        self.x = np.ascontiguousarray(np.concatenate(parts))
        self.starts = np.asarray(starts, dtype=np.int64)
        self.ends = np.asarray(ends, dtype=np.int64)
        self.scored = np.concatenate(scored)
        self._out = np.zeros_like(self.x)

    def z(self, a_coef: float, gamma: float, beta: float) -> np.ndarray:
        """Hysteretic variable (m when A = 1) at the scored samples of every loop, in order."""
        _bouc_wen_z(self.x, self.starts, self.ends, a_coef, gamma, beta, self._out)
        return self._out[self.scored]


def _bw_shape(log_zy: float, ratio: float) -> tuple[float, float]:
    """``(gamma, beta)`` (1/m^2) for A = 1 from the yield displacement and the shape ratio."""
    s = math.exp(-2.0 * log_zy)  # gamma + beta = 1 / z_y^2
    return 0.5 * (1.0 - ratio) * s, 0.5 * (1.0 + ratio) * s


def fit_bouc_wen(loops: Sequence[Loop], starts: int = 3) -> BoucWenDamper:
    """Identify the Bouc-Wen model (docs/model.md 4.3, n = 2, A = 1) from force loops.

    ``F = c0 v + k0 (x - x0) + alpha z`` with ``alpha = alpha_a + alpha_b i``,
    ``c0 = c0a + c0b i``; ``z' = -gamma |v| z |z| - beta v z^2 + v``. With ``A = 1`` fixed (the
    model's scale degeneracy), the shape is set by the yield displacement
    ``z_y = 1/sqrt(gamma + beta)`` (m) and the ratio ``r = (beta - gamma)/(beta + gamma)`` in
    (-1, 1). For fixed ``(z_y, r)`` the force is linear in ``c0a, c0b, alpha_a, alpha_b, k0``
    and the offset ``-k0 x0``, solved by bounded linear least squares (the five coefficients
    >= 0); :func:`scipy.optimize.least_squares` searches ``(log z_y, r)`` from the best
    ``starts`` points of a coarse grid, within ``z_y`` in [1e-5, 10] x max|x| and ``r`` in
    [-0.999, 0.999]. The response is simulated exactly over all loops at once (warm-up of one
    period from ``z = 0``, see :func:`~capsule_env.identification.predict.predict_force`).
    ``x0`` is fitted when the stiffness ``k0 > 0`` carries a plausible offset
    (``|x0| <= max|x|``), else fixed at 0.

    On a Spencer-type damper the optimum tends to the near-Bingham limit (small ``z_y``, ``r``
    at its lower bound): a plain Bouc-Wen element cannot follow the low-velocity roll-off that
    Spencer's series dashpot produces, which is why its error grows with current.
    """
    loops = check_loops(loops)
    starts = check_int("starts", starts, 1)
    seq = BoucWenSequences(loops)
    x, v, f, i = stack_loops(loops)
    with_current = np.unique(i).size > 1
    x_ref = max(float(np.max(np.abs(lp.stroke_m))) for lp in loops)
    if not x_ref > 0.0:
        raise ValueError("the loops have zero stroke everywhere; nothing to identify")

    def design(p: np.ndarray, with_offset: bool) -> np.ndarray:
        z = seq.z(1.0, *_bw_shape(p[0], p[1]))
        cols = [v, i * v, z, i * z, x] if with_current else [v, z, x]
        if with_offset:
            cols.append(np.ones_like(v))
        return np.column_stack(cols)

    def solve(phi: np.ndarray, with_offset: bool) -> tuple[np.ndarray, np.ndarray]:
        lower = np.zeros(phi.shape[1])
        if with_offset:
            lower[-1] = -np.inf
        return lstsq(phi, f, lower)

    def fit(with_offset: bool) -> tuple[np.ndarray, np.ndarray, float]:
        def residual(p: np.ndarray) -> np.ndarray:
            return solve(design(p, with_offset), with_offset)[1]

        grid = [
            np.array([math.log(s * x_ref), r])
            for s in (0.003, 0.01, 0.03, 0.1, 0.3, 1.0)
            for r in (-0.5, 0.0, 0.5)
        ]
        lb = np.array([math.log(1e-5 * x_ref), -0.999])
        ub = np.array([math.log(10.0 * x_ref), 0.999])
        best = multistart_least_squares(residual, grid, lb, ub, starts)
        coef, res = solve(design(best.x, with_offset), with_offset)
        return best.x, coef, float(np.sum(res**2))

    p, coef, _ = fit(with_offset=True)
    k0 = coef[-2]
    x0 = -coef[-1] / k0 if k0 > 0.0 else math.inf
    if not abs(x0) <= x_ref:
        # No stiffness to carry a force offset (or an implausible one): fix x0 = 0.
        p, coef, _ = fit(with_offset=False)
        x0 = 0.0
        coef = np.append(coef, 0.0)
    if with_current:
        c0a, c0b, alpha_a, alpha_b, k0 = coef[:5]
    else:
        (c0a, alpha_a, k0), c0b, alpha_b = coef[:3], 0.0, 0.0
    gamma, beta = _bw_shape(p[0], p[1])
    return BoucWenDamper(
        c0a=float(c0a),
        c0b=float(c0b),
        alpha_a=float(alpha_a),
        alpha_b=float(alpha_b),
        k0=float(k0),
        x0=float(x0),
        gamma=gamma,
        beta=beta,
        a_coef=1.0,
        max_current_a=max(1.5, float(np.max(i))),
    )
