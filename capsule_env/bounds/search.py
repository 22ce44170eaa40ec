"""Best-first branch and bound over all three labels of :mod:`.stroke`'s nodes: a global floor.

A node fixes, per force evaluation ``s``, the stroke rate's sign ``sigma_s`` (``+-1``, 0 not
fixed), the stroke's side ``tau_s`` (``+1, -1``, :data:`~.stroke.INSIDE_BLEND`, 0 not fixed)
and, where ``sigma_s`` is fixed, the rate's magnitude class ``kappa_s``
(:data:`~.stroke.RATE_BREAKS_M_S`, -1 not fixed). Its bound is
:meth:`~.stroke.StrokeBranchProblem.node_bound` with the per-step current (certified from the
solver's dual by weak duality: never a solver objective).

Branching: at one evaluation, the first label not yet fixed, in the order ``sigma`` (children
``+1, -1``: they share ``v = 0``), ``tau`` (``+1, -1, 2``: they share the blend's edges),
``kappa`` (its four classes, sharing the breaks). Each family covers every trajectory of its
parent, so the least bound over the open nodes is a floor on ``J`` of every trajectory the
plant can run (every controller), after any number of nodes. The evaluation chosen is the
earliest (causal order: later states depend on earlier forces) with a label left whose relaxed
force lies outside the model's band ``[F(0 A), F(i_max)]`` at its own relaxed stroke and rate
(by more than :data:`BAND_TOL_KN`); if none is, the earliest with a label left. A node with
every label fixed is final: it is never split, and when it holds the least bound the search is
complete (the floor is then the least leaf bound). ``first`` (e.g. the sampled outputs'
evaluations) are split before the others.

Bound tightening (``tighten=True``). The certificate prices the dual's residual with bounds on
``|F_s|``, ``|v_s|``, ``|x_s|``, and the cuts at evaluations with ``sigma_s = 0`` (the hull
lines, :func:`~.branch.hull_lines`) and the per-step current's McCormick envelope use the rate
bound. :func:`node_magnitudes` recomputes them per node by :func:`~.branch.force_magnitude_bounds`'
forward recursion with the node's own facts: where ``kappa_s`` is fixed, ``|v_s|`` is at
most the class's upper end; where ``tau_s = 2``, ``|x_s| <= blend``. Each is a cut of the
node, so the bounds hold on every trajectory in it; no LP is solved for them (an LP's optimum
would need its own certificate).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from capsule_env.bounds.branch import CUT_SLACK_KN, hull_lines
from capsule_env.bounds.relaxation import (
    FORCE_SCALE_N,
    SLOPE_SLACK_REL,
    DamperEnvelope,
    model_force_parts,
)
from capsule_env.bounds.stroke import INSIDE_BLEND, RATE_BREAKS_M_S, StrokeBranchProblem

__all__ = [
    "BAND_TOL_KN",
    "Node",
    "SearchResult",
    "children",
    "label_search",
    "model_band",
    "node_magnitudes",
    "trajectory_labels",
]

#: An evaluation whose relaxed force is within this (kN) of the model's band is not preferred
#: for branching.
BAND_TOL_KN = 1e-3
#: ``(forces_kn, v_m_s, x_m) -> (N,) bool``: where the relaxed force is outside the model's band.
OutsideBand = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Node:
    """The labels of a node, each (N,) int8: ``sigma``, ``tau`` (0: not fixed), ``kappa``
    (-1: not fixed)."""

    sigma: np.ndarray
    tau: np.ndarray
    kappa: np.ndarray

    @classmethod
    def root(cls, n: int) -> Node:
        z = np.zeros(n, dtype=np.int8)
        return cls(z, z.copy(), np.full(n, -1, dtype=np.int8))

    def open_at(self) -> np.ndarray:
        """(N,) bool: the evaluations with a label not fixed."""
        return (self.sigma == 0) | (self.tau == 0) | (self.kappa < 0)


def children(node: Node, s: int) -> list[Node]:
    """The children of ``node`` at evaluation ``s`` (its first label not fixed; module doc):
    together they hold every trajectory of ``node``. ValueError if every label is fixed."""
    if node.sigma[s] == 0:
        name, values = "sigma", (1, -1)
    elif node.tau[s] == 0:
        name, values = "tau", (1, -1, INSIDE_BLEND)
    elif node.kappa[s] < 0:
        name, values = "kappa", tuple(range(len(RATE_BREAKS_M_S) - 1))
    else:
        raise ValueError(f"children: every label of evaluation {s} is fixed")
    out = []
    for value in values:
        labels = {"sigma": node.sigma, "tau": node.tau, "kappa": node.kappa}
        labels[name] = labels[name].copy()
        labels[name][s] = value
        out.append(Node(**labels))
    return out


def trajectory_labels(v_m_s: np.ndarray, x_m: np.ndarray, blend_m: float) -> Node:
    """The labels of a trajectory (rates ``v``, strokes ``x``): the one leaf that the search
    reaches along it (at ``v = 0`` the sign ``+1``, at a break the upper class, at the blend's
    edge the side beyond it, as each family's first child that holds it)."""
    v, x = np.asarray(v_m_s, dtype=float), np.asarray(x_m, dtype=float)
    sigma = np.where(v >= 0.0, 1, -1).astype(np.int8)
    tau = np.where(x >= blend_m, 1, np.where(x <= -blend_m, -1, INSIDE_BLEND)).astype(np.int8)
    kappa = np.searchsorted(np.asarray(RATE_BREAKS_M_S), np.abs(v), side="right") - 1
    return Node(sigma, tau, np.minimum(kappa, len(RATE_BREAKS_M_S) - 2).astype(np.int8))


def node_magnitudes(
    problem: StrokeBranchProblem, env: DamperEnvelope, node: Node
) -> tuple[np.ndarray, np.ndarray]:
    """``(f_abs, vx_abs)``: (N,) kN bounds on ``|F_s|`` and (2N,) bounds on ``[|v_s|; |x_s|]``
    (m/s, m) on every trajectory of ``node``.

    :func:`~.branch.force_magnitude_bounds`' recursion (``|v_s| <= |alpha_s| + sum_{j<s}
    |A_sj| |F_j|``, ``|F| <= min(s_hi |v|, a_hi + b_hi |v|) + |c|_max``), with ``|v_s|``
    capped by the class's upper end where ``kappa_s`` is fixed (the node's cut ``sigma_s v_s
    <= b_{k+1}``, with ``sigma_s v_s >= 0``), and ``|x_s| <= |beta_s| + sum_j |B_sj| |F_j|``
    capped by the blend where ``tau_s = 2``; never above the a-priori bounds."""
    n, f0 = problem.n, FORCE_SCALE_N
    a_abs, alpha = np.abs(problem.v_aug[:, :n]), np.abs(problem.v_aug[:, n])
    top = np.asarray(RATE_BREAKS_M_S)[np.maximum(node.kappa, 0) + 1]
    cap = np.where((node.kappa >= 0) & (node.sigma != 0), top, math.inf)
    c_abs = max(abs(env.c_lo), abs(env.c_hi)) / f0
    s_hi, a_hi, b_hi = env.slope_hi / f0, env.a_hi / f0, env.b_hi * (1 + SLOPE_SLACK_REL) / f0
    f_abs, rate = np.zeros(n), np.zeros(n)
    for s in range(n):
        rate[s] = min((alpha[s] + a_abs[s, :s] @ f_abs[:s]) * (1.0 + 1e-12), cap[s])
        f_abs[s] = min(s_hi * rate[s], a_hi + b_hi * rate[s]) + c_abs + CUT_SLACK_KN
    f_abs = np.minimum(f_abs, problem.f_abs)
    x_aug = problem.a_aug[n:]
    x_abs = (np.abs(x_aug[:, n]) + np.abs(x_aug[:, :n]) @ f_abs) * (1.0 + 1e-12)
    x_abs = np.where(node.tau == INSIDE_BLEND, np.minimum(x_abs, problem.side.blend_m), x_abs)
    vx = np.minimum(np.r_[np.minimum(rate, problem.v_abs[:n]), x_abs], problem.v_abs)
    return f_abs, vx


_UNSOLVED = -2


def _contradicts(problem: StrokeBranchProblem, node: Node, vx: np.ndarray) -> bool:
    """The node is empty: a fixed class starts above the bound on ``|v_s|``
    (:func:`node_magnitudes`, valid on every trajectory of the node), or a fixed side beyond the
    blend needs ``|x_s| >= blend`` above the bound on ``|x_s|``."""
    n, lo = problem.n, np.asarray(RATE_BREAKS_M_S)[np.maximum(node.kappa, 0)]
    rate = (node.kappa >= 0) & (node.sigma != 0) & (lo > vx[:n])
    side = (np.abs(node.tau) == 1) & (problem.side.blend_m > vx[n:])
    return bool(rate.any() or side.any())


def model_band(code: int, params: np.ndarray, i_max_a: float) -> OutsideBand:
    """The branching preference of the module doc: where a relaxed force (kN) lies outside
    ``[min, max]`` of the model's force at 0 A and ``i_max_a`` at its own stroke and rate by
    more than :data:`BAND_TOL_KN` (a heuristic only: the bounds do not depend on it)."""

    def outside(forces_kn: np.ndarray, v: np.ndarray, x: np.ndarray) -> np.ndarray:
        ends = [np.sum(model_force_parts(code, params, x, v, np.full(v.size, i)), axis=0)
                for i in (0.0, i_max_a)]  # fmt: skip
        lo, hi = np.minimum(*ends) / FORCE_SCALE_N, np.maximum(*ends) / FORCE_SCALE_N
        return (forces_kn < lo - BAND_TOL_KN) | (forces_kn > hi + BAND_TOL_KN)

    return outside


class NodeBounder:
    """Certified node bounds of one problem, with or without per-node tightening
    (:func:`node_magnitudes`); ``calls`` counts the node QPs, ``pruned`` the nodes proven
    empty by their magnitude bounds alone (:func:`_contradicts`: no QP)."""

    def __init__(self, problem: StrokeBranchProblem, env: DamperEnvelope, tighten: bool) -> None:
        self.problem, self.env, self.tighten, self.calls = problem, env, tighten, 0
        self.pruned = 0
        self._prior = (problem.f_abs, problem.v_abs, problem.hull_icpt, problem.hull_slope)

    def __call__(self, node: Node) -> tuple[float, np.ndarray]:
        """``(bound on J, relaxed forces kN)`` of ``node`` (``inf``: proven empty)."""
        p = self.problem
        self.calls += 1
        if not self.tighten:
            return p.node_bound(node.sigma, node.tau, True, node.kappa)
        f_abs, vx = node_magnitudes(p, self.env, node)
        if _contradicts(p, node, vx):
            self.calls -= 1
            self.pruned += 1
            return math.inf, np.zeros(p.n)
        icpt, slope = hull_lines(self.env, vx[: p.n])
        p.f_abs, p.v_abs, p.hull_icpt, p.hull_slope = f_abs, vx, icpt, slope
        try:
            return p.node_bound(node.sigma, node.tau, True, node.kappa)
        finally:
            p.f_abs, p.v_abs, p.hull_icpt, p.hull_slope = self._prior


def _split_at(problem: StrokeBranchProblem, node: Node, forces_kn: np.ndarray,
              outside: OutsideBand | None, first: np.ndarray | None = None) -> int:  # fmt: skip
    """The evaluation to split (module doc), among ``first`` (bool, N) while any of those has a
    label left; -1 when every label is fixed."""
    left = node.open_at()
    if not left.any():
        return -1
    if first is not None and (left & first).any():
        left = left & first
    if outside is not None:
        vx = problem.a_aug[:, :-1] @ forces_kn + problem.a_aug[:, -1]
        bad = left & outside(forces_kn, vx[: problem.n], vx[problem.n :])
        if bad.any():
            return int(np.argmax(bad))
    return int(np.argmax(left))


@dataclass(frozen=True)
class SearchResult:
    """What :func:`label_search` found: ``floor_j`` the certified floor on ``J`` ((m/s^2)^2),
    ``history`` ``(nodes solved, floor)`` after the root and after each split, ``nodes``
    solved (nodes proven empty without a QP, ``pruned``, not counted), ``open_nodes`` left, ``complete`` (the least open node is a leaf: the floor is the
    least leaf bound), ``runtime_s``, ``least`` the labels of the least open node."""

    floor_j: float
    history: tuple[tuple[int, float], ...]
    nodes: int
    open_nodes: int
    complete: bool
    runtime_s: float
    least: Node | None
    open_bounds_j: np.ndarray
    pruned: int = 0

    @property
    def floor_wk_m_s2(self) -> float:
        return math.sqrt(max(self.floor_j, 0.0))

    def floor_j_at(self, nodes: int) -> float:
        """The floor after at most ``nodes`` node QPs."""
        return max((f for k, f in self.history if k <= nodes), default=0.0)


def label_search(
    problem: StrokeBranchProblem,
    env: DamperEnvelope,
    max_nodes: int,
    start: Node | None = None,
    outside: OutsideBand | None = None,
    tighten: bool = True,
    max_seconds: float = math.inf,
    first: np.ndarray | None = None,
) -> SearchResult:
    """Best-first branch and bound over ``(sigma, tau, kappa)`` from ``start`` (default the
    root, nothing fixed): at most ``max_nodes`` node QPs and about ``max_seconds``. The floor
    is the least bound over the open nodes (each at least its parent's); a family cut short by
    the budget keeps its parent's bound for its unsolved children. ``first`` (N, bool): split
    these evaluations before the others (e.g. the sampled outputs, ``lifted.is_output``)."""
    if isinstance(max_nodes, bool) or not isinstance(max_nodes, int) or max_nodes < 1:
        raise ValueError(f"label_search: max_nodes must be an integer >= 1, got {max_nodes!r}")
    if first is not None:
        first = np.asarray(first)
        if first.dtype != bool or first.shape != (problem.n,):
            raise ValueError(
                f"label_search: first must be a bool array of shape ({problem.n},), got "
                f"dtype {first.dtype} shape {first.shape}"
            )
    t0 = time.perf_counter()
    bounder = NodeBounder(problem, env, tighten)
    node = Node.root(problem.n) if start is None else start
    root, forces = bounder(node)
    heap = [(root, 0, _split_at(problem, node, forces, outside, first), node)]
    history, counter = [(1, root)], 1
    while heap and bounder.calls < max_nodes and time.perf_counter() - t0 < max_seconds:
        bound, _, s, node = heap[0]
        if s < 0 or not math.isfinite(bound):
            break
        heapq.heappop(heap)
        for child in children(node, s):
            k = _UNSOLVED
            if bounder.calls < max_nodes:
                own, forces = bounder(child)
                if own == math.inf:
                    continue
                bound_c, k = max(bound, own), _split_at(problem, child, forces, outside, first)
            else:
                bound_c = bound
            heapq.heappush(heap, (bound_c, counter, k, child))
            counter += 1
        history.append((bounder.calls, heap[0][0] if heap else math.inf))
    complete = bool(heap) and heap[0][2] == -1
    return SearchResult(heap[0][0] if heap else math.inf, tuple(history), bounder.calls,
                        len(heap), complete, time.perf_counter() - t0,
                        heap[0][3] if heap else None, np.array([h[0] for h in heap]),
                        bounder.pruned)  # fmt: skip
