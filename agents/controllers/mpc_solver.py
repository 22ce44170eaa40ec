"""One vehicle's semi-active MPC problem and its QP solver (:mod:`capsule_env.agents.controllers.mpc`).

Variables ``y = [w (W blocked moves); eps (N slacks)]``, forces scaled by ``force_scale_n``.
At each interval ``j`` of the horizon, with ``sigma_j`` the sign of the reference stroke rate
``vbar_j`` (the measured rate at ``j = 0``; the previous plan's prediction after):

- dissipative: ``sigma_j u_j >= 0`` (hard);
- in the band the damper can make at the predicted rate ``v_j``, each edge
  (``F(v, 0)``, ``F(v, i_max)`` of the inverted model) linearised at ``vbar_j``:
  ``lower(vbar) + g_lo (v_j - vbar_j) - eps_j <= u_j <= upper(vbar) + g_hi (v_j - vbar_j) + eps_j``;
  where ``v_j`` does not depend on the plan (``j <= delay``) the edges are exact constants;
- the slack ``eps_j >= 0`` costs ``rho_1 eps + rho_2 eps^2`` (an exact penalty: zero whenever
  the band can be met), so the problem is always feasible.

Fixing the sign pattern makes the non-convex set (the band flips with the rate's sign) convex;
:meth:`BandQP.plan` re-solves with the new pattern while the plan's predicted signs differ
from the assumed ones (at most ``max_passes`` solves).

Two solvers (the ``mpc`` extra installs both), the same problem:

- ``"daqp"`` (default): DAQP (Arnstrom, Bemporad & Axehill 2022), a dual active-set solver
  written for the small dense QPs of embedded MPC: the exact optimum (the active set, not an
  approximate iterate), about 20 us and 14 iterations per solve here, warm-started from the
  previous plan's active set;
- ``"osqp"``: OSQP (Stellato et al. 2020), ADMM on the sparse problem, updated in place and
  warm-started from its previous iterate; approximate to ``eps_abs``/``eps_rel`` (polished to
  the active set when polishing succeeds), 125-275 iterations per solve here and 10 x DAQP's
  time. Kept as the independent cross-check (``tests/test_mpc.py``) and for problems that
  grow sparse (long horizons).
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from capsule_env.agents.controllers.mpc_qp import CondensedQP, _edges
from scipy import sparse

__all__ = [
    "SolverOptions",
    "BandQP",
    "PlanResult",
    "solver_available",
    "check_integer",
    "check_real",
]


BACKENDS = ("daqp", "osqp")
_BIG = 1e30  # DAQP's "no bound"


def solver_available(backend: str = "daqp") -> bool:
    """Whether the QP solver ``backend`` (the ``mpc`` extra) is installed."""
    import importlib.util

    return importlib.util.find_spec(backend) is not None


def _module(backend: str) -> Any:
    """The solver's module, imported when a problem is first set up (the ``mpc`` extra)."""
    try:
        return __import__(backend)
    except ImportError:  # pragma: no cover - the dev extra installs both
        raise ImportError(
            f"the MPC controllers need {backend}: pip install 'capsule-env[mpc]'"
        ) from None


@dataclass(frozen=True)
class SolverOptions:
    """The solver's settings (see :class:`capsule_env.agents.controllers.mpc.MPCController`)."""

    backend: str = "daqp"  # or "osqp"
    eps_abs: float = 1e-3  # OSQP's, on forces scaled by max_force_n
    eps_rel: float = 1e-3
    max_iter: int = 4000  # OSQP's ADMM iterations or DAQP's active-set changes
    time_limit_s: float = 0.0  # 0: none (results then do not depend on the machine's load)
    polish: bool = True
    max_passes: int = 2  # solves per step while the sign pattern changes
    constrained_steps: int = 3  # intervals of the horizon under the band (0: all)
    secant_m_s: float = 1e-4  # the band edges' slope: the secant over this rate (1e-4: tangent)

    def check(self) -> SolverOptions:
        """These options with plain Python values; raise ``ValueError`` naming a bad option
        and its accepted type and range (a bool is not a number here)."""
        if not (isinstance(self.backend, str) and self.backend in BACKENDS):
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {self.backend!r}")
        if not isinstance(self.polish, (bool, np.bool_)):
            raise ValueError(f"polish must be True or False, got {self.polish!r}")
        return replace(
            self,
            eps_abs=check_real("eps_abs", self.eps_abs, 0.0, 1.0, open_low=True),
            eps_rel=check_real("eps_rel", self.eps_rel, 0.0, 1.0, open_low=True),
            max_iter=check_integer("max_iter", self.max_iter, 1, 10**6),
            time_limit_s=check_real("time_limit_s", self.time_limit_s, 0.0, 10.0, unit=" s"),
            polish=bool(self.polish),
            max_passes=check_integer("max_passes", self.max_passes, 1, 20),
            constrained_steps=check_integer("constrained_steps", self.constrained_steps, 0, 200),
            secant_m_s=check_real("secant_m_s", self.secant_m_s, 1e-6, 1.0, unit=" m/s"),
        )


def check_integer(name: str, value: Any, low: int, high: int) -> int:
    """``value`` as an int; ``ValueError`` naming ``name`` unless an integer (not a bool) in
    ``[low, high]``."""
    if (
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (int, np.integer))
        or not (low <= value <= high)
    ):
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def check_blocks(blocks: Any, horizon: int) -> tuple[int, ...] | None:
    """``move_blocks`` as a tuple (None stays None); ``ValueError`` naming it unless positive
    integers summing to ``horizon`` (one integer is not a list of lengths)."""
    if blocks is None:
        return None
    given = blocks
    blocks = tuple(blocks) if isinstance(blocks, Iterable) else ()
    if not blocks or sum(check_integer("move_blocks", b, 1, 200) for b in blocks) != horizon:
        raise ValueError(f"move_blocks must be positive integers summing to horizon_steps "
                         f"({horizon}), got {given!r}")  # fmt: skip
    return blocks


def check_real(
    name: str, value: Any, low: float, high: float, *, open_low: bool = False, unit: str = ""
) -> float:
    """``value`` as a float; ``ValueError`` naming ``name`` unless a real number (not a bool)
    in ``[low, high]`` (``(low, high]`` with ``open_low``)."""
    if (
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not (low < value if open_low else low <= value)
        or not value <= high
    ):
        bracket = "(" if open_low else "["
        raise ValueError(f"{name} must be a number in {bracket}{low:g}, {high:g}]{unit}, "
                         f"got {value!r}")  # fmt: skip
    return float(value)


@dataclass
class PlanResult:
    """A plan: the moves ``u`` (N, newtons), the predicted stroke rate and stroke at the start
    of each interval, the solves it took, and its status (``"solved"``, ``"failed"`` or
    ``"time_limit"``; not solved: ``u`` is None)."""

    u: np.ndarray | None
    rate_m_s: np.ndarray | None
    stroke_m: np.ndarray | None
    solves: int
    status: str


class BandQP:
    """The QP of one vehicle (module docstring), set up once, updated and warm-started each
    step."""

    def __init__(
        self, qp: CondensedQP, damper: Any, force_scale_n: float, options: SolverOptions
    ) -> None:
        self.qp, self.damper, self.scale = qp, damper, float(force_scale_n)
        self._params, self._i_max = damper.as_array(), float(damper.max_current_a)
        self.options = options
        n_steps, n_moves = qp.blocking.shape
        self.n_steps, self.n_moves = n_steps, n_moves
        h = qp.h * self.scale**2
        w = float(np.max(np.diag(h)))
        self.rho1 = 1e4 * w  # slack penalty, linear (exact) and a little quadratic
        p = sparse.block_diag([sparse.csc_matrix(h), 1e-2 * w * sparse.eye(n_steps)])
        csc = sparse.csc_matrix(self._pattern())
        self.rows = csc.indices.copy()
        self.cols = np.repeat(np.arange(csc.shape[1]), np.diff(csc.indptr))
        per = n_steps // qp.inputs  # intervals per input (the rows are input-major)
        interval = np.arange(n_steps) % per
        self.unconstrained = np.flatnonzero(interval >= (options.constrained_steps or per))
        self.first = interval == 0  # each input's interval 0: the band at the measured rate
        self.fixed = np.all(qp.rate_w == 0.0, axis=1)  # intervals whose rate the plan cannot move
        self.backend = _module(options.backend)
        self._last: np.ndarray | None = None  # DAQP's warm start: the previous solution
        if options.backend == "daqp":
            self.hessian = np.ascontiguousarray(p.toarray())
        else:
            self._setup_osqp(p, csc.indptr, csc.shape)

    def __reduce__(self) -> tuple[Any, tuple]:
        """Pickled (and deep-copied) as its set-up, the solver modules not being picklable:
        DAQP's warm start travels; OSQP's solver is set up afresh (a cold start)."""
        return _rebuilt, (self.qp, self.damper, self.scale, self.options, self._last)

    def _setup_osqp(self, p: Any, indptr: np.ndarray, shape: tuple[int, int]) -> None:
        osqp, o, n = self.backend, self.options, self.n_steps
        self._solved = int(osqp.SolverStatus.OSQP_SOLVED)
        self._time_limit = int(osqp.SolverStatus.OSQP_TIME_LIMIT_REACHED)
        a = self._constraints(np.zeros(n), np.zeros(n))[self.rows, self.cols]
        self.solver = osqp.OSQP()
        self.solver.setup(
            P=sparse.triu(p, format="csc"), q=np.zeros(self.n_moves + n),
            A=sparse.csc_matrix((a, self.rows, indptr), shape=shape),
            l=np.full(4 * n, -np.inf), u=np.full(4 * n, np.inf),
            eps_abs=o.eps_abs, eps_rel=o.eps_rel, max_iter=o.max_iter,
            time_limit=o.time_limit_s or 1e10, polishing=o.polish, verbose=False,
            warm_starting=True,
        )  # fmt: skip

    def _pattern(self) -> np.ndarray:
        """Every entry the constraint matrix may use (dense in the band rows)."""
        n, m = self.n_steps, self.n_moves
        mask = np.zeros((4 * n, m + n), dtype=bool)
        mask[:n, :m] = self.qp.blocking != 0
        mask[n : 3 * n, :m] = True
        idx = np.arange(n)
        mask[n + idx, m + idx] = mask[2 * n + idx, m + idx] = mask[3 * n + idx, m + idx] = True
        return mask

    def _constraints(self, g_lo: np.ndarray, g_hi: np.ndarray) -> np.ndarray:
        """The dense constraint matrix for edge slopes ``g_lo``, ``g_hi`` (N s/m)."""
        n, m, t = self.n_steps, self.n_moves, self.qp.blocking
        if getattr(self, "_fixed_rows", None) is None:  # the rows that never change
            a = np.zeros((4 * n, m + n))
            a[:n, :m] = t
            a[n : 2 * n, m:] = np.eye(n)
            a[2 * n : 3 * n, m:] = -np.eye(n)
            a[3 * n :, m:] = np.eye(n)
            self._fixed_rows = a
        a = self._fixed_rows.copy()
        a[n : 2 * n, :m] = t - g_lo[:, None] * self.qp.rate_w
        a[2 * n : 3 * n, :m] = t - g_hi[:, None] * self.qp.rate_w
        return a

    def _solve(
        self,
        free_rate: np.ndarray,
        free_stroke: np.ndarray,
        ref_rate: np.ndarray,
        ref_stroke: np.ndarray,
        linear: bool,
    ) -> tuple[np.ndarray | None, str]:
        """One solve with the sign pattern and linearisation of ``ref_rate``, ``ref_stroke``.
        ``free_*``: the predicted rate/stroke with ``w = 0``."""
        n = self.n_steps
        edges = np.empty((4, n))
        _edges(self.damper.code, self._params, self._i_max, ref_stroke, ref_rate,
               self.options.secant_m_s, edges)  # fmt: skip
        edges /= self.scale
        sigma = np.where(ref_rate >= 0.0, 1.0, -1.0)
        pos = sigma > 0  # lower edge: 0 A when moving out, i_max when moving in
        lo = np.where(pos, edges[0], edges[1])
        hi = np.where(pos, edges[1], edges[0])
        g_lo = np.where(pos, edges[2], edges[3]) * self.scale
        g_hi = np.where(pos, edges[3], edges[2]) * self.scale
        g_lo[self.fixed], g_hi[self.fixed] = 0.0, 0.0  # exact constants there
        shift = (free_rate - ref_rate) / self.scale
        lower = np.concatenate([np.where(pos, 0.0, -np.inf), lo + g_lo * shift,
                                np.full(n, -np.inf), np.zeros(n)])  # fmt: skip
        upper = np.concatenate([np.where(pos, np.inf, 0.0), np.full(n, np.inf),
                                hi + g_hi * shift, np.full(n, np.inf)])  # fmt: skip
        free = self.unconstrained  # intervals left outside the band
        lower[free], upper[free], lower[n + free], upper[2 * n + free] = (
            -np.inf,
            np.inf,
            -np.inf,
            np.inf,
        )
        q = np.concatenate([linear * self.scale, np.full(n, self.rho1)])
        a = self._constraints(g_lo, g_hi)
        if self.options.backend == "daqp":
            return self._daqp(q, a, lower, upper)
        self.solver.update(q=q, l=lower, u=upper, Ax=a[self.rows, self.cols])
        res = self.solver.solve(raise_error=False)
        status = res.info.status_val
        if status != self._solved:
            return None, "time_limit" if status == self._time_limit else "failed"
        if not np.all(np.isfinite(res.x)):
            return None, "failed"
        return res.x[: self.n_moves], "solved"

    def _daqp(
        self, q: np.ndarray, a: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> tuple[np.ndarray | None, str]:
        """DAQP's solve, warm-started from the previous solution; a solve over
        ``time_limit_s`` (measured: DAQP has no clock of its own) is discarded."""
        t0 = time.perf_counter()
        x, _, flag, _ = self.backend.solve(
            self.hessian, q, a, np.minimum(upper, _BIG), np.maximum(lower, -_BIG),
            primal_start=self._last, iter_limit=self.options.max_iter,
        )  # fmt: skip
        limit = self.options.time_limit_s
        if limit and time.perf_counter() - t0 > limit:
            self._last = None
            return None, "time_limit"
        # 1 optimal, 2 soft optimal; < 0 infeasible, cycling, iteration limit
        if flag < 1 or not np.all(np.isfinite(x)):
            self._last = None
            return None, "failed"
        self._last = np.asarray(x, dtype=float)
        return self._last[: self.n_moves], "solved"

    def plan(
        self,
        z0: np.ndarray,
        rises: np.ndarray,
        rate_now_m_s: float | np.ndarray,
        stroke_now_m: float | np.ndarray,
        reference_rate_m_s: np.ndarray,
        reference_stroke_m: np.ndarray,
    ) -> PlanResult:
        """The plan from state ``z0`` with ``rises`` (R,) ahead; the band at interval 0 at the
        measured ``rate_now_m_s`` and ``stroke_now_m`` (a float, or one per input);
        ``reference_*``: the previous plan's predictions (N,) for the sign pattern and the
        linearisation of the later intervals.
        A non-finite input is not solved (``"failed"``, no solve) and leaves the warm start
        as it was."""
        given = (z0, rises, rate_now_m_s, stroke_now_m, reference_rate_m_s, reference_stroke_m)
        if not all(np.all(np.isfinite(v)) for v in given):
            return PlanResult(None, None, None, 0, "failed")
        qp = self.qp
        linear = qp.f_z @ z0 + qp.f_d @ rises
        free_rate = qp.rate_z @ z0 + qp.rate_d @ rises
        free_stroke = qp.stroke_z @ z0 + qp.stroke_d @ rises
        ref_rate = np.where(self.fixed, free_rate, reference_rate_m_s)
        ref_stroke = np.where(self.fixed, free_stroke, reference_stroke_m)
        ref_rate[self.first], ref_stroke[self.first] = rate_now_m_s, stroke_now_m
        free_rate = free_rate.copy()
        free_rate[self.first] = rate_now_m_s
        later = ~self.first
        for solves in range(1, self.options.max_passes + 1):
            w, status = self._solve(free_rate, free_stroke, ref_rate, ref_stroke, linear)
            if w is None:
                return PlanResult(None, None, None, solves, status)
            w = w * self.scale
            rate = free_rate + qp.rate_w @ w
            stroke = free_stroke + qp.stroke_w @ w
            same = np.array_equal(rate[later] >= 0.0, ref_rate[later] >= 0.0)
            ref_rate[later], ref_stroke[later] = rate[later], stroke[later]
            if same:
                break
        return PlanResult(qp.blocking @ w, rate, stroke, solves, "solved")


def _rebuilt(
    qp: CondensedQP, damper: Any, scale: float, options: SolverOptions, last: np.ndarray | None
) -> BandQP:
    """A :class:`BandQP` set up again, with DAQP's warm start ``last`` (unpickling)."""
    problem = BandQP(qp, damper, scale, options)
    problem._last = last
    return problem
