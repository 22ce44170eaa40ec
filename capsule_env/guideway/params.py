"""Which guideway an env runs over (:class:`GuidewayParams`), the profile it makes, and
evaluating a profile at positions or times."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capsule_env.common.units import kmh_to_m_s
from capsule_env.common.validation import (
    check_choice,
    check_finite,
    check_nonnegative,
    check_positive,
)
from capsule_env.guideway.deterministic import (
    bump_profile,
    sine_profile,
    step_profile,
    swept_sine_profile,
)
from capsule_env.guideway.random import FRA_CLASS6, FraPsdParams, random_profile

__all__ = [
    "GUIDEWAY_KINDS",
    "GuidewayParams",
    "elevation_at",
    "kmh_to_mps",
    "make_profile",
    "profile_length_m",
    "time_signal",
]

#: Extra samples appended by :func:`make_profile` beyond ``speed * duration``.
_MARGIN_SAMPLES = 4


# --------------------------------------------------------------------------------------------
# Evaluation
# --------------------------------------------------------------------------------------------
def elevation_at(
    profile_m: np.ndarray, spacing_m: float, position_m: np.ndarray | float
) -> np.ndarray:
    """Linearly interpolated elevation of a uniformly sampled profile.

    Same result as ``np.interp(position_m, spacing_m * arange(n), profile_m)``: positions
    before 0 hold the first value and positions beyond the end hold the last one.  The cost is
    O(1) per position (no search), so it is cheap to call every simulation step.

    Parameters
    ----------
    profile_m : numpy.ndarray
        1-D, non-empty elevation samples in m at ``x_j = j * spacing_m``.
    spacing_m : float
        Sample spacing in m, > 0.
    position_m : array_like or float
        Positions along the guideway in m (finite).

    Returns
    -------
    numpy.ndarray
        Elevation in m, same shape as ``position_m`` (0-d for a scalar).
    """
    spacing_m = check_positive("spacing_m", spacing_m)
    z = np.asarray(profile_m, dtype=np.float64)
    if z.ndim != 1 or z.size == 0:
        raise ValueError(f"profile_m must be a non-empty 1-D array, got shape {z.shape}")
    pos = np.asarray(position_m, dtype=np.float64)
    if not np.all(np.isfinite(pos)):
        raise ValueError("position_m must be finite (got NaN or inf)")
    if z.size == 1:
        return np.full(pos.shape, z[0])
    u = np.clip(pos / spacing_m, 0.0, z.size - 1.0)
    i = np.minimum(u.astype(np.intp), z.size - 2)
    frac = u - i
    return z[i] + frac * (z[i + 1] - z[i])


def time_signal(
    profile_m: np.ndarray, spacing_m: float, speed_mps: float, time_s: np.ndarray | float
) -> np.ndarray:
    """Guideway input in time, ``z_g(t) = elevation_at(profile_m, spacing_m, speed_mps * t)``.

    Parameters
    ----------
    profile_m : numpy.ndarray
        1-D elevation samples in m at ``x_j = j * spacing_m``.
    spacing_m : float
        Sample spacing in m, > 0.
    speed_mps : float
        Running speed in m/s, > 0.
    time_s : array_like or float
        Times in s.

    Returns
    -------
    numpy.ndarray
        ``z_g(t)`` in m, same shape as ``time_s``.
    """
    speed_mps = check_positive("speed_mps", speed_mps)
    return elevation_at(profile_m, spacing_m, speed_mps * np.asarray(time_s, dtype=np.float64))


def kmh_to_mps(speed_kmh: float) -> float:
    """Convert a speed from km/h to m/s (``/ 3.6``); e.g. 810 km/h -> 225 m/s."""
    return kmh_to_m_s(check_finite("speed_kmh", speed_kmh))


# --------------------------------------------------------------------------------------------
# Guideway choice used by the environment
# --------------------------------------------------------------------------------------------
GUIDEWAY_KINDS = ("random", "sine", "swept_sine", "bump", "step")


@dataclass(frozen=True)
class GuidewayParams:
    """Which guideway profile to run over, and its parameters.

    [reconstructed] All defaults (random FRA class-6 profile scaled to 8 mm peak, 810 km/h,
    0.25 m spacing, 1.3 Hz sine, 0.5-10 Hz sweep, 10 m bump at 50 m, 1 m step ramp) are
    documented, overridable defaults.

    Parameters
    ----------
    kind : str
        One of :data:`GUIDEWAY_KINDS`.
    peak_m : float or None
        m.  ``random``: scale to this peak, None = unscaled (physical PSD level);
        ``sine`` / ``swept_sine``: amplitude; ``bump`` / ``step``: height.  > 0; None is only
        accepted for ``random``.
    speed_kmh : float
        Running speed in km/h, > 0 (810 km/h = 225 m/s).
    spacing_m : float
        Profile sample spacing in m, > 0 (for ``random`` also <= ``min_wavelength_m / 4``).
    frequency_hz : float
        ``sine`` frequency in Hz, > 0.
    start_hz, stop_hz : float
        ``swept_sine`` start / stop frequencies in Hz, > 0.
    min_wavelength_m, max_wavelength_m : float
        ``random`` wavelength band in m, ``0 < min < max``.
    bump_length_m : float
        ``bump`` base length in m, > 0.
    position_m : float
        ``bump`` / ``step`` start position in m, >= 0.
    psd : FraPsdParams
        ``random`` PSD coefficients.
    ramp_length_m : float
        ``step`` half-cosine ramp length in m, >= 0 (0 = sharp step).
    """

    kind: str = "random"
    peak_m: float | None = 0.008
    speed_kmh: float = 810.0
    spacing_m: float = 0.25
    frequency_hz: float = 1.3
    start_hz: float = 0.5
    stop_hz: float = 10.0
    min_wavelength_m: float = 2.0
    max_wavelength_m: float = 500.0
    bump_length_m: float = 10.0
    position_m: float = 50.0
    psd: FraPsdParams = FRA_CLASS6
    ramp_length_m: float = 1.0

    def __post_init__(self) -> None:
        check_choice("guideway kind", self.kind, GUIDEWAY_KINDS)
        if self.peak_m is None:
            if self.kind != "random":
                raise ValueError(
                    f"peak_m must be a number > 0 for guideway kind {self.kind!r} "
                    "(None = unscaled is only accepted for 'random')"
                )
        else:
            check_positive("peak_m", self.peak_m)
        check_positive("speed_kmh", self.speed_kmh)
        check_positive("spacing_m", self.spacing_m)
        check_positive("frequency_hz", self.frequency_hz)
        check_positive("start_hz", self.start_hz)
        check_positive("stop_hz", self.stop_hz)
        check_positive("min_wavelength_m", self.min_wavelength_m)
        check_positive("max_wavelength_m", self.max_wavelength_m)
        if self.min_wavelength_m >= self.max_wavelength_m:
            raise ValueError(
                f"min_wavelength_m must be < max_wavelength_m, got {self.min_wavelength_m!r} "
                f">= {self.max_wavelength_m!r}"
            )
        if self.kind == "random" and self.spacing_m > self.min_wavelength_m / 4.0:
            raise ValueError(
                f"spacing_m must be in (0, min_wavelength_m / 4] = "
                f"(0, {self.min_wavelength_m / 4.0}], got {self.spacing_m!r}"
            )
        check_positive("bump_length_m", self.bump_length_m)
        check_nonnegative("position_m", self.position_m)
        check_nonnegative("ramp_length_m", self.ramp_length_m)
        if not isinstance(self.psd, FraPsdParams):
            raise ValueError(f"psd must be a FraPsdParams, got {type(self.psd).__name__}")

    @property
    def speed_mps(self) -> float:
        """Running speed in m/s."""
        return kmh_to_mps(self.speed_kmh)


def profile_length_m(params: GuidewayParams, duration_s: float) -> float:
    """The length (m) :func:`make_profile` samples for ``duration_s``: ``speed_mps *
    duration_s`` plus a margin of ``_MARGIN_SAMPLES`` samples."""
    return params.speed_mps * check_positive("duration_s", duration_s) + (
        _MARGIN_SAMPLES * params.spacing_m
    )


def make_profile(
    params: GuidewayParams, duration_s: float, seed: int | None = 0, *, extend_m: float = 0.0
) -> np.ndarray:
    """Sampled profile (m, spacing ``params.spacing_m``) long enough for ``duration_s``.

    The length is ``speed_mps * duration_s`` plus a few samples of margin
    (:func:`profile_length_m`), so :func:`elevation_at` / :func:`time_signal` never run off
    the end for ``0 <= t <= duration_s``.  A swept sine sweeps from ``start_hz`` at t = 0 to
    ``stop_hz`` at ``t = duration_s``.

    Parameters
    ----------
    params : GuidewayParams
        Guideway choice.
    duration_s : float
        Run duration in s, > 0.
    seed : int or None, optional
        Seed for the ``random`` kind (ignored otherwise).  Default 0.
    extend_m : float, optional
        The profile continued this far beyond that length (m, >= 0; default 0), as the
        guideway itself continues: a sine its period, a swept sine its chirp at the same rate,
        a bump or a step its flat end, a random profile its periodic synthesis (what a guideway
        preview looks at past the end of a run).  The samples before are those without it,
        bit for bit.

    Returns
    -------
    numpy.ndarray
        Elevation samples in m at ``x_j = j * params.spacing_m``.

    Raises
    ------
    ValueError
        If ``duration_s`` is not > 0, ``extend_m`` < 0, or if a bump / step position lies
        beyond the profile.
    """
    if not isinstance(params, GuidewayParams):
        raise ValueError(f"params must be a GuidewayParams, got {type(params).__name__}")
    duration_s = check_positive("duration_s", duration_s)
    speed = params.speed_mps
    spacing = params.spacing_m
    length = profile_length_m(params, duration_s)
    kind = params.kind
    if kind == "random":
        return random_profile(
            length,
            spacing,
            seed,
            peak_m=params.peak_m,
            min_wavelength_m=params.min_wavelength_m,
            max_wavelength_m=params.max_wavelength_m,
            psd=params.psd,
            extend_m=extend_m,
        )
    if kind == "sine":
        return sine_profile(
            length,
            spacing,
            frequency_hz=params.frequency_hz,
            speed_mps=speed,
            amplitude_m=params.peak_m,
            extend_m=extend_m,
        )
    if kind == "swept_sine":
        return swept_sine_profile(
            length,
            spacing,
            start_hz=params.start_hz,
            stop_hz=params.stop_hz,
            speed_mps=speed,
            amplitude_m=params.peak_m,
            sweep_duration_s=duration_s,
            extend_m=extend_m,
        )
    if kind == "bump":
        return bump_profile(
            length,
            spacing,
            height_m=params.peak_m,
            bump_length_m=params.bump_length_m,
            position_m=params.position_m,
            extend_m=extend_m,
        )
    # kind == "step" (validated in GuidewayParams)
    return step_profile(
        length,
        spacing,
        height_m=params.peak_m,
        position_m=params.position_m,
        ramp_length_m=params.ramp_length_m,
        extend_m=extend_m,
    )
