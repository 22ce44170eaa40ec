"""Tests of the closed-form Bouc-Wen update against a fine-step numerical integration.

Along a monotone deformation path the Bouc-Wen (n = 2) law is the ODE
``dz/du = A - gamma sign(du) z |z| - beta z^2``; it is integrated here with
``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-10) and compared with ``hysteresis_update``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from capsule_env.dampers import make_damper
from capsule_env.dampers.hysteresis import hysteresis_rate, hysteresis_update, saturation_level

# (A, gamma, beta): Spencer (gamma = beta), beta > gamma, beta < gamma (also beta < 0), and a
# set far from the damper's scale; gamma + beta > 0 and gamma >= 0 throughout.
SHAPES = [
    pytest.param(301.0, 3.63e6, 3.63e6, id="spencer_gamma_eq_beta"),
    pytest.param(301.0, 1.0e6, 6.0e6, id="beta_gt_gamma"),
    pytest.param(301.0, 6.0e6, 1.0e6, id="beta_lt_gamma"),
    pytest.param(301.0, 5.0e6, -2.0e6, id="beta_negative"),
    pytest.param(0.8, 1.5, 2.5, id="unit_scale"),
]
# Starting z0 as a fraction of the saturation level (either sign, including near saturation).
Z0_FRACTIONS = [-0.999999, -0.9, -0.4, 0.0, 0.3, 0.9, 0.999999]
# |du| as a multiple of the yield displacement z_sat / A: tiny to many times.
DU_MULTIPLES = [1e-7, 1e-3, 0.05, 0.5, 1.0, 3.0, 10.0, 60.0]


def ode_solution(z0: float, du: float, a: float, gamma: float, beta: float) -> float:
    """z after the monotone increment du, by fine-step numerical integration of dz/du."""
    s = math.copysign(1.0, du)

    def rhs(_u, z):
        return [a - gamma * s * z[0] * abs(z[0]) - beta * z[0] * z[0]]

    z_sat = math.sqrt(a / (gamma + beta))
    sol = solve_ivp(
        rhs,
        (0.0, du),
        [z0],
        method="DOP853",
        rtol=1e-10,
        atol=1e-13 * z_sat,
        max_step=abs(du) / 20.0,
    )
    assert sol.status == 0, sol.message
    return float(sol.y[0, -1])


@pytest.mark.parametrize("a, gamma, beta", SHAPES)
def test_update_matches_numerical_integration(a, gamma, beta):
    z_sat = math.sqrt(a / (gamma + beta))
    u_yield = z_sat / a
    for frac in Z0_FRACTIONS:
        for mult in DU_MULTIPLES:
            for sign in (1.0, -1.0):
                z0, du = frac * z_sat, sign * mult * u_yield
                expected = ode_solution(z0, du, a, gamma, beta)
                got = hysteresis_update(z0, du, a, gamma, beta)
                err = abs(got - expected) / z_sat
                assert err < 1e-8, (frac, mult, sign, got, expected)


@pytest.mark.parametrize("a, gamma, beta", SHAPES)
def test_composition_of_increments(a, gamma, beta):
    # Exact for monotone paths: two increments of the same sign compose into one.
    z_sat = math.sqrt(a / (gamma + beta))
    u_yield = z_sat / a
    for frac in (-0.95, -0.2, 0.0, 0.6):
        for sign in (1.0, -1.0):
            z0 = frac * z_sat
            d1, d2 = sign * 0.7 * u_yield, sign * 1.9 * u_yield
            two = hysteresis_update(hysteresis_update(z0, d1, a, gamma, beta), d2, a, gamma, beta)
            one = hysteresis_update(z0, d1 + d2, a, gamma, beta)
            assert two == pytest.approx(one, abs=1e-12 * z_sat)


@pytest.mark.parametrize("a, gamma, beta", SHAPES)
def test_small_increment_follows_the_rate(a, gamma, beta):
    # dz ~ (dz/du) du for a tiny du: the derivative of the update is the Bouc-Wen rate law.
    z_sat = math.sqrt(a / (gamma + beta))
    du = 1e-7 * z_sat / a
    for frac in (-0.9, -0.3, 0.0, 0.5, 0.99):
        z0 = frac * z_sat
        for sign in (1.0, -1.0):
            rate = a - gamma * sign * z0 * abs(z0) - beta * z0 * z0  # dz/du, written out
            dz = hysteresis_update(z0, sign * du, a, gamma, beta) - z0
            assert dz == pytest.approx(rate * sign * du, rel=1e-5, abs=1e-18)
            # hysteresis_rate(z, w) is the time-rate form: dz/dt = (dz/du) w.
            w = sign * 0.37
            assert hysteresis_rate(z0, w, a, gamma, beta) == pytest.approx(rate * w, rel=1e-12)


def test_zero_increment_returns_start():
    for z0 in (-0.006, 0.0, 0.004):
        assert hysteresis_update(z0, 0.0, 301.0, 3.63e6, 3.63e6) == z0


@pytest.mark.parametrize("a, gamma, beta", SHAPES)
def test_saturation_approached_never_exceeded_from_below(a, gamma, beta):
    z_sat = math.sqrt(a / (gamma + beta))
    assert saturation_level(a, gamma, beta) == pytest.approx(z_sat, rel=1e-15)
    u_yield = z_sat / a
    tol = 4.0 * np.finfo(float).eps * z_sat  # a few ulp of rounding
    rng = np.random.default_rng(2024)
    for sign in (1.0, -1.0):
        # A long monotone loading from either end of the loop approaches +-z_sat.
        for z0 in (-sign * 0.999 * z_sat, 0.0, sign * 0.5 * z_sat):
            z_far = hysteresis_update(z0, sign * 200.0 * u_yield, a, gamma, beta)
            assert sign * z_far == pytest.approx(z_sat, rel=1e-12)
            assert abs(z_far) <= z_sat + tol
        # Monotone in path length and bounded along the way.
        steps = sign * np.geomspace(1e-4, 50.0, 200) * u_yield
        path = np.array([hysteresis_update(0.0, du, a, gamma, beta) for du in steps])
        assert np.all(np.diff(sign * path) >= -tol)
        assert np.all(np.abs(path) <= z_sat + tol)
    # Random sequences of increments of both signs from inside the loop stay inside it.
    z = 0.0
    for du in rng.choice([-1.0, 1.0], 5000) * 10.0 ** rng.uniform(-6.0, 2.0, 5000) * u_yield:
        z = hysteresis_update(z, du, a, gamma, beta)
        assert abs(z) <= z_sat + tol


def test_spencer_loop_is_the_known_bouc_wen_loop():
    # Cycling the deformation between +-U gives a closed loop with the same z at both visits of
    # +U (rate independence) and antisymmetric branches (z(-U) on unloading = -z(+U)).
    a, g, b = 301.0, 3.63e6, 3.63e6
    u_amp = 5.0 * math.sqrt(a / (g + b)) / a
    z = hysteresis_update(0.0, u_amp, a, g, b)
    first_top = z
    for _ in range(3):
        z = hysteresis_update(z, -2.0 * u_amp, a, g, b)
        bottom = z
        z = hysteresis_update(z, 2.0 * u_amp, a, g, b)
    assert z == pytest.approx(-bottom, rel=1e-12)
    assert first_top == pytest.approx(ode_solution(0.0, u_amp, a, g, b), rel=1e-9)
    assert z == pytest.approx(ode_solution(bottom, 2.0 * u_amp, a, g, b), rel=1e-9)


def test_negative_gamma_loop_is_unbounded_for_the_ode():
    # Independent fact behind the rejection test below: with gamma < 0 < gamma + beta the
    # Bouc-Wen ODE leaves its "saturation" level on unloading (dz/du = A - (beta - gamma) z^2 < 0
    # at z = z_sat), so the loop is not bounded.
    a, g, b = 301.0, -1.0e6, 5.0e6
    z_sat = math.sqrt(a / (g + b))
    assert a - (b - g) * z_sat**2 < 0.0
    z_after = ode_solution(0.99 * z_sat, -0.1 * z_sat / a, a, g, b)
    assert z_after > z_sat


def test_negative_gamma_is_rejected():
    # Bounded Bouc-Wen (n = 2) needs gamma + beta > 0 AND gamma >= 0 (see the test above);
    # gamma + beta > 0 alone lets the models run with a diverging (or silently wrong) z.
    a, g, b = 301.0, -1.0e6, 5.0e6
    with pytest.raises(ValueError, match="gamma"):
        make_damper("bouc_wen", gamma=g, beta=b, a_coef=a)
    with pytest.raises(ValueError, match="gamma"):
        make_damper("reference", gamma=g, beta=b, a_coef=a)
