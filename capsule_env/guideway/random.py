"""Random guideway profiles with the FRA spectrum, by the spectral (random-phase) method."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from capsule_env.common.validation import check_nonnegative, check_positive
from capsule_env.guideway.sampling import n_samples

__all__ = ["FRA_CLASS6", "FraPsdParams", "fft_length", "fra_psd", "random_profile"]

#: The FFT period of :func:`random_profile` is at least this many longest wavelengths, so that
#: the frequency grid ``dW = 2 pi / L`` is fine enough for the rectangle sum of the PSD to match
#: its integral closely even for short profiles (with a period of only 2 longest wavelengths the
#: low-wavenumber end of the band would be resolved by a handful of bins).
_MIN_PERIOD_IN_MAX_WAVELENGTHS = 20.0


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
    n = n_samples(length_m, spacing_m)
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
    extend_m: float = 0.0,
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
    extend_m : float, optional
        The profile continued this far beyond ``length_m`` (m, >= 0; default 0): the same
        synthesis, periodic with the FFT period ``L``, with the ``peak_m`` scale of the first
        ``n`` samples; those ``n`` samples are the ones without it, bit for bit.

    Returns
    -------
    numpy.ndarray
        Elevation ``z[j]`` in m at ``x_j = j * spacing_m``, ``j = 0..n-1``,
        ``n = int(round(length_m / spacing_m)) + 1`` (more with ``extend_m``).

    Raises
    ------
    ValueError
        On an invalid parameter (the message names it and its accepted range).
    """
    n = n_samples(length_m, spacing_m)
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
    extend_m = check_nonnegative("extend_m", extend_m)

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
    z = np.fft.irfft(spectrum, n=n_fft)
    if extend_m > 0.0:  # the periodic synthesis continued (np.resize repeats the period)
        z = np.resize(z, n_samples(float(length_m) + extend_m, spacing_m))
    else:
        z = z[:n]

    if peak_m is not None:
        z *= peak_m / np.max(np.abs(z[:n]))
    return np.ascontiguousarray(z)
