"""A hostile review of the vehicle as data (docs/model.md, "The vehicle as data"), as a user
who declares their own vehicle in one file: a seat on the car body of the 1/4-car (3 masses).

Each bad declaration below is refused when it is declared (or when a bad parameter value is
given), with one ``ValueError``/``TypeError`` naming what is wrong; before the review each one
passed, then crashed later (numba typing, ``LinAlgError``, ``IndexError``, an unhashable list)
or ran a diverging trajectory. The independent facts for the overrides: the undamped modes of
``M^-1 K`` written out by hand here, against the free oscillation the env integrates.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from capsule_env.vehicles import (
    DAMPER,
    Contact,
    Coordinate,
    Point,
    VehicleModel,
    model_of_params,
    register,
    unregister,
)
from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR

DOCS = Path(__file__).resolve().parents[1] / "docs" / "model.md"


def _recipe(step: str) -> str:
    """The docs' code block after the marker ``<!-- vehicle-recipe: <step>``."""
    text = DOCS.read_text(encoding="utf-8")
    after = text[text.index(f"<!-- vehicle-recipe: {step} ") :]
    return after[after.index("```python\n") + len("```python\n") : after.index("\n```\n")]


_DECLARED: dict = {}
exec(_recipe("declare"), _DECLARED)  # the docs' declaration, as a user copies it
SeatCarParams, MODEL = _DECLARED["SeatCarParams"], _DECLARED["MODEL"]
_ELEMENTS, _COORDS = MODEL.elements, MODEL.coordinates


def _declare(name: str = "review50_seat_car", **changes) -> VehicleModel:
    return MODEL.with_name(name, **changes)


def _params_class(**defaults: object) -> type:
    """``SeatCarParams`` with other defaults (a user's typo in their dataclass)."""
    fields = [(f.name, float, dataclasses.field(default=defaults.get(f.name, f.default)))
              for f in dataclasses.fields(SeatCarParams)]  # fmt: skip
    return dataclasses.make_dataclass("TypoParams", fields, frozen=True)


def test_the_documented_recipe_runs_as_written():
    namespace = dict(_DECLARED)
    try:
        exec(_recipe("run"), namespace)
    finally:
        unregister("seat_car")
    env, law = namespace["env"], namespace["law"]
    assert type(env.unwrapped).__name__ == "DeclaredVehicleEnv"
    assert namespace["truncated"] and not namespace["terminated"]  # 1 s, 200 steps, no bump stop
    assert env.unwrapped.batch.step_count[0] == 200 and np.all(np.isfinite(namespace["obs"]))
    assert law.gain.shape == (1, 6)


# ------------------------------------------------------------------- bad numbers, declared
@pytest.mark.parametrize(
    ("defaults", "error", "match"),
    [
        ({"seat_mass_kg": -500.0}, ValueError, "seat_mass_kg must be a finite number > 0"),
        ({"bogie_mass_kg": 0.0}, ValueError, "bogie_mass_kg must be a finite number > 0"),
        ({"seat_stiffness_n_per_m": float("inf")}, ValueError, "seat_stiffness_n_per_m must be "
         "finite"),
        ({"seat_mass_kg": "500"}, TypeError, "seat_mass_kg must be a real number"),
        ({"seat_mass_kg": True}, TypeError, "seat_mass_kg must be a real number"),
        ({"passive_damping_n_s_per_m": float("nan")}, ValueError, "passive_damping_n_s_per_m"),
    ],
)  # fmt: skip
def test_bad_default_values_are_refused_when_declared(defaults, error, match):
    with pytest.raises(error, match=f"vehicle 'review50_seat_car': {match}"):
        _declare(params=_params_class(**defaults))


def test_a_parameter_class_without_defaults_is_refused_when_declared():
    no_defaults = dataclasses.make_dataclass(
        "NoDefaults", [(f.name, float) for f in dataclasses.fields(SeatCarParams)], frozen=True
    )
    with pytest.raises(TypeError, match="params NoDefaults must give every field a default"):
        _declare(params=no_defaults)
    with pytest.raises(TypeError, match="params must be a dataclass type"):
        _declare(params=SeatCarParams())  # an instance, not the class


@pytest.mark.parametrize(
    ("value", "coordinates"),
    [
        (0.0, "seat_displacement_m, car_body_displacement_m, bogie_displacement_m"),  # floats
        (-1.0e6, "seat_displacement_m, car_body_displacement_m, bogie_displacement_m"),
    ],
)
def test_a_vehicle_its_springs_do_not_hold_is_refused(value, coordinates):
    """Before: levitation 0 gave ``LinAlgError: Singular matrix`` in the env's equilibrium;
    a negative stiffness ran a diverging trajectory (reward -5e7 in 52 steps)."""
    model = _declare()
    match = (f"vehicle 'review50_seat_car': the springs do not hold {coordinates}.*"
             f"levitation_stiffness_n_per_m = {value}")  # fmt: skip
    with pytest.raises(ValueError, match=match):
        model.values(SeatCarParams(levitation_stiffness_n_per_m=value))
    with pytest.raises(ValueError, match=match):
        _declare(params=_params_class(levitation_stiffness_n_per_m=value))


def test_a_coordinate_on_no_spring_is_refused_when_declared():
    free = Coordinate("loose_displacement_m", "m", "seat_mass_kg", "loose_velocity_m_s")
    with pytest.raises(ValueError, match="the springs do not hold loose_displacement_m"):
        _declare(coordinates=(*_COORDS, free), relative_positions=())


@pytest.mark.parametrize("offset", [float("nan"), float("inf")])
def test_a_non_finite_number_in_the_geometry_is_refused(offset):
    with pytest.raises(ValueError, match="contact 'guideway' offset_m must be a finite number"):
        Contact("guideway", offset)
    with pytest.raises(ValueError, match="point 'seat' coefficient of 'seat_displacement_m' "
                       "must be a finite number"):  # fmt: skip
        Point("seat", (("seat_displacement_m", offset),))


# ------------------------------------------------------------------- bad shapes, declared
def test_wrong_shapes_and_types_are_named():
    with pytest.raises(TypeError, match=r"point 'seat' terms must be \(coordinate, coefficient\) "
                       "pairs"):  # fmt: skip
        Point("seat", ("seat_displacement_m", 1.0))  # the inner tuple forgotten
    with pytest.raises(TypeError, match="coordinates must hold Coordinate entries"):
        _declare(coordinates=(("seat_displacement_m", "m", "seat_mass_kg", "v"), *_COORDS[1:]))
    with pytest.raises(TypeError, match="comfort_points must be a tuple of str"):
        _declare(comfort_points="seat")
    with pytest.raises(TypeError, match="Coordinate name must be a non-empty string, got 3"):
        Coordinate(3, "m", "seat_mass_kg", "v")  # type: ignore[arg-type]
    listed = _declare(elements=list(_ELEMENTS))  # a list is taken as the tuple it means
    assert listed.elements == _ELEMENTS and hash(listed) == hash(_declare())


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"elements": tuple(e for e in _ELEMENTS if e.kind != DAMPER)}, "declare at least one damper slot"),
        ({"comfort_points": ()}, "declare at least one comfort point"),
        ({"contacts": (), "elements": _ELEMENTS[:4]}, "declare at least one guideway contact"),
        ({"relative_positions": ("seat_dashpot", "secondary_spring", "levitation_spring")},
         "relative_positions must name each of its 3 springs once"),
        ({"relative_positions": ("secondary_spring",)}, "relative_positions must name each"),
    ],
)  # fmt: skip
def test_a_declaration_the_env_or_the_controllers_cannot_run_is_refused(changes, match):
    """Before: an ``IndexError`` (no slot), a numba ``TypingError`` (no comfort point), a
    reshape error (no contact) when the env was made; relative_positions only in the LQR."""
    with pytest.raises(ValueError, match=f"vehicle 'review50_seat_car': {match}"):
        _declare(**changes)


# ------------------------------------------------------------------- the registry
def test_a_variant_sharing_a_parameter_class_is_refused_when_registered():
    """Before: registered silently; from then on every reader given only parameters (the
    quarter-car's ``lqr_gain(VehicleParams())``, the built-in controllers) raised."""
    variant = QUARTER_CAR.with_name("review50_variant", comfort_points=("bogie",))
    with pytest.raises(ValueError, match="review50_variant.*VehicleParams is read by "
                       "'quarter_car', declared differently"):  # fmt: skip
        register(variant)
    assert model_of_params(QUARTER_CAR.params()) is QUARTER_CAR
    same = register(QUARTER_CAR.with_name("review50_copy"))  # the docs' recipe: a copy
    unregister(same.name)


# ------------------------------------------------------------------- overrides, as physics says
def _free_response(vehicle: str, overrides: dict, steps: int = 500) -> np.ndarray:
    """Column 0 of ``full_state`` (the first coordinate, m) after a 10 mm step of the guideway
    (at 50 m, passed by 0.4 s at 810 km/h), the slots' dampers all but removed (1 N s/m)."""
    env = gym.make("CapsuleSuspension-v0", vehicle=vehicle, vehicle_params=overrides,
                   observation="full_state", damper="passive",
                   damper_params={"damping_n_s_per_m": 1.0}, guideway="step",
                   guideway_params={"peak_m": 0.01}, episode_length_s=steps / 200.0)  # fmt: skip
    rows = [env.reset(seed=0)[0]]
    for _ in range(steps - 1):
        rows.append(env.step(np.zeros(env.action_space.shape))[0])
    return np.array(rows, dtype=float)[80:, 0]


def _misfit(x: np.ndarray, frequencies_hz: np.ndarray) -> float:
    """How far ``x`` (200 Hz) is from a constant plus undamped modes at ``frequencies_hz``:
    the least-squares fit's largest error over the signal's largest swing."""
    t = np.arange(x.size) / 200.0
    basis = np.column_stack([np.ones_like(t)] + [f(2 * np.pi * hz * t) for hz in frequencies_hz
                                                 for f in (np.sin, np.cos)])  # fmt: skip
    coef = np.linalg.lstsq(basis, x, rcond=None)[0]
    return float(np.abs(basis @ coef - x).max() / np.abs(x - coef[0]).max())


def _frequencies_hz(mass: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    w2 = np.linalg.eigvals(np.linalg.solve(np.diag(mass), stiffness)).real
    return np.sqrt(np.sort(w2)) / (2.0 * np.pi)


def _quarter_car(mc: float, mb: float, ks: float, kp: float) -> np.ndarray:
    """The 1/4-car's undamped modes, ``M`` and ``K`` written out by hand (docs/model.md 2)."""
    return _frequencies_hz(np.array([mc, mb]), np.array([[ks, -ks], [-ks, ks + kp]]))


def test_an_override_of_the_quarter_car_moves_its_modes_as_its_equations_say():
    """A 4x stiffer secondary spring: the free motion is the hand-written model's modes at the
    new stiffness (1.30 -> 2.01 Hz, 5.42 -> 7.00 Hz), not at the default's."""
    from capsule_env import modal_properties
    from capsule_env.vehicles import VehicleParams

    stiff = 4.0 * 4.95e5
    expected = _quarter_car(6000.0, 2400.0, stiff, 2.25e6)
    got = modal_properties(VehicleParams(secondary_stiffness_n_per_m=stiff)).frequencies_hz
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    x = _free_response("quarter_car", {"secondary_stiffness_n_per_m": stiff})
    assert _misfit(x, expected) < 1e-3  # 3.5e-5 observed (float32 observations)
    assert _misfit(x, _quarter_car(6000.0, 2400.0, 4.95e5, 2.25e6)) > 0.3  # 1.10


def _half_car(m, inertia, a, b, ksf, ksr, kpf, kpr, mf, mr) -> np.ndarray:
    """The half-car's modes from its equations (docs/model.md 2.1), ``q = [z, theta, zbf,
    zbr]``, ``d_sf = z + a theta - zbf``, ``d_sr = z - b theta - zbr``."""
    front, rear = np.array([1.0, a, -1.0, 0.0]), np.array([1.0, -b, 0.0, -1.0])
    k = ksf * np.outer(front, front) + ksr * np.outer(rear, rear) + np.diag([0, 0, kpf, kpr])
    return _frequencies_hz(np.array([m, inertia, mf, mr]), k)


def test_overrides_of_the_half_car_move_its_modes_as_its_equations_say():
    overrides = {"front_secondary_stiffness_n_per_m": 4.0 * 4.95e5,
                 "car_body_pitch_inertia_kg_m2": 4.0e5, "front_bogie_position_m": 8.0,
                 "rear_bogie_mass_kg": 3000.0}  # fmt: skip
    default = (12000.0, 9.0e5, 10.0, 10.0, 4.95e5, 4.95e5, 2.25e6, 2.25e6, 2400.0, 2400.0)
    changed = (12000.0, 4.0e5, 8.0, 10.0, 4 * 4.95e5, 4.95e5, 2.25e6, 2.25e6, 2400.0, 3000.0)
    x = _free_response("half_car", overrides)
    assert _misfit(x, _half_car(*changed)) < 1e-3  # 6.0e-5 observed
    assert _misfit(x, _half_car(*default)) > 0.1  # 0.31


def test_an_override_of_the_user_vehicle_moves_its_modes_as_its_equations_say():
    ms, mc, mb, ks_seat, ks, kp = 800.0, 6000.0, 2400.0, 5.0e5, 4.95e5, 2.25e6
    k = np.array([[ks_seat, -ks_seat, 0.0], [-ks_seat, ks_seat + ks, -ks], [0.0, -ks, ks + kp]])
    register(MODEL)
    try:
        x = _free_response("seat_car", {"seat_mass_kg": ms, "seat_stiffness_n_per_m": ks_seat,
                                        "seat_damping_n_s_per_m": 0.0})  # fmt: skip
    finally:
        unregister("seat_car")
    assert _misfit(x, _frequencies_hz(np.array([ms, mc, mb]), k)) < 1e-3  # 4.4e-5 observed
    default = k.copy()
    default[:2, :2] += (2.0e5 - ks_seat) * np.array([[1.0, -1.0], [-1.0, 1.0]])
    assert _misfit(x, _frequencies_hz(np.array([500.0, mc, mb]), default)) > 0.1  # 0.28


def test_a_damper_slot_whose_ends_move_alike_is_refused_when_declared():
    """Before: the env ran it, the slot's action doing nothing, and its clipped LQR's gain was
    all zeros: a slot joined to a second point on the body it starts from (the bogie
    forgotten)."""
    copy = Point("car_body_copy", (("car_body_displacement_m", 1.0),))
    elements = tuple(e if e.kind != DAMPER else dataclasses.replace(e, lower="car_body_copy")
                     for e in _ELEMENTS)  # fmt: skip
    with pytest.raises(ValueError, match="damper slot 'secondary_damper' joins 'car_body' and "
                       "'car_body_copy', which move alike"):  # fmt: skip
        _declare(points=(*MODEL.points, copy), elements=elements)


def test_the_env_passive_baseline_reads_damper_params_not_the_slot_passive_fields():
    """What the docstrings now say (before, they called ``*_passive_damping_n_s_per_m`` the
    passive baseline's damper; the env never read it): the slots' passive fields leave the
    env's ``damper="passive"`` as it was, ``damper_params`` changes it."""

    def rewards(**options) -> list[float]:
        env = gym.make("CapsuleSuspension-v0", vehicle="half_car", damper="passive",
                       episode_length_s=0.25, **options)  # fmt: skip
        env.reset(seed=0)
        return [env.step(np.zeros(2))[1] for _ in range(50)]

    fields = {"front_passive_damping_n_s_per_m": 3e4, "rear_passive_damping_n_s_per_m": 3e4}
    assert rewards(vehicle_params=fields) == rewards()
    assert rewards(damper_params={"damping_n_s_per_m": 3e4}) != rewards()


def test_a_comfort_point_named_twice_is_refused_when_declared():
    """Before: accepted; the env's observation named ``seat_acceleration_m_s2`` twice and the
    reward weighed the seat twice in its mean over the comfort points."""
    with pytest.raises(ValueError, match=r"comfort_points must name each point once, got \('seat', "
                       r"'car_body', 'seat'\)"):  # fmt: skip
        _declare(comfort_points=("seat", "car_body", "seat"))
