"""The Lagrangian (Shor) dual bound of one lifted episode.

Variables: the forces ``f`` (kN, one per force evaluation of the episode, :mod:`.lifted`) and
each evaluation's offset part ``c`` (kN; the rate part is ``d = f - c``). The ride metric is the
quadratic ``J(f) = |W acc(f)|^2 / T`` (``acc`` affine in ``f``, ``W`` the Wk weighting per FFT
line with the mean removed: :func:`capsule_env.metrics.wk_weighted_rms` squared). Every force
the damper produces satisfies ``q_k(xi_s) >= 0`` (:mod:`.relaxation`). For multipliers
``lam >= 0``::

    g(lam) = min_{f, c}  J(f) - sum_{s, k} lam_{s k} q_k(xi_s(f, c))

is at most ``J`` of every trajectory the plant can run (at the true forces every ``q_k >= 0``)
whenever the minimised quadratic is bounded below, which a Cholesky factorisation with a margin
checks: then ``sqrt(g)`` is a certified floor on the Wk-weighted RMS. The offsets ``c_s`` are
local to their evaluation and are minimised in closed form (a scalar each); what remains is a
dense quadratic in ``f`` (``N + 1`` square) factorised once per evaluation of ``g``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from capsule_env import metrics
from capsule_env.bounds.lifted import LiftedEpisode
from capsule_env.bounds.relaxation import FORCE_SCALE_N

__all__ = ["DualProblem", "DualPoint", "weighting_matrix"]

#: The Cholesky margin, relative to the largest diagonal entry of the Hessian: far above the
#: factorisation's rounding (about ``N eps`` of it), so that a success proves positive definite.
MARGIN_REL = 1e-9
#: The offset's curvature ``N_s[c, c]`` must exceed this (kN^-2 per unit of J).
C_CURVATURE_MIN = 1e-12


def weighting_matrix(n_steps: int, dt_s: float) -> np.ndarray:
    """``W`` (T, T): ``W a`` is the Wk-weighted, mean-removed signal of
    :func:`capsule_env.metrics.wk_weighted_rms` (its RMS is ``|W a| / sqrt(T)``)."""
    weights = np.abs(metrics.wk_weighting(np.fft.rfftfreq(n_steps, dt_s)))
    eye = np.eye(n_steps)
    spectrum = np.fft.rfft(eye - eye.mean(axis=0, keepdims=True), axis=0)
    return np.fft.irfft(spectrum * weights[:, None], n=n_steps, axis=0)


@dataclass(frozen=True)
class DualPoint:
    """``g`` at some multipliers, and what it was minimised at.

    value : g (J units, (m/s^2)^2), ``-inf`` where not positive definite.
    forces_kn : (N,) the minimiser; offsets_kn : (N,); q : (N, K) the constraints there.
    """

    value: float
    forces_kn: np.ndarray
    offsets_kn: np.ndarray
    q: np.ndarray


class DualProblem:
    """``g(lam)`` for one lifted episode and constraint matrices ``mats`` (K, 5, 5).

    ``force_weight`` (per kN^2, >= 0) adds ``force_weight |f|^2`` to ``J`` (a check with a
    known answer: without constraints, ``K = 0``, ``g`` is then the regularised least-squares
    optimum with full preview; the offsets ``c`` are absent when ``K = 0``)."""

    def __init__(self, lifted: LiftedEpisode, mats: np.ndarray, force_weight: float = 0.0) -> None:
        n = lifted.n_forces
        scale = np.ones(n + 1)
        scale[:n] = FORCE_SCALE_N
        self.n, self.mats = n, np.asarray(mats, dtype=float)
        self.a_aug = lifted.v_rows * scale  # v = a_aug @ [f; 1]
        self.b_aug = lifted.x_rows * scale
        n_steps = lifted.acc_rows.shape[0]
        self.wg = weighting_matrix(n_steps, lifted.dt_s) @ (lifted.acc_rows * scale)
        self.p_j = self.wg.T @ self.wg / n_steps
        self.force_weight = float(force_weight)
        self.p_j[np.arange(n), np.arange(n)] += self.force_weight
        self.offsets = self.mats.shape[0] > 0
        self.n_steps = n_steps
        # xi = (d, c, v, x, 1) = T eta with eta = (f, c, v, x, 1), d = f - c
        self.to_xi = np.eye(5)
        self.to_xi[0, 1] = -1.0

    def ride(self, forces_kn: np.ndarray) -> float:
        """``J(f)`` (plus ``force_weight |f|^2``): the mean square of the Wk-weighted body
        acceleration ((m/s^2)^2)."""
        w = self.wg[:, :-1] @ forces_kn + self.wg[:, -1]
        return float(w @ w) / self.n_steps + self.force_weight * float(forces_kn @ forces_kn)

    def local(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per evaluation ``s``: ``N_s = -T^T (sum_k lam_sk M_k) T`` over ``eta`` (N, 5, 5)
        and its Schur complement on ``c`` over ``(f, v, x, 1)`` (N, 4, 4)."""
        q = np.einsum("sk,kij->sij", lam, self.mats)
        big_n = -np.einsum("ai,sab,bj->sij", self.to_xi, q, self.to_xi)
        o = [0, 2, 3, 4]
        if not self.offsets:
            return big_n, big_n[:, o][:, :, o]
        ncc = big_n[:, 1, 1]
        safe = np.where(ncc > C_CURVATURE_MIN, ncc, 1.0)
        col = big_n[:, o, 1]
        schur = big_n[:, o][:, :, o] - col[:, :, None] * col[:, None, :] / safe[:, None, None]
        return big_n, schur

    def assemble(self, schur: np.ndarray) -> np.ndarray:
        """The ``(N + 1)``-square matrix of ``[f; 1]`` of the Lagrangian minimised over ``c``."""
        n, a, b = self.n, self.a_aug, self.b_aug
        h = self.p_j.copy()
        s = schur
        idx = np.arange(n)
        h[idx, idx] += s[:, 0, 0]
        z = s[:, 0, 1, None] * a + s[:, 0, 2, None] * b
        z[idx, n] += s[:, 0, 3]
        h[:n] += z
        h[:, :n] += z.T
        u = np.vstack([a, b])
        v = np.vstack([s[:, 1, 1, None] * a + s[:, 1, 2, None] * b,
                       s[:, 1, 2, None] * a + s[:, 2, 2, None] * b])  # fmt: skip
        h += u.T @ v
        col = a.T @ s[:, 1, 3] + b.T @ s[:, 2, 3]
        h[:, n] += col
        h[n, :] += col
        h[n, n] += s[:, 3, 3].sum()
        return h

    def evaluate(self, lam: np.ndarray) -> DualPoint:
        """``g(lam)`` and its minimiser (``value = -inf`` where the quadratic is not proven
        bounded below); ``lam`` (N, K) >= 0."""
        big_n, schur = self.local(lam)
        k = self.mats.shape[0]
        bad = DualPoint(-math.inf, np.zeros(self.n), np.zeros(self.n), np.zeros((self.n, k)))
        if self.offsets and np.any(big_n[:, 1, 1] <= C_CURVATURE_MIN):
            return bad
        h = self.assemble(schur)
        hff, b = h[: self.n, : self.n], h[: self.n, self.n]
        margin = MARGIN_REL * float(np.max(np.diag(hff)))
        try:
            chol = scipy.linalg.cho_factor(hff - margin * np.eye(self.n), lower=True,
                                           check_finite=False)  # fmt: skip
        except np.linalg.LinAlgError:
            return bad
        f = -scipy.linalg.cho_solve(chol, b, check_finite=False)
        f = f - scipy.linalg.cho_solve(chol, hff @ f + b, check_finite=False)  # refine
        return self._point(f, big_n, hff, b, margin)

    def _point(
        self, f: np.ndarray, big_n: np.ndarray, hff: np.ndarray, b: np.ndarray, margin: float
    ) -> DualPoint:
        """The Lagrangian at ``f`` from its definition, less the residual's worst case."""
        v = self.a_aug[:, :-1] @ f + self.a_aug[:, -1]
        x = self.b_aug[:, :-1] @ f + self.b_aug[:, -1]
        eta = np.stack([f, np.zeros_like(f), v, x, np.ones_like(f)], axis=1)
        o = [0, 2, 3, 4]
        if self.offsets:
            eta[:, 1] = -np.einsum("si,si->s", big_n[:, 1, o], eta[:, o]) / big_n[:, 1, 1]
        c = eta[:, 1].copy()
        lagrangian = self.ride(f) + float(np.einsum("si,sij,sj->", eta, big_n, eta))
        residual = hff @ f + b
        value = lagrangian - float(residual @ residual) / margin
        xi = eta @ self.to_xi.T
        q = np.einsum("si,kij,sj->sk", xi, self.mats, xi)
        return DualPoint(value, f, c, q)


@dataclass(frozen=True)
class DualSolution:
    """The best multipliers found and ``g`` there (:meth:`DualProblem.evaluate`)."""

    lam: np.ndarray
    point: DualPoint
    evaluations: int
    history: tuple[float, ...]


def maximise(
    problem: DualProblem, lam0: np.ndarray, max_iterations: int, lam_scale: float
) -> DualSolution:
    """Maximise ``g`` over ``lam >= 0`` by L-BFGS-B from ``lam0`` (N, K), the variables
    ``lam / lam_scale`` (gradient: ``-q`` at the minimiser, Danskin). A point that is not
    proven positive definite gets the last finite value plus a step penalty, so that the line
    search backs off."""
    from scipy.optimize import minimize

    shape = lam0.shape
    best: list = [None, None]
    history: list[float] = []

    def fun(y: np.ndarray) -> tuple[float, np.ndarray]:
        lam = (y * lam_scale).reshape(shape)
        pt = problem.evaluate(lam)
        if not math.isfinite(pt.value):
            last = history[-1] if history else 0.0
            return -last + 1e3 * (abs(last) + 1.0), -np.ones_like(y)
        history.append(pt.value)
        if best[1] is None or pt.value > best[1].value:
            best[0], best[1] = lam, pt
        return -pt.value, pt.q.reshape(-1) * lam_scale

    minimize(fun, lam0.reshape(-1) / lam_scale, jac=True, method="L-BFGS-B",
             bounds=[(0.0, None)] * lam0.size,
             options={"maxiter": max_iterations, "maxfun": 2 * max_iterations})  # fmt: skip
    if best[1] is None:
        raise RuntimeError("certified_floor: no multipliers with a positive definite "
                           "Lagrangian were found from the start")  # fmt: skip
    return DualSolution(best[0], best[1], len(history), tuple(history))
