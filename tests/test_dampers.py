"""Tests of the damper models (capsule_env.dampers) against independent facts.

Loops under a steady 1 Hz, +-25 mm sinusoidal stroke (the damper test rig of docs/model.md 6):
energy dissipated per cycle, growth with current, docs/model.md 4.2's peak forces of the reference
damper, and an independent ``solve_ivp`` integration of Spencer's model. The force laws and
state derivatives of docs/model.md 4 are written out here and compared with ``damper_force``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from capsule_env.dampers import (
    DAMPER_NAMES,
    BiExponentialDamper,
    BoucWenDamper,
    LinearDamper,
    ReferenceDamper,
    TanhDamper,
    damper_force,
    make_damper,
)
from capsule_env.dampers.rig import simulate_damper, sinusoidal_stroke

from conftest import I_MAX, SPENCER

FREQ_HZ, AMP_M, CYCLES, SPC = 1.0, 0.025, 3, 2000
CURRENTS = np.arange(7) * 0.25  # 0, 0.25, ..., 1.5 A
MR_NAMES = [n for n in DAMPER_NAMES if n != "passive"]


@pytest.fixture(scope="module")
def stroke():
    return sinusoidal_stroke(FREQ_HZ, AMP_M, CYCLES, samples_per_cycle=SPC)


@pytest.fixture(scope="module")
def loops(stroke):
    """name -> (t, x, v, forces[current, sample]) over the last full cycle of a 3-cycle run."""
    t, x, v = stroke
    last = slice(-SPC - 1, None)
    out = {}
    for name in DAMPER_NAMES:
        damper = make_damper(name)
        forces = np.array(
            [simulate_damper(damper, t, x, v, float(i))["force_n"][last] for i in CURRENTS]
        )
        out[name] = (t[last], x[last], v[last], forces)
    return out


def energy_per_cycle(t, v, force):
    """Integral of F dx = integral of F v dt over the cycle (trapezoid rule), J."""
    return float(np.sum(0.5 * (force[1:] * v[1:] + force[:-1] * v[:-1]) * np.diff(t)))


# ------------------------------------------------------------------------------ loops
def test_stroke_is_the_requested_sine(stroke):
    t, x, v = stroke
    assert t[-1] == pytest.approx(CYCLES / FREQ_HZ)
    assert np.max(np.abs(x)) == pytest.approx(AMP_M, rel=1e-6)
    np.testing.assert_allclose(np.gradient(x, t), v, atol=1e-3 * np.max(np.abs(v)))


@pytest.mark.parametrize("name", DAMPER_NAMES)
def test_energy_dissipated_per_cycle_is_positive(loops, name):
    t, _, v, forces = loops[name]
    for i, force in zip(CURRENTS, forces, strict=True):
        assert np.all(np.isfinite(force))
        assert energy_per_cycle(t, v, force) > 0.0, f"{name} at {i} A"


def test_passive_energy_per_cycle_is_pi_c_omega_x2(loops):
    # A viscous damper F = c v dissipates pi c w X^2 per cycle, whatever the current.
    t, _, v, forces = loops["passive"]
    expected = math.pi * 1.5e4 * (2.0 * math.pi * FREQ_HZ) * AMP_M**2
    for force in forces:
        assert energy_per_cycle(t, v, force) == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize("name", MR_NAMES)
def test_energy_and_peak_force_grow_with_current(loops, name):
    t, _, v, forces = loops[name]
    energy = np.array([energy_per_cycle(t, v, f) for f in forces])
    peak = np.max(np.abs(forces), axis=1)
    assert np.all(np.diff(energy) > 0.0), energy
    assert np.all(np.diff(peak) > 0.0), peak
    # Semi-active range: a substantial increase from 0 A to 1.5 A.
    assert energy[-1] > 2.0 * energy[0]


@pytest.mark.parametrize("name", MR_NAMES)
def test_force_grows_with_current_pointwise(loops, name):
    t, _, v, forces = loops[name]
    v_max = np.max(np.abs(v))
    pos, neg = v > 0.3 * v_max, v < -0.3 * v_max
    assert pos.sum() > SPC // 4 and neg.sum() > SPC // 4
    step = np.diff(forces, axis=0)  # F(i_{k+1}) - F(i_k) at the same phase
    assert np.all(step[:, pos] > 0.0)
    assert np.all(step[:, neg] < 0.0)


def test_loops_have_reached_steady_state(stroke):
    # The last cycle is the steady loop: it repeats the one before within 0.1 % of the peak.
    t, x, v = stroke
    for name in DAMPER_NAMES:
        force = simulate_damper(make_damper(name), t, x, v, 1.5)["force_n"]
        last, before = force[-SPC - 1 :], force[-2 * SPC - 1 : -SPC]
        assert np.max(np.abs(last - before)) < 1e-3 * np.max(np.abs(last)), name


def test_reference_peak_forces_match_model_md(loops):
    # docs/model.md 4.2: about 2.06 kN at 0 A and 7.10 kN at 1.5 A under 1 Hz, +-25 mm.
    forces = loops["reference"][3]
    assert np.max(np.abs(forces[0])) == pytest.approx(2060.0, rel=0.03)
    assert np.max(np.abs(forces[-1])) == pytest.approx(7100.0, rel=0.03)


def spencer_rhs(i, p):
    """docs/model.md 4.2 written out: d/dt [z, y] under the prescribed stroke x = X sin(w t)."""
    w = 2.0 * math.pi * FREQ_HZ
    c0, c1, alpha = p["c0a"] + p["c0b"] * i, p["c1a"] + p["c1b"] * i, p["aa"] + p["ab"] * i

    def rhs(t, s):
        z, y = s
        x, xd = AMP_M * math.sin(w * t), AMP_M * w * math.cos(w * t)
        yd = (alpha * z + c0 * xd + p["k0"] * (x - y)) / (c0 + c1)
        r = xd - yd
        zd = -p["g"] * abs(r) * z * abs(z) - p["b"] * r * z * z + p["A"] * r
        return [zd, yd]

    def force(t, z, y):
        x, xd = AMP_M * np.sin(w * t), AMP_M * w * np.cos(w * t)
        yd = (alpha * z + c0 * xd + p["k0"] * (x - y)) / (c0 + c1)
        return c1 * yd + p["k1"] * x

    return rhs, force


@pytest.mark.parametrize("current", [0.0, 1.5])
def test_reference_loop_matches_independent_integration(stroke, current):
    # Spencer's published values x 5 in force, u = 1.5 V/A * i (docs/model.md 4.2 table).
    t, x, v = stroke
    rhs, force = spencer_rhs(current, SPENCER)
    sol = solve_ivp(
        rhs,
        (0.0, t[-1]),
        [0.0, 0.0],
        method="LSODA",
        t_eval=t,
        rtol=1e-9,
        atol=1e-13,
        max_step=5e-4,
    )
    assert sol.status == 0
    expected = force(t, sol.y[0], sol.y[1])
    got = simulate_damper(ReferenceDamper(), t, x, v, current)["force_n"]
    rms = np.sqrt(np.mean(expected**2))
    assert np.sqrt(np.mean((got - expected) ** 2)) < 2e-3 * rms


# -------------------------------------------------------------- damper_force interface
def test_damper_force_shapes():
    d = ReferenceDamper()
    f, ds = damper_force(d, 0.01, 0.1, 0.5)
    assert f.shape == () and ds.shape == (2,)
    f, ds = damper_force(d, np.zeros(5), np.linspace(-1, 1, 5), 1.0)
    assert f.shape == (5,) and ds.shape == (5, 2)
    x = np.linspace(-0.02, 0.02, 3)[:, None]
    v = np.linspace(-0.5, 0.5, 4)[None, :]
    f, ds = damper_force(d, x, v, np.full((3, 4), 0.7), state=np.array([0.001, 0.002]))
    assert f.shape == (3, 4) and ds.shape == (3, 4, 2)
    # Element-wise equal to scalar calls (broadcasting, state broadcast to every element).
    for a in range(3):
        for b in range(4):
            fs, dss = damper_force(d, x[a, 0], v[0, b], 0.7, state=np.array([0.001, 0.002]))
            assert f[a, b] == fs
            np.testing.assert_array_equal(ds[a, b], dss)


def test_bouc_wen_force_and_state_derivative_formula():
    d = BoucWenDamper()
    rng = np.random.default_rng(3)
    n = 200
    x = rng.uniform(-0.05, 0.05, n)
    v = rng.uniform(-2.0, 2.0, n)
    i = rng.uniform(0.0, 1.5, n)
    z = rng.uniform(-0.0064, 0.0064, n)
    state = np.stack([z, np.zeros(n)], axis=-1)
    f, ds = damper_force(d, x, v, i, state)
    # docs/model.md 4.3 with n = 2.
    alpha = d.alpha_a + d.alpha_b * i
    c0 = d.c0a + d.c0b * i
    expected_f = c0 * v + d.k0 * (x - d.x0) + alpha * z
    expected_zd = -d.gamma * np.abs(v) * z * np.abs(z) - d.beta * v * z**2 + d.a_coef * v
    np.testing.assert_allclose(f, expected_f, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(ds[:, 0], expected_zd, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(ds[:, 1], 0.0)


def test_reference_force_and_state_derivative_formula():
    d = ReferenceDamper(x0=0.003)
    rng = np.random.default_rng(4)
    n = 200
    x, v = rng.uniform(-0.05, 0.05, n), rng.uniform(-2.0, 2.0, n)
    i = rng.uniform(0.0, 1.5, n)
    z, y = rng.uniform(-0.0064, 0.0064, n), rng.uniform(-0.05, 0.05, n)
    f, ds = damper_force(d, x, v, i, np.stack([z, y], axis=-1))
    # docs/model.md 4.2 with n = 2.
    c0, c1 = d.c0a + d.c0b * i, d.c1a + d.c1b * i
    alpha = d.alpha_a + d.alpha_b * i
    yd = (alpha * z + c0 * v + d.k0 * (x - y)) / (c0 + c1)
    r = v - yd
    zd = -d.gamma * np.abs(r) * z * np.abs(z) - d.beta * r * z**2 + d.a_coef * r
    np.testing.assert_allclose(f, c1 * yd + d.k1 * (x - d.x0), rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(ds[:, 1], yd, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(ds[:, 0], zd, rtol=1e-9, atol=1e-12)


def _upper_weight(x: np.ndarray, width: float) -> np.ndarray:
    """The documented branch blend: 1 above +width, 0 below -width, a smoothstep between."""
    s = np.clip((1.0 + x / width) / 2.0, 0.0, 1.0)
    return 3.0 * s**2 - 2.0 * s**3


def test_algebraic_models_force_formula():
    rng = np.random.default_rng(5)
    n = 200
    x, v = rng.uniform(-0.05, 0.05, n), rng.uniform(-2.0, 2.0, n)
    i = rng.uniform(0.0, 1.5, n)
    x[:3], v[:3] = 0.0, [0.0, 1e-9, -1e-9]  # edge cases: x = 0 is half-way between the branches
    x[3:9] = [1e-4, -1e-4, 3e-5, -7e-5, 2e-4, -2e-4]  # inside, at and outside the 0.1 mm blend
    # Passive: F = c v.
    f, ds = damper_force(LinearDamper(2.2e4), x, v, i)
    np.testing.assert_allclose(f, 2.2e4 * v, rtol=1e-14)
    np.testing.assert_array_equal(ds, 0.0)
    # tanh, docs/model.md 4.4 with c, k, alpha, f0 linear in i; sign(x) blended over 0.1 mm.
    d = TanhDamper(f0_a=30.0, f0_b=-12.0, k_b=400.0)
    sx = 2.0 * _upper_weight(x, 1e-4) - 1.0
    assert np.all(sx[np.abs(x) >= 1e-4] == np.sign(x[np.abs(x) >= 1e-4]))
    expected = (
        (d.c_a + d.c_b * i) * v
        + (d.k_a + d.k_b * i) * x
        + (d.alpha_a + d.alpha_b * i) * np.tanh(d.beta * v + d.delta * sx)
        + d.f0_a
        + d.f0_b * i
    )
    f, ds = damper_force(d, x, v, i)
    np.testing.assert_allclose(f, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(ds, 0.0)
    # Bi-exponential, docs/model.md 4.5: upper set for x >= 0.1 mm, lower set for x <= -0.1 mm,
    # every parameter blended in between.
    d = BiExponentialDamper(upper_d=30.0, lower_d=45.0, lower_a0=900.0)
    w = _upper_weight(x, 1e-4)

    def pick(name):
        lower = getattr(d, "lower_" + name)
        return lower + w * (getattr(d, "upper_" + name) - lower)

    s_d = np.sign(v) * (1.0 - np.exp(-pick("d") * np.abs(v)))
    expected = (
        (pick("a0") + pick("a1") * i) * s_d
        + (pick("b0") + pick("b1") * i) * v
        + pick("c0")
        + pick("c1") * i
    )
    f, ds = damper_force(d, x, v, i)
    np.testing.assert_allclose(f, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(ds, 0.0)
    # Continuity at x = 0: the literal sign-of-stroke switch would jump by about 700 N.
    default = BiExponentialDamper()
    f_pm, _ = damper_force(default, [1e-9, -1e-9], 0.0, 0.0)
    assert abs(f_pm[0] - f_pm[1]) < 0.1


def test_simulate_damper_state_is_consistent_with_damper_force(stroke):
    # The force returned at each sample is the force law evaluated at the returned state.
    t, x, v = stroke
    for name in ("reference", "bouc_wen"):
        d = make_damper(name)
        r = simulate_damper(d, t, x, v, 0.9)
        state = np.stack([r["hysteretic_z_m"], r["internal_displacement_m"]], axis=-1)
        f, _ = damper_force(d, x, v, r["coil_current_a"], state)
        np.testing.assert_allclose(r["force_n"], f, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(r["coil_current_a"], 0.9)


def test_make_damper_builds_every_model_and_applies_overrides():
    for name in DAMPER_NAMES:
        d = make_damper(name)
        assert d.name == name
    d = make_damper("reference", c0a=2.0e4, gamma=1.0e6)
    assert isinstance(d, ReferenceDamper) and d.c0a == 2.0e4 and d.gamma == 1.0e6
    assert d.c1a == ReferenceDamper().c1a
    assert make_damper("passive", damping_n_s_per_m=1e3) == LinearDamper(1e3)


def test_reference_defaults_are_model_md_values():
    d = ReferenceDamper()
    # docs/model.md 4.2 table (Spencer x 5 in force, u = 1.5 V/A * i).
    p = SPENCER
    assert (d.c0a, d.c0b, d.c1a, d.c1b) == (p["c0a"], p["c0b"], p["c1a"], p["c1b"])
    assert (d.alpha_a, d.alpha_b, d.k0, d.k1, d.x0) == (p["aa"], p["ab"], p["k0"], p["k1"], p["x0"])
    assert (d.gamma, d.beta, d.a_coef, d.max_current_a) == (p["g"], p["b"], p["A"], I_MAX)
    assert d.coil_time_constant_s == pytest.approx(1.0 / p["eta"])


# ------------------------------------------------------------------------ bad input
def test_unknown_model_raises():
    with pytest.raises(ValueError, match="damper model"):
        make_damper("foo")


@pytest.mark.parametrize("name", DAMPER_NAMES)
def test_unknown_override_raises_naming_key(name):
    with pytest.raises(ValueError, match="not_a_parameter"):
        make_damper(name, not_a_parameter=1.0)


@pytest.mark.parametrize(
    "name, key",
    [
        ("passive", "damping_n_s_per_m"),
        ("reference", "c0a"),
        ("reference", "alpha_b"),
        ("reference", "gamma"),
        ("bouc_wen", "k0"),
        ("tanh", "delta"),
        ("bi_exponential", "lower_c1"),
        ("reference", "coil_time_constant_s"),
    ],
)
def test_nan_parameter_raises_naming_it(name, key):
    with pytest.raises(ValueError, match=key):
        make_damper(name, **{key: float("nan")})


@pytest.mark.parametrize(
    "name, overrides",
    [
        ("passive", {"damping_n_s_per_m": -1.0}),
        ("reference", {"c0a": 0.0}),
        ("reference", {"gamma": -4e6}),
        ("bouc_wen", {"a_coef": 0.0}),
        ("tanh", {"beta": -1.0}),
        ("bi_exponential", {"upper_d": 0.0}),
        ("reference", {"max_current_a": 0.0}),
    ],
)
def test_out_of_range_parameter_raises(name, overrides):
    with pytest.raises(ValueError, match=next(iter(overrides))):
        make_damper(name, **overrides)


@pytest.mark.parametrize("name", MR_NAMES)
@pytest.mark.parametrize("bad", [-0.01, 1.51, float("nan")])
def test_current_out_of_range_raises(name, bad):
    d = make_damper(name)
    with pytest.raises(ValueError, match="current_a"):
        damper_force(d, 0.0, 0.1, bad)
    with pytest.raises(ValueError, match="current_a"):
        damper_force(d, np.zeros(3), np.ones(3), np.array([0.0, 1.0, bad]))
    t, x, v = sinusoidal_stroke(1.0, 0.025, 1, samples_per_cycle=50)
    with pytest.raises(ValueError, match="current_a"):
        simulate_damper(d, t, x, v, bad)
    per_sample = np.full(t.shape, 0.5)
    per_sample[7] = bad
    with pytest.raises(ValueError, match="current_a"):
        simulate_damper(d, t, x, v, per_sample)


def test_current_at_limits_is_accepted():
    # Accepted, and the force is docs/model.md 4.2's at rest (z = y = x = 0):
    # F = c1 dy/dt = c1 c0 v / (c0 + c1).
    d, p, v = ReferenceDamper(), SPENCER, 0.1
    for i in (0.0, I_MAX):
        f, _ = damper_force(d, 0.0, v, i)
        c0, c1 = p["c0a"] + p["c0b"] * i, p["c1a"] + p["c1b"] * i
        assert f == pytest.approx(c1 * c0 * v / (c0 + c1), rel=1e-12), i
