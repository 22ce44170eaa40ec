"""Small helpers that turn bad input into a ``ValueError`` naming the parameter and its range."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as float, or raise if it is NaN or infinite."""
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return value


def check_positive(name: str, value: float) -> float:
    """Return ``value`` as float, or raise unless it is finite and > 0."""
    value = check_finite(name, value)
    if value <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return value


def check_nonnegative(name: str, value: float) -> float:
    """Return ``value`` as float, or raise unless it is finite and >= 0."""
    value = check_finite(name, value)
    if value < 0.0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return value


def check_in_range(name: str, value: float, low: float, high: float) -> float:
    """Return ``value`` as float, or raise unless ``low <= value <= high``."""
    value = check_finite(name, value)
    if not low <= value <= high:
        raise ValueError(f"{name} must be in [{low}, {high}], got {value!r}")
    return value


def check_array_in_range(name: str, values: np.ndarray, low: float, high: float) -> np.ndarray:
    """Raise unless every element is finite and in ``[low, high]``; return the array."""
    values = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{name} must be finite (got NaN or inf)")
    if values.size and (values.min() < low or values.max() > high):
        raise ValueError(
            f"{name} must be in [{low}, {high}], got values in "
            f"[{values.min():.6g}, {values.max():.6g}]"
        )
    return values


def check_choice(name: str, value: str, choices: Iterable[str]) -> str:
    """Raise unless ``value`` is one of ``choices``."""
    choices = tuple(choices)
    if value not in choices:
        raise ValueError(f"unknown {name} {value!r}; accepted values: {', '.join(choices)}")
    return value
