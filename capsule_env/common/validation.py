"""Small helpers that turn bad input into a ``ValueError`` naming the parameter and its range."""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterable
from typing import Any

import numpy as np


def check_real(name: str, value: Any) -> float:
    """Return ``value`` as float, or raise ``TypeError`` unless it is a real number (an int or
    float, numpy's too; not a bool, a string or None)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r} ({type(value).__name__})")
    return float(value)


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as float, or raise if it is not a real number or is NaN or infinite."""
    value = check_real(name, value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return value


def check_integer(name: str, value: Any, low: int, high: int) -> int:
    """Return ``value`` as int, or raise ``TypeError`` unless it is an integer (not a bool or a
    float) and ``ValueError`` unless ``low <= value <= high``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(
            f"{name} must be an integer in [{low}, {high}], got {value!r} ({type(value).__name__})"
        )
    if not low <= int(value) <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def available_memory_bytes() -> int:
    """Memory this machine can still give (``MemAvailable`` on Linux; else the physical size)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    try:  # pragma: no cover - not Linux
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return 8 * 2**30


def format_bytes(n: float) -> str:
    """``n`` bytes as a short string (KiB, MiB, GiB)."""
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:  # a huge request (--episode-length 1e300): 3 digits, not 290
            return f"{n / size:.1f} {unit}" if n < 1e6 * size else f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


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
    """Raise unless ``value`` is one of ``choices`` (``TypeError`` if it is not a string)."""
    choices = tuple(choices)
    if not isinstance(value, str):
        shown = repr(value) if len(repr(value)) <= 60 else f"a {type(value).__name__}"
        raise TypeError(
            f"{name} must be one of {', '.join(choices)} (a string), got {shown} "
            f"({type(value).__name__})"
        )
    if value not in choices:
        raise ValueError(f"unknown {name} {value!r}; accepted values: {', '.join(choices)}")
    return value


class UnexpectedArgumentError(TypeError, ValueError):
    """An unknown keyword argument: both a ``TypeError`` (what Python raises for a function
    called with an argument it does not take, and what wrappers such as TorchRL's ``GymEnv``
    catch to retry without an optional argument like ``frameskip``) and a ``ValueError`` (what
    this package raises for every other bad argument), so either ``except`` clause catches it.

    The message follows Python's wording, ``<callable>() got an unexpected keyword argument
    '<name>'``, followed by the accepted names (:func:`unexpected_argument`). The constructor
    takes the message alone, as ``TypeError`` does (``gymnasium.make`` re-raises an env
    constructor's ``TypeError`` as ``type(err)(message)``).
    """


def unexpected_argument(owner: str, name: str, accepted: Iterable[str]) -> UnexpectedArgumentError:
    """The :class:`UnexpectedArgumentError` for keyword ``name`` given to ``owner`` (e.g.
    ``"CapsuleSuspensionEnv.__init__"``), listing the ``accepted`` names (sorted)."""
    return UnexpectedArgumentError(
        f"{owner}() got an unexpected keyword argument {name!r}; accepted: "
        f"{', '.join(sorted(accepted))}"
    )
