"""The branch and bound over rate sign, stroke side and rate class (capsule_env.bounds.search):
its children cover their parent, its per-node magnitude bounds hold on rollouts, a completed
search equals the least leaf of a brute-force enumeration, and its floor stays below the J
of simulated trajectories."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from test_bounds_branch import _rollout

from capsule_env import metrics
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope
from capsule_env.bounds.search import (
    Node,
    NodeBounder,
    children,
    label_search,
    model_band,
    node_magnitudes,
    trajectory_labels,
)
from capsule_env.bounds.stroke import INSIDE_BLEND, RATE_BREAKS_M_S, StrokeBranchProblem, side_cuts
from capsule_env.engine.layout import OUT_BODY_ACC
from capsule_env.oracle.plant import OracleEpisodes


@pytest.fixture(scope="module")
def short() -> OracleEpisodes:
    return OracleEpisodes({"setting": "sim"}, [1000], 0.02)


@pytest.fixture(scope="module")
def longer() -> OracleEpisodes:
    """0.05 s: beyond the blend at some evaluations (at 0.02 s seed 1000 stays inside it, where
    the leaves certify 0)."""
    return OracleEpisodes({"setting": "sim"}, [1000], 0.05)


def _trajectories(ep: OracleEpisodes):
    """0 A, random and on-off rollouts: ``(lifted, forces N, v, x, problem, env, env's J)``,
    the env's J from the compiled kernel (an independent number)."""
    p = ep.damper_params[0]
    env, cuts = damper_envelope(ep.code, p), side_cuts(ep.code, p)
    rng = np.random.default_rng(3)
    for currents in (np.zeros(ep.n_steps), rng.uniform(0, 1.5, ep.n_steps),
                     rng.choice([0.0, 1.5], ep.n_steps)):  # fmt: skip
        lifted, forces = _rollout(ep, currents)
        _, out = ep.run(np.array([0]), currents[None], substeps="env")
        j = float(metrics.wk_weighted_rms(out[0, :, OUT_BODY_ACC], ep.dt_s)) ** 2
        v, x = lifted.affine(lifted.v_rows, forces), lifted.affine(lifted.x_rows, forces)
        yield lifted, forces, v, x, StrokeBranchProblem(lifted, env, cuts), env, j


def _holds(node: Node, v: np.ndarray, x: np.ndarray, blend: float) -> np.ndarray:
    """(N,) bool: the trajectory satisfies the node's defining constraints at each evaluation
    (written from the labels' meaning, not from the search's code)."""
    ok = node.sigma * v >= 0.0
    side = np.where(node.tau == 1, x >= blend, np.where(node.tau == -1, x <= -blend, True))
    ok &= np.where(node.tau == INSIDE_BLEND, np.abs(x) <= blend, side)
    edges = np.asarray(RATE_BREAKS_M_S)
    k = np.maximum(node.kappa, 0)
    u = np.abs(v)
    return ok & ((node.kappa < 0) | ((u >= edges[k]) & (u <= edges[k + 1])))


def _agrees(node: Node, own: Node, s: int) -> bool:
    """The node's labels at ``s`` are the trajectory's or not fixed."""
    return all(getattr(node, a)[s] in (getattr(own, a)[s], unfixed)
               for a, unfixed in (("sigma", 0), ("tau", 0), ("kappa", -1)))  # fmt: skip


def _free(node: Node, at: list[int]) -> Node:
    sigma, tau, kappa = node.sigma.copy(), node.tau.copy(), node.kappa.copy()
    sigma[at], tau[at], kappa[at] = 0, 0, -1
    return Node(sigma, tau, kappa)


def test_children_cover_the_parent_and_the_labels_give_one_path(short: OracleEpisodes) -> None:
    """Along each rollout, from the root down to its own leaf: the rollout satisfies at least
    one child's constraints at every split, exactly one child carries its labels, and every
    node's magnitude bounds (tightened) hold on it."""
    for _, forces, v, x, problem, env, _ in _trajectories(short):
        blend = problem.side.blend_m
        own = trajectory_labels(v, x, blend)
        assert _holds(own, v, x, blend).all()
        node = Node.root(problem.n)
        for s in range(problem.n):
            while node.open_at()[s]:
                kids = children(node, s)
                assert sum(_holds(c, v, x, blend).all() for c in kids) >= 1
                mine = [c for c in kids if _agrees(c, own, s)]
                assert len(mine) == 1
                node = mine[0]
                f_abs, vx = node_magnitudes(problem, env, node)
                assert np.all(np.abs(forces) / FORCE_SCALE_N <= f_abs)
                assert np.all(np.abs(np.r_[v, x]) <= vx)
        assert not node.open_at().any()
        with pytest.raises(ValueError, match="every label"):
            children(node, 0)


def test_tightening_shrinks_the_bounds_in_a_classed_node(short: OracleEpisodes) -> None:
    _, _, v, x, problem, env, _ = next(_trajectories(short))
    leaf = trajectory_labels(v, x, problem.side.blend_m)
    f_abs, vx = node_magnitudes(problem, env, leaf)
    assert np.all(f_abs <= problem.f_abs) and np.all(vx <= problem.v_abs)
    assert f_abs[-1] < 0.9 * problem.f_abs[-1]
    # the fastest class at the first evaluation with a nonzero rate bound: beyond the bound,
    # so the node is empty without a QP (no rollout's |v| comes near 60 mm/s there)
    s = int(np.argmax(problem.v_abs[: problem.n] > 0.0))
    assert problem.v_abs[s] < RATE_BREAKS_M_S[3]
    node = Node.root(problem.n)
    node.sigma[s], node.kappa[s] = 1, 3
    bounder = NodeBounder(problem, env, tighten=True)
    assert bounder(node)[0] == math.inf and (bounder.calls, bounder.pruned) == (0, 1)
    for _, _, v_r, _, _, _, _ in _trajectories(short):
        assert abs(v_r[s]) < RATE_BREAKS_M_S[3]


def test_completed_search_equals_the_least_enumerated_leaf(longer: OracleEpisodes) -> None:
    """Evaluation 40's three labels and evaluation 60's sign and side left free from the 0 A
    rollout's leaf: the completed search equals the least of the 24 x 6 leaves' bounds
    enumerated directly, its floor never falls with the nodes, and it stays below the
    rollout's J."""
    _, _, v, x, problem, env, j = next(_trajectories(longer))
    leaf = trajectory_labels(v, x, problem.side.blend_m)
    start = _free(leaf, [40, 60])
    start.kappa[60] = leaf.kappa[60]
    bounder = NodeBounder(problem, env, tighten=True)
    least = math.inf
    signs_sides = list(itertools.product((1, -1), (1, -1, INSIDE_BLEND)))
    for (sg, tu), ka, (sg2, tu2) in itertools.product(
        signs_sides, range(len(RATE_BREAKS_M_S) - 1), signs_sides
    ):
        node = Node(start.sigma.copy(), start.tau.copy(), start.kappa.copy())
        node.sigma[[40, 60]], node.tau[[40, 60]], node.kappa[40] = (sg, sg2), (tu, tu2), ka
        least = min(least, bounder(node)[0])
    res = label_search(problem, env, 5000, start=start)
    assert res.complete
    assert 0.0 < least <= j
    assert res.floor_j == pytest.approx(least, rel=1e-4)
    floors = [f for _, f in res.history]
    assert all(b >= a for a, b in itertools.pairwise(floors))
    assert res.floor_j <= j


def test_floor_is_below_simulated_trajectories(short: OracleEpisodes) -> None:
    """From the root (any budget) and from a node holding each rollout (its labels at all
    but four evaluations), the floor is at most the rollout's simulated J."""
    for _, _, v, x, problem, env, j in _trajectories(short):
        band = model_band(short.code, short.damper_params[0], short.i_max)
        assert label_search(problem, env, 30, outside=band).floor_j <= j
        leaf = trajectory_labels(v, x, problem.side.blend_m)
        start = _free(leaf, [5, 14, 23, 32])
        for tighten in (True, False):
            res = label_search(problem, env, 200, start=start, outside=band, tighten=tighten)
            assert 0.0 <= res.floor_j <= j


def test_bad_budget_is_refused(short: OracleEpisodes) -> None:
    _, _, _, _, problem, env, _ = next(_trajectories(short))
    for bad in (0, True, 2.5):
        with pytest.raises(ValueError, match="max_nodes must be an integer >= 1"):
            label_search(problem, env, bad)  # type: ignore[arg-type]


def test_outputs_first_splits_only_the_outputs_while_they_have_labels_left(
    short: OracleEpisodes,
) -> None:
    lifted, _, _, _, problem, env, _ = next(_trajectories(short))
    res = label_search(problem, env, 40, first=lifted.is_output)
    assert res.least is not None
    fixed = ~res.least.open_at() | (res.least.sigma != 0) | (res.least.tau != 0)
    assert fixed[lifted.is_output].any()
    assert not fixed[~lifted.is_output].any()
    for bad in (lifted.is_output[:-1], lifted.is_output.astype(int)):
        with pytest.raises(ValueError, match="first must be a bool array of shape"):
            label_search(problem, env, 5, first=bad)


def test_partial_nodes_along_rollouts_beyond_the_blend_hold_them(longer: OracleEpisodes) -> None:
    """0.05 s (strokes beyond the blend, so ``tau = +-1`` is exercised): nodes fixing each
    rollout's labels at random subsets of the evaluations (all, 97 %, 90 %, 50 %; the rest
    free), and its leaf with ``v_0 = 0`` given the sign ``-1`` (``v = 0`` lies in both): the
    tightened magnitudes hold on the rollout's forces, rates and strokes, the node is not
    pruned, and its certified bound is at most the rollout's simulated ``J``; the fully
    labelled nodes certify a positive bound (the check is not vacuous)."""
    rng = np.random.default_rng(47)
    for _, forces, v, x, problem, env, j in _trajectories(longer):
        blend, n = problem.side.blend_m, problem.n
        leaf = trajectory_labels(v, x, blend)
        assert (np.abs(leaf.tau) == 1).any() and v[0] == 0.0
        flipped = Node(leaf.sigma.copy(), leaf.tau.copy(), leaf.kappa.copy())
        flipped.sigma[0] = -1
        nodes = [leaf, flipped]
        for frac in (0.97, 0.9, 0.5):
            nodes.append(_free(leaf, list(np.flatnonzero(rng.random(n) >= frac))))
        bounder = NodeBounder(problem, env, tighten=True)
        bounds = []
        for node in nodes:
            assert _holds(node, v, x, blend).all()
            f_abs, vx = node_magnitudes(problem, env, node)
            assert np.all(np.abs(forces) / FORCE_SCALE_N <= f_abs)
            assert np.all(np.abs(np.r_[v, x]) <= vx)
            bounds.append(bounder(node)[0])
        assert bounder.pruned == 0
        assert all(0.0 <= b <= j for b in bounds)
        assert bounds[0] > 0.0 and bounds[1] > 0.0


def test_every_rate_and_stroke_lies_in_a_leaf_of_one_evaluation() -> None:
    """Coverage checked on points, not only on rollouts (which stay below 60 mm/s and reach
    few classes): splitting one evaluation down to its leaves (2 x 3 x 4 = 24), every rate
    (both signs, 0, each class break and either side of it, far beyond the last break) and
    every stroke (each side of the blend, its edges, 0) lies in some leaf by the labels'
    meaning, and in the leaf that trajectory_labels names."""
    blend = 1e-4
    leaves, stack = [], [Node.root(1)]
    while stack:
        node = stack.pop()
        if node.open_at()[0]:
            stack.extend(children(node, 0))
        else:
            leaves.append(node)
    assert len(leaves) == 24
    breaks = [b for b in RATE_BREAKS_M_S if math.isfinite(b)]
    speeds = [0.0, 1e-12, 0.5, 10.0] + [b * f for b in breaks for f in (1 - 1e-9, 1, 1 + 1e-9)]
    rates = np.array([sg * u for u in speeds for sg in (1.0, -1.0)])
    strokes = np.array([0.0, 0.5, 1.0, 1.0 + 1e-9, 1 - 1e-9, 50.0]) * blend
    for v1, x1 in itertools.product(rates, np.r_[strokes, -strokes]):
        v, x = np.array([v1]), np.array([x1])
        assert any(_holds(leaf, v, x, blend).all() for leaf in leaves), (v1, x1)
        own = trajectory_labels(v, x, blend)
        assert _holds(own, v, x, blend).all(), (v1, x1)
        assert any(all((getattr(leaf, a) == getattr(own, a)).all()
                       for a in ("sigma", "tau", "kappa")) for leaf in leaves)  # fmt: skip
