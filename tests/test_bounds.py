"""The certified floor (capsule_env.bounds): the lifted plant against the compiled env, the
constraints against the damper model on rollouts, the dual against a known answer and weak
duality, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from capsule_env import metrics
from capsule_env.bounds import certified_floor, floor_row, verify
from capsule_env.bounds.dual import DualProblem, weighting_matrix
from capsule_env.bounds.lifted import LiftedEpisode, closed_loop, lift_episode
from capsule_env.bounds.relaxation import (
    FORCE_SCALE_N,
    constraint_matrices,
    constraint_values,
    damper_envelope,
    model_force_parts,
)
from capsule_env.engine.layout import OUT_BODY_ACC, OUT_FORCE
from capsule_env.oracle.plant import OracleEpisodes

SHORT_S = 0.1  # 20 control steps: the algebra, not the figures


@pytest.fixture(scope="module")
def sim() -> OracleEpisodes:
    return OracleEpisodes({"setting": "sim"}, [1000, 1001], SHORT_S)


def _replay(ep: OracleEpisodes, k: int, currents: np.ndarray) -> tuple[LiftedEpisode, np.ndarray]:
    """The lifted episode closed with the plant damper's own force at ``currents`` (T,)."""
    lifted = lift_episode(ep, k)
    p = ep.damper_params[k]

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), currents[[step]])
        return float(d[0] + c[0])

    return lifted, closed_loop(lifted, law)


@pytest.mark.parametrize("kwargs", [{"setting": "sim"}, {"setting": "sim", "damper": "passive"}])
def test_lifted_plant_reproduces_the_compiled_env(kwargs: dict) -> None:
    ep = OracleEpisodes(kwargs, [1003], SHORT_S)
    currents = np.random.default_rng(3).uniform(-0.2, 1.7, ep.n_steps)  # clipped by both
    lifted, forces = _replay(ep, 0, currents)
    _, out = ep.run(np.array([0]), currents[None], substeps="env")
    acc = lifted.affine(lifted.acc_rows, forces)
    env_acc = out[0, :, OUT_BODY_ACC]
    assert np.max(np.abs(acc - env_acc)) <= 1e-9 * np.max(np.abs(env_acc))
    env_force = out[0, :, OUT_FORCE]
    assert np.max(np.abs(forces[lifted.is_output] - env_force)) <= 1e-9 * np.max(np.abs(env_force))


def test_every_force_of_a_rollout_satisfies_every_constraint(sim: OracleEpisodes) -> None:
    """Bang-bang, random and extreme currents: each stage's (D, C, v, x) inside the set."""
    rng = np.random.default_rng(5)
    mats = constraint_matrices(damper_envelope(sim.code, sim.damper_params[0]))
    for currents in (rng.uniform(0, 1.5, sim.n_steps), rng.choice([0.0, 1.5], sim.n_steps)):
        lifted, forces = _replay(sim, 0, currents)
        x, v = lifted.affine(lifted.x_rows, forces), lifted.affine(lifted.v_rows, forces)
        d, c = model_force_parts(sim.code, sim.damper_params[0], x, v, currents[lifted.step_of])
        # numpy's exp against the kernel's fast exp (a few ulp, libm differs across CPUs):
        # 1e-9 relative, far below any force that matters here
        assert np.allclose(d + c, forces, rtol=1e-9, atol=1e-6)
        xi = np.stack([d / FORCE_SCALE_N, c / FORCE_SCALE_N, v, x, np.ones_like(v)], axis=1)
        assert constraint_values(mats, xi).min() >= 0.0


def test_constraints_hold_on_a_grid_of_the_model(sim: OracleEpisodes) -> None:
    """Stroke within and beyond the branch blend, rates to 2 m/s, every current."""
    p = sim.damper_params[0]
    mats = constraint_matrices(damper_envelope(sim.code, p))
    x, v, i = np.meshgrid(np.linspace(-3e-4, 3e-4, 31), np.r_[-np.logspace(-7, 0.3, 40), 0.0,
                          np.logspace(-7, 0.3, 40)], np.linspace(0, 1.5, 7))  # fmt: skip
    x, v, i = x.ravel(), v.ravel(), i.ravel()
    d, c = model_force_parts(sim.code, p, x, v, i)
    xi = np.stack([d / FORCE_SCALE_N, c / FORCE_SCALE_N, v, x, np.ones_like(v)], axis=1)
    assert constraint_values(mats, xi).min() >= 0.0


def test_weighting_matrix_is_the_metric() -> None:
    a = np.random.default_rng(1).normal(size=64) + 3.0
    w = weighting_matrix(64, 0.005)
    assert math.isclose(float(np.sqrt(np.mean((w @ a) ** 2))),
                        float(metrics.wk_weighted_rms(a, 0.005)), rel_tol=1e-9)  # fmt: skip
    # an FFT against a BLAS matrix product: rounding differs across CPUs, so 1e-9, not bits


def test_unconstrained_dual_is_the_regularised_preview_optimum(sim: OracleEpisodes) -> None:
    """No constraints, a force weight rho: g is min_F J + rho |F|^2, a least-squares problem
    solved here by lstsq on the stacked system."""
    lifted = lift_episode(sim, 1)
    rho = 1e-4
    problem = DualProblem(lifted, np.zeros((0, 5, 5)), force_weight=rho)
    g = problem.evaluate(np.zeros((lifted.n_forces, 0))).value
    t = lifted.acc_rows.shape[0]
    wa = metrics.wk_weighting(np.fft.rfftfreq(t, lifted.dt_s))  # W by FFT of each column
    cols = lifted.acc_rows * FORCE_SCALE_N
    cols[:, -1] /= FORCE_SCALE_N
    spec = np.fft.rfft(cols - cols.mean(axis=0), axis=0) * np.abs(wa)[:, None]
    wg = np.fft.irfft(spec, n=t, axis=0) / math.sqrt(t)
    m = np.vstack([wg[:, :-1], math.sqrt(rho) * np.eye(lifted.n_forces)])
    rhs = -np.concatenate([wg[:, -1], np.zeros(lifted.n_forces)])
    f, *_ = np.linalg.lstsq(m, rhs, rcond=None)
    best = float(np.sum((m @ f - rhs) ** 2))
    assert g == pytest.approx(best, rel=1e-6)
    assert 0.0 < g < problem.ride(np.zeros(lifted.n_forces))  # the weight costs something
    # without the weight the body can be held still: g -> 0 with rho
    small = DualProblem(lifted, np.zeros((0, 5, 5)), force_weight=1e-12)
    assert 0.0 <= small.evaluate(np.zeros((lifted.n_forces, 0))).value < 1e-6 * g


def test_weak_duality_on_a_feasible_trajectory(sim: OracleEpisodes) -> None:
    """For multipliers with a positive definite Lagrangian: g <= J - sum lam q <= J of a real
    trajectory."""
    currents = np.random.default_rng(7).uniform(0, 1.5, sim.n_steps)
    lifted, forces = _replay(sim, 0, currents)
    mats = constraint_matrices(damper_envelope(sim.code, sim.damper_params[0]))
    problem = DualProblem(lifted, mats)
    lam = np.tile([2e-8, 4e-8, 0.0, 1e-10, 0.0, 1e-6, 2e-11, 1e-10, 0.0, 1e-10, 1e-9],
                  (lifted.n_forces, 1))  # fmt: skip
    g = problem.evaluate(lam).value
    assert math.isfinite(g)
    x, v = lifted.affine(lifted.x_rows, forces), lifted.affine(lifted.v_rows, forces)
    d, c = model_force_parts(sim.code, sim.damper_params[0], x, v, currents[lifted.step_of])
    xi = np.stack([d / FORCE_SCALE_N, c / FORCE_SCALE_N, v, x, np.ones_like(v)], axis=1)
    j = problem.ride(forces / FORCE_SCALE_N)
    assert math.isclose(j, float(metrics.wk_weighted_rms(
        lifted.affine(lifted.acc_rows, forces), lifted.dt_s)) ** 2, rel_tol=1e-9)  # fmt: skip
    assert g <= j - float(np.sum(lam * constraint_values(mats, xi))) <= j


def test_floor_below_the_oracle_and_the_controllers() -> None:
    from capsule_env.oracle import clairvoyant_bound

    seeds, length = [1000, 1001], 0.35
    env = {"setting": "sim", "guideway_seed": 2026}  # one bank for all three (evaluate.py's)
    result = certified_floor(env, seeds, length, max_iterations=15)
    oracle = clairvoyant_bound(env, seeds, length)
    ep = OracleEpisodes(env, seeds, length)
    _, out = ep.run(np.arange(2), np.zeros((2, ep.n_steps)), substeps="env")  # 0 A, passive
    zero_a = metrics.wk_weighted_rms(out[:, :, OUT_BODY_ACC], ep.dt_s)
    assert np.all(result.floor_wk_m_s2 >= 0.0)
    assert np.all(result.floor_wk_m_s2 <= oracle.wk_rms_body_acc_m_s2)
    assert np.all(oracle.wk_rms_body_acc_m_s2 <= zero_a)
    assert np.allclose(verify(result), result.dual_value, rtol=1e-9, atol=1e-15)
    row = floor_row(result)
    assert row["certified"] is True and row["wk_rms_body_acc_m_s2"] == result.mean_wk_m_s2
    assert len(row["per_episode"]["wk_rms_body_acc_m_s2"]) == 2


@pytest.mark.parametrize(
    ("args", "options", "error", "match"),
    [
        (({"setting": "hils"}, [1000], 0.1), {}, ValueError, "supported"),
        (({"setting": "sim"}, [], 0.1), {}, ValueError, "seeds"),
        (({"setting": "sim"}, [-1], 0.1), {}, ValueError, "seeds"),
        (({"setting": "sim"}, "1000", 0.1), {}, TypeError, "seeds"),
        (({"setting": "sim"}, [1000], 0.0), {}, ValueError, "episode_length_s"),
        (({"setting": "sim"}, [1000], 3.0), {}, ValueError, "at most 4000"),
        (({"setting": "sim"}, [1000], 0.1), {"max_iterations": -1}, ValueError, "max_iter"),
        (({"setting": "sim"}, [1000], 0.1), {"lam_scale": 0.0}, ValueError, "lam_scale"),
        (({"setting": "sim"}, [1000], 0.1), {"lam_start": (1.0,)}, ValueError, "lam_start"),
        (({"setting": "sim"}, [1000], 0.1), {"iterations": 3}, TypeError, "unknown options"),
    ],
)
def test_bad_input(args: tuple, options: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        certified_floor(*args, **options)


def test_offset_sector_constant_is_an_upper_bound_and_tight(sim: OracleEpisodes) -> None:
    from capsule_env.bounds.relaxation import OFFSET_SECTOR_SLOPES, offset_sector_constant

    p = sim.damper_params[0]
    env = damper_envelope(sim.code, p)
    v = np.linspace(1e-6, 0.5, 200001)
    d, _ = model_force_parts(sim.code, p, np.full_like(v, 1.0), v, np.full_like(v, 1.5))
    for m in OFFSET_SECTOR_SLOPES:
        sampled = float(np.max((d - env.b_lo * v) * (d - m * v)))
        delta = offset_sector_constant(env, m)
        assert sampled <= delta <= 1.01 * sampled


def test_dual_reaches_the_shor_sdp_optimum_at_its_multipliers() -> None:
    """An independent solver (Clarabel's interior point on the Shor SDP) against the dual's
    own evaluation: at the SDP's multipliers ``g`` is the SDP optimum (strong duality; the
    assembly, the offsets' elimination and the certificate's margin), and L-BFGS-B's ``g`` is
    below it (weak duality). A narrowed damper set (1 % of the yield force, no offset) so that
    the optimum is well above 0: a check of the algebra, not of the model."""
    from dataclasses import replace

    from capsule_env.bounds import DEFAULT_OPTIONS
    from capsule_env.bounds.dual import maximise
    from capsule_env.bounds.sdp import solve_shor

    ep = OracleEpisodes({"setting": "sim"}, [1000], 0.02)
    lifted = lift_episode(ep, 0)
    env = damper_envelope(ep.code, ep.damper_params[0])
    env = replace(env, a_hi=0.01 * env.a_hi, c_lo=0.0, c_hi=0.0)
    problem = DualProblem(lifted, constraint_matrices(env))
    sdp = solve_shor(problem)
    assert sdp.status == "Solved" and sdp.value > 0.0
    g = problem.evaluate(sdp.multipliers).value
    assert 0.99 * sdp.value <= g <= sdp.value * (1.0 + 1e-6)
    lam0 = np.tile(np.array(DEFAULT_OPTIONS["lam_start"]), (lifted.n_forces, 1))
    found = maximise(problem, lam0, 50, DEFAULT_OPTIONS["lam_scale"]).point.value
    assert found <= sdp.value * (1.0 + 1e-6)


def test_cli_refuses_the_hils_plant_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from capsule_env.bounds.__main__ import main

    with pytest.raises(SystemExit) as exc:
        main(["--setting", "hils", "--episodes", "1", "--episode-length", "0.1"])
    message = str(exc.value.code)
    assert message.startswith("python -m capsule_env.bounds: error:") and "\n" not in message
    assert "supported" in message and capsys.readouterr().out == ""


def test_cli_names_seed_when_the_last_episode_seed_overflows() -> None:
    # the last episode's seed (--seed + --episodes - 1) must stay below 2**63, the env's range;
    # the error used to name seeds[1], a parameter the CLI user never typed
    from capsule_env.bounds.__main__ import main

    with pytest.raises(SystemExit) as exc:
        main(["--seed", str(2**63 - 1), "--episodes", "2", "--episode-length", "0.1"])
    message = str(exc.value.code)
    assert "--seed" in message and "2**63" in message and "seeds[" not in message
