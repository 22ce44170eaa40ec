"""Does the objective cutoff pin the stroke rates? A diagnostic of the certified floor's search
(docs/fair-comparison.md, "What limits it"), not a bound.

    OPENBLAS_NUM_THREADS=1 python experiments/floor_cutoff.py --seeds 1000 1001 --lengths 0.05 0.1

A branch and bound may add ``J <= UB`` to every node, ``UB`` the ``J`` of a trajectory the
plant runs (here the oracle's): the least ``J`` over all trajectories is at most ``UB``, so
no trajectory that could hold it is cut off. Optimisation-based bound tightening then asks, at
the root (no label fixed: the hull lines of :func:`capsule_env.bounds.branch.hull_lines` at
every evaluation), how far each force evaluation's stroke rate ``v_s`` can range under that
cutoff: two second-order cone programs per evaluation (Clarabel; their optima are the
solver's, not certified, which is enough to measure whether the idea could fix labels).
Printed per window and seed, without the cutoff (the root's own ranges) and with it: how many
evaluations' rate signs are fixed (range not containing 0), the ranges' median width against
the oracle's median ``|v|``, and whether the oracle's rates lie inside (they must).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np
import scipy.sparse as sp
from floor_branch import _leaf_signs, _oracle_currents, _rollout  # type: ignore[import-not-found]

from capsule_env.bounds import evaluation_kwargs
from capsule_env.bounds.lifted import lift_episode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope
from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts
from capsule_env.oracle.plant import OracleEpisodes


def _root_cone(
    pr: StrokeBranchProblem, ub_j: float | None
) -> tuple[sp.csc_matrix, np.ndarray, list]:
    """``(A, b, cones)`` of the root's cuts and, unless ``ub_j`` is None, ``|w|^2 / T <= ub_j``
    over the forces (kN)."""
    import clarabel

    n, t = pr.n, pr.t
    gf, gv, h, _ = pr.node_rows(np.zeros(n, np.int8), np.zeros(n, np.int8))
    lin, const = pr.a_aug[:, :n], pr.a_aug[:, n]
    g = sp.csr_matrix(gf[:, :n] + gv @ lin)
    cones = [clarabel.NonnegativeConeT(g.shape[0])]
    if ub_j is None:
        return g.tocsc(), h - gv @ const, cones
    a = sp.vstack([g, sp.csr_matrix((1, n)), sp.csr_matrix(-pr.wf)]).tocsc()
    b = np.r_[h - gv @ const, math.sqrt(t * ub_j), pr.wc]
    return a, b, [*cones, clarabel.SecondOrderConeT(t + 1)]


def rate_intervals(pr: StrokeBranchProblem, ub_j: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` (N,): each evaluation's stroke rate range (m/s) over the root, under the
    cutoff ``J <= ub_j`` unless it is None (the solver's optima)."""
    import clarabel

    a, b, cones = _root_cone(pr, ub_j)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    n, zero = pr.n, sp.csc_matrix((pr.n, pr.n))
    lo, hi = np.zeros(n), np.zeros(n)
    for s in range(n):
        row = pr.v_aug[s, :n]
        for sign, out in ((1.0, lo), (-1.0, hi)):
            sol = clarabel.DefaultSolver(zero, sign * row, a, b, cones, settings).solve()
            out[s] = sign * sol.obj_val + pr.v_aug[s, n]
    return lo, hi


def measure(seed: int, length_s: float, cutoff: float) -> dict[str, Any]:
    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), [seed], length_s)
    oracle_i, oracle_wk = _oracle_currents([seed], length_s)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    pr = StrokeBranchProblem(lifted, damper_envelope(ep.code, p), side_cuts(ep.code, p))
    j_oracle = pr.ride(_rollout(lifted, ep, 0, oracle_i[0]) / FORCE_SCALE_N)
    v_oracle = _leaf_signs(pr, lifted, ep, oracle_i[0])[3]
    out: dict[str, Any] = {"forces": pr.n, "oracle_wk": float(oracle_wk[0]),
                           "cutoff_x_oracle_j": cutoff,
                           "oracle_median_abs_v_m_s": float(np.median(np.abs(v_oracle)))}  # fmt: skip
    for name, ub in (("no_cutoff", None), ("cutoff", cutoff * j_oracle)):
        start = time.perf_counter()
        lo, hi = rate_intervals(pr, ub)
        out[name] = {
            "signs_fixed": int(np.sum((lo > 0.0) | (hi < 0.0))),
            "median_width_m_s": float(np.median(hi - lo)),
            "oracle_inside": bool(np.all((lo <= v_oracle + 1e-9) & (v_oracle <= hi + 1e-9))),
            "seconds": time.perf_counter() - start,
        }
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seeds", type=int, nargs="+", default=[1000, 1001])
    p.add_argument("--lengths", type=float, nargs="+", default=[0.05, 0.1])
    p.add_argument("--cutoff", type=float, default=1.0, help="UB as a multiple of the oracle's J")
    args = p.parse_args(argv)
    if any(s < 0 for s in args.seeds) or any(x <= 0 for x in args.lengths):
        sys.exit("floor_cutoff.py: error: --seeds >= 0 and --lengths > 0 s")
    if not args.cutoff >= 1.0 or not math.isfinite(args.cutoff):
        sys.exit("floor_cutoff.py: error: --cutoff must be a finite number >= 1 (x the oracle's J)")
    for length in args.lengths:
        for seed in args.seeds:
            row = {"length_s": length, "seed": seed, **measure(seed, length, args.cutoff)}
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
