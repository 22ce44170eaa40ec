"""Tests of the time integration (capsule_env.plant) against independent facts.

* Linear plant: steady-state sine responses fitted from ``simulate`` against the analytic
  transfer function ``(j w I - A)^-1 E`` of the state-space matrices.
* Reference damper + plant: the default substep against a 10x finer one, and against an
  independent ``scipy.integrate.solve_ivp`` (LSODA) integration of docs/model.md 2 and 4.2 written out
  here.
* Robustness at stroke rates up to ~2 m/s, the coil lag's exact exponential, and the batched
  kernel (identical rows, single vehicle, serial vs parallel bit for bit).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from capsule_env.dampers import (
    DAMPER_NAMES,
    N_DAMPER_PARAMS,
    LinearDamper,
    ReferenceDamper,
    make_damper,
)
from capsule_env.dampers.rig import simulate_damper
from capsule_env.engine.kernels import PARALLEL_THRESHOLD, PLANT, kernels
from capsule_env.engine.layout import N_PLANT_OUTPUTS as N_OUTPUTS
from capsule_env.engine.layout import STATE_SIZE
from capsule_env.engine.simulate import simulate, step_batch
from capsule_env.guideway import random_profile, sine_profile
from capsule_env.plant import (
    Route,
    block,
    default_substeps,
    initial_state,
    make_plant_params,
    stiffness_rates,
    substep_tables,
)
from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.modes import frequency_response, state_space

from conftest import DT, I_MAX, K_P, K_S, M_B, M_C, SPEED, SPENCER


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


# ------------------------------------------------------------------ transfer function
TF_FREQS = [0.5, 1.0, 1.3, 2.0, 3.0, 5.4, 7.0, 10.0]
TF_AMP = 0.005  # m
TF_SPACING = 0.05  # m


def fit_sine(t: np.ndarray, y: np.ndarray, f: float) -> complex:
    """Least-squares fit y ~ a sin(w t) + b cos(w t) + c; returns the phasor a + j b."""
    w = 2.0 * math.pi * f
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    (a, b, _), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return complex(a, b)


@pytest.fixture(scope="module")
def sine_responses():
    """f -> (measured phasor / input amplitude) of car body and bogie displacement."""
    damper = LinearDamper()  # c = 1.5e4 N s/m
    assert damper.damping_n_s_per_m == 1.5e4
    out = {}
    for f in TF_FREQS:
        duration = 20.0  # transients decay as exp(-1.2 t) at worst (body mode, zeta ~ 0.15)
        profile = sine_profile(
            SPEED * duration + 10.0, TF_SPACING, frequency_hz=f, speed_mps=SPEED, amplitude_m=TF_AMP
        )
        r = simulate(damper, profile, TF_SPACING, SPEED, 0.0, duration, dt_s=DT)
        n_periods = math.floor(6.0 * f)  # an integer number of periods in the last ~6 s
        window = r["time_s"] >= duration - n_periods / f - 1e-9
        t = r["time_s"][window]
        out[f] = tuple(
            fit_sine(t, r[key][window], f) / TF_AMP
            for key in ("car_body_displacement_m", "bogie_displacement_m")
        )
    return out


@pytest.mark.parametrize("f", TF_FREQS)
def test_sine_response_matches_transfer_function(sine_responses, f):
    # z_g = X sin(w t) -> z = |H| X sin(w t + arg H): phasor (a + j b) / X = H.
    h = frequency_response(f, secondary_damping_n_s_per_m=1.5e4)[0]
    for measured, expected in zip(sine_responses[f], (h[0], h[2]), strict=True):
        assert abs(measured) == pytest.approx(abs(expected), rel=0.01)
        phase_err = math.degrees(abs(np.angle(measured / expected)))
        assert phase_err < 2.0


def test_transfer_function_resonances_are_seen(sine_responses):
    # The measured gains peak at the modes: body gain largest near 1.3 Hz, bogie near 5.4 Hz.
    body = {f: abs(v[0]) for f, v in sine_responses.items()}
    bogie = {f: abs(v[1]) for f, v in sine_responses.items()}
    assert max(body, key=body.get) == 1.3
    assert max(bogie, key=bogie.get) == 5.4


# ------------------------------------------------------------------ integration accuracy
ACC_DURATION = 10.0
ACC_SEED = 11


@pytest.fixture(scope="module")
def accuracy_profile():
    return random_profile(2300.0, 0.25, seed=ACC_SEED)


def current_case(case: str) -> np.ndarray | float:
    if case == "0A":
        return 0.0
    if case == "1.5A":
        return I_MAX
    rng = np.random.default_rng(5)
    return rng.uniform(0.0, I_MAX, int(round(ACC_DURATION / DT)))


@pytest.fixture(scope="module")
def accuracy_runs(accuracy_profile):
    damper = ReferenceDamper()
    n_default = default_substeps(damper, DT)
    runs = {}
    for case in ("0A", "1.5A", "random"):
        cmd = current_case(case)
        coarse = simulate(damper, accuracy_profile, 0.25, SPEED, cmd, ACC_DURATION, dt_s=DT)
        fine = simulate(
            damper,
            accuracy_profile,
            0.25,
            SPEED,
            cmd,
            ACC_DURATION,
            dt_s=DT,
            substeps=10 * n_default,
        )
        runs[case] = (coarse, fine)
    return runs


@pytest.mark.parametrize("case", ["0A", "1.5A", "random"])
def test_default_substeps_within_1pct_of_10x_finer(accuracy_runs, case):
    coarse, fine = accuracy_runs[case]
    f_c, f_f = coarse["damper_force_n"][1:], fine["damper_force_n"][1:]
    assert rms(f_f) > 500.0  # the guideway really works the damper
    assert rms(f_c - f_f) / rms(f_f) < 0.01
    for key in ("car_body_displacement_m", "bogie_displacement_m"):
        assert rms(coarse[key] - fine[key]) / rms(fine[key]) < 0.01


def test_default_substeps_meet_documented_accuracy(accuracy_runs):
    # substep_table's docstring: "within 0.5 % RMS of a 10x finer step" on the reference
    # damper (tests/test_substeps.py checks every model and randomised vehicles).
    for coarse, fine in accuracy_runs.values():
        f_c, f_f = coarse["damper_force_n"][1:], fine["damper_force_n"][1:]
        assert rms(f_c - f_f) / rms(f_f) < 0.005


def test_default_substeps_of_reference_damper():
    # RK4 is stable only for |lambda| h <= 2.785: Spencer's pre-yield rate
    # (alpha A + k0) / (c0 + c1) at 1.5 A, from docs/model.md 4.2, bounds the substeps from below.
    damper = ReferenceDamper()
    n = default_substeps(damper, DT)
    p = SPENCER
    rate = ((p["aa"] + 1.5 * p["ab"]) * p["A"] + p["k0"]) / (
        p["c0a"] + 1.5 * p["c0b"] + p["c1a"] + 1.5 * p["c1b"]
    )
    assert n >= math.ceil(rate * DT / 2.785)


def test_stiffness_rates_of_passive_plant_match_state_space_eigenvalues():
    # The linearised plant of the substep rule, for the linear damper, is the passive plant:
    # its eigenvalues come from vehicle.state_space (independent code), per vehicle.
    rng = np.random.default_rng(0)
    c = 1.5e4
    for _ in range(5):
        params = VehicleParams(*(rng.uniform(0.3, 1.7, 4) * [M_C, M_B, K_S, K_P]))
        a, _, _ = state_space(params, c)
        lam = np.linalg.eigvals(a)
        rate, omega = stiffness_rates(LinearDamper(c), params.as_array(), 0.0)
        assert rate[0, 0] == pytest.approx(np.abs(lam.real).max(), rel=1e-9)
        assert omega[0, 0] == pytest.approx(np.abs(lam.imag).max(), rel=1e-9)


def reference_plant_rhs(profile: np.ndarray, spacing: float, i_cmd: float):
    """docs/model.md 2 and 4.2 written out: d/dt [z_c, z_c', z_b, z_b', z, y, i]."""
    p = SPENCER
    positions = np.arange(profile.size) * spacing

    def forces(s):
        zc, vc, zb, vb, z, y, i = s
        x, v = zc - zb, vc - vb
        c0, c1 = p["c0a"] + p["c0b"] * i, p["c1a"] + p["c1b"] * i
        alpha = p["aa"] + p["ab"] * i
        y_dot = (alpha * z + c0 * v + p["k0"] * (x - y)) / (c0 + c1)
        return c1 * y_dot + p["k1"] * (x - p["x0"]), y_dot, v - y_dot

    def rhs(t, s):
        zc, vc, zb, vb, z, y, i = s
        force, y_dot, w = forces(s)
        z_dot = -p["g"] * abs(w) * z * abs(z) - p["b"] * w * z * z + p["A"] * w
        zg = np.interp(SPEED * t, positions, profile)
        secondary = K_S * (zc - zb) + force
        return [
            vc,
            -secondary / M_C,
            vb,
            (secondary - K_P * (zb - zg)) / M_B,
            z_dot,
            y_dot,
            -p["eta"] * (i - i_cmd),
        ]

    return rhs, forces


@pytest.mark.parametrize("i_cmd", [0.0, 1.5])
def test_default_step_matches_independent_solve_ivp(accuracy_profile, i_cmd):
    duration = 3.0
    r = simulate(ReferenceDamper(), accuracy_profile, 0.25, SPEED, i_cmd, duration, dt_s=DT)
    rhs, forces = reference_plant_rhs(accuracy_profile, 0.25, i_cmd)
    t = r["time_s"]
    sol = solve_ivp(
        rhs,
        (0.0, duration),
        np.zeros(7),
        method="LSODA",
        t_eval=t,
        rtol=1e-9,
        atol=1e-12,
        max_step=2e-4,
    )
    assert sol.status == 0, sol.message
    expected = forces(sol.y)[0]
    got = r["damper_force_n"]
    assert rms(expected[1:]) > 500.0
    assert rms(got[1:] - expected[1:]) / rms(expected[1:]) < 0.01
    for key, row in (
        ("car_body_displacement_m", 0),
        ("bogie_displacement_m", 2),
        ("coil_current_a", 6),
    ):
        assert rms(r[key] - sol.y[row]) <= 0.01 * rms(sol.y[row])


def test_coil_lag_is_first_order_exponential():
    # i' = -eta (i - i_cmd), i(0) = 0: i(t) = i_cmd (1 - exp(-eta t)) exactly; then a step down.
    profile = np.zeros(100)
    cmd = np.r_[np.full(20, 1.2), np.full(20, 0.3)]
    r = simulate(ReferenceDamper(), profile, 1.0, SPEED, cmd, 40 * DT, dt_s=DT)
    t = r["time_s"]
    eta = SPENCER["eta"]
    t1 = 20 * DT
    i1 = 1.2 * (1.0 - math.exp(-eta * t1))
    expected = np.where(
        t <= t1 + 1e-12,
        1.2 * (1.0 - np.exp(-eta * t)),
        0.3 + (i1 - 0.3) * np.exp(-eta * (t - t1)),
    )
    np.testing.assert_allclose(r["coil_current_a"], expected, rtol=1e-10, atol=1e-12)
    # Flat guideway, plant at rest: nothing moves and the force stays zero.
    np.testing.assert_array_equal(r["car_body_displacement_m"], 0.0)
    np.testing.assert_array_equal(r["damper_force_n"][1:], 0.0)


def test_current_command_is_clipped_to_range():
    profile = np.zeros(100)
    d = ReferenceDamper(coil_time_constant_s=0.0)
    r = simulate(d, profile, 1.0, SPEED, np.array([-1.0, 5.0, 0.7]), 3 * DT, dt_s=DT)
    np.testing.assert_array_equal(r["coil_current_a"][1:], [0.0, I_MAX, 0.7])


def test_simulate_output_conventions(accuracy_profile):
    r = simulate(LinearDamper(), accuracy_profile, 0.25, SPEED, 0.0, 1.0, dt_s=DT)
    t = r["time_s"]
    np.testing.assert_allclose(t, np.arange(201) * DT, atol=1e-12)
    np.testing.assert_allclose(
        r["stroke_m"], r["car_body_displacement_m"] - r["bogie_displacement_m"]
    )
    positions = np.arange(accuracy_profile.size) * 0.25
    np.testing.assert_allclose(
        r["guideway_m"][1:], np.interp(SPEED * t[1:], positions, accuracy_profile), atol=1e-12
    )
    # F = c v with v the stroke rate; Newton's second law on the car body: m_c a = -k_s x - F.
    np.testing.assert_allclose(r["damper_force_n"][1:], 1.5e4 * r["stroke_rate_m_s"][1:])
    np.testing.assert_allclose(
        M_C * r["body_acc_m_s2"][1:], -K_S * r["stroke_m"][1:] - r["damper_force_n"][1:], atol=1e-6
    )
    np.testing.assert_allclose(
        M_B * r["bogie_acc_m_s2"][1:],
        K_S * r["stroke_m"][1:]
        + r["damper_force_n"][1:]
        - K_P * (r["bogie_displacement_m"][1:] - r["guideway_m"][1:]),
        atol=1e-6,
    )


# ------------------------------------------------------------------------- robustness
ROUNDING = 1.0 + 1e-9


def force_bound(name: str, v_max: float, x_max: float) -> float:
    """Upper bound on |F| from docs/model.md 4's force laws at |v| <= v_max, |x| <= x_max.

    Every coefficient is linear in i on [0, 1.5 A], so its magnitude is at most
    |p_a| + |p_b| 1.5; the hysteretic z of Bouc-Wen stays within sqrt(A / (gamma + beta)), and
    Spencer's internal displacement is taken within +-2 x_max of the stroke. Some of these
    bounds are attained (viscous and saturated terms), hence the rounding margin ROUNDING.
    """
    d = make_damper(name)

    def mag(a, b):
        return abs(a) + abs(b) * I_MAX

    if name == "passive":
        return d.damping_n_s_per_m * v_max
    if name == "reference":
        z_sat = math.sqrt(d.a_coef / (d.gamma + d.beta))
        # F = c1/(c0 + c1) (alpha z + c0 v + k0 (x - y)) + k1 x, c1/(c0 + c1) < 1
        return (
            mag(d.alpha_a, d.alpha_b) * z_sat
            + mag(d.c0a, d.c0b) * v_max
            + d.k0 * 3.0 * x_max
            + d.k1 * x_max
        )
    if name == "bouc_wen":
        z_sat = math.sqrt(d.a_coef / (d.gamma + d.beta))
        return mag(d.c0a, d.c0b) * v_max + d.k0 * x_max + mag(d.alpha_a, d.alpha_b) * z_sat
    if name == "tanh":
        return (
            mag(d.c_a, d.c_b) * v_max
            + mag(d.k_a, d.k_b) * x_max
            + mag(d.alpha_a, d.alpha_b)
            + mag(d.f0_a, d.f0_b)
        )
    return max(
        mag(getattr(d, s + "_a0"), getattr(d, s + "_a1"))
        + mag(getattr(d, s + "_b0"), getattr(d, s + "_b1")) * v_max
        + mag(getattr(d, s + "_c0"), getattr(d, s + "_c1"))
        for s in ("upper", "lower")
    )


CURRENT_CASES = [0.0, 0.75, 1.5, "random"]


def current_signal(case, n: int, seed: int) -> np.ndarray | float:
    if case == "random":
        return np.random.default_rng(seed).uniform(0.0, I_MAX, n)
    return case


@pytest.mark.parametrize("name", DAMPER_NAMES)
def test_damper_alone_finite_and_bounded_at_2_m_per_s(name):
    # 0.1 m at 3.2 Hz: stroke rate up to 2.01 m/s, sampled at the 200 Hz control rate.
    t = np.arange(0.0, 2.0 + 1e-9, DT)
    w = 2.0 * math.pi * 3.2
    x, v = 0.1 * np.sin(w * t), 0.1 * w * np.cos(w * t)
    assert np.max(np.abs(v)) > 2.0
    d = make_damper(name)
    bound = force_bound(name, np.max(np.abs(v)), 0.1)
    for case in CURRENT_CASES:
        i = current_signal(case, t.size, seed=1)
        for substeps in (None, default_substeps(d, DT)):
            kwargs = {} if substeps is None else {"substeps": substeps}
            r = simulate_damper(d, t, x, v, i, **kwargs)
            for key, arr in r.items():
                assert np.all(np.isfinite(arr)), (key, case)
            assert np.max(np.abs(r["force_n"])) <= bound * ROUNDING, (case, substeps)
            assert np.max(np.abs(r["internal_displacement_m"] - x)) <= 2.0 * 0.1
            assert np.max(np.abs(r["hysteretic_z_m"])) <= 0.0065


@pytest.mark.parametrize("name", DAMPER_NAMES)
def test_plant_finite_and_bounded_under_large_sine(name):
    # 50 mm at 8 Hz over the EDS spring drives stroke rates of 2-3 m/s.
    duration = 3.0
    profile = sine_profile(
        SPEED * duration + 5.0, 0.25, frequency_hz=8.0, speed_mps=SPEED, amplitude_m=0.05
    )
    d = make_damper(name)
    n = int(round(duration / DT))
    for case in CURRENT_CASES:
        r = simulate(d, profile, 0.25, SPEED, current_signal(case, n, seed=2), duration, dt_s=DT)
        for key, arr in r.items():
            assert np.all(np.isfinite(arr[1:])), (key, case)
        v_max = np.max(np.abs(r["stroke_rate_m_s"]))
        x_max = np.max(np.abs(r["stroke_m"]))
        assert v_max > 1.9, case
        bound = force_bound(name, v_max, x_max)
        assert np.max(np.abs(r["damper_force_n"][1:])) <= bound * ROUNDING, case
        # Displacements stay of the order of the excitation (no numerical blow-up).
        assert np.max(np.abs(r["bogie_displacement_m"])) < 10 * 0.05
        assert np.max(np.abs(r["hysteretic_z_m"])) <= 0.0065


# ---------------------------------------------------------------------- batched kernel
BATCH_STEPS = 200


def batch_inputs(n: int, identical: bool, seed: int = 0):
    rng = np.random.default_rng(seed)
    damper = ReferenceDamper()
    spacing = 0.25
    profiles = np.stack([random_profile(600.0, spacing, seed=s) for s in (21, 22, 23)])
    dp = np.tile(damper.as_array(), (n, 1))
    vp = np.tile(VehicleParams().as_array(), (n, 1))
    idx = np.zeros(n, dtype=np.int64)
    x0 = np.zeros(n)
    speed = np.full(n, SPEED)
    cmd = rng.uniform(0.0, I_MAX, (BATCH_STEPS, 1)) * np.ones((1, n))
    if not identical:
        dp[:, 0] *= rng.uniform(0.8, 1.2, n)  # c0a
        dp[:, 4] *= rng.uniform(0.8, 1.2, n)  # alpha_a
        vp[:, 0] *= rng.uniform(0.9, 1.1, n)
        idx = rng.integers(0, profiles.shape[0], n).astype(np.int64)
        x0 = rng.uniform(0.0, 100.0, n)
        speed = rng.uniform(150.0, 225.0, n)
        cmd = rng.uniform(0.0, I_MAX, (BATCH_STEPS, n))
    assert dp.shape == (n, N_DAMPER_PARAMS)
    return damper, dict(
        dp=dp,
        vp=vp,
        profiles=profiles,
        idx=idx,
        spacing=spacing,
        x0=x0,
        speed=speed,
        cmd=np.ascontiguousarray(cmd),
    )


def run_batch(code: int, inp: dict, rows: slice | None = None, substeps: int = 5):
    """Step the batch (or a slice of its rows, as a smaller batch) for BATCH_STEPS intervals."""
    rows = rows or slice(None)

    def c(a):
        return np.ascontiguousarray(a[rows])

    dp, vp, idx, x0, speed = (
        c(inp["dp"]),
        c(inp["vp"]),
        c(inp["idx"]),
        c(inp["x0"]),
        c(inp["speed"]),
    )
    n = dp.shape[0]
    plant = make_plant_params(code, dp, vp, substeps, inp["profiles"], inp["spacing"], DT)
    route = Route(idx, x0, speed, np.ones(n))
    state = initial_state(n)
    out = np.empty((n, N_OUTPUTS))
    states = np.empty((BATCH_STEPS, n, STATE_SIZE))
    outs = np.empty((BATCH_STEPS, n, N_OUTPUTS))
    for k in range(BATCH_STEPS):
        cmd = np.ascontiguousarray(inp["cmd"][k, rows])
        step_batch(code, plant, state, cmd, route, DT, out)
        states[k], outs[k] = state, out
    return states, outs


@pytest.mark.parametrize("n", [3, pytest.param(PARALLEL_THRESHOLD + 3, marks=pytest.mark.slow)])
def test_identical_rows_give_identical_results_equal_to_simulate(n):
    damper, inp = batch_inputs(n, identical=True)
    states, outs = run_batch(damper.code, inp)
    assert np.all(np.isfinite(states))
    for row in range(1, n):
        np.testing.assert_array_equal(states[:, row], states[:, 0])
        np.testing.assert_array_equal(outs[:, row], outs[:, 0])
    r = simulate(
        damper,
        inp["profiles"][0],
        inp["spacing"],
        SPEED,
        inp["cmd"][:, 0],
        BATCH_STEPS * DT,
        dt_s=DT,
        substeps=5,
    )
    np.testing.assert_array_equal(r["car_body_displacement_m"][1:], states[:, 0, 0])
    np.testing.assert_array_equal(r["bogie_velocity_m_s"][1:], states[:, 0, 3])
    np.testing.assert_array_equal(r["coil_current_a"][1:], states[:, 0, 6])
    np.testing.assert_array_equal(r["damper_force_n"][1:], outs[:, 0, 0])
    np.testing.assert_array_equal(r["guideway_m"][1:], outs[:, 0, 3])


@pytest.mark.slow
def test_parallel_kernel_equals_serial_bit_for_bit():
    n = PARALLEL_THRESHOLD + 5
    damper, inp = batch_inputs(n, identical=False, seed=9)
    states, outs = run_batch(damper.code, inp)  # n >= threshold: chunks on threads
    assert np.all(np.isfinite(states))
    assert np.ptp(states[-1, :, 0]) > 0.0  # the rows really differ
    for row in range(n):  # each row alone: a batch of 1, the serial kernel
        s1, o1 = run_batch(damper.code, inp, rows=slice(row, row + 1))
        np.testing.assert_array_equal(s1[:, 0], states[:, row])
        np.testing.assert_array_equal(o1[:, 0], outs[:, row])
    # And the serial kernel on a whole sub-threshold block agrees too.
    block = slice(0, PARALLEL_THRESHOLD - 1)
    s_block, _ = run_batch(damper.code, inp, rows=block)
    np.testing.assert_array_equal(s_block, states[:, block])


# ------------------------------------------------- vectorised block kernel vs scalar kernel
def _block_inputs(damper, n: int, seed: int = 4):
    rng = np.random.default_rng(seed)
    spacing = 0.25
    profiles = np.stack([random_profile(600.0, spacing, seed=s) for s in (31, 32)])
    vp = np.tile(VehicleParams().as_array(), (n, 1))
    vp[:, :4] *= rng.uniform(0.9, 1.1, (n, 4))
    return dict(
        dp=np.ascontiguousarray(np.tile(damper.as_array(), (n, 1))),
        vp=np.ascontiguousarray(vp),
        profiles=profiles,
        idx=rng.integers(0, 2, n).astype(np.int64),
        spacing=spacing,
        x0=rng.uniform(0.0, 100.0, n),
        speed=rng.uniform(150.0, 225.0, n),
        gain=np.ones(n),
        cmd=rng.uniform(0.0, I_MAX, (BATCH_STEPS, n)),
        table=substep_tables(damper, DT, vp),  # each vehicle its own table
    )


def _run_kernel(mode, inp, n, code, threaded=False):
    """Step the plant kernels of ``mode`` over ``n`` vehicles: serial, or on all cores."""
    serial, parallel = kernels(PLANT, code, mode)
    plant = make_plant_params(code, inp["dp"], inp["vp"], inp["table"], inp["profiles"],
                              inp["spacing"], DT)  # fmt: skip
    route = Route(inp["idx"], inp["x0"], inp["speed"], inp["gain"])
    state, out = initial_state(n), np.empty((n, N_OUTPUTS))
    states = np.empty((BATCH_STEPS, n, STATE_SIZE))
    for k in range(BATCH_STEPS):
        args = (plant, state, np.ascontiguousarray(inp["cmd"][k]), route, DT, out)
        if threaded:
            parallel(n, *args)
        else:
            serial(0, n, *args)
        states[k] = state
    return states


BLOCK_CASES = {
    "reference": (ReferenceDamper(), block.KERNEL_BLOCK),
    "reference_beta_gt_gamma": (
        ReferenceDamper(gamma=1.0e6, beta=6.26e6),
        block.KERNEL_BLOCK_TANH_UNLOAD,
    ),
    "bi_exponential": (make_damper("bi_exponential"), block.KERNEL_BLOCK),
    "tanh": (make_damper("tanh"), block.KERNEL_BLOCK),
    "passive": (make_damper("passive"), block.KERNEL_BLOCK),
}


@pytest.mark.parametrize("case", list(BLOCK_CASES))
def test_vectorised_block_kernel_matches_scalar_kernel(case):
    # Two independent codings of the same scheme: the scalar kernel (libm, branches, exact
    # hysteresis update of capsule_env.dampers.hysteresis) and the vectorised one (call-free exp/log,
    # selects, lanes sorted by substep count). 10 vehicles with different vehicles, currents,
    # guideway windows and speeds, adaptive substeps, 1 s.
    # Both variants of the block kernel: damper parameters read as constants (KERNEL_UNIFORM,
    # all rows equal) and copied per vehicle (the rows may differ).
    damper, mode = BLOCK_CASES[case]
    n = 10
    inp = _block_inputs(damper, n)
    assert block.block_kernel_mode(damper.code, inp["dp"]) == mode | block.KERNEL_UNIFORM
    s_ref = _run_kernel(block.KERNEL_SCALAR, inp, n, damper.code)
    scale = np.max(np.abs(s_ref), axis=(0, 1)) + 1e-30
    for variant in (mode | block.KERNEL_UNIFORM, mode):
        s_vec = _run_kernel(variant, inp, n, damper.code)
        assert np.max(np.abs(s_vec - s_ref) / scale) < 1e-9
    assert np.ptp(s_vec[-1, :, 0]) > 0.0  # the vehicles really differ


def test_block_kernel_honours_per_vehicle_damper_rows():
    # Rows with different damper parameters (domain randomisation of the damper): the per-row
    # block kernel against each vehicle stepped alone by the scalar kernel.
    base = ReferenceDamper()
    n = 6
    inp = _block_inputs(base, n, seed=3)
    factors = np.linspace(0.7, 1.3, n)
    dp = inp["dp"].copy()
    for col in (0, 2, 4):  # c0a, c1a, alpha_a
        dp[:, col] *= factors
    inp["dp"] = np.ascontiguousarray(dp)
    mode = block.block_kernel_mode(base.code, dp)
    assert mode == block.KERNEL_BLOCK  # not uniform
    s_vec = _run_kernel(mode, inp, n, base.code)
    s_ref = _run_kernel(block.KERNEL_SCALAR, inp, n,
                        base.code)  # fmt: skip
    scale = np.max(np.abs(s_ref), axis=(0, 1)) + 1e-30
    assert np.max(np.abs(s_vec - s_ref) / scale) < 1e-9
    # and the rows matter: the same vehicles with the base damper end elsewhere
    uniform = dict(inp, dp=np.ascontiguousarray(np.tile(base.as_array(), (n, 1))))
    s_base = _run_kernel(mode, uniform, n, base.code)
    assert np.max(np.abs(s_base - s_vec) / scale) > 1e-3


def test_block_kernel_mode_falls_back_to_scalar_where_it_must():
    bw = make_damper("bouc_wen")
    assert block.block_kernel_mode(bw.code, bw.as_array()[None]) == block.KERNEL_SCALAR
    ref = ReferenceDamper()
    unload_tan = ReferenceDamper(gamma=5.0e6, beta=2.26e6)  # beta < gamma: tan/atan branch
    rows = np.stack([ref.as_array(), unload_tan.as_array()])
    assert block.block_kernel_mode(ref.code, rows[1:]) == block.KERNEL_SCALAR
    assert block.block_kernel_mode(ref.code, rows) == block.KERNEL_SCALAR  # rows disagree
    uniform = block.KERNEL_BLOCK | block.KERNEL_UNIFORM
    assert block.block_kernel_mode(ref.code, rows[:1]) == uniform
    assert block.block_kernel_mode(ref.code, np.stack([rows[0], rows[0]])) == uniform


@pytest.mark.slow
@pytest.mark.parametrize("spread", [False, True])
def test_adaptive_substeps_batch_equals_each_vehicle_alone(spread):
    # With adaptive substeps the block kernel sorts its vehicles by substep count; a vehicle's
    # result must not depend on its block mates: the batch (multi-threaded, 2 blocks) against
    # each of a sample of vehicles stepped alone. ``spread``: every third vehicle takes 100x
    # the substeps, counts too far apart for the kernel's counting sort (its fallback).
    damper = ReferenceDamper()
    n = PARALLEL_THRESHOLD + 7
    inp = _block_inputs(damper, n, seed=8)
    if spread:
        inp["table"] = np.ascontiguousarray(
            inp["table"] * np.where(np.arange(n) % 3, 1, 100)[:, None]
        )
    mode = block.block_kernel_mode(damper.code, inp["dp"])
    s_all = _run_kernel(mode, inp, n, damper.code, threaded=True)
    for row in (0, 5, 33, 63, 64, n - 1):
        one = {k: (v[row : row + 1] if isinstance(v, np.ndarray) and k != "profiles"
                   else v) for k, v in inp.items()}  # fmt: skip
        one["cmd"] = np.ascontiguousarray(inp["cmd"][:, row : row + 1])
        np.testing.assert_array_equal(_run_kernel(mode, one, 1, damper.code)[:, 0], s_all[:, row])
