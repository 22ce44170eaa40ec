"""Tests of capsule_env.vehicles.modes against independent facts.

The 2-DOF plant of docs/model.md, section 2 is written out here by hand (equations of motion, the
closed-form characteristic polynomial det(K - w^2 M) = 0) and the module's matrices, modes and
frequency responses are checked against it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.modes import (
    frequency_response,
    modal_properties,
    natural_frequencies_hz,
    state_space,
)

from conftest import C_S, K_P, K_S, M_B, M_C  # docs/model.md section 2, typed in


def closed_form_frequencies_hz(mc: float, mb: float, ks: float, kp: float) -> np.ndarray:
    """Roots of det(K - w^2 M) = mc mb w^4 - (mc (ks + kp) + mb ks) w^2 + ks kp = 0, in Hz."""
    a = mc * mb
    b = -(mc * (ks + kp) + mb * ks)
    c = ks * kp
    disc = math.sqrt(b * b - 4.0 * a * c)
    w2 = np.array([(-b - disc) / (2.0 * a), (-b + disc) / (2.0 * a)])
    return np.sqrt(w2) / (2.0 * math.pi)


def equations_of_motion(state, force, zg, mc, mb, ks, kp, c):
    """docs/model.md 2 written out: returns d/dt [z_c, z_c', z_b, z_b']."""
    zc, vc, zb, vb = state
    secondary = ks * (zc - zb) + c * (vc - vb) + force
    return np.array([vc, -secondary / mc, vb, (secondary - kp * (zb - zg)) / mb])


# ---------------------------------------------------------------------------- modes
def test_default_parameters_are_model_md_values():
    p = VehicleParams()
    assert (p.car_body_mass_kg, p.bogie_mass_kg) == (M_C, M_B)
    assert (p.secondary_stiffness_n_per_m, p.levitation_stiffness_n_per_m) == (K_S, K_P)
    assert p.passive_damping_n_s_per_m == C_S


def test_natural_frequencies_default_plant():
    f = natural_frequencies_hz()
    assert f.shape == (2,)
    # docs/model.md 2: about 1.30 Hz (body) and 5.42 Hz (bogie).
    assert f[0] == pytest.approx(1.30, abs=0.01)
    assert f[1] == pytest.approx(5.42, abs=0.01)
    # Independent: closed-form roots of the 2-DOF characteristic equation.
    np.testing.assert_allclose(f, closed_form_frequencies_hz(M_C, M_B, K_S, K_P), rtol=1e-10)


@pytest.mark.parametrize(
    "params",
    [
        VehicleParams(),
        VehicleParams(car_body_mass_kg=3000.0, bogie_mass_kg=5000.0),
        VehicleParams(secondary_stiffness_n_per_m=2e6, levitation_stiffness_n_per_m=1e5),
        VehicleParams(
            car_body_mass_kg=1.0,
            bogie_mass_kg=1.0,
            secondary_stiffness_n_per_m=1.0,
            levitation_stiffness_n_per_m=1.0,
        ),
    ],
)
def test_natural_frequencies_match_closed_form(params):
    expected = closed_form_frequencies_hz(
        params.car_body_mass_kg,
        params.bogie_mass_kg,
        params.secondary_stiffness_n_per_m,
        params.levitation_stiffness_n_per_m,
    )
    f = natural_frequencies_hz(params)
    np.testing.assert_allclose(f, expected, rtol=1e-10)
    assert f[0] < f[1]


@pytest.mark.parametrize(
    "params", [VehicleParams(), VehicleParams(car_body_mass_kg=2000.0, bogie_mass_kg=7000.0)]
)
def test_mode_shapes_are_eigenvectors(params):
    modes = modal_properties(params)
    m = np.diag([params.car_body_mass_kg, params.bogie_mass_kg])
    ks, kp = params.secondary_stiffness_n_per_m, params.levitation_stiffness_n_per_m
    k = np.array([[ks, -ks], [-ks, ks + kp]])
    assert modes.mode_shapes.shape == (2, 2)
    for j in range(2):
        phi = modes.mode_shapes[:, j]
        w2 = (2.0 * math.pi * modes.frequencies_hz[j]) ** 2
        np.testing.assert_allclose(k @ phi, w2 * (m @ phi), rtol=1e-9, atol=1e-9 * np.abs(k).max())
        # Documented scaling: largest-magnitude entry is +1.
        assert np.max(np.abs(phi)) == pytest.approx(1.0, rel=1e-12)
        assert phi[np.argmax(np.abs(phi))] == pytest.approx(1.0, rel=1e-12)
    # M-orthogonality of distinct modes.
    phi0, phi1 = modes.mode_shapes.T
    assert abs(phi0 @ m @ phi1) < 1e-9 * math.sqrt((phi0 @ m @ phi0) * (phi1 @ m @ phi1))
    # Physics: the low mode moves the two masses in phase, the high mode in anti-phase.
    assert phi0[0] * phi0[1] > 0.0
    assert phi1[0] * phi1[1] < 0.0


def test_default_body_mode_is_body_dominated_and_bogie_mode_bogie_dominated():
    shapes = modal_properties().mode_shapes
    assert shapes[0, 0] == pytest.approx(1.0)  # body mode: car body moves most
    assert shapes[1, 1] == pytest.approx(1.0)  # bogie mode: bogie moves most
    assert abs(shapes[1, 0]) < 0.5 and abs(shapes[0, 1]) < 0.5


# ------------------------------------------------------------------------ state space
@pytest.mark.parametrize("c", [0.0, C_S, 7.3e4])
def test_state_space_matches_equations_of_motion(c):
    a, b, e = state_space(secondary_damping_n_s_per_m=c)
    assert a.shape == (4, 4) and b.shape == (4, 1) and e.shape == (4, 1)
    rng = np.random.default_rng(42)
    for _ in range(20):
        state = rng.normal(scale=[0.01, 0.1, 0.01, 0.1])
        force, zg = rng.normal(scale=1e3), rng.normal(scale=0.005)
        expected = equations_of_motion(state, force, zg, M_C, M_B, K_S, K_P, c)
        got = a @ state + b[:, 0] * force + e[:, 0] * zg
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_state_space_custom_params_matches_equations_of_motion():
    p = VehicleParams(
        car_body_mass_kg=5100.0,
        bogie_mass_kg=1900.0,
        secondary_stiffness_n_per_m=3.1e5,
        levitation_stiffness_n_per_m=4.0e6,
    )
    a, b, e = state_space(p, secondary_damping_n_s_per_m=2e4)
    # Columns of the matrices are the responses to unit state / input vectors.
    for j in range(4):
        unit = np.zeros(4)
        unit[j] = 1.0
        expected = equations_of_motion(unit, 0.0, 0.0, 5100.0, 1900.0, 3.1e5, 4.0e6, 2e4)
        np.testing.assert_allclose(a[:, j], expected, rtol=1e-14)
    np.testing.assert_allclose(
        b[:, 0], equations_of_motion(np.zeros(4), 1.0, 0.0, 5100.0, 1900.0, 3.1e5, 4.0e6, 2e4)
    )
    np.testing.assert_allclose(
        e[:, 0], equations_of_motion(np.zeros(4), 0.0, 1.0, 5100.0, 1900.0, 3.1e5, 4.0e6, 2e4)
    )


def test_undamped_state_space_eigenvalues_are_the_natural_frequencies():
    a, _, _ = state_space()
    lam = np.linalg.eigvals(a)
    np.testing.assert_allclose(lam.real, 0.0, atol=1e-9)
    freqs = np.sort(np.abs(lam.imag)) / (2.0 * math.pi)
    expected = closed_form_frequencies_hz(M_C, M_B, K_S, K_P)
    np.testing.assert_allclose(freqs, np.repeat(expected, 2), rtol=1e-9)


def test_passive_damped_plant_is_stable():
    a, _, _ = state_space(secondary_damping_n_s_per_m=C_S)
    assert np.all(np.linalg.eigvals(a).real < 0.0)


# ------------------------------------------------------------------ frequency response
def test_frequency_response_static_limits_and_formula():
    # Static limit: the whole plant follows the guideway (unit gain, zero velocity).
    h0 = frequency_response(np.array([1e-9]), secondary_damping_n_s_per_m=C_S)[0]
    np.testing.assert_allclose(h0, [1.0, 0.0, 1.0, 0.0], atol=1e-6)
    # Independent 2x2 dynamic-stiffness solve of docs/model.md 2 at s = j w.
    f = np.array([0.5, 1.3, 2.0, 5.42, 10.0, 30.0])
    h = frequency_response(f, secondary_damping_n_s_per_m=C_S)
    assert h.shape == (f.size, 4)
    for row, fk in zip(h, f, strict=True):
        s = 2j * math.pi * fk
        dyn = np.array(
            [
                [M_C * s * s + C_S * s + K_S, -(C_S * s + K_S)],
                [-(C_S * s + K_S), M_B * s * s + C_S * s + K_S + K_P],
            ]
        )
        zc, zb = np.linalg.solve(dyn, np.array([0.0, K_P]))
        np.testing.assert_allclose(row, [zc, s * zc, zb, s * zb], rtol=1e-10)
    # High-frequency roll-off: the car body is isolated.
    assert abs(h[-1, 0]) < 1e-3


def test_frequency_response_undamped_resonance_peaks():
    f_n = closed_form_frequencies_hz(M_C, M_B, K_S, K_P)
    for fn in f_n:
        near = abs(frequency_response(fn * (1 + 1e-6))[0, 0])
        away = abs(frequency_response(fn * 1.2)[0, 0])
        assert near > 1e3 * away


# ----------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    "name",
    [
        "car_body_mass_kg",
        "bogie_mass_kg",
        "secondary_stiffness_n_per_m",
        "levitation_stiffness_n_per_m",
    ],
)
@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_nonpositive_mass_or_stiffness_raises_naming_parameter(name, bad):
    with pytest.raises(ValueError, match=name):
        VehicleParams(**{name: bad})


@pytest.mark.parametrize("bad", [-1.0, float("nan")])
def test_negative_passive_damping_raises(bad):
    with pytest.raises(ValueError, match="passive_damping_n_s_per_m"):
        VehicleParams(passive_damping_n_s_per_m=bad)
    with pytest.raises(ValueError, match="secondary_damping_n_s_per_m"):
        state_space(secondary_damping_n_s_per_m=bad)


def test_zero_passive_damping_is_allowed():
    assert VehicleParams(passive_damping_n_s_per_m=0.0).passive_damping_n_s_per_m == 0.0
