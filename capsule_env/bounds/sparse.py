"""The lifted plant substep by substep: the same RK4 arithmetic as :mod:`.lifted`, with the
state at each substep's start a variable, so that every relation is sparse (the branch and
bound's QPs, :mod:`.branch`, solve in this form and certify in the dense one).

Variables ``X_k`` (4 each: body and bogie displacement and velocity at the start of substep
``k``, ``k = 0 .. K``, ``K = T n_sub``) and the forces ``F`` (N). Substep ``k`` maps ``X_k``
and its four stage forces to ``X_{k+1}``; each stage's stroke rate is affine in ``X_k`` and
the stage forces before it; each step's output force is evaluated at ``X`` after the step and
its sampled body acceleration is affine in that ``X`` and that force. The coefficients come
from :func:`~capsule_env.bounds.lifted._substep` and :func:`~capsule_env.bounds.lifted._rates`
applied to a local basis, with the inputs the lift recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from capsule_env.bounds.lifted import LiftedEpisode, _rates, _substep

__all__ = ["SparseLift", "sparse_lift"]


@dataclass(frozen=True)
class SparseLift:
    """``dyn [X; F] = dyn_rhs`` (the start state and every substep), ``v = v_x X + v_f F +
    v_c`` (N), ``acc = acc_x X + acc_f F + acc_c`` (T), the strokes ``x = x_x X + x_f F +
    x_c`` (N); forces in N, ``X`` flattened (4 (K + 1),)."""

    n_x: int
    dyn: sp.csr_matrix
    dyn_rhs: np.ndarray
    v_x: sp.csr_matrix
    v_f: sp.csr_matrix
    v_c: np.ndarray
    acc_x: sp.csr_matrix
    acc_f: sp.csr_matrix
    acc_c: np.ndarray
    x_x: sp.csr_matrix
    x_f: sp.csr_matrix
    x_c: np.ndarray


class _Rows:
    """COO triplets of a sparse matrix."""

    def __init__(self) -> None:
        self.r: list[int] = []
        self.c: list[int] = []
        self.v: list[float] = []

    def add(self, row: int, cols: np.ndarray, vals: np.ndarray) -> None:
        self.r.extend([row] * len(cols))
        self.c.extend(int(c) for c in cols)
        self.v.extend(float(v) for v in vals)

    def matrix(self, shape: tuple[int, int]) -> sp.csr_matrix:
        return sp.csr_matrix((self.v, (self.r, self.c)), shape=shape)


def sparse_lift(lifted: LiftedEpisode) -> SparseLift:
    """The :class:`SparseLift` of a lifted episode (one from :func:`~.lifted.lift_episode`)."""
    if lifted.substep_inputs is None or lifted.vehicles is None or lifted.state0 is None:
        raise ValueError("sparse_lift: the lifted episode has no recorded substep inputs")
    n, n_sub = lifted.n_forces, lifted.n_sub
    t_steps, per = lifted.acc_rows.shape[0], 4 * n_sub + 1
    n_k = t_steps * n_sub
    n_x = 4 * (n_k + 1)
    h = lifted.dt_s / n_sub
    dx, df, vx, vf, ax, af, xx, xf = (_Rows() for _ in range(8))
    rhs, v_c, acc_c, x_c = np.zeros(n_x), np.zeros(n), np.zeros(t_steps), np.zeros(n)
    for i in range(4):
        dx.add(i, np.array([i]), np.array([1.0]))
    rhs[:4] = lifted.state0
    basis = np.zeros((4, 9))
    basis[:, :4] = np.eye(4)
    for k, (zg0, zgh, zg1, zg_rate, step) in enumerate(lifted.substep_inputs):
        veh = lifted.vehicles[int(step)]
        col = int(step) * per + (k - int(step) * n_sub) * 4
        v_loc, x_loc = np.zeros((8, 9)), np.zeros((8, 9))
        new, _ = _substep(basis, 4, (zg0, zgh, zg1), zg_rate, h, veh, v_loc, x_loc)
        xs, forces = 4 * k + np.arange(4), col + np.arange(4)
        for j in range(4):
            vx.add(col + j, xs, v_loc[4 + j, :4])
            vf.add(col + j, forces, v_loc[4 + j, 4:8])
            v_c[col + j] = v_loc[4 + j, 8]
            xx.add(col + j, xs, x_loc[4 + j, :4])
            xf.add(col + j, forces, x_loc[4 + j, 4:8])
            x_c[col + j] = x_loc[4 + j, 8]
        for i in range(4):  # X_{k+1} - Phi X_k - Psi F = phi
            row = 4 * (k + 1) + i
            dx.add(row, np.r_[4 * (k + 1) + i, xs], np.r_[1.0, -new[i, :4]])
            df.add(row, forces, -new[i, 4:8])
            rhs[row] = new[i, 8]
    out_basis = np.zeros((4, 6))
    out_basis[:, :4] = np.eye(4)
    assert lifted.output_inputs is not None
    for step, (zg, zg_rate) in enumerate(lifted.output_inputs):
        col, xs = step * per + 4 * n_sub, 4 * ((step + 1) * n_sub) + np.arange(4)
        vx.add(col, xs[[1, 3]], np.array([1.0, -1.0]))
        xx.add(col, xs[[0, 2]], np.array([1.0, -1.0]))
        acc = _rates(out_basis, 4, zg, zg_rate, lifted.vehicles[step])[1]
        ax.add(step, xs, acc[:4])
        af.add(step, np.array([col]), acc[4:5])
        acc_c[step] = acc[5]
    dyn = sp.hstack([dx.matrix((n_x, n_x)), df.matrix((n_x, n))]).tocsr()
    return SparseLift(n_x, dyn, rhs, vx.matrix((n, n_x)), vf.matrix((n, n)), v_c,
                      ax.matrix((t_steps, n_x)), af.matrix((t_steps, n)), acc_c,
                      xx.matrix((n, n_x)), xf.matrix((n, n)), x_c)  # fmt: skip
