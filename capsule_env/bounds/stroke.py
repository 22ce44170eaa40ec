"""Nodes that also fix the stroke's side of the branch blend: the offset tied to the stroke.

:mod:`.branch`'s cuts within a stroke-rate sign hold for every stroke, so they let the offset
``c`` be anywhere in ``[c_lo, c_hi]`` (-362..346 N on the ``sim`` damper) at either sign of the
stroke, and take ``c_hi`` at 0 A together with ``a_hi, b_hi`` at ``i_max``. Beyond the blend
(``|x| >= branch_blend_m``) the blend weight is exactly 0 or 1, so the force is *one* branch's,
``F(i) = a(i) S_d(v) + b(i) v + c(i)`` with ``a, b, c`` affine in the one current ``i`` and
``d`` fixed. A node here fixes, beside the stroke rate's sign ``sigma`` at each force
evaluation, the stroke's side ``tau``:

* ``tau = +1``: ``x >= blend`` (the upper branch), ``tau = -1``: ``x <= -blend`` (the lower
  one), ``tau = 2``: ``-blend <= x <= blend`` (inside the blend), ``tau = 0``: not fixed.
  The three fixed values partition every stroke (the boundaries shared), so the children
  ``+1, -1, 2`` of an evaluation cover every trajectory of their parent.
* Where ``tau = +-1`` the node has the linear cut ``tau x_s >= blend`` (``x_s`` affine in the
  forces, :mod:`.lifted`), where ``tau = 2`` the two cuts ``|x_s| <= blend``, and where also
  ``sigma`` is fixed the branch's own cuts (:func:`side_cuts`); every node keeps
  :mod:`.branch`'s cuts too (valid at every stroke).

Optionally (``node_bound(..., current_tie=True)``) the nine evaluations of a control step are
tied to one current: :func:`current_tie_rows` (a per-step current fraction and McCormick's
envelope of its product with the rate), their variables priced by their ranges; only for a
coil without lag (a lagging coil's current moves within the step: refused).
And a node may fix the class of the stroke rate's magnitude (``kappa``,
:data:`RATE_BREAKS_M_S`), which bounds the rate and keeps the lower edge's yield by a chord
(:func:`rate_class_rows`).

The node's bound is certified exactly as :meth:`.branch.BranchProblem.node_bound` certifies it:
the stroke ``x`` enters as further affine rows beside the stroke rate (``[v; x] = [A; B] F +
[alpha; beta]``), their residual priced with an a-priori bound on ``|x_s|`` from
:func:`~.branch.force_magnitude_bounds`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from capsule_env.bounds.branch import CUT_SLACK_KN, TANGENT_RATES_M_S, BranchProblem
from capsule_env.bounds.lifted import LiftedEpisode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, SLOPE_SLACK_REL, DamperEnvelope
from capsule_env.dampers.base import COIL_TAU
from capsule_env.dampers.registry import model_of_code

__all__ = [
    "INSIDE_BLEND",
    "RATE_BREAKS_M_S",
    "current_tie_rows",
    "rate_class_rows",
    "SideCuts",
    "StrokeBranchProblem",
    "branch_corners",
    "side_cut_values",
    "side_cuts",
    "stroke_sides",
]

#: ``tau`` of an evaluation whose stroke is inside the blend, ``|x| <= blend``.
INSIDE_BLEND = 2


def branch_corners(code: int, params: np.ndarray) -> tuple[np.ndarray, float]:
    """``(corners, blend_m)``: ``corners[jx, ji] = (a, b, c, d)`` (SI) of the branch on side
    ``jx`` (0: ``x >= blend``, the upper branch; 1: ``x <= -blend``, the lower) at current
    ``ji`` (0: 0 A, 1: ``i_max``). The passive linear damper is one branch, ``(0, c_lin, 0,
    0)`` at every current, with blend 0."""
    name = model_of_code(code).name
    p = np.asarray(params, dtype=float)
    if name == "passive":
        return np.tile([0.0, float(p[0]), 0.0, 0.0], (2, 2, 1)), 0.0
    if name != "bi_exponential":
        raise ValueError(f"branch_corners: no branch form for the damper {name!r}")
    from capsule_env.dampers import bi_exponential as be
    from capsule_env.dampers.base import BRANCH_BLEND, I_MAX

    out = np.zeros((2, 2, 4))
    for jx, o in enumerate((be.UPPER, be.LOWER)):
        for ji, i in enumerate((0.0, float(p[I_MAX]))):
            out[jx, ji] = (p[o + be.A0] + p[o + be.A1] * i, p[o + be.B0] + p[o + be.B1] * i,
                           p[o + be.C0] + p[o + be.C1] * i, p[o + be.D])  # fmt: skip
    if out[..., 0].min() < 0.0 or out[..., 1].min() < 0.0 or out[..., 3].min() < 0.0:
        raise ValueError("branch_corners: a negative yield force, slope or d at some current")
    return out, float(p[BRANCH_BLEND])


def _sup_above_line(a: np.ndarray, b: np.ndarray, d: np.ndarray, m: float) -> np.ndarray:
    """``sup_{u >= 0} a (1 - exp(-d u)) + (b - m) u`` for ``a, d >= 0`` and ``m >= b``.

    With ``r = m - b >= 0`` the function ``h`` is concave, ``h' = a d exp(-d u) - r``. If
    ``r >= a d``, ``h' <= 0``: the sup is ``h(0) = 0``. If ``0 < r < a d``, ``h' = 0`` at
    ``exp(-d u*) = r / (a d)``, the global maximum: ``a - r/d - (r/d) ln(a d / r)``. If ``r =
    0 < a d``, ``h`` increases to ``a``."""
    r = m - b
    ad = a * d
    with np.errstate(divide="ignore", invalid="ignore"):
        inner = a - r / d - (r / d) * np.log(ad / r)
    return np.where(r >= ad, 0.0, np.where(r <= 0.0, a, inner))


@dataclass(frozen=True)
class SideCuts:
    """The cuts of one damper with the stroke rate's sign ``sigma`` and the stroke's side
    ``tau`` (beyond the blend) fixed, forces in kN, indexed ``[jv, jx]`` (0 for ``+1``, 1 for
    ``-1``): with ``u = sigma v >= 0``, ``sigma F >= lo_slope u + lo_off`` and ``sigma F <=
    up_icpt[..., k] + up_slope[..., k] u`` for every ``k``; ``blend_m`` the blend's width,
    ``corners`` :func:`branch_corners`'s; ``coil_tau_s`` the coil's time constant (0: the
    current is the step's clipped command; above 0 it moves within a step, so
    :func:`current_tie_rows` refuses the damper)."""

    lo_slope: np.ndarray
    lo_off: np.ndarray
    up_icpt: np.ndarray
    up_slope: np.ndarray
    blend_m: float
    corners: np.ndarray
    coil_tau_s: float


def side_cuts(
    code: int, params: np.ndarray, rates_m_s: tuple[float, ...] = TANGENT_RATES_M_S
) -> SideCuts:
    """:class:`SideCuts` of a damper row.

    Proof. Beyond the blend on side ``tau`` the force is the branch's ``F(i) = a(i) S_d(v) +
    b(i) v + c(i)``, affine in ``i`` at fixed ``v`` (``a, b, c`` affine in ``i``, ``d`` the
    branch's), so for every ``i`` in ``[0, i_max]`` ``sigma F(i)`` lies between its values at
    the corners ``i in {0, i_max}``: ``f_j(u) = a_j (1 - exp(-d u)) + b_j u + sigma c_j`` with
    ``u = sigma v >= 0`` (``sigma S_d(v) = 1 - exp(-d u)``). Lower: ``a_j (1 - exp(-d u)) >=
    0``, so ``f_j(u) >= min_j b_j u + min_j sigma c_j``. Upper: for any slope ``m >= max_j
    b_j``, ``f_j(u) <= m u + sigma c_j + sup_u (a_j (1 - exp(-d u)) + (b_j - m) u)`` (closed
    form in :func:`_sup_above_line`), so the line with intercept the max over the corners lies
    above both; the slopes ``m`` are each corner's at each tangent point ``u_k`` (raised to
    ``max_j b_j`` where below it). The kernel's fast exp (a few ulp) and the closed form's rounding
    (a few ulp of at most a few kN) are covered by :data:`~.branch.CUT_SLACK_KN` on each cut
    and :data:`~.relaxation.SLOPE_SLACK_REL` on the lower slope. Unlike :func:`.branch.sign_cuts`
    the offset is the branch's (about -362..-230 N below, +222..+346 N above on ``sim``) and at
    the same current as ``a`` and ``b``."""
    corners, blend = branch_corners(code, params)
    f0 = FORCE_SCALE_N
    u = np.asarray(rates_m_s, dtype=float)
    if u.size == 0 or np.any(~(u >= 0.0)):
        raise ValueError(f"side_cuts: rates_m_s must be numbers >= 0, got {rates_m_s!r}")
    lo_slope, lo_off = np.zeros((2, 2)), np.zeros((2, 2))
    up_icpt, up_slope = np.zeros((2, 2, 2 * u.size)), np.zeros((2, 2, 2 * u.size))
    for jv, sigma in enumerate((1.0, -1.0)):
        for jx in range(2):
            a, b, c, d = (corners[jx, :, q] / (f0 if q < 3 else 1.0) for q in range(4))
            sc = sigma * c
            lo_slope[jv, jx] = b.min() / (1.0 + SLOPE_SLACK_REL)
            lo_off[jv, jx] = sc.min() - CUT_SLACK_KN
            slopes = a[None, :] * d[None, :] * np.exp(-d[None, :] * u[:, None]) + b[None, :]
            for k, m in enumerate(np.maximum(slopes.ravel(), b.max())):
                up_slope[jv, jx, k] = m
                up_icpt[jv, jx, k] = float(np.max(_sup_above_line(a, b, d, float(m)) + sc))
    coil_tau = float(np.asarray(params, dtype=float)[COIL_TAU])
    return SideCuts(lo_slope, lo_off, up_icpt + CUT_SLACK_KN, up_slope, blend, corners, coil_tau)


def side_cut_values(
    cuts: SideCuts, sigma: float, tau: float, force_kn: np.ndarray, v: np.ndarray
) -> np.ndarray:
    """The cuts at ``(sigma, tau)`` at forces ``force_kn`` and rates ``v`` (M,): an (M, 2 + K)
    array, each entry ``>= 0`` where the cut holds (sign, lower edge, tangents)."""
    jv, jx = int(sigma < 0), int(tau < 0)
    u, f = sigma * np.asarray(v, dtype=float), sigma * np.asarray(force_kn, dtype=float)
    lower = f - cuts.lo_slope[jv, jx] * u - cuts.lo_off[jv, jx]
    upper = cuts.up_icpt[jv, jx][None, :] + cuts.up_slope[jv, jx][None, :] * u[:, None]
    return np.column_stack([u, lower, upper - f[:, None]])


def stroke_sides(x_m: np.ndarray, blend_m: float) -> np.ndarray:
    """``tau`` of strokes ``x_m``: +1 beyond ``+blend``, -1 beyond ``-blend``, else
    :data:`INSIDE_BLEND`."""
    x = np.asarray(x_m, dtype=float)
    return np.where(x >= blend_m, 1, np.where(x <= -blend_m, -1, INSIDE_BLEND)).astype(np.int8)


def _corner_kn(cuts: SideCuts, tau: int) -> tuple[np.ndarray, ...]:
    """``(a, b, c, d)`` of side ``tau``'s branch at 0 A and ``i_max`` (kN, kN s/m, kN, s/m)."""
    k = cuts.corners[int(tau < 0)]
    return k[:, 0] / FORCE_SCALE_N, k[:, 1] / FORCE_SCALE_N, k[:, 2] / FORCE_SCALE_N, k[:, 3]


def _tie_rows_at(cuts: SideCuts, sv: float, tau: int, big: float) -> list[tuple[float, ...]]:
    """One evaluation's per-step current cuts as ``(cF, cv, ctheta, cw, rhs)`` on ``cF F + cv
    v + ctheta theta + cw w <= rhs`` (:func:`current_tie_rows`; ``big`` its rate bound)."""
    a, b, c, d = _corner_kn(cuts, tau)
    sc = sv * c
    out = []
    for uk in TANGENT_RATES_M_S:  # sigma F <= (1 - theta) L_0(u) + theta L_1(u)
        m = a * d * np.exp(-d * uk) + b
        icpt = np.array([_sup_above_line(a[j : j + 1], b[j], d[j : j + 1], float(m[j]))[0]
                         for j in range(2)]) + sc + CUT_SLACK_KN  # fmt: skip
        out.append((sv, -m[0] * sv, -(icpt[1] - icpt[0]), -(m[1] - m[0]), icpt[0]))
    chord = a * (1.0 - np.exp(-d * big)) / big + b  # valid for u <= big (f_j concave)
    for g in (b, chord):  # sigma F >= g_0 u + sc_0 + theta (sc_1 - sc_0) + (g_1 - g_0) w
        out.append((-sv, g[0] * sv, sc[1] - sc[0], g[1] - g[0], -sc[0] + CUT_SLACK_KN))
    # w = theta u, McCormick on [0, 1] x [0, big]: w >= 0, w <= u, w <= big theta,
    # w >= u - big (1 - theta)
    out += [(0.0, 0.0, 0.0, -1.0, 0.0), (0.0, -sv, 0.0, 1.0, 0.0), (0.0, 0.0, -big, 1.0, 0.0),
            (0.0, sv, big, -1.0, big)]  # fmt: skip
    return out


def current_tie_rows(
    cuts: SideCuts, step_of: np.ndarray, sigma: np.ndarray, tau: np.ndarray, rate_bound: np.ndarray
) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray, np.ndarray]:
    """The per-step current's cuts ``GF [F; e] + Gv [v; x] <= h`` and ``e``'s magnitude
    bounds, at the evaluations beyond the blend with both signs fixed (``M`` of them).

    ``e = (theta - 1/2, w - U/2)``: per control step ``theta = i / i_max`` in ``[0, 1]`` (the
    kernel clips the current), shared by the step's evaluations, and per evaluation ``w =
    theta u`` in ``[0, U]`` (``u = sigma v`` in ``[0, U]``, ``U = rate_bound``, a bound on
    ``|v|`` of every trajectory). Proof: at fixed ``u`` the force is affine in the current,
    so ``sigma F = (1 - theta) f_0(u) + theta f_1(u)`` exactly (corners as :func:`side_cuts`);
    each corner lies below its own tangent lines ``L_j`` (intercepts by
    :func:`_sup_above_line`), above ``b_j u + sigma c_j`` and, on ``[0, U]``, above its chord
    (concave), so ``(1 - theta) L_0 + theta L_1`` and the two lower combinations bound ``sigma
    F``, linear in ``(F, v, theta, w)``; the McCormick inequalities hold at ``w = theta u``.
    Slack :data:`~.branch.CUT_SLACK_KN` on each force cut, as :func:`side_cuts`.

    Only for a coil without lag (``cuts.coil_tau_s == 0``): a lagging coil's current moves
    within the step (:func:`capsule_env.plant.rk4.rk4_substep` updates it at each half
    substep), the step's evaluations do not share one ``theta`` and these rows could exclude
    the plant's own trajectory; ValueError then."""
    if not cuts.coil_tau_s == 0.0:
        raise ValueError(
            f"current_tie_rows: the damper's coil lags (coil_time_constant_s = "
            f"{cuts.coil_tau_s!r} s, must be 0): its current changes within a control step, "
            "so the step's evaluations share no one current; use current_tie=False"
        )
    n, t_steps = sigma.size, int(step_of.max()) + 1
    rate_bound = np.maximum(rate_bound, 1e-9)  # a larger bound stays valid; no 0 chord
    sel = np.flatnonzero((np.abs(tau) == 1) & (sigma != 0))
    rows, idx = [], []
    for m, s in enumerate(sel):
        for r in _tie_rows_at(cuts, float(sigma[s]), int(tau[s]), float(rate_bound[s])):
            rows.append(r)
            idx.append((s, m))
    arr = np.array(rows, dtype=float).reshape(-1, 5)
    at = np.array(idx, dtype=int).reshape(-1, 2)
    big = rate_bound[sel]
    # the shift to e: theta = e_theta + 1/2, w = e_w + U / 2
    h = arr[:, 4] - 0.5 * arr[:, 2] - 0.5 * big[at[:, 1]] * arr[:, 3]
    r = np.arange(arr.shape[0])
    cols = np.r_[at[:, 0], n + step_of[at[:, 0]], n + t_steps + at[:, 1]]
    gf = sp.csr_matrix((np.r_[arr[:, 0], arr[:, 2], arr[:, 3]], (np.r_[r, r, r], cols)),
                       shape=(r.size, n + t_steps + sel.size))  # fmt: skip
    gv = sp.csr_matrix((arr[:, 1], (r, at[:, 0])), shape=(r.size, 2 * n))
    box = sp.hstack([sp.csr_matrix((2 * t_steps, n)),
                     sp.vstack([sp.identity(t_steps), -sp.identity(t_steps)]),
                     sp.csr_matrix((2 * t_steps, sel.size))])  # fmt: skip
    gf = sp.vstack([gf, box]).tocsr()  # |theta - 1/2| <= 1/2
    gv = sp.vstack([gv, sp.csr_matrix((2 * t_steps, 2 * n))]).tocsr()
    return gf, gv, np.r_[h, np.full(2 * t_steps, 0.5)], np.r_[np.full(t_steps, 0.5), big / 2]


#: Stroke-rate magnitude classes (m/s): class ``k`` is ``u = |v|`` in ``[b_k, b_{k+1}]``.
RATE_BREAKS_M_S = (0.0, 0.005, 0.02, 0.06, math.inf)


def rate_class_rows(
    cuts: SideCuts, sigma: np.ndarray, tau: np.ndarray, kappa: np.ndarray,
    breaks: tuple[float, ...] = RATE_BREAKS_M_S,
) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:  # fmt: skip
    """Cuts ``GF F + Gv [v; x] <= h`` of a node that also fixes the rate's magnitude class
    ``kappa`` (-1: not fixed) where ``sigma`` is fixed: ``b_k <= u <= b_{k+1}`` (``u = sigma
    v``; the classes cover ``u >= 0``), and where ``tau = +-1`` too the lower edge's yield.

    Proof (lower edge). Beyond the blend ``sigma F >= g(u) = min_j f_j(u)`` (corners as
    :func:`side_cuts`), ``g`` concave (a minimum of concave functions), so on ``[b_k,
    b_{k+1}]`` it lies above its chord; on ``[b_k, inf)``, ``f_j(u) >= f_j(b_k) + b_j (u -
    b_k)`` (``f_j' >= b_j``), so ``sigma F >= g(b_k) + min_j b_j (u - b_k)``. Slack
    :data:`~.branch.CUT_SLACK_KN` on each."""
    n = sigma.size
    edges = np.asarray(breaks, dtype=float)
    at = np.flatnonzero((np.asarray(kappa) >= 0) & (sigma != 0))
    rows: list[tuple[int, float, float, float]] = []  # s, coefficient of F, of v, rhs
    for s in at:
        sv, lo, hi = float(sigma[s]), edges[kappa[s]], edges[kappa[s] + 1]
        rows.append((s, 0.0, -sv, -lo))
        if math.isfinite(hi):
            rows.append((s, 0.0, sv, hi))
        if abs(tau[s]) != 1:
            continue
        a, b, c, d = _corner_kn(cuts, int(tau[s]))
        ends = [np.min(a * (1.0 - np.exp(-d * u)) + b * u + sv * c) if math.isfinite(u) else 0.0
                for u in (lo, hi)]  # fmt: skip
        slope = (ends[1] - ends[0]) / (hi - lo) if math.isfinite(hi) else float(b.min())
        rows.append((s, -sv, slope * sv, -ends[0] + slope * lo + CUT_SLACK_KN))
    arr = np.array(rows, dtype=float).reshape(-1, 4)
    r, col = np.arange(arr.shape[0]), arr[:, 0].astype(int)
    gf = sp.csr_matrix((arr[:, 1], (r, col)), shape=(r.size, n))
    return gf, sp.csr_matrix((arr[:, 2], (r, col)), shape=(r.size, 2 * n)), arr[:, 3]


class StrokeBranchProblem(BranchProblem):
    """:class:`~.branch.BranchProblem` whose nodes also fix the stroke's side ``tau`` (module
    doc); the certificate's affine rows are ``[v; x]`` (2N), forces in kN."""

    def __init__(self, lifted: LiftedEpisode, env: DamperEnvelope, cuts: SideCuts) -> None:
        from capsule_env.bounds.sparse import sparse_lift

        super().__init__(lifted, env)
        f0, n = FORCE_SCALE_N, self.n
        self.side, self.step_of = cuts, lifted.step_of
        self.v_aug = self.a_aug
        x_aug = lifted.x_rows.copy()
        x_aug[:, :n] *= f0
        self.a_aug = np.vstack([self.v_aug, x_aug])
        x_abs = np.abs(x_aug[:, n]) + np.abs(x_aug[:, :n]) @ self.f_abs
        self.v_abs = np.r_[self.v_abs, x_abs * (1.0 + 1e-12)]
        sl, sq = sparse_lift(lifted), self._sparse
        sq.v_x = sp.vstack([sq.v_x, sl.x_x]).tocsr()
        sq.v_f = sp.vstack([sq.v_f, sl.x_f * f0]).tocsr()
        sq.v_c = np.r_[sq.v_c, sl.x_c]

    def rows(  # type: ignore[override]
        self, sigma: np.ndarray, tau: np.ndarray | None = None
    ) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
        """The node's cuts ``GF F + Gv [v; x] <= h``: :meth:`.branch.BranchProblem.rows`,
        the stroke's side cuts where ``tau`` is fixed and the branch's cuts where ``sigma`` is
        fixed too."""
        n, c = self.n, self.side
        gf0, gv0, h0 = super().rows(sigma)
        gv0 = sp.hstack([gv0, sp.csr_matrix((h0.size, n))]).tocsr()
        if tau is None:
            return gf0, gv0, h0
        tau = np.asarray(tau)
        dec = np.flatnonzero((np.abs(tau) == 1) & (sigma != 0))
        sg = sigma[dec].astype(float)
        jv, jx = (sigma[dec] < 0).astype(int), (tau[dec] < 0).astype(int)
        idx, cf, cv, cx = [dec], [-sg], [c.lo_slope[jv, jx] * sg], [np.zeros(dec.size)]
        rhs = [-c.lo_off[jv, jx]]
        for k in range(c.up_slope.shape[2]):  # sigma F - m sigma v <= icpt
            idx.append(dec)
            cf.append(sg)
            cv.append(-c.up_slope[jv, jx, k] * sg)
            cx.append(np.zeros(dec.size))
            rhs.append(c.up_icpt[jv, jx, k])
        side, inside = np.flatnonzero(np.abs(tau) == 1), np.flatnonzero(tau == INSIDE_BLEND)
        for at, coef in ((side, -tau[side].astype(float)), (inside, np.ones(inside.size)),
                         (inside, -np.ones(inside.size))):  # fmt: skip
            idx.append(at)  # coef x <= -blend (tau x >= blend) or +-x <= blend
            cf.append(np.zeros(at.size))
            cv.append(np.zeros(at.size))
            cx.append(coef)
            rhs.append(np.full(at.size, -c.blend_m if at is side else c.blend_m))
        col = np.concatenate(idx)
        row = np.arange(col.size)
        gf = sp.csr_matrix((np.concatenate(cf), (row, col)), shape=(col.size, n))
        gv = sp.csr_matrix((np.r_[np.concatenate(cv), np.concatenate(cx)],
                            (np.r_[row, row], np.r_[col, col + n])), shape=(col.size, 2 * n))  # fmt: skip
        return (sp.vstack([gf0, gf]).tocsr(), sp.vstack([gv0, gv]).tocsr(),
                np.r_[h0, np.concatenate(rhs)])  # fmt: skip

    def node_rows(
        self, sigma: np.ndarray, tau: np.ndarray | None = None, kappa: np.ndarray | None = None,
        current_tie: bool = False, tie_rate: np.ndarray | None = None,
    ) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray, np.ndarray]:  # fmt: skip
        """The node's cuts ``GF [F; e] + Gv [v; x] <= h`` and the ranges of ``e`` (empty
        without the per-step current): :meth:`rows`, :func:`rate_class_rows` where ``kappa``
        is given, and with ``current_tie`` :func:`current_tie_rows` at the rate bound
        ``tie_rate``, default the a-priori one capped by each fixed class's upper end (valid
        in the node; another is valid only if it bounds every ``|v|`` of the node)."""
        parts, extra = [self.rows(sigma, tau)], np.zeros(0)
        if kappa is not None and tau is not None:
            parts.append(rate_class_rows(self.side, sigma, np.asarray(tau), np.asarray(kappa)))
        if current_tie and tau is not None:
            rate = self.v_abs[: self.n] if tie_rate is None else np.asarray(tie_rate, dtype=float)
            if tie_rate is None and kappa is not None:
                top = np.asarray(RATE_BREAKS_M_S)[np.asarray(kappa) + 1]
                rate = np.where(np.asarray(kappa) >= 0, np.minimum(rate, top), rate)
            *part, extra = current_tie_rows(self.side, self.step_of, sigma, np.asarray(tau), rate)
            parts.append((part[0], part[1], part[2]))
        width = self.n + extra.size
        gf = sp.vstack([sp.hstack([f, sp.csr_matrix((f.shape[0], width - f.shape[1]))])
                        for f, _, _ in parts]).tocsr()  # fmt: skip
        gv = sp.vstack([v for _, v, _ in parts]).tocsr()
        return gf, gv, np.concatenate([h for _, _, h in parts]), extra

    def node_bound(  # type: ignore[override]
        self, sigma: np.ndarray, tau: np.ndarray | None = None, current_tie: bool = False,
        kappa: np.ndarray | None = None,
    ) -> tuple[float, np.ndarray]:  # fmt: skip
        """The certified bound of the node (:meth:`node_rows`) and its relaxed forces (kN)."""
        gf, gv, h, extra = self.node_rows(sigma, tau, kappa, current_tie)
        y_w, z, forces = self._sparse.solve(gf, gv, h)
        return self.certify(gf, gv, h, y_w, z, extra), forces

    def violation(self, forces_kn: np.ndarray) -> np.ndarray:
        """As :meth:`.branch.BranchProblem.violation` (the stroke-rate sign's cuts)."""
        a, self.a_aug = self.a_aug, self.v_aug
        try:
            return super().violation(forces_kn)
        finally:
            self.a_aug = a
