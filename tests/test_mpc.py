"""The semi-active MPC (agents/controllers/mpc.py) against independent facts: Giorgetti et al. (2006)'s
one-step result (the MPC is the clipped LQR), the unconstrained LQ optimum (Tomizuka's preview
law of agents/controllers/preview_lq.py, a separate derivation), the band of the damper written out by
hand, a QP solved by SciPy, the fallback, determinism and bad input; with both QP solvers
(DAQP, active set; OSQP, ADMM)."""

from __future__ import annotations

import numpy as np
import pytest
from capsule_env.agents.controllers.mpc import MPCController
from capsule_env.agents.controllers.mpc_qp import condense, prediction_model
from capsule_env.agents.controllers.mpc_solver import BandQP, SolverOptions
from capsule_env.agents.controllers.preview_lq import preview_lq_gains
from scipy.optimize import minimize

from capsule_env.engine.config import MEASURED_NAMES, EnvConfig
from capsule_env.evaluation.episodes import run_episodes
from capsule_env.vehicles import VehicleParams

WEIGHTS = (2.0, 100.0, 3e-8)  # q_stroke, q_gap (1/s^4), r_force (1/kg^2)
COL = {name: k for k, name in enumerate(MEASURED_NAMES)}
TIGHT = {"eps_abs": 1e-7, "eps_rel": 1e-7, "max_iter": 20000}


def band_by_hand(stroke_m: float, rate_m_s: float) -> tuple[float, float]:
    """The Bi-exponential force at 0 A and at i_max (paper eq. 4, the branch of the stroke's
    sign; strokes here are far beyond the 0.1 mm blend)."""
    dmp = EnvConfig().inverse_damper
    side = "upper" if stroke_m >= 0 else "lower"
    a0, a1, b0, b1, c0, c1, d = (getattr(dmp, f"{side}_{k}") for k in
                                 ("a0", "a1", "b0", "b1", "c0", "c1", "d"))  # fmt: skip
    s_d = np.sign(rate_m_s) * (1.0 - np.exp(-d * abs(rate_m_s)))
    i = dmp.max_current_a
    return a0 * s_d + b0 * rate_m_s + c0, (a0 + a1 * i) * s_d + (
        b0 + b1 * i
    ) * rate_m_s + c0 + c1 * i


def measured_obs(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random measured observations: stroke +-8 mm (beyond the blend), velocities 0.1 m/s."""
    obs = np.zeros((n, len(MEASURED_NAMES)))
    stroke = rng.uniform(1e-3, 8e-3, n) * rng.choice([-1.0, 1.0], n)
    body, bogie = rng.normal(0, 0.1, n), rng.normal(0, 0.1, n)
    obs[:, COL["stroke_m"]] = stroke
    obs[:, COL["car_body_velocity_estimate_m_s"]] = body
    obs[:, COL["bogie_velocity_estimate_m_s"]] = bogie
    obs[:, COL["stroke_rate_m_s"]] = body - bogie
    obs[:, COL["levitation_gap_m"]] = rng.normal(0, 2e-3, n)
    return obs


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
@pytest.mark.parametrize("delay_steps", [0, 1])
def test_one_step_horizon_is_clipped_lqr(delay_steps: int, backend: str) -> None:
    """Giorgetti et al. 2006: with a one-step horizon and the LQ cost-to-go as terminal cost
    the semi-active MPC is the LQR force clipped to the dissipative band."""
    rng = np.random.default_rng(3)
    obs = measured_obs(rng, 60)
    ctrl = MPCController(q_stroke=WEIGHTS[0], q_levitation=WEIGHTS[1], r_force=WEIGHTS[2],
                         horizon_steps=1, delay_steps=delay_steps, coil_time_constant_s=0.0,
                         solver={**TIGHT, "backend": backend})  # fmt: skip
    force = ctrl.desired_force(obs)
    gains = preview_lq_gains(VehicleParams(), 0.005, 0, *WEIGHTS, delay_steps=delay_steps)
    x = obs[:, [COL["stroke_m"], COL["car_body_velocity_estimate_m_s"], COL["levitation_gap_m"],
                COL["bogie_velocity_estimate_m_s"]]]  # fmt: skip
    lqr = -x @ gains.state_gain  # nothing in flight at the first step
    checked = 0
    for k in range(len(obs)):
        v, s = obs[k, COL["stroke_rate_m_s"]], obs[k, COL["stroke_m"]]
        f0, fmax = band_by_hand(s, v)
        lo, hi = (max(f0, 0.0), fmax) if v > 0 else (fmax, min(f0, 0.0))
        if lo > hi:  # no dissipative force in the band: the slack's compromise, not checked
            continue
        expected = np.clip(np.clip(lqr[k], lo, hi), -8000.0, 8000.0)  # and the env's scale
        # DAQP: exact; OSQP: its tolerance, 1e-7 x 8 kN
        assert force[k] == pytest.approx(expected, abs=0.5 if backend == "osqp" else 1e-6)
        checked += 1
    assert checked >= 50
    assert ctrl.counters["fallback_steps"] == 0


def test_unconstrained_plan_is_the_preview_lq_law() -> None:
    """With the band lifted, the first move of a 12-step plan with a delay and 60 rises ahead
    equals Tomizuka's preview LQ law (agents/controllers/preview_lq.py: another derivation)."""
    model = prediction_model(VehicleParams(), 0.005, 1, 0.0)
    qp = condense(model, WEIGHTS, 12, 60)
    gains = preview_lq_gains(VehicleParams(), 0.005, 60, *WEIGHTS, delay_steps=1)
    rng = np.random.default_rng(5)
    for _ in range(5):
        z0 = np.concatenate([rng.normal(0, [5e-3, 0.1, 2e-3, 0.1]), rng.normal(0, 2e3, 1)])
        rises = rng.normal(0, 1e-4, 60)
        w = np.linalg.solve(qp.h, -(qp.f_z @ z0 + qp.f_d @ rises))
        expected = -(gains.state_gain @ z0[:4] + gains.delay_gain @ z0[4:]
                     + gains.preview_gain @ rises)  # fmt: skip
        assert w[0] == pytest.approx(expected, rel=1e-7, abs=1e-6)


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_plan_agrees_with_scipy(backend: str) -> None:
    """A 3-step plan, the band on the first move: each solver's plan is SciPy's bounded
    minimum of the same quadratic (L-BFGS-B)."""
    model = prediction_model(VehicleParams(), 0.005, 0, 0.0)
    qp = condense(model, WEIGHTS, 3, 0)
    solver = BandQP(qp, EnvConfig().inverse_damper, 8000.0,
                    SolverOptions(constrained_steps=1, backend=backend, **TIGHT))  # fmt: skip
    z0 = np.array([8e-3, 0.02, -5e-3, 0.0])  # the LQ force pulls, the rate opens: 0 A's edge
    rate, stroke = 0.02, 8e-3
    plan = solver.plan(z0, np.zeros(3), rate, stroke, np.full(3, rate), np.full(3, stroke))
    f0, fmax = band_by_hand(stroke, rate)
    linear = qp.f_z @ z0
    ref = minimize(lambda w: 0.5 * w @ qp.h @ w + linear @ w, np.zeros(3),
                   jac=lambda w: qp.h @ w + linear, method="L-BFGS-B",
                   bounds=[(max(f0, 0), fmax), (None, None), (None, None)],
                   options={"ftol": 1e-15, "gtol": 1e-12})  # fmt: skip
    assert plan.status == "solved"
    unconstrained = np.linalg.solve(qp.h, -linear)[0]
    assert not (max(f0, 0) <= unconstrained <= fmax)  # the band is active
    np.testing.assert_allclose(plan.u, ref.x, rtol=1e-4, atol=1.0)


def test_plans_stay_in_the_band_on_the_hils_plant() -> None:
    """Over an episode on the hils plant every requested force is dissipative and inside the
    band at the measured rate (where that intersection is not empty)."""
    ctrl = MPCController()
    seen = []
    original = ctrl.plan

    def spy(k, z0, rises, rate, stroke):
        result = original(k, z0, rises, rate, stroke)
        seen.append((result.u, rate, stroke))
        return result

    ctrl.plan = spy
    run_episodes(ctrl, {**ctrl.env_kwargs, "setting": "hils"}, 2, 0, 0.5)
    checked = 0
    for u, rate, stroke in seen:
        assert u is not None
        f0, fmax = band_by_hand(stroke, rate) if abs(stroke) > 2e-4 else (None, None)
        if f0 is None:
            continue
        lo, hi = (max(f0, 0.0), fmax) if rate > 0 else (fmax, min(f0, 0.0))
        if lo <= hi:
            assert lo - 1.0 - 1e-3 * abs(lo) <= u[0] <= hi + 1.0 + 1e-3 * abs(hi)
            checked += 1
    assert checked > 100
    assert ctrl.counters["fallback_steps"] == 0


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_fallback_is_counted_and_is_the_lq_law(backend: str) -> None:
    """A solver stopped after one iteration fails: the law falls back to the LQ force and
    counts it."""
    obs = measured_obs(np.random.default_rng(1), 4)
    ctrl = MPCController(coil_time_constant_s=0.0, delay_steps=0, max_force_n=1e6,
                         solver={"max_iter": 1, "polish": False, "backend": backend})  # fmt: skip
    force = ctrl.desired_force(obs)
    assert ctrl.counters["failed_solves"] == 4 and ctrl.counters["fallback_steps"] == 4
    gains = preview_lq_gains(VehicleParams(), 0.005, 0, ctrl.q_stroke, ctrl.q_levitation,
                             ctrl.r_force)  # fmt: skip
    x = obs[:, [COL["stroke_m"], COL["car_body_velocity_estimate_m_s"], COL["levitation_gap_m"],
                COL["bogie_velocity_estimate_m_s"]]]  # fmt: skip
    np.testing.assert_allclose(force, -x @ gains.state_gain, rtol=1e-6)


def test_same_seed_same_trajectory() -> None:
    runs = []
    for _ in range(2):
        ctrl = MPCController(preview=True)
        roll = run_episodes(ctrl, {**ctrl.env_kwargs, "setting": "hils"}, 2, 7, 0.3)
        runs.append(roll.signals["car_body_acceleration_m_s2"])
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"horizon_steps": 0}, "horizon_steps"),
        ({"horizon_steps": 2.5}, "horizon_steps"),
        ({"r_force": 0.0}, "r_force"),
        ({"q_stroke": -1.0}, "q_stroke"),
        ({"q_levitation": float("nan")}, "q_levitation"),
        ({"solver": {"eps_abs": 0.0}}, "eps_abs"),
        ({"solver": {"max_iter": 0}}, "max_iter"),
        ({"solver": {"time_limit_s": -1.0}}, "time_limit_s"),
        ({"solver": {"warp": 1}}, "warp"),
        ({"solver": {"backend": "cvxopt"}}, "backend"),
        ({"horizon_steps": 4, "move_blocks": (2, 1)}, "move_blocks"),
        ({"horizon_steps": 4, "move_blocks": 4}, "move_blocks"),  # one integer: a TypeError once
        ({"delay_steps": -1}, "delay_steps"),
        ({"inverse_model": "csdc"}, "inverse_model"),
        ({"preview": True, "preview_points": 0}, "preview_points"),
    ],
)
def test_bad_options_name_the_parameter(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        MPCController(**kwargs)


def test_move_blocking_holds_the_moves() -> None:
    model = prediction_model(VehicleParams(), 0.005, 1, 1 / 190)
    qp = condense(model, WEIGHTS, 6, 0, blocks=(1, 2, 3))
    assert qp.h.shape == (3, 3)
    np.testing.assert_array_equal(qp.blocking @ np.array([1.0, 2.0, 3.0]), [1, 2, 2, 3, 3, 3])


def test_evaluate_without_the_solver_drops_or_refuses_the_mpc_rows(monkeypatch, capsys) -> None:
    import capsule_env.agents.controllers.mpc_solver as mpc_solver

    from capsule_env.evaluation.evaluate import DEFAULT_CONTROLLERS, build_controllers

    monkeypatch.setattr(mpc_solver, "solver_available", lambda: False)
    ctrls = build_controllers(list(DEFAULT_CONTROLLERS), [], shipped=False)
    assert "mpc-biexp-meas" in DEFAULT_CONTROLLERS and not [n for n in ctrls if "mpc" in n]
    assert "DAQP is not installed" in capsys.readouterr().err
    with pytest.raises(ValueError, match="mpc-biexp-meas need a QP solver"):
        build_controllers(["passive", "mpc-biexp-meas"], [], shipped=False)


def test_without_the_solver_the_shipped_residual_on_the_mpc_is_left_out_or_refused(
    monkeypatch, capsys
) -> None:
    pytest.importorskip("stable_baselines3")  # the rl extra (the dev extra installs it)
    import capsule_env.agents.controllers.mpc_solver as mpc_solver
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, load_policy, shipped_policies

    from capsule_env.evaluation.evaluate import build_controllers

    monkeypatch.setattr(mpc_solver, "solver_available", lambda: False)
    ctrls = build_controllers(["passive"], [], shipped=True)
    assert "residual-ppo-mpc" not in ctrls and "ppo-measured" in ctrls
    assert "residual-ppo-mpc left out" in capsys.readouterr().err
    assert "residual-ppo-mpc" not in shipped_policies() and "ppo-preview" in shipped_policies()
    with pytest.raises(ValueError, match="mpc-biexp-meas needs a QP solver"):
        load_policy(PRETRAINED_DIR / "residual-ppo-mpc.zip")
    monkeypatch.undo()  # with the solver: the residual is a row again
    assert "residual-ppo-mpc" in build_controllers(["passive"], [], shipped=True)


@pytest.mark.slow
def test_bench_mpc_quick_reports_consistent_figures(tmp_path) -> None:
    """The benchmark's arithmetic (no speed is asserted: the machine decides it)."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "bench.json"
    done = subprocess.run([sys.executable, "benchmarks/bench_mpc.py", "--quick", "--json",
                           str(out)], cwd=root, capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    data = json.loads(out.read_text())
    for name, row in data["step"].items():
        assert 0 < row["median_ms"] <= row["p99_ms"] <= row["max_ms"], name
        assert 0.0 <= row["over_budget_rel"] <= 1.0 and row["steps"] == 80
    assert data["step"]["mpc-biexp-meas"]["solves_per_step"] >= 1.0
    per = data["evaluation"]["per_controller_s"]
    assert set(per) == {"passive", "lqr-clipped-biexp-meas", "mpc-biexp-meas"}
    assert data["evaluation"]["with_mpc_s"] == pytest.approx(sum(per.values()))
    assert data["evaluation"]["without_mpc_s"] == pytest.approx(
        per["passive"] + per["lqr-clipped-biexp-meas"]
    )


def test_wk_cost_filter_is_the_metric_weighting() -> None:
    """The cost's Wk filter is the metric's weighting without its band limits (0.4 Hz
    high-pass, 100 Hz low-pass): compared as complex responses with capsule_env.metrics."""
    from capsule_env.agents.controllers.mpc_qp import wk_state_space

    from capsule_env.metrics import wk_weighting

    a, b, c = wk_state_space()
    f = np.array([0.5, 1.3, 2.37, 4.0, 5.4, 8.0, 12.5, 20.0])
    s = 2j * np.pi * f
    ours = np.array([c @ np.linalg.solve(x * np.eye(4) - a, b) for x in s])
    q = 1 / np.sqrt(2)
    w1, w2 = 2 * np.pi * 0.4, 2 * np.pi * 100.0
    band = (s**2 / (s**2 + w1 / q * s + w1**2)) * (w2**2 / (s**2 + w2 / q * s + w2**2))
    np.testing.assert_allclose(ours, wk_weighting(f) / band, rtol=1e-10)


def test_wk_cost_runs_on_the_measured_acceleration() -> None:
    ctrl = MPCController(wk_cost=True)
    assert "car_body_acceleration_m_s2" in ctrl.signals_read
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, "setting": "hils"}, 1, 3, 0.3)
    assert np.all(np.isfinite(roll.signals["car_body_acceleration_m_s2"]))
    assert ctrl.counters["fallback_steps"] == 0 and ctrl.counters["vehicle_steps"] == 60


def test_variants_experiment_runs_every_variant(tmp_path) -> None:
    import json

    from conftest import load_script

    script = load_script("experiments/mpc_variants.py")
    out = tmp_path / "variants.json"
    assert script.main(["--episodes", "1", "--length", "0.5", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert set(rows) == {"lqr-clipped-biexp-meas", *script.VARIANTS}
    assert all(r["fallback_steps"] == 0 for k, r in rows.items() if k in script.VARIANTS)


def test_evaluate_runs_the_mpc_rows(tmp_path) -> None:
    import json

    from capsule_env.evaluation import evaluate

    out = tmp_path / "eval.json"
    argv = ["--setting", "hils", "--episodes", "1", "--episode-length", "1", "--json", str(out),
            "--controllers", "passive,mpc-biexp-meas,preview-mpc-biexp-meas",
            "--no-shipped-policy"]  # fmt: skip
    assert evaluate.main(argv) == 0
    rows = json.loads(out.read_text())["settings"]["hils"]["controllers"]
    assert rows["mpc-biexp-meas"]["observation"] == "measured"
    assert rows["preview-mpc-biexp-meas"]["preview"] is True
    assert rows["mpc-biexp-meas"]["gains"]["horizon_s"] == pytest.approx(0.05)


def test_fair_comparison_mpc_table_is_its_json() -> None:
    """docs/fair-comparison.md's MPC rows, written by hand, read back against the run's JSON
    (and the passive and oracle rows of the main evaluation, the same episodes)."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    ctrls = json.loads((root / "docs/figures/mpc_evaluation.json").read_text())["settings"]
    ctrls = ctrls["hils"]["controllers"]
    main = json.loads((root / "docs/figures/evaluation.json").read_text())["settings"]["hils"]
    main = main["controllers"]
    passive, oracle = (main[n]["wk_rms_body_acc_m_s2"] for n in ("passive", "oracle"))
    for name in ctrls:  # the rows both runs have agree; the LQ laws' gains come from a
        # Riccati solve (LAPACK), whose last bits differ between CPUs: 1e-9 relative (seen:
        # 3e-12 for preview LQ between the two runs' machines)
        if name in main:
            assert ctrls[name]["wk_rms_body_acc_m_s2"] == pytest.approx(
                main[name]["wk_rms_body_acc_m_s2"], rel=1e-9
            )
    lqr = ctrls["lqr-clipped-biexp-meas"]["wk_rms_body_acc_m_s2"]
    page = (root / "docs/fair-comparison.md").read_text().splitlines()
    start = page.index(next(line for line in page if line.startswith("| group | MPC row |")))
    seen = set()
    for line in page[start + 2 :]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        m = ctrls[cells[1]]
        wk = m["wk_rms_body_acc_m_s2"]
        assert cells[2:] == [
            f"{wk:.4f}", f"{wk / lqr:.3f}", f"{m['vre_pct']['body_mode1']:.1f} %",
            f"{1e3 * m['max_stroke_m']:.1f} mm", f"{m['sperling_ride_index']:.2f}",
            f"{m['en12299_comfort_index']:.2f}", f"{100 * (passive - wk) / (passive - oracle):.0f} %",
        ], cells[1]  # fmt: skip
        seen.add(cells[1])
    assert seen == {"mpc-biexp-meas", "preview-mpc-biexp-meas", "mpc-biexp", "preview-mpc-biexp"}
