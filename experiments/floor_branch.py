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

Leaf diagnostics instead (each prints one JSON line per window and seed): ``--narrowed``
(narrowed, not valid, cut sets), ``--diagnose`` (how the leaves' relaxed solutions depart
from the plant; with ``--stroke`` the leaves that also fix the stroke's side of the blend,
capsule_env.bounds.stroke), ``--current-tie`` (the oracle's (rate, stroke) leaf with the
per-step current's cuts and with its rate classes, and 0 A's leaf with both), ``--partial``
(nodes fixing the oracle's labels at only a fraction of the evaluations), ``--search`` (the
best-first search over rate sign, stroke side and rate class, capsule_env.bounds.search: its
global floor after 1, 10, 100, ``--nodes`` node QPs, at most ``--max-seconds`` per run).
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


def _rollout(lifted: Any, ep: OracleEpisodes, k: int, currents: np.ndarray) -> np.ndarray:
    """The lifted plant's forces (N) under per-step ``currents`` (A)."""
    p = ep.damper_params[k]

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), currents[[step]])
        return float(d[0] + c[0])

    return closed_loop(lifted, law)


def _leaf(problem: BranchProblem, lifted: Any, ep: OracleEpisodes, k: int, currents: np.ndarray):
    """(J of the trajectory, the bound of the leaf of its signs)."""
    forces = _rollout(lifted, ep, k, currents)
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


def _causal_realisation(
    problem: BranchProblem, lifted: Any, ep: OracleEpisodes, k: int, target_kn: np.ndarray
) -> float:
    """Wk of the plant run causally towards the relaxed forces ``target_kn``: per control step,
    the current (of 301 in ``[0, i_max]``) whose force at the step's first evaluation is
    nearest the relaxed one, held for the step's evaluations."""
    p, grid = ep.damper_params[k], np.linspace(0.0, ep.i_max, 301)
    chosen: dict[int, float] = {}
    counter = iter(range(lifted.n_forces))

    def law(x: float, v: float, step: int) -> float:
        s = next(counter)
        if step not in chosen:
            d, c = model_force_parts(ep.code, p, np.full(grid.size, x), np.full(grid.size, v), grid)
            chosen[step] = float(grid[np.argmin(np.abs(d + c - target_kn[s] * FORCE_SCALE_N))])
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), np.array([chosen[step]]))
        return float(d[0] + c[0])

    return math.sqrt(problem.ride(closed_loop(lifted, law) / FORCE_SCALE_N))


def diagnose_leaf(problem: BranchProblem, lifted: Any, ep: OracleEpisodes, k: int,
                  *node: np.ndarray) -> dict[str, float]:  # fmt: skip
    """How the leaf ``node`` (``problem.node_bound``'s arguments)'s relaxed solution departs from the plant: the share of its
    force evaluations outside the model's band ``[F(0 A), F(i_max)]`` at their own relaxed
    stroke and rate (above it, below it in raw force; stronger: beyond it in the stroke
    rate's direction; 1e-3 kN tolerance), the mean excess over
    all evaluations (kN), the mean ``|F|``, the within-step spread (max - min) of the current
    fraction each relaxed force needs (clipped to [0, 1]; mean and median over steps), and the
    Wk of realising the relaxed forces causally (:func:`_causal_realisation`)."""
    bound, forces = problem.node_bound(*node)
    f0, n, p = FORCE_SCALE_N, lifted.n_forces, ep.damper_params[k]
    v = lifted.affine(lifted.v_rows, forces * f0)
    x = lifted.affine(lifted.x_rows, forces * f0)
    zero = np.sum(model_force_parts(ep.code, p, x, v, np.zeros(n)), axis=0) / f0
    full = np.sum(model_force_parts(ep.code, p, x, v, np.full(n, ep.i_max)), axis=0) / f0
    lo, hi = np.minimum(zero, full), np.maximum(zero, full)
    excess = np.maximum(lo - forces, 0.0) + np.maximum(forces - hi, 0.0)
    width = full - zero
    safe = np.where(np.abs(width) > 1e-9, width, 1.0)
    theta = np.clip((forces - zero) / safe, 0.0, 1.0)
    spread = np.array([np.ptp(theta[lifted.step_of == t]) for t in range(ep.n_steps)])
    return {"leaf_bound_wk": math.sqrt(bound),
            "outside_share": float(np.mean(excess > 1e-3)),
            "above_share": float(np.mean(forces - hi > 1e-3)),
            "below_share": float(np.mean(lo - forces > 1e-3)),
        "stronger_share": float(np.mean(np.where(v >= 0.0, forces - hi, lo - forces) > 1e-3)),
            "mean_excess_kn": float(excess.mean()), "mean_abs_force_kn": float(np.abs(forces).mean()),
            "step_spread_mean": float(spread.mean()), "step_spread_median": float(np.median(spread)),
            "causal_realisation_wk": _causal_realisation(problem, lifted, ep, k, forces)}  # fmt: skip


def diagnose(seed: int, length_s: float, stroke: bool = False) -> dict[str, Any]:
    """:func:`diagnose_leaf` at the leaves of the oracle's and of 0 A's stroke-rate signs
    (``stroke``: and their strokes' sides, :mod:`capsule_env.bounds.stroke`)."""
    from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts, stroke_sides

    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), [seed], length_s)
    oracle_i, oracle_wk = _oracle_currents([seed], length_s)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    cuts = side_cuts(ep.code, p)
    problem = (StrokeBranchProblem(lifted, damper_envelope(ep.code, p), cuts) if stroke
               else BranchProblem(lifted, damper_envelope(ep.code, p)))  # fmt: skip
    out: dict[str, Any] = {"length_s": length_s, "seed": seed, "oracle_wk": float(oracle_wk[0])}
    for name, currents in (("oracle_signs", oracle_i[0]), ("zero_a_signs", np.zeros(ep.n_steps))):
        forces = _rollout(lifted, ep, 0, currents)
        node = [np.where(lifted.affine(lifted.v_rows, forces) >= 0.0, 1, -1).astype(np.int8)]
        if stroke:
            node.append(stroke_sides(lifted.affine(lifted.x_rows, forces), cuts.blend_m))
        out[name] = diagnose_leaf(problem, lifted, ep, 0, *node)
    return out


def _leaf_signs(problem: Any, lifted: Any, ep: OracleEpisodes, currents: np.ndarray):
    """``(sigma, tau, kappa, v)`` of the trajectory under ``currents``: its rate signs,
    stroke sides and rate classes (:data:`~capsule_env.bounds.stroke.RATE_BREAKS_M_S`)."""
    from capsule_env.bounds.stroke import RATE_BREAKS_M_S, stroke_sides

    forces = _rollout(lifted, ep, 0, currents)
    v = lifted.affine(lifted.v_rows, forces)
    tau = stroke_sides(lifted.affine(lifted.x_rows, forces), problem.side.blend_m)
    kappa = np.searchsorted(np.asarray(RATE_BREAKS_M_S), np.abs(v), side="right") - 1
    return np.where(v >= 0.0, 1, -1).astype(np.int8), tau, kappa, v


def current_tie(seed: int, length_s: float) -> dict[str, Any]:
    """The leaf at the oracle's (rate, stroke) signs (Wk, certified and at the solver's
    relaxed forces): as is; with the per-step current's cuts
    (:func:`capsule_env.bounds.stroke.current_tie_rows`) at the a-priori rate bound (valid)
    and, as a what-if that is NOT valid, at twice the oracle run's largest ``|v|``; with the
    oracle's rate classes (:func:`~capsule_env.bounds.stroke.rate_class_rows`), alone and with
    the per-step current at each class's upper end (valid in that leaf); and 0 A's (rate,
    stroke, class) leaf with both."""
    from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts

    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), [seed], length_s)
    oracle_i, oracle_wk = _oracle_currents([seed], length_s)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    problem = StrokeBranchProblem(lifted, damper_envelope(ep.code, p), side_cuts(ep.code, p))
    sigma, tau, kappa, v = _leaf_signs(problem, lifted, ep, oracle_i[0])
    zero = _leaf_signs(problem, lifted, ep, np.zeros(ep.n_steps))[:3]
    cases = {"leaf": (sigma, tau, None, False, None),
             "tie_apriori": (sigma, tau, None, True, None),
             "tie_twice_oracle_max_not_valid": (sigma, tau, None, True,
                                                np.full(problem.n, 2 * np.abs(v).max())),
             "classes": (sigma, tau, kappa, False, None),
             "classes_tie": (sigma, tau, kappa, True, None),
             "zero_a_classes_tie": (*zero, True, None)}  # fmt: skip
    out: dict[str, Any] = {"oracle_wk": float(oracle_wk[0])}
    for name, args in cases.items():
        gf, gv, h, extra = problem.node_rows(*args)
        y_w, z, forces = problem._sparse.solve(gf, gv, h)
        out[f"{name}_wk"] = math.sqrt(problem.certify(gf, gv, h, y_w, z, extra))
        out[f"{name}_solver_wk"] = math.sqrt(problem.ride(forces))
    return out


def partial(seed: int, length_s: float) -> dict[str, Any]:
    """Nodes that fix the oracle's (rate sign, stroke side, rate class) at only a fraction of
    the evaluations (a random subset, seed 0, or the window's first part), the rest free,
    with the per-step current: how much of the leaf's bound a partly decided node keeps."""
    from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts

    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), [seed], length_s)
    oracle_i, oracle_wk = _oracle_currents([seed], length_s)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    problem = StrokeBranchProblem(lifted, damper_envelope(ep.code, p), side_cuts(ep.code, p))
    sigma, tau, kappa, _ = _leaf_signs(problem, lifted, ep, oracle_i[0])
    rng = np.random.default_rng(0)
    out: dict[str, Any] = {"oracle_wk": float(oracle_wk[0])}
    for frac in (1.0, 0.99, 0.9, 0.5):
        draw = rng.random(problem.n)
        for name, keep in (
            ("random", draw < frac),
            ("first", np.arange(problem.n) < frac * problem.n),
        ):
            node = (
                np.where(keep, sigma, 0).astype(np.int8),
                np.where(keep, tau, 0).astype(np.int8),
            )
            bound, _ = problem.node_bound(*node, True, np.where(keep, kappa, -1))
            out[f"{name}_{frac:g}_wk"] = math.sqrt(bound)
    return out


def search_floor(seeds: list[int], length_s: float, nodes: int, max_seconds: float,
                 tighten: bool = True, outputs_first: bool = False) -> list[dict[str, Any]]:  # fmt: skip
    """The global floor of :func:`capsule_env.bounds.search.label_search` (split where the
    relaxed force leaves the model's band; ``tighten``: magnitude bounds per node) against
    the oracle; also how many evaluations the least open node labels fully, how many open
    nodes have bound 0 and how many a bound above the oracle's J (they cannot hold the
    optimum). ``outputs_first``: split the sampled outputs' evaluations before the others."""
    from capsule_env.bounds.search import label_search, model_band
    from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts

    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), seeds, length_s)
    _, oracle_wk = _oracle_currents(seeds, length_s)
    rows = []
    for k, seed in enumerate(seeds):
        lifted, p = lift_episode(ep, k), ep.damper_params[k]
        env = damper_envelope(ep.code, p)
        problem = StrokeBranchProblem(lifted, env, side_cuts(ep.code, p))
        res = label_search(problem, env, nodes, outside=model_band(ep.code, p, ep.i_max),
                           tighten=tighten, max_seconds=max_seconds,
                           first=lifted.is_output if outputs_first else None)  # fmt: skip
        floor = {str(b): math.sqrt(max(res.floor_j_at(b), 0.0))
                 for b in (1, 10, 100, nodes) if b <= res.nodes}  # fmt: skip
        rows.append({"length_s": length_s, "seed": seed, "forces": problem.n,
                     "oracle_wk": float(oracle_wk[k]), "floor_wk_at_nodes": floor,
                     "floor_wk": res.floor_wk_m_s2, "floor_to_oracle": res.floor_wk_m_s2
                     / float(oracle_wk[k]), "nodes": res.nodes, "open_nodes": res.open_nodes,
                     "complete": res.complete, "runtime_s": res.runtime_s,
                     "s_per_node": res.runtime_s / res.nodes,
                     "least_open_labelled": int(np.sum(~res.least.open_at())) if res.least else 0,
                     "open_zero": int(np.sum(res.open_bounds_j <= 0.0)),
                     "open_above_oracle": int(np.sum(res.open_bounds_j > oracle_wk[k] ** 2)),
                     "pruned": res.pruned})  # fmt: skip
        print(json.dumps(rows[-1]), flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seeds", type=int, nargs="+", default=[1000, 1001])
    p.add_argument("--lengths", type=float, nargs="+", default=[0.1, 0.35])
    p.add_argument("--nodes", type=int, default=100)
    p.add_argument("--json", type=Path, default=None)
    p.add_argument("--narrowed", action="store_true",
                   help="print only the 0 A leaf with narrowed (not valid) cut sets")  # fmt: skip
    p.add_argument(
        "--current-tie",
        action="store_true",
        help="print only the oracle's (rate, stroke) leaf with the per-step current's cuts "
        "and the rate classes (certified, and J at the solver's relaxed forces)",
    )
    p.add_argument(
        "--partial",
        action="store_true",
        help="print only nodes fixing the oracle's labels at a fraction of the evaluations",
    )
    p.add_argument(
        "--stroke",
        action="store_true",
        help="with --diagnose: leaves that also fix the stroke's side of the blend",
    )
    p.add_argument(
        "--diagnose",
        action="store_true",
        help="print only how the leaves at the oracle's and 0 A's signs depart "
        "from the plant (band excess, per-step current spread, causal realisation)",
    )
    p.add_argument(
        "--search",
        action="store_true",
        help="the search over (rate sign, stroke side, rate class): global floor",
    )
    p.add_argument(
        "--max-seconds",
        type=float,
        default=600.0,
        help="with --search: stop a run after about this many seconds",
    )
    p.add_argument(
        "--no-tighten",
        action="store_true",
        help="with --search: the a-priori magnitude bounds at every node",
    )
    p.add_argument(
        "--outputs-first",
        action="store_true",
        help="with --search: split the sampled outputs' evaluations before the others",
    )
    args = p.parse_args(argv)
    if args.nodes < 1 or any(s < 0 for s in args.seeds) or any(x <= 0 for x in args.lengths):
        sys.exit("floor_branch.py: error: --nodes >= 1, --seeds >= 0 and --lengths > 0 s")
    modes = {"narrowed": narrowed, "current_tie": current_tie, "partial": partial,
             "diagnose": lambda seed, length: diagnose(seed, length, args.stroke)}  # fmt: skip
    for name, fn in modes.items():
        if getattr(args, name):
            for length in args.lengths:
                for seed in args.seeds:
                    print(json.dumps({"length_s": length, "seed": seed, **fn(seed, length)}),
                          flush=True)  # fmt: skip
            return 0
    if args.search and not args.max_seconds > 0:
        sys.exit("floor_branch.py: error: --max-seconds must be > 0")

    def searched(seeds: list[int], length: float, nodes: int) -> list[dict[str, Any]]:
        return search_floor(
            seeds, length, nodes, args.max_seconds, not args.no_tighten, args.outputs_first
        )

    runner = searched if args.search else run
    rows = [r for length in args.lengths for r in runner(args.seeds, length, args.nodes)]
    if args.json is not None:
        tmp = args.json.with_suffix(".tmp")
        tmp.write_text(json.dumps(rows, indent=1))
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
