"""The type check every env applies to an action before the plant reads it.

``numpy.asarray(actions, dtype=float)`` takes more than numbers: it drops the imaginary part
of a complex action (with a ``ComplexWarning``) and parses a string (``"0.5"`` is 0.5). An
env's actions are real numbers; anything else is a caller's mistake, refused by name.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["real_actions"]

#: numpy dtype kinds of real numbers: bool, signed and unsigned integers, floats.
REAL_KINDS = "biuf"


def real_actions(actions: Any, name: str = "actions") -> np.ndarray:
    """``actions`` (a number, a list, an array) as a numpy array of real numbers (booleans,
    integers or floats; not converted). Complex numbers, strings and other objects raise
    ``TypeError`` naming ``name``; a ragged list raises ``ValueError``."""
    try:
        a = np.asarray(actions)
    except ValueError:  # a ragged list
        raise ValueError(f"{name} must be an array of numbers, got a ragged sequence") from None
    if a.dtype.kind not in REAL_KINDS:
        what = "complex ones" if a.dtype.kind == "c" else f"{type(actions).__name__} of {a.dtype}"
        raise TypeError(f"{name} must be real numbers, got {what}")
    return a
