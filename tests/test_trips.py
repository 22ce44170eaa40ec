"""Trips against independent integration (SciPy's quad) and their defining limits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from capsule_env.envelope.trips import (
    TripParams,
    draw_window_start_s,
    trip_acceleration_m_s2,
    trip_position_m,
    trip_speed_m_s,
)


def test_position_is_the_integral_of_the_speed():
    trip = TripParams(cruise_duration_s=30.0)
    times = np.linspace(0.0, trip.duration_s, 37)
    t1, t2, _ = trip.phase_ends_s
    for t in times:
        exact, _ = quad(lambda s: float(trip_speed_m_s(s, trip)), 0.0, t, points=[t1, t2],
                        epsabs=1e-9, limit=200)  # fmt: skip
        assert trip_position_m(t, trip) == pytest.approx(exact, rel=1e-9, abs=1e-6)


def test_speed_respects_the_limits_and_ends():
    trip = TripParams()
    t = np.linspace(0.0, trip.duration_s, 200_001)
    v = trip_speed_m_s(t, trip)
    assert v[0] == pytest.approx(150 / 3.6) and v[-1] == pytest.approx(150 / 3.6, abs=1e-9)
    assert v.max() == pytest.approx(1000 / 3.6)
    slope = np.diff(v) / np.diff(t)
    assert slope.max() <= 1.0 + 1e-9 and slope.min() >= -1.0 - 1e-9
    # the speed-up takes (1000 - 150) / 3.6 / 1.0 s, about 4 minutes
    assert trip.phase_ends_s[0] == pytest.approx(236.1, abs=0.05)
    # the acceleration is the speed's slope away from the phase changes (one sample either side)
    away = np.all(np.abs(t[:, None] - np.array(trip.phase_ends_s)) > 2 * (t[1] - t[0]), axis=1)
    np.testing.assert_allclose(trip_acceleration_m_s2(t, trip)[away], np.gradient(v, t)[away],
                               atol=1e-6)  # fmt: skip


def test_windows_are_drawn_inside_the_trip():
    trip = TripParams(cruise_duration_s=0.0)
    rng = np.random.default_rng(0)
    starts = [draw_window_start_s(rng, 10.0, trip) for _ in range(200)]
    assert min(starts) >= 0.0 and max(starts) <= trip.duration_s - 10.0
    with pytest.raises(ValueError, match="episode_s"):
        draw_window_start_s(rng, trip.duration_s + 1.0, trip)
    with pytest.raises(ValueError, match="acceleration_m_s2"):
        TripParams(acceleration_m_s2=0.0)


def test_a_cruise_below_the_lift_off_names_the_cruise_speed():
    # issue 40: trip_params={"cruise_speed_kmh": 100} blamed lift_off_speed_kmh alone
    import gymnasium as gym

    import capsule_env  # noqa: F401  (registers the tasks)

    with pytest.raises(ValueError, match=r"^trip_params: cruise_speed_kmh must be >= "
                                         r"lift_off_speed_kmh .*cruise_speed_kmh=100"):  # fmt: skip
        gym.make("CapsuleTrip-v0", trip_params={"cruise_speed_kmh": 100})
    with pytest.raises(ValueError, match=r"lift_off_speed_kmh must be in \[0.0, 2000.0\]"):
        gym.make("CapsuleTrip-v0", trip_params={"lift_off_speed_kmh": -5})
