"""The half-car capsule (issue 42, items 1-2): its declaration against independent facts.

- Equal halves at a dynamic index of 1: each end of the body moves on its own bogie exactly as
  the 1/4-car does on its guideway, and not at all on the other bogie's (the kinetic energy
  ``m z'^2 / 2 + m a b theta'^2 / 2`` is ``m_f z_f'^2 / 2 + m_r z_r'^2 / 2`` in the end points'
  displacements, with ``m_f = m b / (a + b)``, ``m_r = m a / (a + b)``): transfer functions.
- Natural frequencies against the closed form: a symmetric vehicle splits into a bounce and a
  pitch 2-mass system (body mass ``m / 2`` and ``I / (2 a^2)`` on one corner); an asymmetric
  one against Newton's 4x4 mass and stiffness matrices written out here.
- An independent stiff solve: Newton's equations written out here, integrated by Radau, against
  the package's absolute model integrated exactly (a matrix exponential) on a sine guideway
  with the wheelbase delay.
- The parameters' validation; the registry.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eigh, expm

from capsule_env.vehicles import (
    BUILT_IN,
    VehicleParams,
    absolute_model,
    mechanical_matrices,
    model_named,
    model_of_params,
    names,
    relative_model,
)
from capsule_env.vehicles.half_car import MODEL as HALF_CAR
from capsule_env.vehicles.half_car import HalfCarParams
from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR

from conftest import C_S, K_P, K_S, M_B, M_C, SPEED  # docs/model.md 2, typed in

FREQS_HZ = np.logspace(-1.0, 2.0, 37)


def _corners(side: str, q: VehicleParams) -> dict[str, float]:
    return {
        f"{side}_bogie_mass_kg": q.bogie_mass_kg,
        f"{side}_secondary_stiffness_n_per_m": q.secondary_stiffness_n_per_m,
        f"{side}_levitation_stiffness_n_per_m": q.levitation_stiffness_n_per_m,
        f"{side}_passive_damping_n_s_per_m": q.passive_damping_n_s_per_m,
        f"{side}_levitation_damping_n_s_per_m": q.levitation_damping_n_s_per_m,
    }


def _response(model, params, slot_damping, freqs_hz, output_rows: np.ndarray) -> np.ndarray:
    """``(len(freqs), outputs, contacts)``: ``rows (j w I - A)^-1 (E + j w E_rate)``."""
    lin = absolute_model(model, params, slot_damping=slot_damping)
    out = []
    for f in freqs_hz:
        s = 2j * np.pi * f
        x = np.linalg.solve(s * np.eye(lin.a.shape[0]) - lin.a, lin.e + s * lin.e_rate)
        out.append(output_rows @ x)
    return np.array(out)


def _end_rows(a_m: float, b_m: float) -> np.ndarray:
    """The body's points above the bogies, ``z_c + a theta`` and ``z_c - b theta``, over the
    state ``[z_c, z_c', theta, theta', ...]`` (written out, not the package's points)."""
    rows = np.zeros((2, 8))
    rows[:, 0] = 1.0
    rows[0, 2], rows[1, 2] = a_m, -b_m
    return rows


# ------------------------------------------------------------------- equal halves, index 1
@pytest.mark.parametrize(
    "a_m, b_m, rear_k_s",
    [(8.5, 8.5, K_S), (11.0, 7.0, 3.1e5)],  # the case; then unequal arms and corners
)
def test_at_dynamic_index_one_each_end_is_a_quarter_car(a_m, b_m, rear_k_s):
    mass = 2.0 * M_C
    front = VehicleParams(car_body_mass_kg=mass * b_m / (a_m + b_m),
                          levitation_damping_n_s_per_m=-700.0)  # fmt: skip
    rear = VehicleParams(car_body_mass_kg=mass * a_m / (a_m + b_m), secondary_stiffness_n_per_m=rear_k_s,
                         passive_damping_n_s_per_m=1.1e4, levitation_damping_n_s_per_m=400.0)  # fmt: skip
    half = HalfCarParams(car_body_mass_kg=mass, car_body_pitch_inertia_kg_m2=mass * a_m * b_m,
                         front_bogie_position_m=a_m, rear_bogie_position_m=-b_m,
                         **_corners("front", front), **_corners("rear", rear))  # fmt: skip
    assert half.dynamic_index == pytest.approx(1.0, rel=1e-15)
    slots = [front.passive_damping_n_s_per_m, rear.passive_damping_n_s_per_m]
    for damping in ([0.0, 0.0], slots):  # the MR-damped plant's open slots; the passive one
        h = _response(HALF_CAR, half, damping, FREQS_HZ, _end_rows(a_m, b_m))
        for i, quarter in enumerate((front, rear)):
            q = _response(QUARTER_CAR, quarter, damping[i], FREQS_HZ, np.eye(4)[:1])[:, 0, 0]
            # LAPACK solves of an 8x8 and a 4x4 system: 1e-9 relative, and 1e-14 m per m of
            # guideway for their rounding near 100 Hz, where the response is down to 1e-6
            np.testing.assert_allclose(h[:, i, i], q, rtol=1e-9, atol=1e-14)
            assert np.all(np.abs(h[:, 1 - i, i]) <= 1e-9 * np.abs(q) + 1e-14)  # no cross transfer


def test_the_default_is_the_papers_quarter_car_as_the_halves():
    p = HalfCarParams()
    assert p.car_body_mass_kg == 2 * M_C
    assert (p.front_lever_arm_m, p.rear_lever_arm_m, p.bogie_spacing_m) == (10.0, 10.0, 20.0)
    assert p.car_body_pitch_inertia_kg_m2 == 2 * M_C * 30.0**2 / 12  # a uniform 30 m body
    assert p.dynamic_index == 0.75
    assert p == HalfCarParams.from_quarter_car()
    for side in ("front", "rear"):
        assert p.quarter_params(side) == VehicleParams(M_C, M_B, K_S, K_P, C_S, 0.0)
    # unequal arms: each bogie carries its static share of the body, m b / (a + b) in front
    p = HalfCarParams(front_bogie_position_m=6.0, rear_bogie_position_m=-14.0)
    assert p.quarter_params("front").car_body_mass_kg == pytest.approx(12000.0 * 14.0 / 20.0)
    assert p.quarter_params("rear").car_body_mass_kg == pytest.approx(12000.0 * 6.0 / 20.0)
    k = p.with_levitation(1.9e6, -800.0)
    assert (k.front_levitation_stiffness_n_per_m, k.rear_levitation_damping_n_s_per_m) == (
        1.9e6,
        -800.0,
    )


def test_the_rear_contact_meets_the_front_profile_a_wheelbase_later():
    p = HalfCarParams()
    offsets = HALF_CAR.contact_offsets_m(p)
    assert list(offsets) == [10.0, -10.0]  # +a ahead, -b behind the centre of mass
    delay = (offsets[0] - offsets[1]) / SPEED
    assert delay == p.wheelbase_delay_s(SPEED) == pytest.approx(0.0889, abs=5e-5)  # 810 km/h
    # the points: z_c + x theta, nose up positive
    values = HALF_CAR.values(p)
    assert list(HALF_CAR.point_row("front_car_body", values)) == [1.0, 10.0, 0.0, 0.0]
    assert list(HALF_CAR.point_row("rear_car_body", values)) == [1.0, -10.0, 0.0, 0.0]


# ------------------------------------------------------------------- natural frequencies
def _two_mass_hz(mc: float, mb: float, ks: float, kp: float) -> np.ndarray:
    """Roots of mc mb w^4 - (mc (ks + kp) + mb ks) w^2 + ks kp = 0 (Hz)."""
    b = mc * (ks + kp) + mb * ks
    disc = np.sqrt(b * b - 4.0 * mc * mb * ks * kp)
    return np.sqrt(np.array([b - disc, b + disc]) / (2.0 * mc * mb)) / (2.0 * np.pi)


def _package_hz(params: HalfCarParams) -> np.ndarray:
    m, k, _ = mechanical_matrices(HALF_CAR, params)
    return np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(m, k)).real)) / (2.0 * np.pi)


def test_natural_frequencies_of_a_symmetric_vehicle_split_into_bounce_and_pitch():
    for index in (1.0, 0.75, 0.4, 1.6):
        p = HalfCarParams.from_quarter_car(front_bogie_position_m=9.0, rear_bogie_position_m=-9.0,
                                           dynamic_index=index)  # fmt: skip
        bounce = _two_mass_hz(p.car_body_mass_kg / 2, M_B, K_S, K_P)
        pitch = _two_mass_hz(p.car_body_pitch_inertia_kg_m2 / (2 * 9.0**2), M_B, K_S, K_P)
        # eigenvalues by LAPACK (last bits differ across CPUs): 1e-9 is far below any physics
        np.testing.assert_allclose(_package_hz(p), np.sort(np.r_[bounce, pitch]), rtol=1e-9)
    # index 1: bounce and pitch are both the 1/4-car's modes (docs/model.md 2: 1.30, 5.42 Hz)
    np.testing.assert_allclose(bounce if index == 1 else _two_mass_hz(M_C, M_B, K_S, K_P),
                               [1.2998, 5.4196], atol=1e-4)  # fmt: skip
    # the defaults (docs/model.md 2.1): bounce 1.300 Hz, pitch 1.497 Hz, bogies 5.420, 5.433 Hz
    np.testing.assert_allclose(_package_hz(HalfCarParams()), [1.300, 1.497, 5.420, 5.433],
                               atol=6e-4)  # fmt: skip


def _newton_matrices(p: HalfCarParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M, K, C over ``[z_c, theta, z_bf, z_br]`` from the equations of motion (module doc of
    half_car, docs/model.md 2.1), written out, with the passive dampers in the slots."""
    a, b = p.front_bogie_position_m, -p.rear_bogie_position_m
    ksf, ksr = p.front_secondary_stiffness_n_per_m, p.rear_secondary_stiffness_n_per_m
    kpf, kpr = p.front_levitation_stiffness_n_per_m, p.rear_levitation_stiffness_n_per_m
    csf, csr = p.front_passive_damping_n_s_per_m, p.rear_passive_damping_n_s_per_m
    cpf, cpr = p.front_levitation_damping_n_s_per_m, p.rear_levitation_damping_n_s_per_m
    m = np.diag([p.car_body_mass_kg, p.car_body_pitch_inertia_kg_m2, p.front_bogie_mass_kg,
                 p.rear_bogie_mass_kg])  # fmt: skip

    def body_bogie(kf, kr, gf, gr):
        return np.array([[kf + kr, a * kf - b * kr, -kf, -kr],
                         [a * kf - b * kr, a * a * kf + b * b * kr, -a * kf, b * kr],
                         [-kf, -a * kf, kf + gf, 0.0],
                         [-kr, b * kr, 0.0, kr + gr]])  # fmt: skip

    return m, body_bogie(ksf, ksr, kpf, kpr), body_bogie(csf, csr, cpf, cpr)


ASYMMETRIC = HalfCarParams(
    car_body_mass_kg=11000.0, car_body_pitch_inertia_kg_m2=7.9e5, front_bogie_position_m=11.0,
    rear_bogie_position_m=-8.0, front_bogie_mass_kg=2600.0, rear_bogie_mass_kg=2200.0,
    front_secondary_stiffness_n_per_m=5.3e5, rear_secondary_stiffness_n_per_m=4.4e5,
    front_levitation_stiffness_n_per_m=2.1e6, rear_levitation_stiffness_n_per_m=2.4e6,
    front_passive_damping_n_s_per_m=1.6e4, rear_passive_damping_n_s_per_m=1.2e4,
    front_levitation_damping_n_s_per_m=-700.0, rear_levitation_damping_n_s_per_m=500.0,
)  # fmt: skip


def test_natural_frequencies_of_an_asymmetric_vehicle_from_newtons_matrices():
    m_hand, k_hand, _ = _newton_matrices(ASYMMETRIC)
    m, k, _ = mechanical_matrices(HALF_CAR, ASYMMETRIC)
    assert np.array_equal(m, m_hand)
    np.testing.assert_allclose(k, k_hand, rtol=1e-13, atol=0.0)  # sums of products, reordered
    w2 = eigh(k_hand, m_hand, eigvals_only=True)  # the symmetric-definite eigenproblem
    np.testing.assert_allclose(_package_hz(ASYMMETRIC), np.sqrt(w2) / (2 * np.pi), rtol=1e-9)


# ------------------------------------------------------------------- independent stiff solve
def test_the_absolute_model_integrated_exactly_matches_radau_on_newtons_equations():
    """A 5 mm, 1.7 Hz sine under the front bogie, the same a wheelbase later under the rear, at
    810 km/h; passive dampers in both slots, levitation damping of both signs."""
    p, amp_m, w = ASYMMETRIC, 5e-3, 2 * np.pi * 1.7
    tau = (p.front_bogie_position_m - p.rear_bogie_position_m) / SPEED  # (a + b) / v by hand
    m, k, c = _newton_matrices(p)
    kpf, kpr = p.front_levitation_stiffness_n_per_m, p.rear_levitation_stiffness_n_per_m
    cpf, cpr = p.front_levitation_damping_n_s_per_m, p.rear_levitation_damping_n_s_per_m

    def rhs(t, y):
        q, v = y[:4], y[4:]
        zg = amp_m * np.sin(w * np.array([t, t - tau]))
        zg_rate = amp_m * w * np.cos(w * np.array([t, t - tau]))
        lift = [kpf * zg[0] + cpf * zg_rate[0], kpr * zg[1] + cpr * zg_rate[1]]
        ground = np.array([0.0, 0.0, *lift])  # the levitation's guideway terms on the bogies
        return np.r_[v, np.linalg.solve(m, ground - k @ q - c @ v)]

    y0 = np.array([1e-3, -2e-4, -5e-4, 3e-4, 0.01, 0.002, -0.02, 0.01])  # [q, q']
    t = np.linspace(0.0, 3.0, 301)
    sol = solve_ivp(rhs, (0.0, 3.0), y0, method="Radau", t_eval=t, rtol=1e-11, atol=1e-14)
    assert sol.status == 0, sol.message
    # the package: state [z_c, z_c', theta, theta', ...]; the guideway from a sine generator
    # s = [sin wt, cos wt] appended to the state, the delay from the contacts' offsets
    lin = absolute_model(HALF_CAR, p, slot_damping=[p.front_passive_damping_n_s_per_m,
                                                    p.rear_passive_damping_n_s_per_m])  # fmt: skip
    offsets = HALF_CAR.contact_offsets_m(p)
    phase = w * (offsets[0] - offsets) / SPEED  # 0 in front, w tau behind
    g = amp_m * np.column_stack([np.cos(phase), -np.sin(phase)])  # z_g = g s
    omega = np.array([[0.0, w], [-w, 0.0]])  # s' = omega s
    aug = np.block([[lin.a, lin.e @ g + lin.e_rate @ g @ omega], [np.zeros((2, 8)), omega]])
    x0 = np.r_[np.ravel(np.column_stack([y0[:4], y0[4:]])), 0.0, 1.0]
    step = expm(aug * (t[1] - t[0]))
    x, exact = x0, []
    for _ in t:
        exact.append(x[:8])
        x = step @ x
    exact = np.array(exact).T
    expected = np.vstack([sol.y[[0, 4]], sol.y[[1, 5]], sol.y[[2, 6]], sol.y[[3, 7]]])
    # Radau at rtol 1e-11 over 3 s (16 periods of the 5.4 Hz bogie modes) and 300 products by
    # one matrix exponential: they agree to ~2e-12 of each signal's peak here; 1e-9 leaves room
    # for other CPUs and SciPy versions, far below a wrong term (a sign, a delay: order 1)
    for row in range(8):
        peak = np.max(np.abs(expected[row]))
        np.testing.assert_allclose(exact[row], expected[row], rtol=0.0, atol=1e-9 * peak)


def test_the_relative_form_is_the_absolute_one_in_deflections():
    """``d = D q - G z_g`` (both secondary strokes, both levitation gaps): for any state, both
    forms give the same accelerations, and the deflections' rates ``D q' - G z_g'``."""
    p, rng = ASYMMETRIC, np.random.default_rng(7)
    a, b = 11.0, 8.0
    d = np.array([[1, a, -1, 0], [1, -b, 0, -1], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)
    g = np.array([[0, 0], [0, 0], [1, 0], [0, 1]], dtype=float)
    ab, rel = absolute_model(HALF_CAR, p), relative_model(HALF_CAR, p)
    for _ in range(5):
        q, v = rng.normal(size=4) * [1e-2, 1e-3, 1e-2, 1e-2], rng.normal(size=4) * 0.1
        zg, zg_rate = rng.normal(size=2) * 1e-2, rng.normal(size=2) * 0.1
        force = rng.normal(size=2) * 3e3
        x_abs = np.ravel(np.column_stack([q, v]))
        x_rel = np.ravel(np.column_stack([d @ q - g @ zg, v]))
        dx_abs = ab.a @ x_abs + ab.b @ force + ab.e @ zg + ab.e_rate @ zg_rate
        dx_rel = rel.a @ x_rel + rel.b @ force + rel.e_rate @ zg_rate
        np.testing.assert_allclose(dx_rel[1::2], dx_abs[1::2], rtol=1e-9, atol=1e-9)  # BLAS order
        np.testing.assert_allclose(dx_rel[0::2], d @ v - g @ zg_rate, rtol=1e-12, atol=1e-15)


# ------------------------------------------------------------------- validation, registry
@pytest.mark.parametrize(
    "field, value, accepted",
    [
        ("car_body_mass_kg", 0.0, "[1.0, 1000000.0]"),
        ("car_body_pitch_inertia_kg_m2", -1.0, "[1.0, 1000000000.0]"),
        ("front_bogie_position_m", -3.0, "[0.01, 100.0]"),  # the front bogie is ahead
        ("rear_bogie_position_m", 3.0, "[-100.0, -0.01]"),  # the rear one behind
        ("rear_bogie_mass_kg", 2e6, "[1.0, 1000000.0]"),
        ("front_secondary_stiffness_n_per_m", 0.5, "[1.0, 10000000000.0]"),
        ("rear_levitation_stiffness_n_per_m", 1e11, "[1.0, 10000000000.0]"),
        ("front_passive_damping_n_s_per_m", -1.0, "[0.0, 1000000000.0]"),
        ("rear_levitation_damping_n_s_per_m", 3e4, "[-20000.0, 20000.0]"),
    ],
)
def test_a_value_out_of_range_is_refused_by_name(field, value, accepted):
    with pytest.raises(ValueError, match=re.escape(f"{field} must be in {accepted}, got {value}")):
        HalfCarParams(**{field: value})


def test_other_bad_input_is_refused_by_name():
    with pytest.raises(ValueError, match="car_body_mass_kg must be a finite number"):
        HalfCarParams(car_body_mass_kg=float("nan"))
    with pytest.raises(TypeError, match="car_body_mass_kg must be a real number"):
        HalfCarParams(car_body_mass_kg="12000")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"dynamic_index must be in \[0.05, 20.0\]"):
        HalfCarParams.from_quarter_car(dynamic_index=0.0)
    with pytest.raises(ValueError, match="unknown bogie 'middle'; accepted values: front, rear"):
        HalfCarParams().quarter_params("middle")
    with pytest.raises(ValueError, match="speed_m_s must be > 0"):
        HalfCarParams().wheelbase_delay_s(0.0)
    with pytest.raises(ValueError, match="rear_bogie_position_m must be in"):
        dataclasses.replace(HalfCarParams(), rear_bogie_position_m=0.0)


def test_the_half_car_is_a_built_in_vehicle():
    assert "half_car" in BUILT_IN and "half_car" in names()
    assert model_named("half_car") is HALF_CAR
    assert model_of_params(HalfCarParams()) is HALF_CAR
    assert [e.name for e in HALF_CAR.dampers] == ["front_secondary_damper", "rear_secondary_damper"]
    assert HALF_CAR.comfort_points == ("front_car_body", "car_body", "rear_car_body")
