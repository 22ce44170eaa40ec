"""The vehicle as data (issue 41): a declaration, its one linear model, the registry.

Independent facts: the 1/4-car's matrices written out by hand from its equations of motion
(docs/model.md 2); the two-mass system's closed-form natural frequencies; for a 3-DOF toy
declared here, Newton's equations written out by hand, and the relative form's consistency with
the absolute one under the change of coordinates (a kinematic identity, not the code's output);
a clipped-LQR gain for the toy that stabilises it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from capsule_env.agents.controllers.lqr import lqr_gain

from capsule_env.vehicles import (
    DAMPER,
    DASHPOT,
    SPRING,
    Contact,
    Coordinate,
    Element,
    Point,
    VehicleModel,
    VehicleParams,
    absolute_model,
    mechanical_matrices,
    model_named,
    model_of_params,
    names,
    register,
    relative_model,
    unregister,
)
from capsule_env.vehicles.modes import natural_frequencies_hz, state_space
from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR

P = VehicleParams(car_body_mass_kg=5500.0, levitation_damping_n_s_per_m=-700.0)
MC, MB, KS, KP, CP = 5500.0, 2400.0, 4.95e5, 2.25e6, -700.0


def test_quarter_car_absolute_form_is_the_equations_of_motion():
    lin = absolute_model(QUARTER_CAR, P, slot_damping=1.2e4)
    c = 1.2e4
    a = np.array([[0, 1, 0, 0],
                  [-KS / MC, -c / MC, KS / MC, c / MC],
                  [0, 0, 0, 1],
                  [KS / MB, c / MB, -(KS + KP) / MB, -(c + CP) / MB]])  # fmt: skip
    assert np.array_equal(lin.a, a)
    assert np.array_equal(lin.b[:, 0], [0, -1 / MC, 0, 1 / MB])
    assert np.array_equal(lin.e[:, 0], [0, 0, 0, KP / MB])
    assert np.array_equal(lin.e_rate[:, 0], [0, 0, 0, CP / MB])
    assert np.array_equal(lin.c_acc[0], a[1]) and lin.d_acc[0, 0] == -1 / MC
    assert np.array_equal(lin.stroke[0], [1, 0, -1, 0])
    assert np.array_equal(state_space(P, c)[0], a)


def test_quarter_car_relative_form_is_the_controllers_plant():
    """``x = [z_c - z_b, z_c', z_b - z_g, z_b']`` with the guideway's velocity as input."""
    lin = relative_model(QUARTER_CAR, P)
    a = np.array([[0, 1, 0, -1],
                  [-KS / MC, 0, 0, 0],
                  [0, 0, 0, 1],
                  [KS / MB, 0, -KP / MB, -CP / MB]])  # fmt: skip
    assert np.array_equal(lin.a, a)
    assert np.array_equal(lin.b[:, 0], [0, -1 / MC, 0, 1 / MB])
    assert np.array_equal(lin.e_rate[:, 0], [0, 0, -1, CP / MB])
    assert np.array_equal(lin.stroke[0], [1, 0, 0, 0])
    assert lin.state_names[0::2] == ("secondary_spring_deflection_m",
                                     "levitation_spring_deflection_m")  # fmt: skip


def test_two_mass_modes_match_the_closed_form():
    m, k, _ = mechanical_matrices(QUARTER_CAR, P)
    assert np.array_equal(m, np.diag([MC, MB]))
    # det(K - w^2 M) = 0: m_c m_b w^4 - (m_c (k_s + k_p) + m_b k_s) w^2 + k_s k_p = 0
    b = MC * (KS + KP) + MB * KS
    disc = np.sqrt(b * b - 4 * MC * MB * KS * KP)
    w2 = np.array([(b - disc), (b + disc)]) / (2 * MC * MB)
    # eigenvalues by LAPACK (last bits differ across CPUs): 1e-9 is far below any physics
    np.testing.assert_allclose(natural_frequencies_hz(P), np.sqrt(w2) / (2 * np.pi), rtol=1e-9)


# ------------------------------------------------------------------- a 3-DOF toy, one file
@dataclasses.dataclass(frozen=True)
class SeatParams:
    seat_mass_kg: float = 300.0
    car_body_mass_kg: float = 6000.0
    bogie_mass_kg: float = 2400.0
    seat_stiffness_n_per_m: float = 6.0e4
    seat_damping_n_s_per_m: float = 900.0
    secondary_stiffness_n_per_m: float = 4.95e5
    levitation_stiffness_n_per_m: float = 2.25e6
    levitation_damping_n_s_per_m: float = 0.0


def _toy(name: str = "seat_toy") -> VehicleModel:
    coords = tuple(Coordinate(f"{b}_displacement_m", "m", f"{b}_mass_kg", f"{b}_velocity_m_s")
                   for b in ("seat", "car_body", "bogie"))  # fmt: skip
    return VehicleModel(
        name=name,
        params=SeatParams,
        coordinates=coords,
        points=tuple(
            Point(b, ((c.name, 1.0),)) for b, c in zip(("seat", "car_body", "bogie"), coords)
        ),
        contacts=(Contact("guideway"),),
        elements=(
            Element(SPRING, "seat_spring", "seat", "car_body", "seat_stiffness_n_per_m"),
            Element(DASHPOT, "seat_dashpot", "seat", "car_body", "seat_damping_n_s_per_m"),
            Element(SPRING, "secondary_spring", "car_body", "bogie", "secondary_stiffness_n_per_m"),
            Element(DAMPER, "secondary_damper", "car_body", "bogie"),
            Element(
                SPRING, "levitation_spring", "bogie", "guideway", "levitation_stiffness_n_per_m"
            ),
            Element(
                DASHPOT, "levitation_damping", "bogie", "guideway", "levitation_damping_n_s_per_m"
            ),  # fmt: skip
        ),
        comfort_points=("seat",),
        relative_positions=("seat_spring", "secondary_spring", "levitation_spring"),
    )


def test_a_three_dof_toy_declared_in_one_file_has_newtons_equations():
    toy, p = _toy(), SeatParams()
    m, k, c = mechanical_matrices(toy, p)
    ms, mc, mb = 300.0, 6000.0, 2400.0
    k1, k2, k3, c1 = 6.0e4, 4.95e5, 2.25e6, 900.0
    assert np.array_equal(m, np.diag([ms, mc, mb]))
    np.testing.assert_array_equal(k, [[k1, -k1, 0], [-k1, k1 + k2, -k2], [0, -k2, k2 + k3]])
    np.testing.assert_array_equal(c, [[c1, -c1, 0], [-c1, c1, 0], [0, 0, 0]])
    lin = absolute_model(toy, p)
    assert np.array_equal(lin.b[:, 0], [0, 0, 0, -1 / mc, 0, 1 / mb])
    assert np.array_equal(lin.e[:, 0], [0, 0, 0, 0, 0, k3 / mb])
    assert np.array_equal(lin.c_acc[0], lin.a[1])  # the comfort point is the seat


def test_relative_form_is_the_absolute_form_in_other_coordinates():
    """``d = D q - g z_g``: for any state and guideway, ``d' = D q' - g z_g'`` and the
    accelerations agree."""
    rng = np.random.default_rng(4)
    for model, params in (
        (QUARTER_CAR, P),
        (_toy(), SeatParams(levitation_damping_n_s_per_m=300.0)),
    ):
        ab, rel = absolute_model(model, params), relative_model(model, params)
        n = len(model.coordinates)
        values = model.values(params)
        springs = {e.name: e for e in model.elements}
        rows = [model.element_rows(springs[s], values) for s in model.relative_positions]
        d_mat, g_mat = np.array([j for j, _ in rows]), np.array([g for _, g in rows])
        for _ in range(5):
            q, v = rng.normal(size=n) * 0.01, rng.normal(size=n) * 0.1
            zg, zg_rate, force = rng.normal() * 0.01, rng.normal() * 0.1, rng.normal() * 3e3
            x_abs = np.ravel(np.column_stack([q, v]))
            d = d_mat @ q - g_mat[:, 0] * zg
            x_rel = np.ravel(np.column_stack([d, v]))
            dx_abs = ab.a @ x_abs + ab.b[:, 0] * force + ab.e[:, 0] * zg + ab.e_rate[:, 0] * zg_rate
            dx_rel = rel.a @ x_rel + rel.b[:, 0] * force + rel.e_rate[:, 0] * zg_rate
            # sums of products of O(1e3) terms in other orders (BLAS dot): relative 1e-9
            np.testing.assert_allclose(dx_rel[1::2], dx_abs[1::2], rtol=1e-9, atol=1e-9)
            # coefficients +-1 and 0: only the summation order may differ (BLAS)
            np.testing.assert_allclose(dx_rel[0::2], d_mat @ v - g_mat[:, 0] * zg_rate, rtol=1e-12,
                                       atol=1e-15)  # fmt: skip
            stroke_abs = ab.stroke[0] @ x_abs
            # rel.stroke goes through a LAPACK inverse: relative 1e-9
            np.testing.assert_allclose(rel.stroke[0] @ x_rel, stroke_abs, rtol=1e-9, atol=1e-15)


def test_the_clipped_lqr_gain_reads_any_registered_vehicle():
    toy = register(_toy())
    try:
        assert model_of_params(SeatParams()) is toy
        gain = lqr_gain(SeatParams(), q_stroke=1e3, q_levitation=1e3, r_force=1e-9)
        rel = relative_model(toy, SeatParams())
        closed = rel.a - rel.b @ gain[None, :]
        assert gain.shape == (6,) and np.linalg.eigvals(closed).real.max() < 0.0
    finally:
        unregister("seat_toy")


def test_registry():
    assert "quarter_car" in names() and model_named("quarter_car") is QUARTER_CAR
    copy = register(QUARTER_CAR.with_name("quarter_car_copy"))
    try:
        assert model_named("quarter_car_copy") is copy
        assert model_of_params(VehicleParams()) is QUARTER_CAR  # the built-in comes first
        np.testing.assert_array_equal(absolute_model(copy, P).a, absolute_model(QUARTER_CAR, P).a)
        with pytest.raises(ValueError, match="quarter_car_copy.*taken"):
            register(QUARTER_CAR.with_name("quarter_car_copy"))
    finally:
        unregister("quarter_car_copy")
    with pytest.raises(ValueError, match="built in"):
        unregister("quarter_car")
    with pytest.raises(ValueError, match="vehicle.*quarter_car"):
        model_named("no_such_vehicle")
    with pytest.raises(TypeError, match="VehicleModel"):
        register("quarter_car")  # type: ignore[arg-type]


def test_a_declaration_that_names_what_it_lacks_is_refused():
    with pytest.raises(ValueError, match="element 'secondary_spring'.*'nowhere'"):
        dataclasses.replace(
            QUARTER_CAR,
            elements=(
                Element(
                    SPRING, "secondary_spring", "car_body", "nowhere", "secondary_stiffness_n_per_m"
                ),
            ),
        )
    with pytest.raises(ValueError, match="'mass_of_nothing', not a field of VehicleParams"):
        dataclasses.replace(
            QUARTER_CAR,
            coordinates=(
                Coordinate("car_body_displacement_m", "m", "mass_of_nothing", "v"),
                QUARTER_CAR.coordinates[1],
            ),  # fmt: skip
        )
    with pytest.raises(ValueError, match="kind must be one of"):
        dataclasses.replace(
            QUARTER_CAR, elements=(Element("magnet", "x", "car_body", "bogie", "bogie_mass_kg"),)
        )


# ------------------------------------------------------------------- through the env
def _rollout(**kwargs) -> dict[str, np.ndarray]:
    import gymnasium as gym

    env = gym.make("CapsuleSuspension-v0", setting="hils", observation="measured",
                   vehicle_randomization=0.2, **kwargs)  # fmt: skip
    obs, _ = env.reset(seed=5)
    actions = np.random.default_rng(1).uniform(-1.0, 1.0, size=(300, 1))
    out = {"obs": [obs]}
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a.astype(np.float32))
        out["obs"].append(obs)
        out.setdefault("reward", []).append(reward)
        out.setdefault("acc", []).append(info["car_body_acceleration_m_s2"])
    env.close()
    return {k: np.asarray(v) for k, v in out.items()}


def test_a_copy_of_the_quarter_car_under_another_name_runs_bit_identically():
    register(QUARTER_CAR.with_name("quarter_car_copy"))
    try:
        mass = {"car_body_mass_kg": 5800.0}
        base = _rollout(vehicle_params=mass)
        copy = _rollout(vehicle="quarter_car_copy", vehicle_params=mass)
    finally:
        unregister("quarter_car_copy")
    for key in base:
        assert np.array_equal(base[key], copy[key]), key


def test_the_env_runs_a_vehicle_of_another_form_or_names_what_cannot():
    import gymnasium as gym

    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv
    from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv

    register(_toy())
    try:  # the declared plant runs it; the quarter-car's vector env cannot, and says so
        assert isinstance(gym.make("CapsuleSuspension-v0", vehicle="seat_toy").unwrapped,
                          DeclaredVehicleEnv)  # fmt: skip
        with pytest.raises(ValueError, match="vehicle 'seat_toy'.*3 coordinates"):
            CapsuleSuspensionVectorEnv(2, vehicle="seat_toy")
    finally:
        unregister("seat_toy")
    with pytest.raises(
        ValueError,
        match="unknown vehicle .no_such_vehicle.; accepted values: half_car, quarter_car",
    ):
        gym.make("CapsuleSuspension-v0", vehicle="no_such_vehicle")
    with pytest.raises(ValueError, match="unknown key 'seat_mass_kg' in vehicle_params"):
        gym.make("CapsuleSuspension-v0", vehicle_params={"seat_mass_kg": 1.0})


# ------------------------------------------------------------------- a hostile user's cases
def test_nothing_silently_wrong_in_a_declaration_or_its_numbers():
    """Found by a review (issue 41): each of these gave wrong numbers without an error."""
    with pytest.raises(ValueError, match="unknown parameter.*levitation_stiffnes_n_per_m"):
        absolute_model(QUARTER_CAR, levitation_stiffnes_n_per_m=1e9)  # a typo
    with pytest.raises(ValueError, match="damper slot 'ground'.*two points"):
        dataclasses.replace(QUARTER_CAR, elements=(*QUARTER_CAR.elements,
                            Element(DAMPER, "ground", "bogie", "guideway")))  # fmt: skip
    with pytest.raises(ValueError, match="point and contact names must be unique"):
        dataclasses.replace(QUARTER_CAR, contacts=(Contact("bogie"),))
    with pytest.raises(ValueError, match="car_body_mass_kg must be a finite number > 0"):
        absolute_model(QUARTER_CAR, car_body_mass_kg=0.0)
    with pytest.raises(ValueError, match="levitation_stiffness_n_per_m must be finite"):
        absolute_model(QUARTER_CAR, levitation_stiffness_n_per_m=float("nan"))
    with pytest.raises(ValueError, match="slot_damping must be finite and >= 0"):
        absolute_model(QUARTER_CAR, P, slot_damping=-1e4)


def test_a_variant_sharing_the_parameter_class_is_not_mistaken_for_the_quarter_car():
    springs = [e if e.name != "levitation_spring" else dataclasses.replace(
        e, coefficient="secondary_stiffness_n_per_m") for e in QUARTER_CAR.elements]  # fmt: skip
    with pytest.raises(ValueError, match="VehicleParams is read by 'quarter_car', declared "
                       "differently"):  # refused when registered (review 50), not later  # fmt: skip
        register(QUARTER_CAR.with_name("qc_variant", elements=tuple(springs)))
    assert lqr_gain(VehicleParams(), q_stroke=1e3, q_levitation=1e3, r_force=1e-9).shape == (4,)


def test_the_env_checks_the_form_at_the_parameters_given():
    """A lever arm the compiled plant cannot follow is refused, not ignored."""
    import gymnasium as gym

    @dataclasses.dataclass(frozen=True)
    class RatioParams(VehicleParams):
        motion_ratio: float = 1.0

    points = (QUARTER_CAR.points[0], Point("bogie", (("bogie_displacement_m", "motion_ratio"),)))
    register(QUARTER_CAR.with_name("qc_ratio", params=RatioParams, points=points))
    try:
        env = gym.make("CapsuleSuspension-v0", vehicle="qc_ratio")  # at 1.0: the 1/4-car
        env.close()
        with pytest.raises(ValueError, match="vehicle 'qc_ratio'.*parameters given"):
            gym.make("CapsuleSuspension-v0", vehicle="qc_ratio",
                     vehicle_params={"motion_ratio": 2.0})  # fmt: skip
    finally:
        unregister("qc_ratio")


def test_a_declaration_or_a_call_of_the_wrong_type_is_named():
    """Found by a review (issue 41): these gave raw errors or nothing at all."""
    from capsule_env.agents.controllers.lqr import lqr_gain

    from capsule_env.engine import observations

    body, bogie = QUARTER_CAR.coordinates
    with pytest.raises(ValueError, match="joins 'car_body' to itself"):
        dataclasses.replace(QUARTER_CAR, elements=(*QUARTER_CAR.elements, Element(
            SPRING, "loop", "car_body", "car_body", "secondary_stiffness_n_per_m")))  # fmt: skip
    with pytest.raises(ValueError, match="coordinate and rate names must be unique"):
        dataclasses.replace(QUARTER_CAR, coordinates=(body, dataclasses.replace(
            bogie, rate_name=body.rate_name)))  # fmt: skip
    with pytest.raises(ValueError, match="unit must be one of"):
        dataclasses.replace(QUARTER_CAR, coordinates=(dataclasses.replace(body, unit="ft"), bogie))
    with pytest.raises(TypeError, match="coefficient must name a parameter"):
        dataclasses.replace(QUARTER_CAR, elements=(Element(SPRING, "s", "car_body", "bogie", 5.0),
                                                   *QUARTER_CAR.elements[1:]))  # fmt: skip
    with pytest.raises(TypeError, match="model must be a VehicleModel"):
        absolute_model("quarter_car")
    with pytest.raises(TypeError, match="q_stroke must be a number"):
        lqr_gain(P, "1", 1.0, 1e-9)
    with pytest.raises(ValueError, match="r_force must be finite and > 0"):
        lqr_gain(P, 1.0, 1.0, -1e-9)
    with pytest.raises(ValueError, match="observation must be one of"):
        observations.columns("bogus")
