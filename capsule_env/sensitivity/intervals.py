"""Per-episode 95 % intervals of the study's VREs and gaps (issue 43).

Every figure of the study is a mean over the same evaluation-bank episodes. A pair's VRE is
given with Student's t interval over its per-episode VREs; a gap (Bi-exponential - CSDC) with
the *paired* t interval: the t interval of the per-episode differences, because both pairs run
on the same episodes and share their guideway (the episode-to-episode spread, which the two
pairs have in common, cancels in the differences). Student's t rather than a bootstrap: with
10 episodes a percentile bootstrap is known to cover less than its nominal level (it has no
``n - 1`` and no t quantile), while the t interval is exact for normal differences and close
for the mildly skewed VREs seen here.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import stats

__all__ = ["paired_t_interval", "t_interval"]


def t_interval(samples: Sequence[float] | np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """Student's t interval ``(low, high)`` for the mean of ``samples`` at ``level``.

    ``ValueError`` for fewer than 2 samples, non-finite samples or ``level`` outside (0, 1).
    """
    x = np.asarray(samples, dtype=float).ravel()
    if x.size < 2:
        raise ValueError(f"samples must hold at least 2 values for an interval, got {x.size}")
    if not np.all(np.isfinite(x)):
        raise ValueError("samples must be finite (got NaN or inf)")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    mean = float(np.mean(x))
    half = float(stats.t.ppf(0.5 + level / 2.0, x.size - 1) * np.std(x, ddof=1) / np.sqrt(x.size))
    return mean - half, mean + half


def paired_t_interval(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, level: float = 0.95
) -> tuple[float, float]:
    """The paired t interval ``(low, high)`` of ``mean(b - a)``: ``a[k]`` and ``b[k]`` are
    measured on the same episode ``k`` (``ValueError`` for arrays of different lengths)."""
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    if a.size != b.size:
        raise ValueError(f"paired samples must have equal lengths, got {a.size} and {b.size}")
    return t_interval(b - a, level)
