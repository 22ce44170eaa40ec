"""Sampled profiles: how many samples a length takes, and where they lie."""

from __future__ import annotations

import numpy as np

from capsule_env.common.validation import check_positive

__all__ = ["n_samples", "positions"]


def n_samples(length_m: float, spacing_m: float) -> int:
    """Number of samples ``int(round(length_m / spacing_m)) + 1`` after validating both."""
    length_m = check_positive("length_m", length_m)
    spacing_m = check_positive("spacing_m", spacing_m)
    return int(round(length_m / spacing_m)) + 1


def positions(length_m: float, spacing_m: float) -> np.ndarray:
    """Sample positions ``x_j = j * spacing_m`` (m), ``j = 0..n-1``."""
    return np.arange(n_samples(length_m, spacing_m), dtype=np.float64) * float(spacing_m)
