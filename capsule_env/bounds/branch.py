"""Branch and bound over the sign of the stroke rate: a floor that the yield band cannot erase.

The Shor relaxation of :mod:`.relaxation` must hold the Bi-exponential band at both signs of
the stroke rate ``v`` at once, so it lets the damper push with any force near ``v = 0`` and
certifies almost nothing. With the sign ``sigma`` of ``v_s`` fixed at a force evaluation ``s``,
the damper's set becomes convex and is outer-approximated by linear inequalities in the lifted
forces (:func:`sign_cuts`, each proved in its docstring):

* ``sigma v_s >= 0`` (the sign itself: ``v_s`` is affine in the forces, :mod:`.lifted`);
* ``sigma F_s >= b_lo sigma v_s + low_sigma`` (the rate part has ``v``'s sign and at least the
  lowest slope; the offset at its lowest in ``sigma``'s direction);
* ``sigma F_s <= U(u_k) + U'(u_k)(sigma v_s - u_k) + high_sigma`` at tangent points ``u_k``,
  ``U(u) = a_hi (1 - exp(-d_hi u)) + b_hi u`` concave, so every tangent lies above it.

A node fixes the signs of some evaluations (``sigma in {-1, 0, +1}``, 0 undecided: no
constraint there, a valid relaxation) and its bound is the convex QP ``min J`` under its
cuts, solved by Clarabel and *certified* from the solver's dual by weak duality: for multipliers
``z`` (any, ``z >= 0`` on the inequalities) every trajectory the plant can run inside the node
has ``J >= -t^2 Q + t S`` for every ``t >= 0`` (:meth:`BranchProblem.node_bound`), where the
dual's residual on the forces is paid with an a-priori bound on every force's magnitude
(:func:`force_magnitude_bounds`, valid for every controller whatever its signs). A child's bound
is at least its parent's. Best-first search: the smallest bound over the open nodes is a valid
floor after any number of nodes.
"""

from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from capsule_env.bounds.dual import DualProblem
from capsule_env.bounds.lifted import LiftedEpisode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, SLOPE_SLACK_REL, DamperEnvelope

__all__ = [
    "TANGENT_RATES_M_S",
    "SignCuts",
    "BranchProblem",
    "BranchResult",
    "branch_and_bound",
    "force_magnitude_bounds",
    "sign_cut_values",
    "sign_cuts",
]

#: Stroke rates (m/s) at which the band's concave upper edge ``U`` is replaced by its tangent
#: (0 gives the steepest slope ``a_hi d_hi + b_hi`` through the origin).
TANGENT_RATES_M_S = (0.0, 0.002, 0.005, 0.01, 0.02, 0.04, 0.08, 0.2)
#: Absolute slack (kN) on every cut: covers the kernel's fast exp and the rounding of ``v``.
CUT_SLACK_KN = 1e-9
#: An undecided evaluation whose relaxed force is within this (kN) of one sign's cuts is not
#: branched on.
VIOLATION_TOL_KN = 1e-6


@dataclass(frozen=True)
class SignCuts:
    """The cuts of one damper with the stroke rate's sign fixed (forces in kN, rates m/s).

    With ``sigma = +1``, every force the damper produces at a rate ``v >= 0`` satisfies
    ``F >= lo_slope v + lo_off[0]`` and ``F <= up_icpt[k] + up_slope[k] v + up_off[0]`` for
    every ``k``; with ``sigma = -1`` (``v <= 0``), ``-F >= lo_slope (-v) + lo_off[1]`` and
    ``-F <= up_icpt[k] + up_slope[k] (-v) + up_off[1]``.
    """

    lo_slope: float
    lo_off: tuple[float, float]
    up_icpt: np.ndarray
    up_slope: np.ndarray
    up_off: tuple[float, float]


def sign_cuts(env: DamperEnvelope, rates_m_s: tuple[float, ...] = TANGENT_RATES_M_S) -> SignCuts:
    """The linear cuts valid at each sign of the stroke rate (:class:`SignCuts`).

    Proof. The force is ``F = D + C`` (:mod:`.relaxation`): ``D = a S_d(v) + b v`` with ``a`` in
    ``[a_lo, a_hi]`` (``a_lo >= 0``, checked by :func:`~.relaxation.damper_envelope`), ``b`` in
    ``[b_lo, b_hi]`` (``b_lo >= 0``), ``0 <= d <= d_hi``, ``S_d(v) = sign(v)(1 - exp(-d|v|))``,
    and ``C`` in ``[c_lo, c_hi]``. Let ``u = sigma v >= 0``. Then ``sigma D = a (1 - exp(-d u))
    + b u``: the first term is ``>= 0`` and the second ``>= b_lo u``, so ``sigma D >= b_lo u``;
    ``1 - exp(-d u)`` grows with ``d`` and is at most 1, so ``sigma D <= U(u) = a_hi (1 -
    exp(-d_hi u)) + b_hi u``. ``U`` is concave on ``u >= 0`` (``U'' = -a_hi d_hi^2 exp(-d_hi
    u) <= 0``), so its tangent at any ``u_k >= 0`` lies above it for every ``u >= 0``: ``sigma D
    <= U(u_k) + U'(u_k)(u - u_k)``. Finally ``sigma C`` lies in ``[c_lo, c_hi]`` for ``sigma =
    +1`` and in ``[-c_hi, -c_lo]`` for ``sigma = -1``; adding the two parts' bounds gives the
    cuts. The kernel's fast exp (within a few ulp) and rounding are covered by a relative slack
    :data:`~.relaxation.SLOPE_SLACK_REL` on the slopes and :data:`CUT_SLACK_KN` on each cut.
    (At ``v = 0`` both signs' cuts hold: ``D = 0``.) The lower edge ``a_lo (1 - exp(-d u)) +
    b_lo u`` is concave, so no linear cut valid for every ``u >= 0`` can keep its yield force:
    the relaxation's looseness within a sign.
    """
    f0 = FORCE_SCALE_N
    u = np.asarray(rates_m_s, dtype=float)
    if u.size == 0 or np.any(~(u >= 0.0)):
        raise ValueError(f"sign_cuts: rates_m_s must be numbers >= 0, got {rates_m_s!r}")
    grow = 1.0 + SLOPE_SLACK_REL
    e = np.exp(-env.d_hi * u)
    slope = (env.a_hi * env.d_hi * e + env.b_hi) * grow / f0
    value = (env.a_hi * (1.0 - e) + env.b_hi * u) * grow / f0
    icpt = value - slope * u + CUT_SLACK_KN
    c_lo, c_hi = env.c_lo / f0, env.c_hi / f0
    return SignCuts(
        lo_slope=env.b_lo / f0 / grow,
        lo_off=(c_lo - CUT_SLACK_KN, -c_hi - CUT_SLACK_KN),
        up_icpt=icpt,
        up_slope=slope,
        up_off=(c_hi, -c_lo),
    )


def sign_cut_values(
    cuts: SignCuts, sigma: float, force_kn: np.ndarray, v: np.ndarray
) -> np.ndarray:
    """The cuts at sign ``sigma`` evaluated at forces ``force_kn`` and rates ``v`` (M,): an
    (M, 2 + K) array, each entry ``>= 0`` where the cut holds (sign, lower edge, tangents)."""
    j = 0 if sigma > 0 else 1
    u, f = sigma * np.asarray(v, dtype=float), sigma * np.asarray(force_kn, dtype=float)
    lower = f - cuts.lo_slope * u - cuts.lo_off[j]
    upper = (
        cuts.up_icpt[None, :] + cuts.up_slope[None, :] * u[:, None] + cuts.up_off[j] - f[:, None]
    )
    return np.column_stack([u, lower, upper])


def force_magnitude_bounds(
    lifted: LiftedEpisode, env: DamperEnvelope
) -> tuple[np.ndarray, np.ndarray]:
    """(N,) kN and (N,) m/s: ``|F_s|`` and ``|v_s|`` are at most these on every trajectory
    the plant can run, any currents.

    ``|F| <= min(s_hi |v|, a_hi + b_hi |v|) + max(|c_lo|, |c_hi|)`` at every sign of ``v``
    (``|S_d(v)| <= min(d |v|, 1)``), and ``|v_s| <= |alpha_s| + sum_{j<s} |A_sj| |F_j|`` (the
    lift is strictly causal): a forward recursion. Used only to price the dual's residual."""
    f0 = FORCE_SCALE_N
    n = lifted.n_forces
    a_abs = np.abs(lifted.v_rows[:, :n]) * f0  # m/s per kN
    alpha = np.abs(lifted.v_rows[:, n])
    c_abs = max(abs(env.c_lo), abs(env.c_hi)) / f0
    s_hi, a_hi, b_hi = env.slope_hi / f0, env.a_hi / f0, env.b_hi * (1 + SLOPE_SLACK_REL) / f0
    out, rate = np.zeros(n), np.zeros(n)
    for s in range(n):
        rate[s] = (alpha[s] + a_abs[s, :s] @ out[:s]) * (1.0 + 1e-12)
        out[s] = min(s_hi * rate[s], a_hi + b_hi * rate[s]) + c_abs + CUT_SLACK_KN
    return out, rate


def hull_lines(env: DamperEnvelope, rate_bound_m_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per evaluation, a line ``(icpt, slope)`` (kN, kN s/m) valid at *both* signs of ``v``
    when ``|v| <= V`` (``V = rate_bound_m_s``): ``F <= icpt + slope v + c_hi`` and ``-F <=
    icpt - slope v - c_lo``.

    Proof (upper cut; the lower one is its mirror, ``-D`` at ``-v`` being the same set). The
    line is either the tangent of the concave ``U`` (:func:`sign_cuts`) at some ``u* >= 0``
    whose value at ``v = -V`` is at least ``-b_lo V``, or, where no ``u*`` up to 10 m/s
    qualifies, ``a_hi + (b_hi - b_lo) V + b_hi v``. For ``v >= 0``: ``D <= U(v)``, and the
    tangent lies above ``U``, as does ``a_hi + b_hi v`` (``1 - exp <= 1``). For ``-V <= v <
    0``: ``D <= b_lo v`` (``-D >= b_lo |v|``), and the line minus ``b_lo v`` is affine on
    ``[-V, 0]``, ``>= 0`` at both ends (at 0 the tangent is ``>= U(0) = 0``), so ``>= 0``
    between (the fallback: ``a_hi + (b_hi - b_lo)(v + V) >= 0``). ``C <= c_hi`` adds the
    offset. The tangent point is found by bisection, its condition checked again on the
    result."""
    f0, grow = FORCE_SCALE_N, 1.0 + SLOPE_SLACK_REL
    big_v = np.asarray(rate_bound_m_s, dtype=float) * (1.0 + 1e-12)
    a_hi, d_hi, b_hi, b_lo = env.a_hi / f0, env.d_hi, env.b_hi / f0, env.b_lo / f0 / grow

    def tangent(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e = np.exp(-d_hi * u)
        slope = (a_hi * d_hi * e + b_hi) * grow
        return (a_hi * (1.0 - e) + b_hi * u) * grow - slope * u + CUT_SLACK_KN, slope

    def ok(u: np.ndarray) -> np.ndarray:
        icpt, slope = tangent(u)
        return icpt - slope * big_v >= -b_lo * big_v

    lo, hi = np.zeros_like(big_v), np.full_like(big_v, 10.0)
    for _ in range(60):  # the condition is monotone in u: the smallest u* that passes
        mid = 0.5 * (lo + hi)
        good = ok(mid)
        hi, lo = np.where(good, mid, hi), np.where(good, lo, mid)
    icpt, slope = tangent(hi)
    fallback = ~ok(hi)
    icpt = np.where(fallback, (a_hi + (b_hi - b_lo) * big_v) * grow + CUT_SLACK_KN, icpt)
    return icpt, np.where(fallback, b_hi * grow, slope)


class _SparseQP:
    """The node QP in the sparse form: ``x = (X, F, acc, w)``, forces in kN."""

    def __init__(self, lifted: LiftedEpisode, t: int) -> None:
        from capsule_env.bounds.dual import weighting_matrix
        from capsule_env.bounds.sparse import sparse_lift

        sl = sparse_lift(lifted)
        f0, n, nx = FORCE_SCALE_N, lifted.n_forces, sl.n_x
        self.nx, self.n, self.t = nx, n, t
        dyn_x, dyn_f = sl.dyn[:, :nx], sl.dyn[:, nx:] * f0
        w = sp.csr_matrix(weighting_matrix(t, lifted.dt_s))
        z_tn, z_tt = sp.csr_matrix((t, n)), sp.csr_matrix((t, t))
        self.eq = sp.vstack([
            sp.hstack([dyn_x, dyn_f, sp.csr_matrix((nx, 2 * t))]),
            sp.hstack([-sl.acc_x, -sl.acc_f * f0, sp.identity(t), z_tt]),
            sp.hstack([sp.csr_matrix((t, nx)), z_tn, -w, sp.identity(t)]),
        ]).tocsr()  # fmt: skip
        self.b_eq = np.r_[sl.dyn_rhs, sl.acc_c, np.zeros(t)]
        self.v_x, self.v_f, self.v_c = sl.v_x, sl.v_f * f0, sl.v_c
        size = nx + n + 2 * t
        diag = np.zeros(size)
        diag[-t:] = 2.0 / t
        self.p = sp.diags(diag).tocsc()

    def solve(
        self, gf: sp.csr_matrix, gv: sp.csr_matrix, h: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Clarabel on the cuts ``gf F + gv v <= h`` (``v`` replaced by its sparse form):
        the multipliers of ``w`` (T) and of the cuts, and the forces (kN; zeros if none).
        Columns of ``gf`` beyond the N forces are further variables (in no equality)."""
        import clarabel

        nx, n, t = self.nx, self.n, self.t
        e = gf.shape[1] - n
        g = sp.hstack([gv @ self.v_x, gf[:, :n] + gv @ self.v_f, sp.csr_matrix((h.size, 2 * t)),
                       gf[:, n:]])  # fmt: skip
        eq, p = self.eq, self.p
        if e:
            eq = sp.hstack([eq, sp.csr_matrix((eq.shape[0], e))])
            p = sp.block_diag([p, sp.csr_matrix((e, e))]).tocsc()
        a = sp.vstack([eq, g]).tocsc()
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        # J is 1e-5..1e-1 (m/s^2)^2: the default absolute gap (1e-8) would be 1e-3 of it
        settings.tol_gap_abs, settings.tol_gap_rel, settings.tol_feas = 1e-13, 1e-10, 1e-10
        m = self.b_eq.size
        cones = [clarabel.ZeroConeT(m), clarabel.NonnegativeConeT(h.size)]
        b = np.r_[self.b_eq, h - gv @ self.v_c]
        sol = clarabel.DefaultSolver(p, np.zeros(a.shape[1]), a, b, cones, settings).solve()
        dual, x = np.asarray(sol.z), np.asarray(sol.x)
        forces = x[nx : nx + n] if x.size else np.zeros(n)
        return dual[m - t : m], dual[m:], forces


class BranchProblem:
    """One lifted episode's node QPs (forces in kN): ``x = (F, v, w)``, ``v = A F + alpha``
    (N), ``w = Wf F + wc`` (T, the Wk-weighted accelerations), every cut sparse in ``(F_s,
    v_s)``."""

    def __init__(self, lifted: LiftedEpisode, env: DamperEnvelope, cuts: SignCuts | None = None):
        base = DualProblem(lifted, np.zeros((0, 5, 5)))
        self.n = base.n
        self.t = base.n_steps
        self.a_aug = base.a_aug  # v = a_aug @ [F; 1]
        self.wf, self.wc = base.wg[:, :-1], base.wg[:, -1]
        self.ride = base.ride
        self.cuts = sign_cuts(env) if cuts is None else cuts
        self.f_abs, self.v_abs = force_magnitude_bounds(lifted, env)
        self.hull_icpt, self.hull_slope = hull_lines(env, self.v_abs)
        self.c_lo, self.c_hi = env.c_lo / FORCE_SCALE_N, env.c_hi / FORCE_SCALE_N
        self._sparse = _SparseQP(lifted, base.n_steps)

    def rows(self, sigma: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
        """The node's cuts as ``GF F + Gv v <= h`` (sparse): the sign cuts where ``sigma`` is
        decided, the hull lines (:func:`hull_lines`) where it is 0."""
        n, c = self.n, self.cuts
        dec, und = np.flatnonzero(sigma), np.flatnonzero(sigma == 0)
        sg = sigma[dec].astype(float)
        j = (sigma[dec] < 0).astype(int)
        lo_off, up_off = np.array(c.lo_off)[j], np.array(c.up_off)[j]
        # each cut: (index, coefficient of F, coefficient of v, rhs)
        idx = [dec, dec]
        cf = [np.zeros(dec.size), -sg]
        cv = [-sg, c.lo_slope * sg]
        rhs = [np.zeros(dec.size), -lo_off]
        for icpt, slope in zip(c.up_icpt, c.up_slope, strict=True):
            idx.append(dec)
            cf.append(sg)
            cv.append(-slope * sg)
            rhs.append(icpt + up_off)
        ones = np.ones(und.size)
        idx += [und, und]
        cf += [ones, -ones]
        cv += [-self.hull_slope[und], self.hull_slope[und]]
        rhs += [self.hull_icpt[und] + self.c_hi, self.hull_icpt[und] - self.c_lo]
        col = np.concatenate(idx)
        row = np.arange(col.size)
        gf = sp.csr_matrix((np.concatenate(cf), (row, col)), shape=(col.size, n))
        gv = sp.csr_matrix((np.concatenate(cv), (row, col)), shape=(col.size, n))
        return gf, gv, np.concatenate(rhs)

    def node_bound(self, sigma: np.ndarray) -> tuple[float, np.ndarray]:
        """A certified lower bound on ``J`` over the node's trajectories (``inf`` where the
        solver's certificate proves it empty) and the relaxed forces (kN).

        Solved in the sparse form (:mod:`.sparse`), certified in the dense one. With
        multipliers ``y`` (free) of the equalities ``v - A F = alpha``, ``w - Wf F = wc`` and
        ``z >= 0`` of the cuts ``GF F + Gv v <= h``, every trajectory of the node (where the
        equalities and every cut hold) has ``J = |w|^2 / T >= |w|^2 / T + y . (E x - b) + z .
        (G x - h)``. Minimised over ``w`` (``-T |y_w|^2 / 4``), with ``y_v = -Gv^T z`` (no
        ``v`` left) and the forces' part ``r_F . F`` (the dual's residual) at least ``-|r_F| .
        f_abs`` (:func:`force_magnitude_bounds`): ``J >= S - Q``, ``Q = T |y_w|^2 / 4``, ``S =
        -y . b - z . h - |r_F| . f_abs``. Any ``(y_w, z)`` with ``z >= 0`` gives a valid
        bound, the solver's are only a good choice; scaled by ``t >= 0`` they
        give ``t S - t^2 Q``, at best ``S^2 / (4 Q)`` when ``S > 0`` (a Farkas ray of an
        infeasible node, ``Q = 0``, gives ``inf``); and ``J >= 0``. The floating point sums
        are made safe in :meth:`certify` (a rounding budget taken off ``S``): the value is at
        most the exact ``S^2 / (4 Q)`` at the multipliers it used. Exact for the lifted plant's
        arithmetic, not the kernel's (they agree to about 1e-15 relative, :mod:`.lifted`)."""
        gf, gv, h = self.rows(sigma)
        y_w, z, forces = self._sparse.solve(gf, gv, h)
        return self.certify(gf, gv, h, y_w, z), forces

    def certify(
        self,
        gf: sp.csr_matrix,
        gv: sp.csr_matrix,
        h: np.ndarray,
        y_w: np.ndarray,
        z: np.ndarray,
        extra_abs: np.ndarray | None = None,
    ) -> float:
        """The bound of :meth:`node_bound` at multipliers ``y_w`` (T) and ``z`` (clipped to
        ``>= 0``), in the dense lift (:mod:`.lifted`, the tested one), with ``y_v = -Gv^T z``;
        any multipliers give a valid bound (non-finite ones the trivial 0).

        Rounding: the multipliers are first scaled by a power of two (exact; the bound does not
        depend on their scale) so that the largest is about 1, and ``S`` loses a budget of
        ``gamma = 2 (K + 8) eps`` (``K`` the longest dot product) times the sum of its terms'
        magnitudes, which covers every rounding in ``S`` and in ``r_F``, and ``r_v = y_v + Gv^T
        z`` (not exactly 0 in floating point) paid with :func:`force_magnitude_bounds`'s rate
        bound. ``|y_w|`` comes from ``math.hypot`` (no underflow). The result is at most the
        exact ``S^2 / (4 Q)`` at the multipliers used. Columns of ``gf`` beyond the N forces
        are further variables, each at most ``extra_abs`` in magnitude on every trajectory of
        the node (:mod:`.stroke`'s per-step current): their residual ``Ge^T z`` is priced like
        the forces'."""
        if not (np.isfinite(y_w).all() and np.isfinite(z).all()):
            return 0.0
        z = np.maximum(z, 0.0)
        big = max(float(np.abs(y_w).max(initial=0.0)), float(z.max(initial=0.0)))
        if big == 0.0:
            return 0.0
        shift = -math.frexp(big)[1]  # up to 1074 for subnormal ones: 2^shift is no float
        y_w, z = np.ldexp(y_w, shift), np.ldexp(z, shift)
        extra = np.zeros(0) if extra_abs is None else np.asarray(extra_abs, dtype=float)
        if extra.size != gf.shape[1] - self.n:
            raise ValueError("certify: extra_abs must have one entry per column beyond N")
        return self._safe_bound((gf, gv, h), y_w, z, np.r_[self.f_abs, extra])

    def _safe_bound(
        self, rows: tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray], y_w: np.ndarray,
        z: np.ndarray, f_abs: np.ndarray,
    ) -> float:  # fmt: skip
        """:meth:`certify` at multipliers already scaled (module doc of the rounding budget)
        for the cuts ``rows = (gf, gv, h)``; ``f_abs`` bounds every column of ``gf``."""
        (gf, gv, h), n, t, a = rows, self.n, self.t, self.a_aug
        eps = np.finfo(float).eps
        gamma = 2.0 * (a.shape[0] + t + h.size + 8) * eps  # a: N rows (2N with strokes)
        y_v = -(gv.T @ z)
        r_f = gf.T @ z
        r_f[:n] += -self.wf.T @ y_w - a[:, :n].T @ y_v
        r_f_mag = abs(gf).T @ z
        r_f_mag[:n] += np.abs(self.wf).T @ np.abs(y_w) + np.abs(a[:, :n]).T @ np.abs(y_v)
        r_v_mag = abs(gv).T @ z  # |y_v + Gv^T z| <= gamma this
        terms = (-float(y_w @ self.wc), -float(y_v @ a[:, n]), -float(z @ h),
                 -float(np.abs(r_f) @ f_abs))  # fmt: skip
        mags = (float(np.abs(y_w) @ np.abs(self.wc)) + float(np.abs(y_v) @ np.abs(a[:, n]))
                + float(z @ np.abs(h)) + float((np.abs(r_f) + r_f_mag) @ f_abs)
                + float(r_v_mag @ self.v_abs))  # fmt: skip
        lin = math.fsum(terms) - gamma * mags
        if lin <= 0.0:
            return 0.0
        norm = math.hypot(*(float(x) for x in y_w)) * (1.0 + 4.0 * eps)
        if norm == 0.0:
            return math.inf  # a Farkas ray: no trajectory in the node
        return (lin / (math.sqrt(t) * norm)) ** 2 * (1.0 - 8.0 * eps)

    def violation(self, forces_kn: np.ndarray) -> np.ndarray:
        """(N,) kN: how far each evaluation's relaxed force is from the nearer sign's cuts."""
        v = self.a_aug[:, :-1] @ forces_kn + self.a_aug[:, -1]
        worst = [np.maximum(-sign_cut_values(self.cuts, s, forces_kn, v), 0.0).max(axis=1)
                 for s in (1.0, -1.0)]  # fmt: skip
        return np.minimum(*worst)


@dataclass(frozen=True)
class BranchResult:
    """What :func:`branch_and_bound` found: ``floor_j`` the certified floor on ``J``
    ((m/s^2)^2; the Wk floor is its square root), ``root_j`` the root's bound, ``history``
    ``(nodes solved, floor)`` after the root and after each branching, ``nodes`` solved, ``open_nodes`` left, ``complete`` (the
    smallest open node needed no branching: the floor is the relaxation's optimum),
    ``runtime_s``."""

    floor_j: float
    root_j: float
    history: tuple[tuple[int, float], ...]
    nodes: int
    open_nodes: int
    complete: bool
    runtime_s: float

    @property
    def floor_wk_m_s2(self) -> float:
        return math.sqrt(max(self.floor_j, 0.0))

    def floor_j_at(self, nodes: int) -> float:
        """The floor after at most ``nodes`` node QPs (the any-time curve)."""
        return max((f for k, f in self.history if k <= nodes), default=0.0)


_FINAL, _UNSOLVED = -1, -2


def _select(problem: BranchProblem, sigma: np.ndarray, forces: np.ndarray,
            candidates: np.ndarray) -> int:  # fmt: skip
    """The undecided candidate whose relaxed force violates its nearer sign's cuts most; -1
    when none does by more than :data:`VIOLATION_TOL_KN`."""
    viol = problem.violation(forces)[candidates]
    viol[sigma[candidates] != 0] = 0.0
    k = int(np.argmax(viol)) if viol.size else 0
    return int(candidates[k]) if viol.size and viol[k] > VIOLATION_TOL_KN else -1


def branch_and_bound(
    problem: BranchProblem,
    max_nodes: int,
    candidates: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
) -> BranchResult:
    """Best-first branch and bound over the stroke rate's sign at the evaluations
    ``candidates`` (default all): at most ``max_nodes`` node QPs. The floor is the smallest
    bound over the open nodes (each node's bound at least its parent's), valid after any
    node; ``complete`` when the node holding it needs no more branching. ``fixed`` (N,) in
    {-1, 0, 1}: signs decided from the start (the search then bounds that sub-node only)."""
    if isinstance(max_nodes, bool) or not isinstance(max_nodes, int) or max_nodes < 1:
        raise ValueError(f"branch_and_bound: max_nodes must be an integer >= 1, got {max_nodes!r}")
    t0 = time.perf_counter()
    cand = np.arange(problem.n) if candidates is None else np.asarray(candidates, dtype=int)
    sigma0 = np.zeros(problem.n, dtype=np.int8) if fixed is None else np.sign(fixed).astype(np.int8)
    root, forces = problem.node_bound(sigma0)
    heap = [(root, 0, sigma0, _select(problem, sigma0, forces, cand))]
    history, nodes, counter = [(1, root)], 1, 1
    while heap and nodes < max_nodes:
        bound, _, sigma, k = heap[0]
        if k == _FINAL or not math.isfinite(bound):
            break  # the smallest node needs no branching: the floor is final
        heapq.heappop(heap)
        for sign in (1, -1):
            if nodes >= max_nodes:  # the second child unsolved: it keeps its parent's bound
                heapq.heappush(heap, (bound, counter, _child(sigma, k, sign), _UNSOLVED))
                counter += 1
                continue
            child = _child(sigma, k, sign)
            own, forces = problem.node_bound(child)
            nodes += 1
            if own < math.inf:
                heapq.heappush(heap, (max(bound, own), counter, child,
                                      _select(problem, child, forces, cand)))  # fmt: skip
                counter += 1
        history.append((nodes, heap[0][0] if heap else math.inf))
    complete = bool(heap) and heap[0][3] == _FINAL
    floor = heap[0][0] if heap else math.inf
    return BranchResult(floor, root, tuple(history), nodes, len(heap), complete,
                        time.perf_counter() - t0)  # fmt: skip


def _child(sigma: np.ndarray, k: int, sign: int) -> np.ndarray:
    out = sigma.copy()
    out[k] = sign
    return out
