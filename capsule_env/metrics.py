"""Ride-quality and control metrics (pure numpy functions, no Gym import).

- :func:`amplitude_spectrum`, :func:`band_peak` and :func:`vibration_reduction_effect`: the
  paper's eq. 16 (docs/model.md 10), ``VRE_k = (P_passive,k - P_control,k) / P_passive,k * 100 %``
  with ``P`` the peak of the single-sided amplitude spectrum of a displacement inside mode
  band ``k``.
- :func:`wk_weighting` and :func:`wk_weighted_rms`: ISO 2631-1:1997 frequency weighting Wk
  (vertical whole-body vibration, seated/standing), applied exactly in the frequency domain.
- :func:`rms`, :func:`coil_power_w`, :func:`force_tracking_error`.
"""

from __future__ import annotations

import numpy as np

from capsule_env._validation import check_positive

__all__ = [
    "DEFAULT_BANDS_HZ",
    "amplitude_spectrum",
    "band_peak",
    "vibration_reduction_effect",
    "wk_weighting",
    "wk_weighted_rms",
    "rms",
    "coil_power_w",
    "force_tracking_error",
]

#: Mode bands (Hz) of the default plant (docs/model.md 10): first (body) and second (bogie) mode.
DEFAULT_BANDS_HZ = {"mode1": (1.0, 3.0), "mode2": (4.5, 7.0)}
#: Coil resistance for the coil power (ohm) [reconstructed: typical of large MR dampers].
DEFAULT_COIL_RESISTANCE_OHM = 5.0


def amplitude_spectrum(signal: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided amplitude spectrum of a real signal (mean removed, rectangular window).

    A sine of amplitude ``A`` at a bin frequency shows as ``A`` at that bin. Returns
    ``(frequencies_hz, amplitudes)``; the last axis is time, leading axes are kept.
    """
    dt_s = check_positive("dt_s", dt_s)
    x = np.asarray(signal, dtype=float)
    x = x - x.mean(axis=-1, keepdims=True)
    n = x.shape[-1]
    spectrum = np.abs(np.fft.rfft(x, axis=-1)) * (2.0 / n)
    spectrum[..., 0] /= 2.0
    if n % 2 == 0:
        spectrum[..., -1] /= 2.0
    return np.fft.rfftfreq(n, dt_s), spectrum


def band_peak(
    frequencies_hz: np.ndarray, amplitudes: np.ndarray, band_hz: tuple[float, float]
) -> np.ndarray:
    """Largest amplitude with ``band[0] <= f <= band[1]`` (over the last axis)."""
    lo, hi = band_hz
    inside = (frequencies_hz >= lo) & (frequencies_hz <= hi)
    if not inside.any():
        raise ValueError(f"band_hz {band_hz} contains no spectral line (resolution too coarse)")
    return np.max(np.asarray(amplitudes)[..., inside], axis=-1)


def vibration_reduction_effect(
    passive_signal: np.ndarray,
    controlled_signal: np.ndarray,
    dt_s: float,
    band_hz: tuple[float, float],
) -> np.ndarray:
    """Paper eq. 16: ``(P_passive - P_control) / P_passive * 100`` in a mode band (per cent).

    Both signals must come from the same guideway realisation.
    """
    f, a_pass = amplitude_spectrum(passive_signal, dt_s)
    _, a_ctrl = amplitude_spectrum(controlled_signal, dt_s)
    p_pass = band_peak(f, a_pass, band_hz)
    p_ctrl = band_peak(f, a_ctrl, band_hz)
    return (p_pass - p_ctrl) / p_pass * 100.0


def _second_order(s: np.ndarray, f_hz: float, q: float) -> np.ndarray:
    w = 2.0 * np.pi * f_hz
    return s**2 + (w / q) * s + w**2


def wk_weighting(frequencies_hz: np.ndarray) -> np.ndarray:
    """Complex ISO 2631-1 Wk weighting at the given frequencies (Annex A, all four factors).

    Band limiting: high-pass f1 = 0.4 Hz and low-pass f2 = 100 Hz (Q = 1/sqrt 2);
    acceleration-velocity transition f3 = f4 = 12.5 Hz, Q4 = 0.63; upward step
    f5 = 2.37 Hz, Q5 = 0.91, f6 = 3.35 Hz, Q6 = 0.91.
    """
    f = np.asarray(frequencies_hz, dtype=float)
    s = 2j * np.pi * f
    w2, w3, w4 = (2.0 * np.pi * x for x in (100.0, 12.5, 12.5))
    q = 1.0 / np.sqrt(2.0)
    high_pass = s**2 / _second_order(s, 0.4, q)
    low_pass = w2**2 / _second_order(s, 100.0, q)
    transition = (1.0 + s / w3) / (1.0 + s / (0.63 * w4) + (s / w4) ** 2)
    step = _second_order(s, 2.37, 0.91) / _second_order(s, 3.35, 0.91)
    return high_pass * low_pass * transition * step


def wk_weighted_rms(acceleration_m_s2: np.ndarray, dt_s: float) -> np.ndarray:
    """RMS of the Wk-weighted acceleration (m/s^2), weighting applied per FFT line (exact for
    the analog filter up to the Nyquist frequency; periodic extension of the record)."""
    dt_s = check_positive("dt_s", dt_s)
    a = np.asarray(acceleration_m_s2, dtype=float)
    n = a.shape[-1]
    spectrum = np.fft.rfft(a - a.mean(axis=-1, keepdims=True), axis=-1)
    weighted = spectrum * np.abs(wk_weighting(np.fft.rfftfreq(n, dt_s)))
    return rms(np.fft.irfft(weighted, n=n, axis=-1))


def rms(signal: np.ndarray) -> np.ndarray:
    """Root mean square over the last axis."""
    x = np.asarray(signal, dtype=float)
    return np.sqrt(np.mean(x**2, axis=-1))


def coil_power_w(
    current_a: np.ndarray, resistance_ohm: float = DEFAULT_COIL_RESISTANCE_OHM
) -> np.ndarray:
    """Mean electrical coil power ``R <i^2>`` (W) over the last axis."""
    return check_positive("resistance_ohm", resistance_ohm) * np.mean(
        np.asarray(current_a, float) ** 2, axis=-1
    )


def force_tracking_error(desired_force_n: np.ndarray, delivered_force_n: np.ndarray) -> np.ndarray:
    """Relative RMS error of the delivered damper force against the request,
    ``rms(F - F_d) / rms(F_d)``, over the samples where a force was requested (F_d != 0)."""
    fd = np.asarray(desired_force_n, float)
    f = np.asarray(delivered_force_n, float)
    mask = fd != 0.0
    num = np.sqrt(np.sum(np.where(mask, (f - fd) ** 2, 0.0), axis=-1))
    den = np.sqrt(np.sum(np.where(mask, fd**2, 0.0), axis=-1))
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
