"""Guideway vertical irregularity ``z_g`` (MODEL.md section 3).

The capsule rides over a guideway whose vertical irregularity ``z_g(x)`` (m) excites the
1/4-car suspension through ``z_g(t) = profile(V t)``.  This module builds such profiles as
uniformly sampled arrays ``z[j]`` at ``x_j = j * spacing_m`` (m) and evaluates them at arbitrary
positions or times.

Available profiles
------------------
* ``random`` (default): a random vertical profile whose one-sided spatial PSD is the FRA
  (US Federal Railroad Administration) shape

  .. math:: S(W) = k A_v W_c^2 / (W^2 (W^2 + W_c^2))

  with ``W`` in rad/m and ``S`` in m^2/(rad/m), synthesised by the spectral (random-phase)
  method over wavelengths 2-500 m and scaled so that ``max |z_g| = 8 mm``.
* ``sine``: a pure sine of a given temporal frequency at the running speed.
* ``swept_sine``: a linear chirp in time, for frequency responses.
* ``bump``: an isolated (1 - cos) bump.
* ``step``: a smoothed (half-cosine ramp) step.

[reconstructed] Every numerical value here -- the FRA class-6 coefficients, the 2-500 m band,
the 8 mm peak, the 810 km/h (225 m/s) speed, the sine / sweep frequencies and the bump / step
geometry -- is a documented, overridable default reconstructed for this project, not a value
taken from a measured guideway.

The module is pure numpy (no gymnasium import).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from capsule_env._validation import (
    check_choice,
    check_finite,
    check_nonnegative,
    check_positive,
)

__all__ = [
    "FRA_CLASS6",
    "GUIDEWAY_KINDS",
    "FraPsdParams",
    "GuidewayParams",
    "bump_profile",
    "elevation_at",
    "fft_length",
    "fra_psd",
    "kmh_to_mps",
    "make_profile",
    "random_profile",
    "sine_profile",
    "step_profile",
    "swept_sine_profile",
    "time_signal",
]

#: The FFT period of :func:`random_profile` is at least this many longest wavelengths, so that
#: the frequency grid ``dW = 2 pi / L`` is fine enough for the rectangle sum of the PSD to match
#: its integral closely even for short profiles (with a period of only 2 longest wavelengths the
#: low-wavenumber end of the band would be resolved by a handful of bins).
_MIN_PERIOD_IN_MAX_WAVELENGTHS = 20.0

#: Extra samples appended by :func:`make_profile` beyond ``speed * duration``.
_MARGIN_SAMPLES = 4

#: Minimum number of samples per spatial wavelength of the sine / swept-sine profiles.
_MIN_SAMPLES_PER_WAVELENGTH = 4.0


# --------------------------------------------------------------------------------------------
# FRA power spectral density
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FraPsdParams:
    """Coefficients of the FRA vertical-irregularity PSD.

    ``S(W) = k * A_v * W_c**2 / (W**2 * (W**2 + W_c**2))`` in m^2/(rad/m), ``W`` in rad/m.

    [reconstructed] The defaults are the FRA class-6 values (the best US track class); they
    are a documented, overridable default, not a measurement of a Hyperloop guideway.

    Parameters
    ----------
    k : float
        Dimensionless scale factor (FRA convention, 0.25), > 0.
    roughness_m_rad : float
        Roughness coefficient ``A_v`` in m rad, > 0 (class 6: 3.39e-6).
    cutoff_rad_per_m : float
        Cut-off wavenumber ``W_c`` in rad/m, > 0 (class 6: 0.8245).
    """

    k: float = 0.25
    roughness_m_rad: float = 3.39e-6
    cutoff_rad_per_m: float = 0.8245

    def __post_init__(self) -> None:
        check_positive("k", self.k)
        check_positive("roughness_m_rad", self.roughness_m_rad)
        check_positive("cutoff_rad_per_m", self.cutoff_rad_per_m)


#: FRA class-6 PSD coefficients ([reconstructed] default).
FRA_CLASS6 = FraPsdParams()


def fra_psd(
    wavenumber_rad_per_m: np.ndarray | float, params: FraPsdParams = FRA_CLASS6
) -> np.ndarray:
    """One-sided FRA spatial PSD of the vertical irregularity.

    Parameters
    ----------
    wavenumber_rad_per_m : array_like or float
        Spatial angular frequency ``W`` in rad/m; every value must be finite and > 0.
    params : FraPsdParams, optional
        PSD coefficients, default :data:`FRA_CLASS6` ([reconstructed]).

    Returns
    -------
    numpy.ndarray
        ``S(W)`` in m^2/(rad/m), same shape as the input (0-d for a scalar).

    Raises
    ------
    ValueError
        If any wavenumber is not finite or not > 0.
    """
    w = np.asarray(wavenumber_rad_per_m, dtype=np.float64)
    if not np.all(np.isfinite(w)):
        raise ValueError("wavenumber_rad_per_m must be finite (got NaN or inf)")
    if w.size and w.min() <= 0.0:
        raise ValueError(f"wavenumber_rad_per_m must be > 0, got minimum {w.min():.6g}")
    wc2 = params.cutoff_rad_per_m**2
    w2 = w * w
    return params.k * params.roughness_m_rad * wc2 / (w2 * (w2 + wc2))


# --------------------------------------------------------------------------------------------
# Profiles
# --------------------------------------------------------------------------------------------
def _n_samples(length_m: float, spacing_m: float) -> int:
    """Number of samples ``int(round(length_m / spacing_m)) + 1`` after validating both."""
    length_m = check_positive("length_m", length_m)
    spacing_m = check_positive("spacing_m", spacing_m)
    return int(round(length_m / spacing_m)) + 1


def _positions(length_m: float, spacing_m: float) -> np.ndarray:
    """Sample positions ``x_j = j * spacing_m`` (m), ``j = 0..n-1``."""
    return np.arange(_n_samples(length_m, spacing_m), dtype=np.float64) * float(spacing_m)


def _fast_fft_length(minimum: int) -> int:
    """Smallest ``2**a * 3**b * 5**c >= minimum`` (an efficient FFT length)."""
    minimum = max(1, int(minimum))
    best = 1 << (minimum - 1).bit_length()  # power of two >= minimum
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            candidate = p35
            while candidate < minimum:
                candidate <<= 1
            best = min(best, candidate)
            p35 *= 3
        p5 *= 5
    return best


def fft_length(length_m: float, spacing_m: float, max_wavelength_m: float) -> int:
    """FFT length :func:`random_profile` uses for a profile of ``length_m``: at least its
    samples, and a period of at least 20 longest wavelengths (``_MIN_PERIOD_IN_MAX_WAVELENGTHS``)."""
    n = _n_samples(length_m, spacing_m)
    min_period = max(float(length_m), _MIN_PERIOD_IN_MAX_WAVELENGTHS * max_wavelength_m)
    return _fast_fft_length(max(n, math.ceil(min_period / spacing_m - 1e-9)))


def random_profile(
    length_m: float,
    spacing_m: float = 0.25,
    seed: int | None = 0,
    *,
    peak_m: float | None = 0.008,
    min_wavelength_m: float = 2.0,
    max_wavelength_m: float = 500.0,
    psd: FraPsdParams = FRA_CLASS6,
) -> np.ndarray:
    """Random vertical guideway profile with the FRA PSD (spectral / random-phase method).

    ``z(x) = sum_k a_k cos(W_k x + phi_k)`` with ``W_k = 2 pi k / L`` on the band
    ``[2 pi / max_wavelength_m, 2 pi / min_wavelength_m]``, ``a_k = sqrt(2 S(W_k) dW)``,
    ``dW = 2 pi / L`` and phases ``phi_k`` uniform on ``[0, 2 pi)`` drawn from
    ``np.random.default_rng(seed)``; it is evaluated with one inverse real FFT.  The FFT period
    ``L`` is at least ``max(length_m, 20 * max_wavelength_m)`` (so at least the
    ``max(length_m, 2 * max_wavelength_m)`` needed to resolve the band).  Over one period the
    unscaled profile has zero mean and variance ``sum_k S(W_k) dW``, the rectangle-rule value of
    the integral of ``S`` over the band.  Then, unless ``peak_m`` is None, the profile is scaled
    so that ``max |z| == peak_m``.

    [reconstructed] The defaults (FRA class 6, 2-500 m band, 8 mm peak) are documented,
    overridable defaults.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float, optional
        Sample spacing in m, > 0 and <= ``min_wavelength_m / 4``; default 0.25 m.
    seed : int or None, optional
        Seed of ``np.random.default_rng``; the same seed gives the identical array.
        None draws fresh entropy.  Default 0.
    peak_m : float or None, optional
        Scale so that ``max |z| == peak_m`` (m, > 0); None keeps the physical PSD level.
        Default 0.008 m.
    min_wavelength_m, max_wavelength_m : float, optional
        Wavelength band in m, ``0 < min < max``; default 2 m and 500 m.
    psd : FraPsdParams, optional
        PSD coefficients, default :data:`FRA_CLASS6`.

    Returns
    -------
    numpy.ndarray
        Elevation ``z[j]`` in m at ``x_j = j * spacing_m``, ``j = 0..n-1``,
        ``n = int(round(length_m / spacing_m)) + 1``.

    Raises
    ------
    ValueError
        On an invalid parameter (the message names it and its accepted range).
    """
    n = _n_samples(length_m, spacing_m)
    spacing_m = float(spacing_m)
    min_wavelength_m = check_positive("min_wavelength_m", min_wavelength_m)
    max_wavelength_m = check_positive("max_wavelength_m", max_wavelength_m)
    if min_wavelength_m >= max_wavelength_m:
        raise ValueError(
            f"min_wavelength_m must be < max_wavelength_m, got {min_wavelength_m!r} "
            f">= {max_wavelength_m!r}"
        )
    if spacing_m > min_wavelength_m / 4.0:
        raise ValueError(
            f"spacing_m must be in (0, min_wavelength_m / 4] = (0, {min_wavelength_m / 4.0}] "
            f"so that the shortest wavelength is sampled, got {spacing_m!r}"
        )
    if peak_m is not None:
        peak_m = check_positive("peak_m", peak_m)
    if not isinstance(psd, FraPsdParams):
        raise ValueError(f"psd must be a FraPsdParams, got {type(psd).__name__}")

    n_fft = fft_length(length_m, spacing_m, max_wavelength_m)
    period = n_fft * spacing_m
    d_w = 2.0 * math.pi / period

    # Bins k with W_k in the band: period / max_wl <= k <= period / min_wl (tolerant to rounding).
    k_lo = max(1, math.ceil(period / max_wavelength_m - 1e-9))
    k_hi = min((n_fft - 1) // 2, math.floor(period / min_wavelength_m + 1e-9))  # below Nyquist
    if k_hi < k_lo:
        raise ValueError(
            "min_wavelength_m and max_wavelength_m define a band with no frequency bin; "
            f"widen it (got {min_wavelength_m!r}, {max_wavelength_m!r})"
        )
    k = np.arange(k_lo, k_hi + 1)
    amplitude = np.sqrt(2.0 * fra_psd(k * d_w, psd) * d_w)
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0.0, 2.0 * np.pi, size=k.size)

    # irfft(X)[j] = (1/N) [X_0 + 2 sum_k Re(X_k exp(2 pi i k j / N))] for k below Nyquist, so
    # X_k = (N / 2) a_k exp(i phi_k) gives sum_k a_k cos(W_k x_j + phi_k).
    spectrum = np.zeros(n_fft // 2 + 1, dtype=np.complex128)
    spectrum[k] = (0.5 * n_fft) * amplitude * np.exp(1j * phase)
    z = np.fft.irfft(spectrum, n=n_fft)[:n]

    if peak_m is not None:
        z *= peak_m / np.max(np.abs(z))
    return np.ascontiguousarray(z)


def _check_sampled(name: str, highest_hz: float, speed_mps: float, spacing_m: float) -> None:
    """Raise unless the shortest spatial wavelength ``speed / f`` has >= 4 samples."""
    wavelength = speed_mps / highest_hz
    if spacing_m > wavelength / _MIN_SAMPLES_PER_WAVELENGTH:
        raise ValueError(
            f"{name} too high for spacing_m: the spatial wavelength speed_mps / {name} = "
            f"{wavelength:.6g} m needs spacing_m <= {wavelength / _MIN_SAMPLES_PER_WAVELENGTH:.6g}"
            f" m, got {spacing_m!r}"
        )


def sine_profile(
    length_m: float,
    spacing_m: float,
    *,
    frequency_hz: float,
    speed_mps: float,
    amplitude_m: float,
) -> np.ndarray:
    """Sinusoidal profile ``z(x) = amplitude_m * sin(2 pi frequency_hz x / speed_mps)``.

    Run at ``speed_mps`` it gives ``z_g(t) = amplitude_m * sin(2 pi frequency_hz t)``.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0, with at least 4 samples per wavelength
        ``speed_mps / frequency_hz``.
    frequency_hz : float
        Temporal frequency at ``speed_mps`` in Hz, > 0.
    speed_mps : float
        Running speed in m/s, > 0.
    amplitude_m : float
        Amplitude in m, >= 0.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    x = _positions(length_m, spacing_m)
    frequency_hz = check_positive("frequency_hz", frequency_hz)
    speed_mps = check_positive("speed_mps", speed_mps)
    amplitude_m = check_nonnegative("amplitude_m", amplitude_m)
    _check_sampled("frequency_hz", frequency_hz, speed_mps, float(spacing_m))
    return amplitude_m * np.sin(2.0 * np.pi * frequency_hz * x / speed_mps)


def swept_sine_profile(
    length_m: float,
    spacing_m: float,
    *,
    start_hz: float,
    stop_hz: float,
    speed_mps: float,
    amplitude_m: float,
    sweep_duration_s: float | None = None,
) -> np.ndarray:
    """Linear-in-time swept sine (chirp) expressed in space.

    ``z_g(t) = A sin(2 pi (f0 t + (f1 - f0) t**2 / (2 T)))`` with ``t = x / speed_mps``, so the
    instantaneous frequency rises (or falls) linearly from ``f0 = start_hz`` at ``t = 0`` to
    ``f1 = stop_hz`` at ``t = T``.  ``T`` defaults to the run duration ``length_m / speed_mps``;
    beyond ``T`` (if ``sweep_duration_s`` is shorter) the chirp continues at the same rate.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0, with at least 4 samples per shortest wavelength.
    start_hz, stop_hz : float
        Start and stop frequencies in Hz, > 0 (a downward sweep is allowed).
    speed_mps : float
        Running speed in m/s, > 0.
    amplitude_m : float
        Amplitude in m, >= 0.
    sweep_duration_s : float or None, optional
        Sweep duration ``T`` in s, > 0; None (default) uses ``length_m / speed_mps``.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    x = _positions(length_m, spacing_m)
    start_hz = check_positive("start_hz", start_hz)
    stop_hz = check_positive("stop_hz", stop_hz)
    speed_mps = check_positive("speed_mps", speed_mps)
    amplitude_m = check_nonnegative("amplitude_m", amplitude_m)
    if sweep_duration_s is None:
        sweep_duration_s = float(length_m) / speed_mps
    sweep_duration_s = check_positive("sweep_duration_s", sweep_duration_s)
    t = x / speed_mps
    highest_hz = max(start_hz, start_hz + (stop_hz - start_hz) * t[-1] / sweep_duration_s)
    name = "stop_hz" if stop_hz >= start_hz else "start_hz"
    _check_sampled(name, highest_hz, speed_mps, float(spacing_m))
    phase = 2.0 * np.pi * (start_hz * t + (stop_hz - start_hz) * t * t / (2.0 * sweep_duration_s))
    return amplitude_m * np.sin(phase)


def bump_profile(
    length_m: float,
    spacing_m: float,
    *,
    height_m: float = 0.008,
    bump_length_m: float = 10.0,
    position_m: float = 50.0,
) -> np.ndarray:
    """Isolated (1 - cos) bump on an otherwise flat guideway.

    ``z = height_m / 2 * (1 - cos(2 pi (x - position_m) / bump_length_m))`` for
    ``position_m <= x <= position_m + bump_length_m``, 0 elsewhere.

    [reconstructed] Defaults (8 mm high, 10 m long, starting at 50 m) are documented,
    overridable defaults.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0.
    height_m : float, optional
        Bump height in m (finite; negative gives a dip).  Default 0.008 m.
    bump_length_m : float, optional
        Bump base length in m, > 0.  Default 10 m.
    position_m : float, optional
        Start of the bump in m, in ``[0, length_m]``.  Default 50 m.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    x = _positions(length_m, spacing_m)
    height_m = check_finite("height_m", height_m)
    bump_length_m = check_positive("bump_length_m", bump_length_m)
    position_m = _check_position(position_m, length_m)
    u = (x - position_m) / bump_length_m
    inside = (u >= 0.0) & (u <= 1.0)
    return np.where(inside, 0.5 * height_m * (1.0 - np.cos(2.0 * np.pi * u)), 0.0)


def _check_position(position_m: float, length_m: float) -> float:
    """``position_m`` must lie on the profile, else the feature would silently be missing."""
    position_m = check_finite("position_m", position_m)
    if not 0.0 <= position_m <= float(length_m):
        raise ValueError(
            f"position_m must be in [0, length_m] = [0, {float(length_m)}], got {position_m!r}"
        )
    return position_m


def step_profile(
    length_m: float,
    spacing_m: float,
    *,
    height_m: float = 0.008,
    position_m: float = 50.0,
    ramp_length_m: float = 1.0,
) -> np.ndarray:
    """Smoothed step: 0 before ``position_m``, ``height_m`` after the ramp.

    On ``position_m <= x <= position_m + ramp_length_m`` the profile is the half-cosine ramp
    ``height_m / 2 * (1 - cos(pi (x - position_m) / ramp_length_m))``; ``ramp_length_m = 0``
    gives a sharp step (``z = height_m`` for ``x >= position_m``).

    [reconstructed] Defaults (8 mm, at 50 m, 1 m ramp) are documented, overridable defaults.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0.
    height_m : float, optional
        Step height in m (finite; negative gives a step down).  Default 0.008 m.
    position_m : float, optional
        Start of the step in m, in ``[0, length_m]``.  Default 50 m.
    ramp_length_m : float, optional
        Ramp length in m, >= 0.  Default 1 m.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    x = _positions(length_m, spacing_m)
    height_m = check_finite("height_m", height_m)
    position_m = _check_position(position_m, length_m)
    ramp_length_m = check_nonnegative("ramp_length_m", ramp_length_m)
    if ramp_length_m == 0.0:
        return np.where(x >= position_m, height_m, 0.0)
    u = np.clip((x - position_m) / ramp_length_m, 0.0, 1.0)
    return 0.5 * height_m * (1.0 - np.cos(np.pi * u))


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
    return check_finite("speed_kmh", speed_kmh) / 3.6


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


def make_profile(params: GuidewayParams, duration_s: float, seed: int | None = 0) -> np.ndarray:
    """Sampled profile (m, spacing ``params.spacing_m``) long enough for ``duration_s``.

    The length is ``speed_mps * duration_s`` plus a few samples of margin, so
    :func:`elevation_at` / :func:`time_signal` never run off the end for ``0 <= t <=
    duration_s``.  A swept sine sweeps from ``start_hz`` at t = 0 to ``stop_hz`` at
    ``t = duration_s``.

    Parameters
    ----------
    params : GuidewayParams
        Guideway choice.
    duration_s : float
        Run duration in s, > 0.
    seed : int or None, optional
        Seed for the ``random`` kind (ignored otherwise).  Default 0.

    Returns
    -------
    numpy.ndarray
        Elevation samples in m at ``x_j = j * params.spacing_m``.

    Raises
    ------
    ValueError
        If ``duration_s`` is not > 0, or if a bump / step position lies beyond the profile.
    """
    if not isinstance(params, GuidewayParams):
        raise ValueError(f"params must be a GuidewayParams, got {type(params).__name__}")
    duration_s = check_positive("duration_s", duration_s)
    speed = params.speed_mps
    spacing = params.spacing_m
    length = speed * duration_s + _MARGIN_SAMPLES * spacing
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
        )
    if kind == "sine":
        return sine_profile(
            length,
            spacing,
            frequency_hz=params.frequency_hz,
            speed_mps=speed,
            amplitude_m=params.peak_m,
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
        )
    if kind == "bump":
        return bump_profile(
            length,
            spacing,
            height_m=params.peak_m,
            bump_length_m=params.bump_length_m,
            position_m=params.position_m,
        )
    # kind == "step" (validated in GuidewayParams)
    return step_profile(
        length,
        spacing,
        height_m=params.peak_m,
        position_m=params.position_m,
        ramp_length_m=params.ramp_length_m,
    )
