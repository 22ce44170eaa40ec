"""Review of capsule_env.bounds.stroke and the certificate (issue 43): the per-step current
tie needs one current per control step, which a lagging coil does not give; the certificate
takes any multipliers, subnormal ones included."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import linprog

from capsule_env import metrics
from capsule_env.bounds.lifted import closed_loop, lift_episode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope, model_force_parts
from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts, stroke_sides
from capsule_env.dampers.base import COIL_TAU
from capsule_env.engine.layout import OUT_BODY_ACC
from capsule_env.oracle.plant import OracleEpisodes


def _lagged_currents(commands: np.ndarray, n_sub: int, h_s: float, tau_s: float) -> np.ndarray:
    """The current at each force evaluation of a lagging coil, as the kernel updates it
    (:func:`capsule_env.plant.rk4.rk4_substep`: exact over each half substep, from 0 A;
    stages at ``i, i_half, i_half, i_1``, the sample point after the step)."""
    e_half, out, ic = math.exp(-0.5 * h_s / tau_s), [], 0.0
    for cmd in commands:
        for _ in range(n_sub):
            i_half = cmd + (ic - cmd) * e_half
            i_one = cmd + (i_half - cmd) * e_half
            out += [ic, i_half, i_half, i_one]
            ic = i_one
        out.append(ic)
    return np.array(out)


def test_the_per_step_current_is_refused_when_the_coil_lags() -> None:
    """With a lagging coil (``coil_time_constant_s`` 0.3 ms) the current moves within a
    control step: the plant's own trajectory under alternating 0 / 1.5 A commands (its J the
    compiled env's, an independent number) satisfies no per-step current rows at any
    ``theta`` (the LP over ``e`` is infeasible), so those rows would exclude a real
    trajectory. The tie is refused for such a damper; the node without it still holds."""
    ep = OracleEpisodes({"setting": "sim", "coil_time_constant_s": 3e-4}, [1000], 0.1)
    p = ep.damper_params[0]
    lifted = lift_episode(ep, 0)
    commands = np.resize([0.0, 1.5], ep.n_steps)
    h_s = ep.dt_s / lifted.n_sub
    current = _lagged_currents(commands, lifted.n_sub, h_s, float(p[COIL_TAU]))
    n = lifted.n_forces
    forces = np.zeros(n)
    for s in range(n):  # the lifted plant closed with the lagged currents, causally
        x = lifted.x_rows[s, :s] @ forces[:s] + lifted.x_rows[s, n]
        v = lifted.v_rows[s, :s] @ forces[:s] + lifted.v_rows[s, n]
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), current[[s]])
        forces[s] = d[0] + c[0]
    _, out = ep.run(np.array([0]), commands[None], substeps="env")
    env_j = float(metrics.wk_weighted_rms(out[0, :, OUT_BODY_ACC], ep.dt_s)) ** 2
    cuts = side_cuts(ep.code, p)
    problem = StrokeBranchProblem(lifted, damper_envelope(ep.code, p), cuts)
    assert problem.ride(forces / FORCE_SCALE_N) == pytest.approx(env_j, rel=1e-9)
    v, x = lifted.affine(lifted.v_rows, forces), lifted.affine(lifted.x_rows, forces)
    sigma = np.where(v >= 0.0, 1, -1).astype(np.int8)
    tau = stroke_sides(x, cuts.blend_m)
    problem.side = dataclasses.replace(cuts, coil_tau_s=0.0)  # rows as if it did not lag
    gf, gv, h, extra = problem.node_rows(sigma, tau, current_tie=True)
    rhs = h - gf[:, :n] @ (forces / FORCE_SCALE_N) - gv @ np.r_[v, x] + 1e-12
    lp = linprog(np.zeros(extra.size), A_ub=gf[:, n:], b_ub=rhs,
                 bounds=[(-e, e) for e in extra], method="highs")  # fmt: skip
    assert lp.status == 2  # infeasible: no per-step current fits the lagged trajectory
    problem.side = cuts
    assert cuts.coil_tau_s == pytest.approx(3e-4)
    with pytest.raises(ValueError, match="coil_time_constant_s"):
        problem.node_bound(sigma, tau, current_tie=True)
    bound, _ = problem.node_bound(sigma, tau)
    assert 0.0 < bound <= env_j


def test_subnormal_multipliers_certify_a_bound_below_the_trajectory() -> None:
    """``certify`` takes any multipliers: the solver's times 2^-1070 (subnormal: the scale
    that brings them to about 1 is 2^1070, beyond a float) give a valid bound, below the
    0 A trajectory's J, not an OverflowError; times 2^-500 or 2^500 the unscaled bound."""
    ep = OracleEpisodes({"setting": "sim"}, [1000], 0.1)
    p = ep.damper_params[0]
    lifted = lift_episode(ep, 0)
    cuts = side_cuts(ep.code, p)
    problem = StrokeBranchProblem(lifted, damper_envelope(ep.code, p), cuts)

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), np.zeros(1))
        return float(d[0] + c[0])

    forces = closed_loop(lifted, law)
    v, x = lifted.affine(lifted.v_rows, forces), lifted.affine(lifted.x_rows, forces)
    node = (np.where(v >= 0.0, 1, -1).astype(np.int8), stroke_sides(x, cuts.blend_m))
    gf, gv, h, extra = problem.node_rows(*node, current_tie=True)
    y_w, z, _ = problem._sparse.solve(gf, gv, h)
    ride = problem.ride(forces / FORCE_SCALE_N)
    plain = problem.certify(gf, gv, h, y_w, z, extra)
    assert 0.0 < plain <= ride
    for scale in (2.0**-500, 2.0**500):  # exact scalings: the same bound
        assert problem.certify(gf, gv, h, y_w * scale, z * scale, extra) == plain
    tiny = problem.certify(gf, gv, h, y_w * 2.0**-1070, z * 2.0**-1070, extra)
    assert 0.0 <= tiny <= ride
