"""Least-squares building blocks shared by the model fitters (variable projection).

Each forward model is linear in most of its coefficients once a few shape parameters are fixed
(Bi-exponential ``d``; tanh ``beta, delta``; Bouc-Wen ``z_y`` and the loop-shape ratio), so
every fitter is an outer search over the shape parameters wrapped around an inner linear
least-squares solve. The result is the joint least-squares optimum of all coefficients (within
the stated bounds), found in a fraction of a second and far less prone to local minima than a
search over all coefficients at once. This module holds the pieces: the inner solve
(:func:`lstsq`, optionally bounded below), the outer multistart search
(:func:`multistart_least_squares`), a straight line in current (:func:`line_fit`), the stroke
rate scale that sets search ranges (:func:`velocity_scale`) and :func:`rmse`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy import linalg, optimize

from capsule_env.identification.loops import Loop

__all__ = ["line_fit", "lstsq", "multistart_least_squares", "rmse", "velocity_scale"]


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root-mean-square difference of two equal-length arrays (same unit as the inputs)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    return float(np.sqrt(np.mean((a - b) ** 2)))


def lstsq(
    phi: np.ndarray, f: np.ndarray, lower: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients and residual of ``phi @ c ~ f``, optionally ``c >= lower``.

    The columns are normalised and the problem reduced to its small triangular form through
    the Cholesky factor of the Gram matrix (fast for tall ``phi``); a nearly rank-deficient
    ``phi`` falls back to the SVD (or, with bounds, the full bounded solver).
    """
    scale = np.linalg.norm(phi, axis=0)
    scale[scale == 0.0] = 1.0
    a = phi / scale
    gram = a.T @ a
    rhs = a.T @ f
    try:
        r = np.linalg.cholesky(gram).T  # upper triangular, gram = r.T r
        well_posed = float(np.min(np.abs(np.diag(r)))) > 1e-5
    except np.linalg.LinAlgError:
        well_posed = False
    if lower is None:
        if well_posed:
            coef = linalg.cho_solve((r, False), rhs)
        else:
            coef = np.linalg.lstsq(a, f, rcond=None)[0]
    else:
        bounds = (np.asarray(lower, float), np.full(phi.shape[1], np.inf))
        if well_posed:
            y = linalg.solve_triangular(r, rhs, trans="T")
            coef = optimize.lsq_linear(r, y, bounds=bounds, method="bvls").x
        else:
            coef = optimize.lsq_linear(a, f, bounds=bounds, method="bvls").x
    coef = coef / scale
    return coef, f - phi @ coef


def multistart_least_squares(
    residual: Callable[[np.ndarray], np.ndarray],
    grid: Sequence[np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    starts: int,
) -> optimize.OptimizeResult:
    """Minimise ``sum(residual(p)**2)`` within ``[lower, upper]`` from the best grid points.

    ``residual`` is evaluated at every point of the coarse ``grid``; from the ``starts`` best
    points :func:`scipy.optimize.least_squares` runs (tolerances 1e-10), and the solution of
    lowest cost is returned (the first one on ties).
    """
    costs = [float(np.sum(residual(p) ** 2)) for p in grid]
    best = None
    for k in np.argsort(costs)[:starts]:
        sol = optimize.least_squares(residual, grid[k], bounds=(lower, upper),
                                     xtol=1e-10, ftol=1e-10, gtol=1e-10)  # fmt: skip
        if best is None or sol.cost < best.cost:
            best = sol
    return best


def velocity_scale(loops: Sequence[Loop]) -> float:
    """The largest stroke-rate magnitude over the loops (m/s), which sets the fitters' search
    ranges; ``ValueError`` when it is zero."""
    v_ref = max(float(np.max(np.abs(lp.stroke_rate_m_s))) for lp in loops)
    if not v_ref > 0.0:
        raise ValueError("the loops have zero stroke rate everywhere; nothing to identify")
    return v_ref


def line_fit(currents: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """``(p0, p1)`` of the least-squares line ``p0 + p1 i`` (``p1 = 0`` for one current)."""
    if currents.size == 1:
        return float(values[0]), 0.0
    p1, p0 = np.polyfit(currents, values, 1)
    return float(p0), float(p1)
