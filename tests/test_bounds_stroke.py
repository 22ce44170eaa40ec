"""Nodes that also fix the stroke's side of the blend (capsule_env.bounds.stroke): the
branch's cuts hold on the damper model and on rollouts, the tie of the offset to the stroke
cuts off forces the untied cuts admit, and the leaves bound the trajectories they contain."""

from __future__ import annotations

import numpy as np
import pytest
from test_bounds_branch import _rollout

from capsule_env import metrics
from capsule_env.bounds.branch import BranchProblem, sign_cut_values, sign_cuts
from capsule_env.bounds.lifted import LiftedEpisode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope, model_force_parts
from capsule_env.bounds.stroke import (
    INSIDE_BLEND,
    RATE_BREAKS_M_S,
    StrokeBranchProblem,
    current_tie_rows,
    rate_class_rows,
    side_cut_values,
    side_cuts,
    stroke_sides,
)
from capsule_env.engine.layout import OUT_BODY_ACC
from capsule_env.oracle.plant import OracleEpisodes


@pytest.fixture(scope="module")
def sim() -> OracleEpisodes:
    return OracleEpisodes({"setting": "sim"}, [1000], 0.1)


@pytest.fixture(scope="module")
def window() -> OracleEpisodes:
    return OracleEpisodes({"setting": "sim"}, [1000], 0.35)


def _model(ep: OracleEpisodes, x: np.ndarray, v: np.ndarray, i: np.ndarray) -> np.ndarray:
    d, c = model_force_parts(ep.code, ep.damper_params[0], x, v, i)
    return (d + c) / FORCE_SCALE_N


def test_side_cuts_hold_on_the_model_beyond_the_blend(sim: OracleEpisodes) -> None:
    cuts = side_cuts(sim.code, sim.damper_params[0])
    blend = cuts.blend_m
    assert blend == pytest.approx(1e-4)
    rates = np.r_[-np.logspace(-7, 0.3, 80), 0.0, np.logspace(-7, 0.3, 80)]
    for tau in (1.0, -1.0):
        strokes = tau * blend * np.r_[1.0, 1.0 + 1e-12, 1.5, 10.0, 300.0]
        x, v, i = np.meshgrid(strokes, rates, np.linspace(0.0, 1.5, 13))
        x, v, i = x.ravel(), v.ravel(), i.ravel()
        force = _model(sim, x, v, i)
        for sigma in (1.0, -1.0):
            at = sigma * v >= 0.0
            assert side_cut_values(cuts, sigma, tau, force[at], v[at]).min() >= 0.0
    # a force against the stroke rate is cut off, as with the stroke-rate sign alone
    assert side_cut_values(cuts, 1.0, 1.0, np.array([-0.5]), np.array([0.05])).min() < 0.0


def test_the_offset_tie_cuts_off_forces_the_untied_cuts_admit(sim: OracleEpisodes) -> None:
    """Stroke beyond +blend, rate negative: the upper branch's offset (+222..+346 N) opposes
    the rate, so the largest ``-F`` is well below what cuts that let the offset be the lower
    branch's (-362 N) admit. The model's own maximum over the currents is the independent
    fact: the untied cuts admit forces above it by about 0.5 kN, the tied ones do not."""
    env = damper_envelope(sim.code, sim.damper_params[0])
    untied, tied = sign_cuts(env), side_cuts(sim.code, sim.damper_params[0])
    for rate in (-0.002, -0.02, -0.1):
        x = np.full(301, 5e-3)
        real_max = float(np.max(-_model(sim, x, np.full(301, rate), np.linspace(0, 1.5, 301))))
        v = np.array([rate])
        untied_max = float(np.min(sign_cut_values(untied, -1.0, np.zeros(1), v)[0, 2:]))
        tied_max = float(np.min(side_cut_values(tied, -1.0, 1.0, np.zeros(1), v)[0, 2:]))
        # -F at most untied_max and tied_max (the cut values at F = 0 are the upper edges)
        assert untied_max - real_max > 0.45
        assert tied_max >= real_max - 1e-9
        assert tied_max - real_max < untied_max - real_max - 0.4
        # the untied cuts hold at a force 0.4 kN beyond the model; the tied ones cut it off
        beyond = np.array([-(real_max + 0.4)])
        assert sign_cut_values(untied, -1.0, beyond, v).min() >= 0.0
        assert side_cut_values(tied, -1.0, 1.0, beyond, v).min() < 0.0


def test_stroke_sides_partition_the_strokes() -> None:
    x = np.array([-1e-3, -1e-4, -5e-5, 0.0, 5e-5, 1e-4, 1e-3])
    assert stroke_sides(x, 1e-4).tolist() == [-1, -1, INSIDE_BLEND, INSIDE_BLEND,
                                              INSIDE_BLEND, 1, 1]  # fmt: skip


def test_sparse_strokes_reproduce_the_dense_lift(sim: OracleEpisodes) -> None:
    from scipy.sparse.linalg import spsolve_triangular

    from capsule_env.bounds.sparse import sparse_lift

    lifted, forces = _rollout(sim, np.random.default_rng(2).uniform(0, 1.5, sim.n_steps))
    sl = sparse_lift(lifted)
    state = spsolve_triangular(sl.dyn[:, : sl.n_x].tocsr(),
                               sl.dyn_rhs - sl.dyn[:, sl.n_x :] @ forces)  # fmt: skip
    x = sl.x_x @ state + sl.x_f @ forces + sl.x_c
    assert np.allclose(x, lifted.affine(lifted.x_rows, forces), rtol=0, atol=1e-15)


def _signs(lifted: LiftedEpisode, forces: np.ndarray, blend: float):
    v = lifted.affine(lifted.v_rows, forces)
    x = lifted.affine(lifted.x_rows, forces)
    return np.where(v >= 0.0, 1, -1).astype(np.int8), stroke_sides(x, blend), v, x


def _cases(ep: OracleEpisodes, seed: int):
    """0 A, random and on-off rollouts: ``(currents, lifted, forces, problem, the compiled
    env's J)`` (the env's J an independent number: its own kernel)."""
    p = ep.damper_params[0]
    env, cuts = damper_envelope(ep.code, p), side_cuts(ep.code, p)
    rng = np.random.default_rng(seed)
    for currents in (np.zeros(ep.n_steps), rng.uniform(0, 1.5, ep.n_steps),
                     rng.choice([0.0, 1.5], ep.n_steps)):  # fmt: skip
        lifted, forces = _rollout(ep, currents)
        _, out = ep.run(np.array([0]), currents[None], substeps="env")
        env_wk = float(metrics.wk_weighted_rms(out[0, :, OUT_BODY_ACC], ep.dt_s))
        yield currents, lifted, forces, StrokeBranchProblem(lifted, env, cuts), env_wk**2


def test_rollouts_lie_in_their_leaf_and_the_leaf_bounds_them(window: OracleEpisodes) -> None:
    """Every force evaluation of 0 A, random and on-off rollouts satisfies its own side's
    cuts; the leaf of the trajectory's own (rate, stroke) signs is certified below its
    simulated J (the compiled env's: an independent number) and is at least the leaf of
    the rate's signs alone (its cuts are a superset)."""
    leaves = []
    for _, lifted, forces, problem, env_j in _cases(window, 11):
        cuts = problem.side
        sigma, tau, v, x = _signs(lifted, forces, cuts.blend_m)
        f = forces / FORCE_SCALE_N
        for s_v in (1, -1):
            for s_x in (1, -1):
                at = (sigma == s_v) & (tau == s_x)
                assert side_cut_values(cuts, s_v, s_x, f[at], v[at]).min(initial=0.0) >= 0.0
        assert np.all(np.abs(x) <= problem.v_abs[problem.n :])
        bound, _ = problem.node_bound(sigma, tau)
        env = damper_envelope(window.code, window.damper_params[0])
        plain, _ = BranchProblem(lifted, env).node_bound(sigma)
        assert 0.0 <= bound <= env_j
        assert bound >= plain * (1.0 - 1e-6)
        leaves.append((bound, plain))
    assert leaves[0][0] > 1.5 * leaves[0][1]  # the tie matters on the 0 A leaf


def test_rollouts_satisfy_the_per_step_current_cuts(window: OracleEpisodes) -> None:
    """At a rollout's own forces, with ``theta`` its steps' currents over ``i_max`` and ``w
    = theta u``, every per-step current cut holds (the rollout's currents are the independent
    fact); the leaf with them is certified below the compiled env's J and at least the leaf
    without them, and on the 0 A rollout above it."""
    gains = []
    for currents, lifted, forces, problem, env_j in _cases(window, 5):
        cuts = problem.side
        sigma, tau, v, x = _signs(lifted, forces, cuts.blend_m)
        rate = problem.v_abs[: problem.n]
        gf, gv, h, extra = current_tie_rows(cuts, lifted.step_of, sigma, tau, rate)
        sel = np.flatnonzero((np.abs(tau) == 1) & (sigma != 0))
        theta = currents / 1.5
        w = theta[lifted.step_of[sel]] * sigma[sel] * v[sel]
        e = np.r_[theta - 0.5, w - np.maximum(rate[sel], 1e-9) / 2]
        assert np.all(np.abs(e) <= extra)
        lhs = gf @ np.r_[forces / FORCE_SCALE_N, e] + gv @ np.r_[v, x]
        assert np.all(lhs <= h + 1e-12)  # at theta = 1, w = u: equal up to rounding
        tied, _ = problem.node_bound(sigma, tau, current_tie=True)
        untied, _ = problem.node_bound(sigma, tau)
        assert untied * (1.0 - 1e-6) <= tied <= env_j
        gains.append(tied / untied)
    assert gains[0] > 1.05


@pytest.mark.parametrize("tie", [False, True])
def test_any_multipliers_certify_below_the_trajectory(window: OracleEpisodes, tie: bool) -> None:
    """Weak duality with the stroke rows (and the per-step current's variables, priced by
    their ranges): random multipliers, not the solver's, still bound the 0 A trajectory's J
    from below; a wrong number of ranges is refused."""
    p = window.damper_params[0]
    cuts = side_cuts(window.code, p)
    lifted, forces = _rollout(window, np.zeros(window.n_steps))
    problem = StrokeBranchProblem(lifted, damper_envelope(window.code, p), cuts)
    sigma, tau, _, _ = _signs(lifted, forces, cuts.blend_m)
    if tie:
        gf, gv, h, extra = problem.node_rows(sigma, tau, current_tie=True)
    else:
        (gf, gv, h), extra = problem.rows(sigma, tau), np.zeros(0)
    # the trajectory is in the node: theta = 0 and w = 0 at 0 A
    at = np.r_[forces / FORCE_SCALE_N, -extra]
    assert np.all(gv @ problem.a_aug @ np.r_[forces / FORCE_SCALE_N, 1.0] + gf @ at <= h + 1e-12)
    y_w, z, _ = problem._sparse.solve(gf, gv, h)
    ride = problem.ride(forces / FORCE_SCALE_N)
    rng = np.random.default_rng(8)
    for scale in (0.5, 1.0, 2.0):
        noisy = z * rng.uniform(0, 2, z.size)
        assert problem.certify(gf, gv, h, scale * y_w, noisy, extra) <= ride
    assert ride >= problem.certify(gf, gv, h, y_w, z, extra) > 0.0
    with pytest.raises(ValueError, match="extra_abs"):
        problem.certify(gf, gv, h, y_w, z, np.r_[extra, 1.0])


def test_rate_class_cuts_hold_on_the_model_and_keep_the_yield(sim: OracleEpisodes) -> None:
    """In each rate class the lower edge's chord holds on the model (both sides beyond the
    blend, both rate signs, 13 currents), and it cuts off what the class-free cuts admit:
    a force at ``b u + c`` inside the yield band, below every current's force there."""
    cuts = side_cuts(sim.code, sim.damper_params[0])
    breaks = np.asarray(RATE_BREAKS_M_S)
    rates = np.r_[np.logspace(-7, 0.3, 200), breaks[1:-1]]
    for tau in (1, -1):
        for sigma in (1, -1):
            x, u, i = np.meshgrid(tau * np.array([1e-4, 5e-3]), rates, np.linspace(0, 1.5, 13))
            v = sigma * u.ravel()
            force = _model(sim, x.ravel(), v, i.ravel())
            for k in range(breaks.size - 1):
                at = (u.ravel() >= breaks[k]) & (u.ravel() <= breaks[k + 1])
                n = int(at.sum())
                kappa = np.full(n, k)
                gf, gv, h = rate_class_rows(cuts, np.full(n, sigma, dtype=np.int8),
                                            np.full(n, tau, dtype=np.int8), kappa)  # fmt: skip
                lhs = gf @ force[at] + gv @ np.r_[v[at], x.ravel()[at]]
                assert np.all(lhs <= h)
    # at u = 10 mm/s (class 1), stroke 5 mm, v > 0: the model's least force (0 A, 0.90 kN)
    # is 0.6 kN above b u + c (0.30 kN, the cuts without classes); 0.3 kN below it is cut
    one = np.ones(1, dtype=np.int8)
    least = float(_model(sim, np.array([5e-3]), np.array([0.01]), np.zeros(1))[0])
    below = np.array([least - 0.3])
    gf, gv, h = rate_class_rows(cuts, one, one, np.array([1]))
    assert np.any(gf @ below + gv @ np.r_[0.01, 5e-3] > h)
    untied = sign_cuts(damper_envelope(sim.code, sim.damper_params[0]))
    assert sign_cut_values(untied, 1.0, below, np.array([0.01])).min() >= 0.0
    assert side_cut_values(cuts, 1.0, 1.0, below, np.array([0.01])).min() >= 0.0


def test_leaf_with_rate_classes_bounds_its_rollouts(window: OracleEpisodes) -> None:
    """Rollouts lie in the leaf of their own (rate, stroke, rate class) and its bound, with
    and without the per-step current (at each class's upper end), is below their J."""
    breaks = np.asarray(RATE_BREAKS_M_S)
    for _, lifted, forces, problem, env_j in _cases(window, 3):
        sigma, tau, v, x = _signs(lifted, forces, problem.side.blend_m)
        kappa = np.searchsorted(breaks, np.abs(v), side="right") - 1
        gf, gv, h = rate_class_rows(problem.side, sigma, tau, kappa)
        assert np.all(gf @ (forces / FORCE_SCALE_N) + gv @ np.r_[v, x] <= h)
        rate = np.minimum(problem.v_abs[: problem.n], breaks[kappa + 1])
        assert np.all(np.abs(v) <= rate)
        for tie in (False, True):  # the tie at the class's upper end by default
            bound, _ = problem.node_bound(sigma, tau, tie, kappa)
            assert 0.0 < bound <= env_j
