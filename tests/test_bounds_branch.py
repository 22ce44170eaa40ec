"""The branch and bound over the stroke rate's sign (capsule_env.bounds.branch): its cuts hold
on the damper model, its bounds lie below simulated trajectories, and it finds what
enumerating every sign pattern finds."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from capsule_env import metrics
from capsule_env.bounds import certified_floor, check_floor
from capsule_env.bounds.branch import (
    BranchProblem,
    branch_and_bound,
    force_magnitude_bounds,
    hull_lines,
    sign_cut_values,
    sign_cuts,
)
from capsule_env.bounds.lifted import LiftedEpisode, closed_loop, lift_episode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope, model_force_parts
from capsule_env.engine.layout import OUT_BODY_ACC
from capsule_env.oracle.plant import OracleEpisodes


@pytest.fixture(scope="module")
def sim() -> OracleEpisodes:
    return OracleEpisodes({"setting": "sim"}, [1000], 0.1)


def _model_points(ep: OracleEpisodes) -> tuple[np.ndarray, np.ndarray]:
    """Forces (kN) and rates (m/s) of the model on a grid: strokes inside and beyond the
    branch blend, rates 1e-7..2 m/s of both signs and 0, every current."""
    x, v, i = np.meshgrid(np.linspace(-3e-4, 3e-4, 13), np.r_[-np.logspace(-7, 0.3, 60), 0.0,
                          np.logspace(-7, 0.3, 60)], np.linspace(0, 1.5, 7))  # fmt: skip
    d, c = model_force_parts(ep.code, ep.damper_params[0], x.ravel(), v.ravel(), i.ravel())
    return (d + c) / FORCE_SCALE_N, v.ravel()


def _rollout(ep: OracleEpisodes, currents: np.ndarray) -> tuple[LiftedEpisode, np.ndarray]:
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), currents[[step]])
        return float(d[0] + c[0])

    return lifted, closed_loop(lifted, law)


def test_sign_cuts_hold_on_the_model_and_cut_off_the_wrong_sign(sim: OracleEpisodes) -> None:
    env = damper_envelope(sim.code, sim.damper_params[0])
    cuts = sign_cuts(env)
    force, v = _model_points(sim)
    for sigma in (1.0, -1.0):
        at = sigma * v >= 0.0  # v = 0 belongs to both signs
        assert sign_cut_values(cuts, sigma, force[at], v[at]).min() >= 0.0
    # a force against the stroke rate (what an active actuator could do) is cut off
    wrong = sign_cut_values(cuts, 1.0, np.array([-0.5]), np.array([0.05]))
    assert wrong.min() < 0.0
    # and so is one above the maximum-current band at 0.1 m/s (U = 6.1 kN there)
    assert sign_cut_values(cuts, 1.0, np.array([7.0]), np.array([0.1])).min() < 0.0


def test_hull_lines_hold_at_both_signs_within_the_rate_bound(sim: OracleEpisodes) -> None:
    env = damper_envelope(sim.code, sim.damper_params[0])
    force, v = _model_points(sim)
    c_lo, c_hi = env.c_lo / FORCE_SCALE_N, env.c_hi / FORCE_SCALE_N
    for bound in (1e-3, 0.05, 0.3, 1.0, 2.0):
        icpt, slope = hull_lines(env, np.array([bound]))
        at = np.abs(v) <= bound
        assert np.all(force[at] <= icpt[0] + slope[0] * v[at] + c_hi)
        assert np.all(-force[at] <= icpt[0] - slope[0] * v[at] - c_lo)
        # tighter than the band's worst case at v = 0 for a small bound
    small, _ = hull_lines(env, np.array([1e-3]))
    assert small[0] + c_hi < env.a_hi / FORCE_SCALE_N


def test_every_rollout_force_within_its_signs_cuts_and_magnitude_bounds(
    sim: OracleEpisodes,
) -> None:
    env = damper_envelope(sim.code, sim.damper_params[0])
    rng = np.random.default_rng(7)
    for currents in (np.zeros(sim.n_steps), rng.uniform(0, 1.5, sim.n_steps),
                     rng.choice([0.0, 1.5], sim.n_steps)):  # fmt: skip
        lifted, forces = _rollout(sim, currents)
        f_abs, v_abs = force_magnitude_bounds(lifted, env)
        v = lifted.affine(lifted.v_rows, forces)
        f = forces / FORCE_SCALE_N
        assert np.all(np.abs(f) <= f_abs) and np.all(np.abs(v) <= v_abs)
        problem = BranchProblem(lifted, env)
        assert problem.violation(f).max() == 0.0


@pytest.fixture(scope="module")
def window() -> OracleEpisodes:
    return OracleEpisodes({"setting": "sim"}, [1000], 0.35)


def test_leaf_bounds_below_the_trajectories_they_contain(window: OracleEpisodes) -> None:
    """The leaf fixing a simulated trajectory's own signs bounds that trajectory's J (its
    simulated cost: an independent number); the 0 A leaf's bound is informative (> 0)."""
    env = damper_envelope(window.code, window.damper_params[0])
    rng = np.random.default_rng(11)
    bounds = []
    for currents in (np.zeros(window.n_steps), rng.uniform(0, 1.5, window.n_steps)):
        lifted, forces = _rollout(window, currents)
        problem = BranchProblem(lifted, env)
        v = lifted.affine(lifted.v_rows, forces)
        bound, _ = problem.node_bound(np.where(v >= 0.0, 1, -1).astype(np.int8))
        _, out = window.run(np.array([0]), currents[None], substeps="env")  # the compiled env
        env_wk = float(metrics.wk_weighted_rms(out[0, :, OUT_BODY_ACC], window.dt_s))
        assert 0.0 <= bound <= env_wk**2
        bounds.append(bound)
    assert bounds[0] > 1e-3


def test_branch_and_bound_equals_enumerating_the_sign_patterns(sim: OracleEpisodes) -> None:
    """Four evaluations around the 0 A trajectory's sign change left free, the others fixed
    at its signs: the branch and bound, run to completion, gives the least bound over the 16
    patterns. Offsets dropped from the cuts (an algorithmic check, not a valid relaxation) so
    that the bounds are not all 0 on this short window."""
    env = damper_envelope(sim.code, sim.damper_params[0])
    lifted, forces = _rollout(sim, np.zeros(sim.n_steps))
    cuts = dataclasses.replace(sign_cuts(env), lo_off=(0.0, 0.0), up_off=(0.0, 0.0))
    problem = BranchProblem(lifted, env, cuts)
    problem.c_lo = problem.c_hi = 0.0
    v = lifted.affine(lifted.v_rows, forces)
    sigma = np.where(v >= 0.0, 1, -1).astype(np.int8)
    change = int(np.flatnonzero(np.diff(sigma))[0])
    free = np.arange(change - 1, change + 3)
    fixed = sigma.copy()
    fixed[free] = 0
    values = []
    for signs in itertools.product((1, -1), repeat=free.size):
        leaf = fixed.copy()
        leaf[free] = signs
        values.append(problem.node_bound(leaf)[0])
    result = branch_and_bound(problem, 100, candidates=free, fixed=fixed)
    assert result.complete and result.nodes < 100
    assert max(values) > 0.0
    assert result.floor_j == pytest.approx(min(values), rel=1e-4, abs=1e-12)
    floors = [f for _, f in result.history]
    assert floors == sorted(floors)  # any-time: never decreases


def test_certified_floor_with_branching_is_at_least_without() -> None:
    seeds, length = [1000], 0.1
    plain = certified_floor({"setting": "sim"}, seeds, length, max_iterations=2)
    branched = certified_floor({"setting": "sim"}, seeds, length, max_iterations=2, branch_nodes=5)
    assert np.all(branched.floor_wk_m_s2 >= plain.floor_wk_m_s2)
    ep, _, _ = check_floor({"setting": "sim"}, seeds, length)
    _, out = ep.run(np.array([0]), np.zeros((1, ep.n_steps)), substeps="env")  # 0 A
    assert branched.floor_wk_m_s2[0] <= metrics.wk_weighted_rms(out[0, :, OUT_BODY_ACC], ep.dt_s)
    summary = branched.summary()
    assert summary["branch"][0]["nodes"] == 5 and "branch" not in plain.summary()
    with pytest.raises(ValueError, match="branch_nodes"):
        certified_floor({"setting": "sim"}, seeds, length, branch_nodes=-1)


def test_sparse_lift_reproduces_the_dense_lift(sim: OracleEpisodes) -> None:
    """Forward-substituting the sparse substep relations gives the dense lift's stroke
    rates and accelerations (the dense lift is checked against the compiled env)."""
    from scipy.sparse.linalg import spsolve_triangular

    from capsule_env.bounds.sparse import sparse_lift

    lifted, forces = _rollout(sim, np.random.default_rng(2).uniform(0, 1.5, sim.n_steps))
    sl = sparse_lift(lifted)
    x = spsolve_triangular(sl.dyn[:, : sl.n_x].tocsr(), sl.dyn_rhs - sl.dyn[:, sl.n_x :] @ forces)
    v = sl.v_x @ x + sl.v_f @ forces + sl.v_c
    acc = sl.acc_x @ x + sl.acc_f @ forces + sl.acc_c
    assert np.allclose(v, lifted.affine(lifted.v_rows, forces), rtol=0, atol=1e-12)
    assert np.allclose(acc, lifted.affine(lifted.acc_rows, forces), rtol=0, atol=1e-12)


def test_any_multipliers_certify_a_bound_below_the_trajectory(window: OracleEpisodes) -> None:
    """Weak duality: random multipliers, not the solver's, still bound the 0 A
    trajectory's J from below (its leaf's cuts hold there)."""
    env = damper_envelope(window.code, window.damper_params[0])
    lifted, forces = _rollout(window, np.zeros(window.n_steps))
    problem = BranchProblem(lifted, env)
    v = lifted.affine(lifted.v_rows, forces)
    gf, gv, h = problem.rows(np.where(v >= 0.0, 1, -1).astype(np.int8))
    y_w, z, _ = problem._sparse.solve(gf, gv, h)
    ride = problem.ride(forces / FORCE_SCALE_N)
    rng = np.random.default_rng(4)
    noisy = []
    for scale in (0.5, 1.0, 2.0):
        noisy.append(problem.certify(gf, gv, h, scale * y_w, z * rng.uniform(0, 2, z.size)))
        assert noisy[-1] <= ride
    assert ride >= problem.certify(gf, gv, h, y_w, z) >= max(noisy)
    assert problem.certify(gf, gv, h, y_w, z) > 0.0


def test_floor_runs_the_episodes_evaluate_and_the_oracle_run() -> None:
    """Without a guideway_seed the floor used the env's default bank, not evaluate.py's
    (``EVALUATION_GUIDEWAY_SEED``, which the oracle defaults to too)."""
    from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED

    episodes, _, _ = check_floor({"setting": "sim"}, [1000, 1001], 0.1)
    kwargs = {"setting": "sim", "guideway_seed": EVALUATION_GUIDEWAY_SEED}
    evaluation = OracleEpisodes(kwargs, [1000, 1001], 0.1)
    default = OracleEpisodes({"setting": "sim"}, [1000, 1001], 0.1)
    assert not np.array_equal(default.state0, evaluation.state0)  # the banks differ
    assert np.array_equal(episodes.state0, evaluation.state0)
    assert np.array_equal(episodes.profiles, evaluation.profiles)
