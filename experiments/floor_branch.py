"""The branched certified floor (capsule_env.bounds.branch) against the oracle, by window length
and node budget, with the leaf diagnostics of docs/fair-comparison.md ("A certified floor").

    OPENBLAS_NUM_THREADS=1 python experiments/floor_branch.py --seeds 1000 1001 \\
        --lengths 0.02 0.05 0.1 0.2 0.35 0.5 1.0 --nodes 1000 --json /tmp/floor_branch.json

Episodes of evaluate.py's guideway bank (``guideway_seed`` 2026). Per window and seed: the
oracle's Wk (``clairvoyant_bound``; below 0.335 s its spectral-length
check is bypassed, the search itself needs none), 0 A's Wk, the branch and bound's floor after
1, 10, 100, ``--nodes`` node QPs and its time per node, and the bound of the single leaf that
fixes the 0 A trajectory's signs and the oracle's (complete branching can certify at most the
least leaf bound: these two bound what any budget can reach with these cuts).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.bounds import evaluation_kwargs
from capsule_env.bounds.branch import BranchProblem, branch_and_bound
from capsule_env.bounds.lifted import closed_loop, lift_episode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope, model_force_parts
from capsule_env.oracle.plant import OracleEpisodes


def _oracle_currents(seeds: list[int], length_s: float) -> tuple[np.ndarray, np.ndarray]:
    from capsule_env.oracle import search

    saved = search.check_episode_length
    search.check_episode_length = lambda *args: None  # the spectral check, not the search's
    try:
        res = search.clairvoyant_bound(evaluation_kwargs({"setting": "sim"}), seeds, length_s)
    finally:
        search.check_episode_length = saved
    return res.currents_a, res.wk_rms_body_acc_m_s2


def _leaf(problem: BranchProblem, lifted: Any, ep: OracleEpisodes, k: int, currents: np.ndarray):
    """(J of the trajectory, the bound of the leaf of its signs)."""
    p = ep.damper_params[k]

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), currents[[step]])
        return float(d[0] + c[0])

    forces = closed_loop(lifted, law)
    v = lifted.affine(lifted.v_rows, forces)
    bound, _ = problem.node_bound(np.where(v >= 0.0, 1, -1).astype(np.int8))
    return problem.ride(forces / FORCE_SCALE_N), bound


def run(seeds: list[int], length_s: float, nodes: int) -> list[dict[str, Any]]:
    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), seeds, length_s)
    oracle_i, oracle_wk = _oracle_currents(seeds, length_s)
    rows = []
    for k, seed in enumerate(seeds):
        lifted = lift_episode(ep, k)
        problem = BranchProblem(lifted, damper_envelope(ep.code, ep.damper_params[k]))
        j_zero, leaf_zero = _leaf(problem, lifted, ep, k, np.zeros(ep.n_steps))
        j_oracle, leaf_oracle = _leaf(problem, lifted, ep, k, oracle_i[k])
        res = branch_and_bound(problem, nodes)
        budgets = [b for b in (1, 10, 100, nodes) if b <= res.nodes]
        rows.append({
            "length_s": length_s, "seed": seed, "forces": problem.n,
            "oracle_wk": float(oracle_wk[k]), "oracle_wk_lifted": math.sqrt(j_oracle),
            "zero_a_wk": math.sqrt(j_zero),
            "floor_wk_at_nodes": {str(b): math.sqrt(res.floor_j_at(b)) for b in budgets},
            "nodes": res.nodes, "complete": res.complete, "open_nodes": res.open_nodes,
            "s_per_node": res.runtime_s / res.nodes,
            "leaf_bound_wk_zero_a_signs": math.sqrt(leaf_zero),
            "leaf_bound_wk_oracle_signs": math.sqrt(leaf_oracle),
        })  # fmt: skip
        print(json.dumps(rows[-1]), flush=True)
    return rows


def narrowed(seed: int, length_s: float) -> dict[str, float]:
    """The 0 A leaf's bound (Wk) with narrowed cut sets, NOT valid bounds: which looseness
    inside a sign matters (no offset; the lower edge's yield by its chord up to the largest
    stroke rate of the 0 A run; both)."""
    from capsule_env.dampers import bi_exponential as be

    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), [seed], length_s)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    env = damper_envelope(ep.code, p)
    problem = BranchProblem(lifted, env)

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), np.zeros(1))
        return float(d[0] + c[0])

    v = lifted.affine(lifted.v_rows, closed_loop(lifted, law))
    sigma = np.where(v >= 0.0, 1, -1).astype(np.int8)
    top, d_lo = float(np.max(np.abs(v))), min(p[be.LOWER + be.D], p[be.UPPER + be.D])
    chord = (env.a_lo * (1.0 - math.exp(-d_lo * top)) / top + env.b_lo) / FORCE_SCALE_N
    cuts = problem.cuts
    sets = {"as shipped": cuts,
            "no offset": dataclasses.replace(cuts, lo_off=(0.0, 0.0), up_off=(0.0, 0.0)),
            "yield chord": dataclasses.replace(cuts, lo_slope=chord),
            "both": dataclasses.replace(cuts, lo_off=(0.0, 0.0), up_off=(0.0, 0.0),
                                        lo_slope=chord)}  # fmt: skip
    out = {}
    for name, c in sets.items():
        problem.cuts = c
        out[name] = math.sqrt(problem.node_bound(sigma)[0])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seeds", type=int, nargs="+", default=[1000, 1001])
    p.add_argument("--lengths", type=float, nargs="+", default=[0.1, 0.35])
    p.add_argument("--nodes", type=int, default=100)
    p.add_argument("--json", type=Path, default=None)
    p.add_argument("--narrowed", action="store_true",
                   help="print only the 0 A leaf with narrowed (not valid) cut sets")  # fmt: skip
    args = p.parse_args(argv)
    if args.nodes < 1 or any(s < 0 for s in args.seeds) or any(x <= 0 for x in args.lengths):
        sys.exit("floor_branch.py: error: --nodes >= 1, --seeds >= 0 and --lengths > 0 s")
    if args.narrowed:
        for length in args.lengths:
            for seed in args.seeds:
                print(json.dumps({"length_s": length, "seed": seed, **narrowed(seed, length)}))
        return 0
    rows = [r for length in args.lengths for r in run(args.seeds, length, args.nodes)]
    if args.json is not None:
        tmp = args.json.with_suffix(".tmp")
        tmp.write_text(json.dumps(rows, indent=1))
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
