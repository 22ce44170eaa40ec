"""Speed in one unit: the library computes in m/s; km/h only where a person types a speed (the
env's ``speed_kmh``, ``speed_range_kmh``, the trip's and the levitation's ``*_kmh`` parameters)
or reads one. Every conversion goes through these two functions."""

from __future__ import annotations

from typing import TypeVar

__all__ = ["KMH_PER_M_S", "kmh_to_m_s", "m_s_to_kmh"]

#: km/h in one m/s.
KMH_PER_M_S = 3.6

T = TypeVar("T")


def kmh_to_m_s(speed_kmh: T) -> T:
    """A speed (float or array) from km/h to m/s: 810 km/h -> 225 m/s."""
    return speed_kmh / KMH_PER_M_S  # type: ignore[operator,no-any-return]


def m_s_to_kmh(speed_m_s: T) -> T:
    """A speed (float or array) from m/s to km/h."""
    return speed_m_s * KMH_PER_M_S  # type: ignore[operator,no-any-return]
