"""The levitation's checks of issue 43 (item 4) against independent facts: the coil's dynamic
stiffness against a simulation of its circuit, the magnet's filter against a numerical moving
average, the lift-off speed against the sag condition, the quarter car against its matrices."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from test_figures_legible import assert_legible, drawn  # noqa: F401  (drawn: the fixture)

from capsule_env.common.units import kmh_to_m_s
from capsule_env.envelope.levitation import (
    GRAVITY_M_S2,
    EdsCoil,
    eds_coil,
    equilibrium_sag_m,
    levitation_stiffness_n_per_m,
    magnetic_drag_n,
)
from capsule_env.envelope.published import (
    _body_acceleration,
    dynamic_stiffness_n_per_m,
    lift_off_speed_m_s,
    lift_over_drag,
    magnet_length_gain,
    main,
    mode_frequencies_hz,
    quasi_static_stiffness_n_per_m,
    wk_ratio,
)
from capsule_env.vehicles import VehicleParams


def _simulated_force_phasor(r: float, heave_ratio: int) -> tuple[complex, EdsCoil, float, float]:
    """A heave ``z0 + dz sin(W t)`` at ``W = w / heave_ratio`` through the L-R circuit, written
    in its total flux linkage ``psi = L i + a z cos(w t)`` (``psi' = -R i``), integrated by
    SciPy; the force ``a i cos(w t)``'s component at ``W`` fitted over whole heave periods
    after the transient (uniform samples without the end point: the ripple at the harmonics
    of ``W`` is then orthogonal to it), as a phasor per unit ``dz`` (the restoring stiffness
    is minus it)."""
    inductance, k_inf = 1e-3, 1e6
    a = math.sqrt(2 * inductance * k_inf)
    omega = 2 * math.pi * 100.0
    resistance = omega * inductance / r
    heave = omega / heave_ratio
    z0, dz = 0.03, 0.002

    def flux(t):
        return a * (z0 + dz * np.sin(heave * t)) * np.cos(omega * t)

    def rhs(t, y):
        return [-resistance * (y[0] - flux(t)) / inductance]

    transient = 14 * inductance / resistance
    t0 = math.ceil(transient * heave / (2 * math.pi)) * 2 * math.pi / heave
    t = np.linspace(t0, t0 + 6 * 2 * math.pi / heave, 120_000, endpoint=False)
    sol = solve_ivp(rhs, (0.0, t[-1]), [flux(0.0)], method="DOP853", t_eval=t, rtol=1e-11,
                    atol=1e-13, max_step=2 * math.pi / omega / 50)  # fmt: skip
    force = (sol.y[0] - flux(t)) / inductance * a * np.cos(omega * t)
    design = np.column_stack([np.ones_like(t), np.sin(heave * t), np.cos(heave * t)])
    (_, in_phase, quadrature), *_ = np.linalg.lstsq(design, force, rcond=None)
    v = 10.0  # any speed: the model depends on r and tau only
    coil = EdsCoil(k_inf, v / r, inductance / resistance, 1.0, 0.0, omega / v)
    # z = dz sin(W t) = Im(dz e^{jWt}); F = Im(P dz e^{jWt}) = dz (Re P sin + Im P cos)
    return complex(in_phase, quadrature) / dz, coil, v, heave / (2 * math.pi)


@pytest.mark.parametrize("r", [0.72, 3.9])  # lift-off (150 km/h) and cruise (810 km/h)
@pytest.mark.parametrize("heave_ratio", [4, 15])
def test_dynamic_stiffness_matches_the_simulated_circuit(r, heave_ratio):
    phasor, coil, v, f = _simulated_force_phasor(r, heave_ratio)
    exact = complex(dynamic_stiffness_n_per_m(f, v, coil))
    assert abs(-phasor - exact) < 1e-7 * abs(exact)  # 6e-10 measured
    # the quasi-static spring and damper are off by far more (7.6e-4 to 1.5e-2 of |K|)
    quasi = complex(quasi_static_stiffness_n_per_m(f, v, coil))
    assert abs(quasi - exact) > 1e3 * 1e-7 * abs(exact)


def test_quasi_static_is_the_dynamic_stiffness_to_first_order():
    coil = eds_coil()
    for kmh in (150.0, 810.0):
        v = kmh_to_m_s(kmh)
        assert complex(dynamic_stiffness_n_per_m(0.0, v, coil)) == pytest.approx(
            float(levitation_stiffness_n_per_m(v, coil)), rel=1e-13)  # fmt: skip
        for f in (1e-3, 1e-2):
            exact = complex(dynamic_stiffness_n_per_m(f, v, coil))
            quasi = complex(quasi_static_stiffness_n_per_m(f, v, coil))
            # the error is second order in the frequency: it falls 100x for 10x
            err = abs(exact - quasi) / abs(exact)
            assert err < 1e-6 * (f / 1e-2) ** 2 * 10


@pytest.mark.parametrize("length_over_wavelength", [0.1, 0.5, 0.9, 1.5, 2.0])
def test_magnet_gain_is_the_moving_average_of_a_sine(length_over_wavelength):
    wavelength = 4.0
    length = length_over_wavelength * wavelength
    x = np.linspace(0.0, 2 * wavelength, 401)
    offsets = np.linspace(-length / 2, length / 2, 4001)
    averaged = np.trapezoid(np.sin(2 * np.pi * (x[:, None] + offsets) / wavelength), offsets,
                            axis=1) / length  # fmt: skip
    gain = float(magnet_length_gain(wavelength, length))
    assert np.max(np.abs(averaged - gain * np.sin(2 * np.pi * x / wavelength))) < 1e-6
    assert magnet_length_gain(wavelength, 0.0) == 1.0


def test_lift_off_speed_solves_the_sag_condition():
    vehicle = VehicleParams()
    coil = eds_coil(vehicle)
    # the env's calibration: the unladen capsule sags by the 0.1 m travel at 150 km/h
    assert lift_off_speed_m_s(coil, coil.weight_n, 0.1) == pytest.approx(
        kmh_to_m_s(150.0), rel=1e-12
    )
    heavy = (vehicle.car_body_mass_kg * 1.4 + vehicle.bogie_mass_kg) * GRAVITY_M_S2
    v = lift_off_speed_m_s(coil, heavy, 0.1)
    assert heavy / float(levitation_stiffness_n_per_m(v, coil)) == pytest.approx(0.1, rel=1e-12)
    assert v > kmh_to_m_s(180.0)  # +40 %: the sag at 150 km/h is over the travel
    assert heavy / float(levitation_stiffness_n_per_m(kmh_to_m_s(150.0), coil)) > 0.12
    assert lift_off_speed_m_s(coil, 10 * coil.stiffness_limit_n_per_m, 0.1) == math.inf


def test_lift_over_drag_is_weight_over_drag_and_rises_with_speed():
    coil = eds_coil()
    speeds = np.array([41.7, 100.0, 225.0, 333.0])
    ratio = lift_over_drag(speeds, coil)
    assert np.allclose(ratio, coil.weight_n / magnetic_drag_n(speeds, coil), rtol=1e-12)
    assert np.all(np.diff(ratio) > 0)
    assert np.allclose(equilibrium_sag_m(speeds, coil) * levitation_stiffness_n_per_m(speeds, coil),
                       coil.weight_n)  # fmt: skip


def test_quarter_car_response_and_modes_match_its_matrices():
    vehicle = VehicleParams()
    m = np.diag([vehicle.car_body_mass_kg, vehicle.bogie_mass_kg])
    ks, cs, kl = vehicle.secondary_stiffness_n_per_m, vehicle.passive_damping_n_s_per_m, 2.25e6
    stiff = np.array([[ks, -ks], [-ks, ks + kl]])
    damp = np.array([[cs, -cs], [-cs, cs]])
    for f in (0.7, 1.3, 5.0, 20.0):
        s = 2j * np.pi * f
        z = np.linalg.solve(m * s**2 + damp * s + stiff, np.array([0.0, kl]))
        assert complex(_body_acceleration(np.array(f), np.array(kl), vehicle)) == pytest.approx(
            s**2 * z[0], rel=1e-12)  # fmt: skip
    modes = mode_frequencies_hz(kl, vehicle)
    for f in modes:  # the undamped matrix is singular at each mode
        w2 = (2 * np.pi * f) ** 2
        assert abs(np.linalg.det(stiff - w2 * m)) < 1e-9 * np.linalg.norm(stiff) ** 2


def test_wk_ratios_are_one_for_the_envs_model():
    coil = eds_coil()
    assert wk_ratio(kmh_to_m_s(810.0), coil, n=20_000) == 1.0
    # a longer magnet filters more
    short = wk_ratio(kmh_to_m_s(150.0), coil, magnet_length_m=1.35, n=20_000)
    long = wk_ratio(kmh_to_m_s(150.0), coil, magnet_length_m=5.4, n=20_000)
    assert long < short < 1.0


def test_bad_input_is_named():
    coil = eds_coil()
    with pytest.raises(ValueError, match="magnet_length_m"):
        magnet_length_gain(2.0, -1.0)
    with pytest.raises(ValueError, match="weight_n"):
        lift_off_speed_m_s(coil, 0.0, 0.1)
    with pytest.raises(ValueError, match="travel_m"):
        lift_off_speed_m_s(coil, 1.0, -0.1)


def test_main_prints_the_three_tables_and_a_legible_figure(capsys, tmp_path, drawn):  # noqa: F811
    out = tmp_path / "envelope_published.png"
    assert main(["--figure", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.count("| speed (km/h) |") == 2 and "| payload |" in text
    assert_legible(drawn, 1)
