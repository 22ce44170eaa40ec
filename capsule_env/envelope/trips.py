"""Trips: the capsule's speed from lift-off to cruise and back, and windows of it for episodes.

A trip accelerates at a constant rate from the lift-off speed to the cruise speed,
cruises, and brakes at a constant rate back to the lift-off speed (below it the capsule rolls
on its wheels, outside this model). Speed and position are closed-form piecewise linear and
quadratic functions of time; an episode is a window of a trip starting at a time drawn from the
vehicle's own random stream, and the guideway is sampled at the position travelled.

Defaults, [reconstructed], each overridable (:class:`TripParams`): cruise at 1000 km/h (the
capsule's design speed in the paper's introduction); lift-off at 150 km/h (as
:class:`capsule_env.envelope.levitation.EdsParams`); acceleration and braking at 1.0 m/s^2 (0.102 g),
just below the 0.11-0.15 g longitudinal comfort range of ground-transport studies (Hoberock, "A
survey of longitudinal acceleration comfort studies in ground transportation vehicles", J.
Dyn. Syst. Meas. Control 99(2):76-84, 1977), so that the speed-up takes about 4 minutes; a
cruise of 10 minutes. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capsule_env.common.units import kmh_to_m_s
from capsule_env.common.validation import check_in_range

__all__ = ["TripParams", "trip_speed_m_s", "trip_position_m", "trip_acceleration_m_s2",
           "draw_window_start_s", "own_trip_s"]  # fmt: skip


@dataclass(frozen=True)
class TripParams:
    """One trip's speed profile (see the module docstring for the sources).

    Attributes
    ----------
    cruise_speed_kmh : cruise speed (km/h), default 1000.
    lift_off_speed_kmh : speed at the trip's two ends (km/h), default 150.
    acceleration_m_s2 : constant acceleration from lift-off to cruise (m/s^2), default 1.0.
    braking_m_s2 : constant deceleration from cruise to lift-off (m/s^2), default 1.0.
    cruise_duration_s : time at cruise speed (s), default 600.
    """

    cruise_speed_kmh: float = 1000.0
    lift_off_speed_kmh: float = 150.0
    acceleration_m_s2: float = 1.0
    braking_m_s2: float = 1.0
    cruise_duration_s: float = 600.0

    def __post_init__(self) -> None:
        check_in_range("cruise_speed_kmh", self.cruise_speed_kmh, 1.0, 2000.0)
        check_in_range("lift_off_speed_kmh", self.lift_off_speed_kmh, 0.0, 2000.0)
        if self.lift_off_speed_kmh > self.cruise_speed_kmh:  # both named: either may be the slip
            raise ValueError(
                f"cruise_speed_kmh must be >= lift_off_speed_kmh (a trip rises from lift-off to "
                f"cruise), got cruise_speed_kmh={self.cruise_speed_kmh!r} and "
                f"lift_off_speed_kmh={self.lift_off_speed_kmh!r}"
            )
        check_in_range("acceleration_m_s2", self.acceleration_m_s2, 1e-3, 20.0)
        check_in_range("braking_m_s2", self.braking_m_s2, 1e-3, 20.0)
        check_in_range("cruise_duration_s", self.cruise_duration_s, 0.0, 1e6)

    @property
    def phase_ends_s(self) -> tuple[float, float, float]:
        """Ends of the acceleration, cruise and braking phases (s from the trip's start)."""
        dv = kmh_to_m_s(self.cruise_speed_kmh - self.lift_off_speed_kmh)
        t_acc = dv / self.acceleration_m_s2
        t_cruise = t_acc + self.cruise_duration_s
        return t_acc, t_cruise, t_cruise + dv / self.braking_m_s2

    @property
    def duration_s(self) -> float:
        """The whole trip's duration (s)."""
        return self.phase_ends_s[2]


def _phases(t_s: np.ndarray, trip: TripParams):
    t = np.clip(np.asarray(t_s, dtype=float), 0.0, trip.duration_s)
    t1, t2, _ = trip.phase_ends_s
    return t, t1, t2, kmh_to_m_s(trip.lift_off_speed_kmh), kmh_to_m_s(trip.cruise_speed_kmh)


def trip_speed_m_s(t_s: np.ndarray | float, trip: TripParams) -> np.ndarray:
    """Speed (m/s) at times ``t_s`` from the trip's start (held at its ends outside the trip)."""
    t, t1, t2, v0, v1 = _phases(t_s, trip)
    return np.where(t < t1, v0 + trip.acceleration_m_s2 * t,
                    np.where(t < t2, v1, v1 - trip.braking_m_s2 * (t - t2)))  # fmt: skip


def trip_acceleration_m_s2(t_s: np.ndarray | float, trip: TripParams) -> np.ndarray:
    """Longitudinal acceleration (m/s^2) at times ``t_s`` (0 outside the trip)."""
    t = np.asarray(t_s, dtype=float)
    t1, t2, t3 = trip.phase_ends_s
    inside = (t >= 0.0) & (t < t3)
    return np.where(inside & (t < t1), trip.acceleration_m_s2,
                    np.where(inside & (t >= t2), -trip.braking_m_s2, 0.0))  # fmt: skip


def trip_position_m(t_s: np.ndarray | float, trip: TripParams) -> np.ndarray:
    """Distance travelled (m) from the trip's start at times ``t_s`` in ``[0, duration]``: the
    exact integral of :func:`trip_speed_m_s`."""
    t, t1, t2, v0, v1 = _phases(t_s, trip)
    a, b = trip.acceleration_m_s2, trip.braking_m_s2
    x1 = v0 * t1 + 0.5 * a * t1 * t1
    x2 = x1 + v1 * (t2 - t1)
    tb = t - t2
    return np.where(t < t1, v0 * t + 0.5 * a * t * t,
                    np.where(t < t2, x1 + v1 * (t - t1), x2 + v1 * tb - 0.5 * b * tb * tb))  # fmt: skip


def own_trip_s(trip: TripParams, lift_off_m_s: float) -> tuple[float, float]:
    """``(start, end)``: the times (s from ``trip``'s start) between which ``trip`` is at or
    above ``lift_off_m_s`` (at or above its own ends). At constant rates this part of the trip is
    the trip from and to that lift-off speed, shifted in time."""
    v0 = kmh_to_m_s(trip.lift_off_speed_kmh)
    dv = max(lift_off_m_s - v0, 0.0)
    return dv / trip.acceleration_m_s2, trip.duration_s - dv / trip.braking_m_s2


def draw_window_start_s(rng: np.random.Generator, episode_s: float, trip: TripParams,
                        lift_off_m_s: float | None = None) -> float:  # fmt: skip
    """A uniformly drawn start time of an episode of ``episode_s`` seconds inside the trip; with
    ``lift_off_m_s``, inside the part of the trip at or above that speed (:func:`own_trip_s`)."""
    if lift_off_m_s is None:
        check_in_range("episode_s", episode_s, 0.0, trip.duration_s)
        return float(rng.uniform(0.0, trip.duration_s - episode_s))
    start, end = own_trip_s(trip, lift_off_m_s)
    check_in_range("episode_s", episode_s, 0.0, end - start)
    return float(rng.uniform(start, end - episode_s))
