"""Ride-quality and control metrics (pure numpy functions, no Gym import).

- :func:`amplitude_spectrum`, :func:`band_peak` and :func:`vibration_reduction_effect`: the
  paper's eq. 16 (docs/model.md 10), ``VRE_k = (P_passive,k - P_control,k) / P_passive,k * 100 %``
  with ``P`` the peak of the single-sided amplitude spectrum of a displacement inside mode
  band ``k``.
- :func:`wk_weighting` and :func:`wk_weighted_rms`: ISO 2631-1:1997 frequency weighting Wk
  (vertical whole-body vibration, seated/standing), applied exactly in the frequency domain.
- :func:`wb_weighting` and :func:`mean_comfort_vertical`: rail ride comfort after EN 12299
  (mean comfort, standard method), vertical term only: Wb weighting, 5 s RMS values, their
  95th percentile and ``N = 6 a_ZP95``.
- :func:`sperling_weighting` and :func:`sperling_index`: Sperling's ride index Wz, vertical.
- :func:`rms`, :func:`coil_power_w`, :func:`force_tracking_error`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.common.validation import check_positive

__all__ = [
    "DEFAULT_BANDS_HZ",
    "amplitude_spectrum",
    "wk_analog_zpk",
    "wk_filter_sos",
    "band_peak",
    "vibration_reduction_effect",
    "wk_weighting",
    "wk_weighted_rms",
    "we_weighting",
    "we_weighted_rms",
    "EN12299_WINDOW_S",
    "wb_weighting",
    "mean_comfort_vertical",
    "SPERLING_BAND_HZ",
    "sperling_weighting",
    "sperling_index",
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
    s = 2j * np.pi * np.asarray(frequencies_hz, dtype=float)
    step = _second_order(s, 2.37, 0.91) / _second_order(s, 3.35, 0.91)
    return _band_limited_transition(s, 12.5) * step


def _band_limited_transition(s: np.ndarray, f_transition_hz: float) -> np.ndarray:
    """ISO 2631-1's band limiting (f1 = 0.4 Hz, f2 = 100 Hz, Q = 1/sqrt 2) times the
    acceleration-velocity transition at f3 = f4 = ``f_transition_hz``, Q4 = 0.63."""
    w2, w3, w4 = (2.0 * np.pi * x for x in (100.0, f_transition_hz, f_transition_hz))
    q = 1.0 / np.sqrt(2.0)
    high_pass = s**2 / _second_order(s, 0.4, q)
    low_pass = w2**2 / _second_order(s, 100.0, q)
    transition = (1.0 + s / w3) / (1.0 + s / (0.63 * w4) + (s / w4) ** 2)
    return high_pass * low_pass * transition


def wk_weighted_rms(acceleration_m_s2: np.ndarray, dt_s: float) -> np.ndarray:
    """RMS of the Wk-weighted acceleration (m/s^2), weighting applied per FFT line (exact for
    the analog filter up to the Nyquist frequency; periodic extension of the record)."""
    return _weighted_rms(acceleration_m_s2, dt_s, wk_weighting)


def _weighted_rms(signal: np.ndarray, dt_s: float, weighting: Any) -> np.ndarray:
    """RMS of ``signal`` weighted per FFT line by ``|weighting(f)|`` (mean removed)."""
    dt_s = check_positive("dt_s", dt_s)
    a = np.asarray(signal, dtype=float)
    n = a.shape[-1]
    spectrum = np.fft.rfft(a - a.mean(axis=-1, keepdims=True), axis=-1)
    weighted = spectrum * np.abs(weighting(np.fft.rfftfreq(n, dt_s)))
    return rms(np.fft.irfft(weighted, n=n, axis=-1))


def we_weighting(frequencies_hz: np.ndarray) -> np.ndarray:
    """Complex ISO 2631-1 We weighting (rotational vibration, Table 3 and Annex A): the band
    limiting of :func:`wk_weighting` (f1 = 0.4 Hz, f2 = 100 Hz, Q = 1/sqrt 2) and the
    acceleration-velocity transition f3 = f4 = 1 Hz, Q4 = 0.63; no upward step."""
    return _band_limited_transition(2j * np.pi * np.asarray(frequencies_hz, dtype=float), 1.0)


def we_weighted_rms(acceleration_rad_s2: np.ndarray, dt_s: float) -> np.ndarray:
    """RMS of the We-weighted angular acceleration (rad/s^2), as :func:`wk_weighted_rms`
    (ISO 2631-1 multiplies it by k = 0.40 for pitch at a seated person's seat surface)."""
    return _weighted_rms(acceleration_rad_s2, dt_s, we_weighting)


def wk_analog_zpk() -> tuple[np.ndarray, np.ndarray, float]:
    """Zeros and poles (rad/s) and gain of the analog Wk filter of :func:`wk_weighting`, for
    :func:`scipy.signal.bilinear_zpk` and the like: ``H(s) = k prod(s - z) / prod(s - p)``."""
    q = 1.0 / np.sqrt(2.0)

    def roots(f_hz: float, quality: float) -> np.ndarray:
        w = 2.0 * np.pi * f_hz
        return np.roots([1.0, w / quality, w * w])

    w2, w3, w4 = (2.0 * np.pi * x for x in (100.0, 12.5, 12.5))
    zeros = np.concatenate([[0.0, 0.0], [-w3], roots(2.37, 0.91)])
    poles = np.concatenate([roots(0.4, q), roots(100.0, q), roots(12.5, 0.63), roots(3.35, 0.91)])
    # high-pass s^2 / (.), low-pass w2^2 / (.), transition (1 + s/w3) w4^2 / (.), step (.) / (.)
    gain = w2**2 * (w4**2 / w3)
    return zeros, poles, float(gain)


def wk_filter_sos(dt_s: float) -> np.ndarray:
    """The Wk weighting as a causal digital filter at the sample interval ``dt_s``: second-order
    sections ``(b0, b1, b2, 1, a1, a2)`` (:func:`scipy.signal.sosfilt` layout), the bilinear
    transform of :func:`wk_analog_zpk`.

    The bilinear transform warps frequency (``f_digital = atan(pi f dt) / (pi dt)``): at 200 Hz
    sampling the gain is within 0.25 % of :func:`wk_weighting` up to 10 Hz and 3.1 % at
    20 Hz, and the 100 Hz low-pass acts near 64 Hz. It is what the env's
    ``reward_acceleration_filter="wk"`` runs per step; :func:`wk_weighted_rms`, exact per FFT
    line, is what the tables report."""
    from scipy.signal import bilinear_zpk, zpk2sos

    dt_s = check_positive("dt_s", dt_s)
    zeros, poles, gain = wk_analog_zpk()
    z, p, k = bilinear_zpk(zeros, poles, gain, fs=1.0 / dt_s)
    return np.ascontiguousarray(zpk2sos(z, p, k))


#: Length of the EN 12299 RMS windows (s).
EN12299_WINDOW_S = 5.0

# Wb realisations: (Q4 of the a-v transition, Q5 and Q6 of the upward step). Shared by both:
# f1 = 0.4 Hz, f2 = 100 Hz (Q1 = Q2 = 1/sqrt 2), f3 = f4 = 16 Hz, f5 = 2.5 Hz, f6 = 4 Hz and
# K = 1.024 with the step written as below (EN 12299 writes it with unit DC gain and K = 0.4;
# 0.4 (f6/f5)^2 = 1.024, the same filter).
_WB_Q = {"en12299": (0.63, 0.8, 0.8), "iso2631-4": (0.55, 0.9, 0.95)}
_WB_GAIN = 1.024

#: Band of the Sperling evaluation (Hz).
SPERLING_BAND_HZ = (0.5, 30.0)


def _record(name: str, value: np.ndarray, min_samples: int) -> np.ndarray:
    """``value`` as a float array with time on the last axis and at least ``min_samples``."""
    x = np.asarray(value, dtype=float)
    if x.ndim == 0 or x.shape[-1] < min_samples:
        got = "a scalar" if x.ndim == 0 else f"{x.shape[-1]} samples"
        raise ValueError(f"{name} needs at least {min_samples} samples on its last axis, got {got}")
    return x


def wb_weighting(frequencies_hz: np.ndarray, standard: str = "en12299") -> np.ndarray:
    """Complex Wb weighting (vertical vibration of rail passengers) at the given frequencies (Hz).

    ``Wb(s) = K H_h(s) H_l(s) H_t(s) H_s(s)`` with ``s = j 2 pi f`` and ``w_i = 2 pi f_i``:

    - band limiting, 2nd-order Butterworth: high-pass ``H_h = s^2 / (s^2 + w1 s/Q1 + w1^2)``,
      f1 = 0.4 Hz, and low-pass ``H_l = w2^2 / (s^2 + w2 s/Q2 + w2^2)``, f2 = 100 Hz,
      Q1 = Q2 = 1/sqrt 2;
    - acceleration-velocity transition ``H_t = (1 + s/w3) / (1 + s/(Q4 w4) + s^2/w4^2)``,
      f3 = f4 = 16 Hz;
    - upward step ``H_s = (s^2 + w5 s/Q5 + w5^2) / (s^2 + w6 s/Q6 + w6^2)``, f5 = 2.5 Hz,
      f6 = 4 Hz;
    - gain K = 1.024.

    ``standard`` picks the realisation (the Q values; all else is shared):

    - ``"en12299"`` (default; EN 12299:2009 / ENV 12299): Q4 = 0.63, Q5 = Q6 = 0.8. EN 12299
      writes the step with unit gain at DC and K = 0.4; ``0.4 (f6/f5)^2 = 1.024``, the same
      filter.
    - ``"iso2631-4"`` (ISO 2631-4:2001 Table A.1, ISO 8041, BS 6841): Q4 = 0.55, Q5 = 0.9,
      Q6 = 0.95.

    Both have ``|Wb|`` near 0.4 from 0.5 to 2 Hz, near 1 from 5 to 10 Hz and fall as 1/f from 16 to
    100 Hz (velocity); they differ by up to about 13 % near 16 Hz and 8 % near 4 Hz.

    Sources [secondary, the standards' texts were not at hand]: ISO values from the ISO 8041
    table reproduced in the Larson Davis HVM200 manual (Table 3.1), checked against the
    published ISO 2631-4 value ``|Wb(100 rad/s)| = 0.8126``; EN 12299 values as implemented by the
    open-source comfpy and pyridy packages, both citing EN 12299:2009.
    """
    if standard not in _WB_Q:
        raise ValueError(f"standard must be one of {sorted(_WB_Q)}, got {standard!r}")
    q4, q5, q6 = _WB_Q[standard]
    f = np.asarray(frequencies_hz, dtype=float)
    s = 2j * np.pi * f
    w2, w3, w4 = (2.0 * np.pi * x for x in (100.0, 16.0, 16.0))
    q = 1.0 / np.sqrt(2.0)
    high_pass = s**2 / _second_order(s, 0.4, q)
    low_pass = w2**2 / _second_order(s, 100.0, q)
    transition = (1.0 + s / w3) / (1.0 + s / (q4 * w4) + (s / w4) ** 2)
    step = _second_order(s, 2.5, q5) / _second_order(s, 4.0, q6)
    return _WB_GAIN * high_pass * low_pass * transition * step


def mean_comfort_vertical(
    acceleration_m_s2: np.ndarray, dt_s: float, standard: str = "en12299"
) -> np.ndarray:
    """EN 12299 mean comfort, standard method, vertical term: ``N = 6 a_ZP95`` (dimensionless).

    1. The floor vertical acceleration ``a_z(t)`` (m/s^2) is weighted with :func:`wb_weighting`
       (complex, per FFT line over the whole record: the steady-state response of the analog
       filter up to the Nyquist frequency, periodic extension of the record, no start-up
       transient).
    2. ``a_ZW,i`` (m/s^2): RMS of the weighted acceleration over consecutive, non-overlapping
       windows of :data:`EN12299_WINDOW_S` = 5 s (``round(5 / dt_s)`` samples); an incomplete
       last window is dropped.
    3. ``a_ZP95``: the 95th percentile of the ``a_ZW,i`` (``numpy.percentile``, linear
       interpolation between order statistics).
    4. ``N = 6 a_ZP95``.

    The full index is ``N_MV = 6 sqrt(a_XP95^2 + a_YP95^2 + a_ZP95^2)``, with the longitudinal
    and lateral terms X, Y weighted by Wd. A vertical quarter-car has neither, so this is only
    the vertical contribution to ``N_MV``. Scale: N < 1 very comfortable, 1-2 comfortable,
    2-4 medium, 4-5 uncomfortable, > 5 very uncomfortable. EN 12299 computes each ``N_MV``
    over 5 min (60 windows); a shorter record gives the same statistic over fewer windows.

    Leading axes are batch axes, time is the last; the result has the leading shape. Raises
    ``ValueError`` when the record is shorter than one 5 s window.
    """
    dt_s = check_positive("dt_s", dt_s)
    window = max(1, int(round(EN12299_WINDOW_S / dt_s)))
    try:
        a = _record("acceleration_m_s2", acceleration_m_s2, window)
    except ValueError as exc:
        raise ValueError(
            f"{exc} (one {EN12299_WINDOW_S:g} s window = {window} samples at dt_s={dt_s:g})"
        ) from None
    n = a.shape[-1]
    weights = wb_weighting(np.fft.rfftfreq(n, dt_s), standard)
    weighted = np.fft.irfft(np.fft.rfft(a, axis=-1) * weights, n=n, axis=-1)
    n_windows = n // window
    blocks = weighted[..., : n_windows * window].reshape(*a.shape[:-1], n_windows, window)
    return 6.0 * np.percentile(rms(blocks), 95.0, axis=-1)


def sperling_weighting(frequencies_hz: np.ndarray) -> np.ndarray:
    """Sperling's vertical frequency weighting ``B(f)`` (dimensionless, real), f in Hz:

    ``B(f) = 0.588 sqrt[(1.911 f^2 + (0.25 f^2)^2)
    / ((1 - 0.277 f^2)^2 + (1.563 f - 0.0368 f^3)^2)]``

    (the lateral weighting is 1.25 B(f); some sources write 0.2777 for 0.277, which changes B by
    less than 0.3 % over 0.5-30 Hz). ``B`` is an amplitude weighting for
    ``Wz = (b B)^0.3`` with ``b`` in cm/s^2 (see :func:`sperling_index`); it is not the
    correction factor ``F(f)`` of the form ``0.896 (b^3 F(f) / f)^0.1``.
    """
    f = np.asarray(frequencies_hz, dtype=float)
    num = 1.911 * f**2 + (0.25 * f**2) ** 2
    den = (1.0 - 0.277 * f**2) ** 2 + (1.563 * f - 0.0368 * f**3) ** 2
    return 0.588 * np.sqrt(num / den)


def sperling_index(
    acceleration_m_s2: np.ndarray,
    dt_s: float,
    band_hz: tuple[float, float] = SPERLING_BAND_HZ,
    combine: str = "lines",
) -> np.ndarray:
    """Sperling ride index ``Wz`` of a vertical acceleration record (dimensionless).

    Per spectral line ``i`` with ``band_hz[0] <= f_i <= band_hz[1]`` (default 0.5-30 Hz):
    ``b_i = 100 A_i``, the peak amplitude in **cm/s^2** (``A_i`` in m/s^2 from
    :func:`amplitude_spectrum`: mean removed, rectangular window, a sine on a bin shows its
    amplitude), and ``Wz_i = (b_i B(f_i))^(3/10) = (b_i^3 B(f_i)^3)^(1/10)`` with ``B`` from
    :func:`sperling_weighting`. Then

    - ``combine="lines"`` (default, the classic sum): ``Wz = (sum_i Wz_i^10)^(1/10)
      = (sum_i (b_i B_i)^3)^(1/10)``;
    - ``combine="rms"``: ``Wz = (sum_i (b_i B_i)^2)^(3/20) = 4.42 a_w^0.3``, with ``a_w`` the
      RMS of the B-weighted acceleration in the band (m/s^2) and ``4.42 = (100 sqrt 2)^0.3``.

    Both give ``(b B(f))^0.3`` for one sine. For a broadband record the line sum depends on the
    record length (line amplitudes scale as sqrt(df), so ``sum b^3`` grows as ``T^(1/2)``);
    compare ``"lines"`` values only between records of equal length, or use ``"rms"``.

    Conventions: Sperling's classic single-frequency form is ``Wz = 0.896 (b^3 F(f) / f)^(1/10)``
    (b in cm/s^2; ``F`` the piecewise correction factor, vertical: 0.325 f^2 for 0.5-5.9 Hz,
    400/f^2 for 5.9-20 Hz, 1 above 20 Hz; from ``2.7 (z^3 f^5 F)^(1/10)`` with z the
    displacement amplitude in cm, ``0.896 = 2.7 (4 pi^2)^(-3/10)``). The continuous ``B``
    follows ``0.70 (F/f)^(1/3)`` and ``0.896 * 0.70^(-3/10) = 1.00``: the 0.896 and the 1/f are
    inside ``B``, and ``(b B)^0.3`` matches the classic form within 1.2 % from 0.7 to 5.5 Hz and
    from 6.5 to 10 Hz, within 4 % over 0.5-15 Hz (2.5 % at the 5.9 Hz kink of ``F``) and 5 % at
    20 Hz. Example: 1 m/s^2 amplitude at 1 Hz, b = 100 cm/s^2,
    B(1) = 0.489, Wz = 48.9^0.3 = 3.21 (classic: 0.896 (10^6 * 0.325)^0.1 = 3.19).

    Scale (ride quality) [as commonly quoted; not checked against Sperling's text]: 1 very
    good, 2 good, 3 satisfactory, 4 acceptable for running, 4.5 not acceptable for running,
    5 dangerous.

    Leading axes are batch axes, time is the last. Raises ``ValueError`` when the record is
    shorter than ``1 / band_hz[0]`` (2 s by default: the lines, ``1/T`` apart, must resolve the
    lower band edge) or sampled too slowly for any line to fall in the band. Lines above the
    Nyquist frequency are absent, so sample at ``dt_s <= 1 / (2 band_hz[1])`` for the whole band.
    """
    dt_s = check_positive("dt_s", dt_s)
    lo, hi = (float(x) for x in band_hz)
    if not 0.0 < lo < hi:
        raise ValueError(f"band_hz must satisfy 0 < low < high, got {band_hz!r}")
    if combine not in ("lines", "rms"):
        raise ValueError(f"combine must be 'lines' or 'rms', got {combine!r}")
    # The line spacing 1/T must resolve the lower band edge: T >= 1/low.
    min_samples = int(np.ceil(1.0 / (lo * dt_s) - 1e-9))
    a = _record("acceleration_m_s2", acceleration_m_s2, max(2, min_samples))
    f, amplitudes = amplitude_spectrum(a, dt_s)
    inside = (f >= lo) & (f <= hi)
    if not inside.any():
        raise ValueError(
            f"acceleration_m_s2 has no spectral line in band_hz {band_hz}: dt_s={dt_s:g} puts "
            f"the Nyquist frequency at {f[-1]:g} Hz"
        )
    x = 100.0 * amplitudes[..., inside] * sperling_weighting(f[inside])
    if combine == "lines":
        return np.sum(x**3, axis=-1) ** 0.1
    return np.sum(x**2, axis=-1) ** 0.15


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
