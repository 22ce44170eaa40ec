"""Lift-off under payload (issue 43, item 4): ``levitation_params={"lift_off": "payload"}``.

The coil is calibrated on the unladen vehicle; with the option each vehicle levitates only from
its own lift-off speed, the speed at which the coil carries its weight at the travel. Checked
against the coil's formulas solved here independently (root finding on the calibration's two
conditions and on the sag), against docs/envelope.md's table (the +40 % payload lifts off at
184.4 km/h), and against the default, which keeps today's episodes bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from capsule_env.common.units import kmh_to_m_s, m_s_to_kmh
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.envelope.trips import TripParams, draw_window_start_s, trip_speed_m_s
from capsule_env.vehicles import VehicleParams

PAYLOAD = {"levitation": "eds", "levitation_params": {"lift_off": "payload"}}
G = 9.80665  # m/s^2


def _shape(v: float, v_c: float) -> float:
    return (v / v_c) ** 2 / (1.0 + (v / v_c) ** 2)


def _independent_lift_off_kmh(payload: float) -> float:
    """The speed at which the coil carries the weight at the 0.1 m travel: the coil
    ``k_p(v) = K_inf r^2 / (1 + r^2)`` calibrated by root finding on its two conditions
    (2.25e6 N/m at 810 km/h; the unladen sag 0.1 m at 150 km/h), then the sag solved."""
    vehicle = VehicleParams()
    unladen = (vehicle.car_body_mass_kg + vehicle.bogie_mass_kg) * G
    weight = (vehicle.car_body_mass_kg * (1.0 + payload) + vehicle.bogie_mass_kg) * G
    v_ref, v_lo, k_ref = kmh_to_m_s(810.0), kmh_to_m_s(150.0), 2.25e6

    def sag_at_lift_off(v_c):
        return unladen / (k_ref / _shape(v_ref, v_c) * _shape(v_lo, v_c)) - 0.1

    v_c = brentq(sag_at_lift_off, 1.0, 500.0, xtol=1e-13)
    k_inf = k_ref / _shape(v_ref, v_c)
    v = brentq(lambda v: weight / (k_inf * _shape(v, v_c)) - 0.1, 1.0, 1000.0, xtol=1e-13)
    return m_s_to_kmh(v)


def test_the_independent_lift_off_is_the_documented_table():
    """docs/envelope.md, "Lift-off under payload": 126.1, 150.0 and 184.4 km/h."""
    assert _independent_lift_off_kmh(0.4) == pytest.approx(184.4, abs=0.05)
    assert _independent_lift_off_kmh(0.0) == pytest.approx(150.0, abs=1e-6)
    assert _independent_lift_off_kmh(-0.3) == pytest.approx(126.1, abs=0.05)


def test_a_constant_speed_below_the_heaviest_payloads_lift_off_is_refused():
    heavy = _independent_lift_off_kmh(0.4)
    config = EnvConfig(**PAYLOAD, payload_range=(0.0, 0.4), speed_kmh=heavy + 0.01)
    assert m_s_to_kmh(config.envelope.lift_off_range_m_s(config)[1]) == pytest.approx(
        heavy, abs=1e-6
    )
    with pytest.raises(ValueError, match=r"speed_kmh must be at least 184\.44 km/h"):
        EnvConfig(**PAYLOAD, payload_range=(0.0, 0.4), speed_kmh=heavy - 0.01)
    with pytest.raises(ValueError, match=r"speed_range_kmh\[0\] must be at least 184\.44"):
        EnvConfig(**PAYLOAD, payload_range=(0.0, 0.4), speed_range_kmh=(150.0, 800.0))
    EnvConfig(levitation="eds", payload_range=(0.0, 0.4), speed_kmh=150.0)  # the default: as before


def test_a_light_payload_levitates_below_the_calibrations_lift_off():
    light = _independent_lift_off_kmh(-0.3)
    EnvConfig(**PAYLOAD, payload_range=(-0.3, -0.3), speed_kmh=light + 0.01)
    with pytest.raises(ValueError, match="speed_kmh must be at least"):
        EnvConfig(**PAYLOAD, payload_range=(-0.3, -0.3), speed_kmh=light - 0.01)
    with pytest.raises(ValueError, match="speed_kmh must be at least the lift-off speed 150"):
        EnvConfig(levitation="eds", payload_range=(-0.3, -0.3), speed_kmh=light + 0.01)


class _Edge:
    """A generator stand-in whose ``uniform`` returns one end of its interval."""

    def __init__(self, end: int) -> None:
        self.end = end

    def uniform(self, low: float, high: float) -> float:
        return (low, high)[self.end]


def test_the_trip_windows_lie_at_or_above_the_own_lift_off():
    """The earliest window starts at the payload's lift-off on the way up; the latest ends at
    it on the way down (the trip's schedule, trips.trip_speed_m_s)."""
    config = EnvConfig(**PAYLOAD, speed_profile="trip", payload_range=(-0.3, 0.4))
    trip = config.envelope.trip
    assert trip.lift_off_speed_kmh == pytest.approx(_independent_lift_off_kmh(-0.3), abs=1e-6)
    own = kmh_to_m_s(_independent_lift_off_kmh(0.4))
    first = draw_window_start_s(_Edge(0), 10.0, trip, own)
    last = draw_window_start_s(_Edge(1), 10.0, trip, own) + 10.0
    assert float(trip_speed_m_s(first, trip)) == pytest.approx(own, rel=1e-9)
    assert float(trip_speed_m_s(last, trip)) == pytest.approx(own, rel=1e-9)
    assert last > trip.phase_ends_s[1]  # on the way down
    # today's trip from 150 km/h, for contrast: the heavy capsule rides below its lift-off
    today = TripParams()
    assert float(trip_speed_m_s(draw_window_start_s(_Edge(0), 10.0, today), today)) < own


@pytest.mark.parametrize("payload", [(0.4, 0.4), (-0.3, -0.3)])
def test_on_a_trip_every_step_is_at_or_above_the_own_lift_off(payload):
    """Short trips (to 10 km/h above the lift-off, no cruise) so that the windows reach the
    lift-off: over whole episodes the speed the env reports never falls below the payload's own
    lift-off speed and comes within 2 km/h of it; without the option the heavy capsule rides
    far below it."""
    own = _independent_lift_off_kmh(payload[0])
    trip = {"cruise_speed_kmh": own + 10.0, "cruise_duration_s": 0.0}
    kwargs = {"speed_profile": "trip", "payload_range": payload, "episode_length_s": 2.0}
    lowest = {}
    runs = (("payload", PAYLOAD), ("unladen", {"levitation": "eds"}))
    for name, lev in runs if payload[0] > 0 else runs[:1]:
        params = trip if name == "payload" else {**trip, "lift_off_speed_kmh": 150.0}
        batch = CapsuleBatch(EnvConfig(**lev, **kwargs, trip_params=params), 16)
        batch.seed(4)
        batch.reset()
        speeds = [batch.obs[:, -2].copy()]
        for _ in range(batch.max_steps):
            batch.step(np.zeros(16))
            speeds.append(batch.obs[:, -2].copy())
        lowest[name] = m_s_to_kmh(float(np.min(speeds)))
    assert own - 1e-4 <= lowest["payload"] < own + 2.0  # float32 observation
    if payload[0] > 0:  # the same trip from 150 km/h
        assert lowest["unladen"] < own - 10.0


def test_the_default_keeps_todays_episodes_bit_for_bit():
    """The trip task's draws at seed 5, recorded before the option existed (commit a560d78),
    and the whole run equal with the option left out or set to its default."""
    task = {
        "setting": "hils",
        "observation": "measured",
        "levitation": "eds",  # fmt: skip
        "speed_profile": "trip",
        "spans": "continuous",
        "payload_range": (-0.3, 0.4),
    }
    runs = []
    for lev in ({}, {"levitation_params": {"lift_off": "unladen"}}):
        batch = CapsuleBatch(EnvConfig(**task, **lev), 3)
        batch.seed(5)
        batch.reset()
        assert [float(x).hex() for x in batch.speed] == [
            "0x1.64d11c379987ap+5", "0x1.7216dceeb4720p+6", "0x1.7a95fdf9b24eep+7"]  # fmt: skip
        assert [float(x).hex() for x in batch.env_state.envelope[0]] == [
            "0x1.77bc6e244324bp+1", "0x1.96d86488138ecp+5", "0x1.ce4c479e05336p+9"]  # fmt: skip
        obs = [batch.obs.copy()]
        for k in range(200):
            batch.step(np.full(3, np.sin(0.1 * k)))
            obs.append(batch.obs.copy())
        runs.append(np.array(obs))
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"levitation_params": {"lift_off": "heavy"}}, "lift_off 'heavy'; accepted values: unladen, payload"),
        ({"speed_profile": "trip", "trip_params": {"lift_off_speed_kmh": 200.0}},
         r"trip_params\['lift_off_speed_kmh'\] must not be set"),
        ({"speed_profile": "trip", "payload_range": (1.0, 1.0),
          "trip_params": {"cruise_speed_kmh": 200.0}}, r"trip_params\['cruise_speed_kmh'\] must be at least"),
        ({"payload_range": (5.0, 5.0)}, "payload_range must leave every vehicle a lift-off speed"),
        ({"speed_profile": "trip", "payload_range": (0.4, 0.4), "episode_length_s": 10.0,
          "trip_params": {"cruise_speed_kmh": 190.0, "cruise_duration_s": 0.0}},
         "episode_length_s must be at most"),
    ],
)  # fmt: skip
def test_bad_lift_off_options_are_named(kwargs, named):
    options = {**PAYLOAD, **kwargs}
    options["levitation_params"] = {"lift_off": "payload", **kwargs.get("levitation_params", {})}
    with pytest.raises(ValueError, match=named):
        EnvConfig(**options)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"levitation": "eds", "levitation_params": {"lift_off": 1}},
         r"^levitation_params: lift_off must be one of unladen, payload"),
        ({"levitation": "eds", "levitation_params": {"lift_off_speed_kmh": "fast"}},
         r"^levitation_params: lift_off_speed_kmh must be a real number"),
        ({"speed_profile": "trip", "trip_params": {"lift_off_speed_kmh": "fast"}},
         r"^trip_params: lift_off_speed_kmh must be a real number"),
    ],
)  # fmt: skip
def test_a_field_of_the_wrong_type_names_its_dict(kwargs, named):
    """Both dicts have a lift_off_speed_kmh: a TypeError names the dict as a ValueError does."""
    with pytest.raises(TypeError, match=named):
        EnvConfig(**kwargs)


def _stated_kmh(options: dict, phrase: str) -> float:
    """The speed an error message states after ``phrase`` (km/h)."""
    with pytest.raises(ValueError, match=phrase) as error:
        EnvConfig(**options)
    return float(str(error.value).split(phrase)[1].split()[0])


@pytest.mark.parametrize(
    "options",
    [
        {**PAYLOAD, "payload_range": (-0.3, 0.4), "speed_kmh": 150.0},  # 184.4347 km/h
        {**PAYLOAD, "payload_range": (-0.3, -0.2), "speed_kmh": 100.0},
        {**PAYLOAD, "vehicle_randomization": 0.2, "speed_range_kmh": (150.0, 800.0)},
        {"levitation": "eds", "levitation_params": {"lift_off_speed_kmh": 150.004},
         "speed_kmh": 120.0},  # the calibration's lift-off (the default mode)
    ],
)  # fmt: skip
def test_the_lowest_speed_an_error_states_is_accepted(options):
    """Following the message works: the stated lowest speed (rounded up, not to nearest)."""
    own = options.get("levitation_params", {}).get("lift_off") != "payload"
    stated = _stated_kmh(options, "must be at least " + ("the lift-off speed " if own else ""))
    stated_options = {key: value for key, value in options.items() if key != "speed_range_kmh"}
    EnvConfig(**{**stated_options, "speed_kmh": stated})
    with pytest.raises(ValueError, match="must be at least"):
        EnvConfig(**{**stated_options, "speed_kmh": stated - 0.01})


def test_the_lowest_cruise_an_error_states_is_accepted():
    options = {**PAYLOAD, "speed_profile": "trip", "payload_range": (-0.3, 0.4),
               "trip_params": {"cruise_speed_kmh": 180.0, "cruise_duration_s": 60.0}}  # fmt: skip
    stated = _stated_kmh(options, "must be at least ")
    EnvConfig(**{**options, "trip_params": {"cruise_speed_kmh": stated, "cruise_duration_s": 60.0}})


@pytest.mark.parametrize("lift_off", ["payload", "unladen"])
def test_the_longest_episode_an_error_states_is_accepted(lift_off):
    """The own trip lasts 16.05 s here (the trip 16.76 s unladen): the stated longest episode
    is rounded down, so that it is accepted."""
    trip = {"cruise_speed_kmh": 190.0, "cruise_duration_s": 12.96}
    options = {"levitation": "eds", "levitation_params": {"lift_off": lift_off},
               "speed_profile": "trip", "payload_range": (0.4, 0.4), "episode_length_s": 30.0}  # fmt: skip
    if lift_off == "unladen":
        trip["lift_off_speed_kmh"] = 183.16
    options["trip_params"] = trip
    phrase = "must be at most " + ("" if lift_off == "payload" else "the trip's duration ")
    stated = _stated_kmh(options, phrase)
    EnvConfig(**{**options, "episode_length_s": stated})
