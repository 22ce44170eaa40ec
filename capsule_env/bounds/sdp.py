"""The same relaxation solved as a semidefinite program (Shor), for cross-checks on tiny
episodes: an independent route to the bound of :mod:`.dual` (the ``bounds`` extra: Clarabel).

Variables: the moment matrix ``X`` of ``u = (f, c, 1)`` (``2N + 1`` square, ``X >= 0``,
``X[-1, -1] = 1``); objective ``tr(P X)`` with ``P`` the ride metric's matrix; constraints
``tr(E_s^T M_k E_s X) >= 0``, ``E_s`` mapping ``u`` to evaluation ``s``'s ``(d, c, v, x, 1)``.
Its optimum is the best bound the Lagrangian dual can give (strong duality holds for this
conic program when both sides are strictly feasible); its dual multipliers of the constraints
are multipliers for :meth:`~capsule_env.bounds.dual.DualProblem.evaluate`. Dense, and Clarabel's
factorisation grows fast: 36 force evaluations (0.02 s of the ``sim`` setting) solve in about
20 s; 90 (0.05 s) took more than 14 GB before it was stopped; refused beyond ``max_forces``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from capsule_env.bounds.dual import DualProblem

__all__ = ["ShorSolution", "solve_shor"]


class ShorSolution(NamedTuple):
    """``value``: the SDP optimum ((m/s^2)^2); ``multipliers``: (N, K); ``status``."""

    value: float
    multipliers: np.ndarray
    status: str


def _svec(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clarabel's triangle order (upper triangle, column by column) and the sqrt(2) scaling."""
    rows, cols = np.triu_indices(n)
    order = np.lexsort((rows, cols))
    rows, cols = rows[order], cols[order]
    return rows, cols, np.where(rows == cols, 1.0, np.sqrt(2.0))


def _lift(problem: DualProblem, s: int) -> np.ndarray:
    """``E_s`` (5, 2N + 1): ``u = (f, c, 1)`` to ``(d, c, v, x, 1)`` of evaluation ``s``."""
    n = problem.n
    e = np.zeros((5, 2 * n + 1))
    e[0, s], e[0, n + s], e[1, n + s] = 1.0, -1.0, 1.0
    e[2, :n], e[2, -1] = problem.a_aug[s, :-1], problem.a_aug[s, -1]
    e[3, :n], e[3, -1] = problem.b_aug[s, :-1], problem.b_aug[s, -1]
    e[4, -1] = 1.0
    return e


def solve_shor(problem: DualProblem, max_forces: int = 60) -> ShorSolution:
    """Solve the Shor SDP of ``problem`` with Clarabel; ValueError beyond ``max_forces``."""
    import clarabel

    n, k = problem.n, problem.mats.shape[0]
    if n > max_forces:
        raise ValueError(f"solve_shor: {n} force evaluations, at most {max_forces} (dense SDP)")
    size = 2 * n + 1
    rows, cols, scale = _svec(size)
    p_full = np.zeros((size, size))
    keep = np.r_[np.arange(n), size - 1]
    p_full[np.ix_(keep, keep)] = problem.p_j
    ineq = np.empty((n * k, rows.size))
    for s in range(n):
        e = _lift(problem, s)
        for j in range(k):
            ineq[s * k + j] = -(e.T @ problem.mats[j] @ e)[rows, cols] * scale
    last = np.zeros(rows.size)
    last[-1] = 1.0  # (size-1, size-1) is the last entry of the column order
    a = sp.vstack([sp.csr_matrix(last), sp.csr_matrix(ineq), -sp.identity(rows.size)]).tocsc()
    b = np.r_[1.0, np.zeros(n * k + rows.size)]
    cones = [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(n * k),
             clarabel.PSDTriangleConeT(size)]  # fmt: skip
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    q = p_full[rows, cols] * scale
    sol = clarabel.DefaultSolver(sp.csc_matrix((rows.size, rows.size)), q, a, b, cones,
                                 settings).solve()  # fmt: skip
    z = np.asarray(sol.z)[1 : 1 + n * k].reshape(n, k)
    return ShorSolution(float(sol.obj_val), np.maximum(z, 0.0), str(sol.status))
