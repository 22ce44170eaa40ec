"""Tests of capsule_env.guideway against independent facts (analytic PSD, signal analysis)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal

from capsule_env.guideway import (
    FRA_CLASS6,
    GUIDEWAY_KINDS,
    FraPsdParams,
    GuidewayParams,
    bump_profile,
    elevation_at,
    fra_psd,
    kmh_to_mps,
    make_profile,
    random_profile,
    sine_profile,
    step_profile,
    swept_sine_profile,
    time_signal,
)

from conftest import SPEED

W_LO = 2.0 * np.pi / 500.0  # rad/m, longest wavelength of the default band
W_HI = 2.0 * np.pi / 2.0  # rad/m, shortest wavelength of the default band


@pytest.fixture(scope="module")
def long_unscaled() -> tuple[np.ndarray, float]:
    """A 200 km unscaled profile at 0.25 m (shared by the statistics tests)."""
    spacing = 0.25
    return random_profile(200_000.0, spacing, seed=1234, peak_m=None), spacing


# ------------------------------------------------------------------------------------- PSD
def test_fra_psd_formula_and_asymptotes():
    # Independent facts: S = k A Wc^2 / (W^2 (W^2 + Wc^2)); ~ k A / W^2 far below the cut-off,
    # ~ k A Wc^2 / W^4 far above, and exactly half of the low asymptote at W = Wc.
    k, a, wc = 0.25, 3.39e-6, 0.8245
    assert FRA_CLASS6 == FraPsdParams(k, a, wc)
    assert fra_psd(1e-4) == pytest.approx(k * a / 1e-8, rel=1e-6)
    assert fra_psd(1e3) == pytest.approx(k * a * wc**2 / 1e12, rel=1e-6)
    assert fra_psd(wc) == pytest.approx(0.5 * k * a / wc**2, rel=1e-12)
    w = np.array([0.1, 1.0, 2.0])
    assert fra_psd(w).shape == (3,)
    custom = FraPsdParams(k=0.5, roughness_m_rad=1e-6, cutoff_rad_per_m=1.0)
    assert fra_psd(1.0, custom) == pytest.approx(0.5 * 1e-6 * 1.0 / (1.0 * 2.0))


@pytest.mark.parametrize("bad", [0.0, -1.0, np.array([1.0, -0.5]), np.nan])
def test_fra_psd_rejects_nonpositive_wavenumber(bad):
    with pytest.raises(ValueError, match="wavenumber_rad_per_m"):
        fra_psd(bad)


@pytest.mark.parametrize("field", ["k", "roughness_m_rad", "cutoff_rad_per_m"])
def test_fra_params_validated(field):
    with pytest.raises(ValueError, match=field):
        FraPsdParams(**{field: -1.0})


# ---------------------------------------------------------------------------- random profile
def test_random_profile_shape_and_seed():
    a = random_profile(1000.0, 0.25, seed=7)
    assert a.shape == (4001,)
    assert np.array_equal(a, random_profile(1000.0, 0.25, seed=7))
    b = random_profile(1000.0, 0.25, seed=8)
    assert not np.allclose(a, b)
    assert np.all(np.isfinite(a))


def test_random_profile_peak_scaling():
    z = random_profile(5000.0)
    assert abs(np.max(np.abs(z)) - 0.008) < 1e-12
    z = random_profile(5000.0, peak_m=0.003)
    assert abs(np.max(np.abs(z)) - 0.003) < 1e-12


def test_random_profile_unscaled_variance_matches_psd_integral(long_unscaled):
    z, _ = long_unscaled
    # integrate in log-space pieces: S spans ~5 decades over the band
    edges = np.geomspace(W_LO, W_HI, 9)
    pieces = zip(edges[:-1], edges[1:], strict=True)
    expected = sum(integrate.quad(fra_psd, lo, hi)[0] for lo, hi in pieces)
    assert np.var(z) == pytest.approx(expected, rel=0.05)
    # sanity: the physical class-6 level over 2-500 m is of order millimetres RMS
    assert 1e-4 < math.sqrt(expected) < 1e-2


def _welch_rad_per_m(z: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided PSD in m^2/(rad/m) versus W in rad/m via Welch (averaged over segments)."""
    f, g = signal.welch(z, fs=1.0 / spacing, nperseg=2**14, detrend="constant")
    return 2.0 * np.pi * f, g / (2.0 * np.pi)


def test_random_profile_spectrum_follows_fra_psd(long_unscaled):
    z, spacing = long_unscaled
    w, s_est = _welch_rad_per_m(z, spacing)
    band = (w >= 0.1) & (w <= 2.0)
    logw = np.log(w[band])
    slope_est = np.polyfit(logw, np.log(s_est[band]), 1)[0]
    slope_ref = np.polyfit(logw, np.log(fra_psd(w[band])), 1)[0]
    assert abs(slope_est - slope_ref) < 0.15
    # level: average the estimate over +-10 % in W around a few wavenumbers
    for w0 in (0.15, 0.5, 1.0, 1.8):
        near = (w >= 0.9 * w0) & (w <= 1.1 * w0)
        ratio = np.mean(s_est[near]) / np.mean(fra_psd(w[near]))
        assert 0.8 < ratio < 1.2, (w0, ratio)
    # outside the band (wavelength < 2 m) there is essentially no content
    above = w > 1.2 * W_HI
    assert np.max(s_est[above]) < 1e-3 * fra_psd(W_HI)


def test_random_profile_custom_band_has_no_short_waves():
    spacing = 0.25
    z = random_profile(20_000.0, spacing, seed=3, peak_m=None, min_wavelength_m=10.0)
    w, s_est = _welch_rad_per_m(z, spacing)
    assert np.max(s_est[w > 1.2 * 2 * np.pi / 10.0]) < 1e-3 * fra_psd(2 * np.pi / 10.0)


# ------------------------------------------------------------------ deterministic profiles
def test_sine_profile_frequency_and_amplitude():
    speed, f0, amp = SPEED, 2.0, 0.004
    duration = 10.0  # exactly 20 periods
    spacing = 0.25
    z = sine_profile(speed * duration, spacing, frequency_hz=f0, speed_mps=speed, amplitude_m=amp)
    fs = 1000.0
    t = np.arange(int(duration * fs)) / fs
    zt = time_signal(z, spacing, speed, t)
    spec = np.abs(np.fft.rfft(zt))
    freqs = np.fft.rfftfreq(t.size, 1.0 / fs)
    k = np.argmax(spec)
    assert freqs[k] == pytest.approx(f0, abs=1e-9)
    assert 2.0 * spec[k] / t.size == pytest.approx(amp, rel=1e-3)
    assert np.max(np.abs(zt)) == pytest.approx(amp, rel=1e-3)
    # z_g(t) = A sin(2 pi f t) directly
    assert np.allclose(zt, amp * np.sin(2 * np.pi * f0 * t), atol=1e-4 * amp)


def test_swept_sine_instantaneous_frequency():
    speed, f0, f1, amp = SPEED, 0.5, 10.0, 0.002
    duration = 20.0
    spacing = 0.25
    z = swept_sine_profile(
        speed * duration, spacing, start_hz=f0, stop_hz=f1, speed_mps=speed, amplitude_m=amp
    )
    fs = 500.0
    t = np.arange(int(duration * fs) + 1) / fs
    zt = time_signal(z, spacing, speed, t)
    assert np.max(np.abs(zt)) == pytest.approx(amp, rel=1e-3)
    phase = np.unwrap(np.angle(signal.hilbert(zt)))
    f_inst = np.gradient(phase, t) / (2 * np.pi)
    inner = (t > 0.1 * duration) & (t < 0.9 * duration)
    slope, intercept = np.polyfit(t[inner], f_inst[inner], 1)
    assert intercept == pytest.approx(f0, abs=0.05)
    assert intercept + slope * duration == pytest.approx(f1, rel=0.02)
    # upward sweep: zero crossings become denser towards the end
    crossings = np.flatnonzero(np.diff(np.signbit(zt)))
    first = np.sum(crossings < 2 * fs)
    last = np.sum(crossings > (duration - 2) * fs)
    assert last > 5 * first


def test_bump_profile():
    spacing, h, lb, pos = 0.25, 0.008, 10.0, 50.0
    z = bump_profile(200.0, spacing, height_m=h, bump_length_m=lb, position_m=pos)
    x = np.arange(z.size) * spacing
    assert np.max(z) == pytest.approx(h, rel=1e-12)
    assert x[np.argmax(z)] == pytest.approx(pos + lb / 2)
    assert np.all(z[(x < pos) | (x > pos + lb)] == 0.0)
    assert np.all(z >= 0.0)
    # area of a (1 - cos) bump is height * length / 2
    assert integrate.trapezoid(z, x) == pytest.approx(h * lb / 2, rel=1e-6)


def test_step_profile():
    spacing, h, pos, ramp = 0.25, 0.008, 50.0, 2.0
    z = step_profile(200.0, spacing, height_m=h, position_m=pos, ramp_length_m=ramp)
    x = np.arange(z.size) * spacing
    assert np.all(z[x <= pos] == 0.0)
    assert np.allclose(z[x >= pos + ramp], h, rtol=0, atol=1e-15)
    assert np.all(np.diff(z) >= 0.0)
    assert z[np.argmin(np.abs(x - (pos + ramp / 2)))] == pytest.approx(h / 2)
    sharp = step_profile(200.0, spacing, height_m=h, position_m=pos, ramp_length_m=0.0)
    assert np.all(sharp[x < pos] == 0.0) and np.all(sharp[x >= pos] == h)


# ---------------------------------------------------------------------------- interpolation
def test_elevation_at_linear_exact_and_holds_ends():
    spacing = 0.5
    x = np.arange(101) * spacing
    prof = 0.003 * x - 0.1
    q = np.array([0.0, 0.1, 3.33, 17.77, 49.99, 50.0])
    assert np.allclose(elevation_at(prof, spacing, q), 0.003 * q - 0.1, rtol=0, atol=1e-14)
    # beyond the end hold the last value, before the start the first (np.interp semantics)
    assert elevation_at(prof, spacing, 1000.0) == pytest.approx(prof[-1])
    assert elevation_at(prof, spacing, -3.0) == pytest.approx(prof[0])
    # matches np.interp on an arbitrary profile
    rng = np.random.default_rng(0)
    prof = rng.normal(size=101)
    q = rng.uniform(-5, 60, size=500)
    assert np.allclose(elevation_at(prof, spacing, q), np.interp(q, x, prof), atol=1e-14)
    assert np.ndim(elevation_at(prof, spacing, 1.3)) == 0


def test_time_signal_and_speed_conversion():
    assert kmh_to_mps(810.0) == pytest.approx(225.0)
    assert GuidewayParams().speed_mps == pytest.approx(225.0)
    prof = np.arange(11, dtype=float)  # z = x / spacing at spacing 1 m
    assert time_signal(prof, 1.0, 2.0, np.array([0.0, 1.25, 4.0])) == pytest.approx([0, 2.5, 8])


# ---------------------------------------------------------------------------- make_profile
@pytest.mark.parametrize("kind", GUIDEWAY_KINDS)
def test_make_profile_covers_duration(kind):
    params = GuidewayParams(kind=kind)
    duration = 2.0
    z = make_profile(params, duration, seed=5)
    assert (z.size - 1) * params.spacing_m > params.speed_mps * duration
    assert np.max(np.abs(z)) == pytest.approx(0.008, rel=2e-3)
    if kind == "random":
        assert np.array_equal(z, make_profile(params, duration, seed=5))


def test_make_profile_unscaled_random():
    z = make_profile(GuidewayParams(peak_m=None), 4.0, seed=0)
    assert 1e-4 < np.std(z) < 1e-2


# ------------------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: random_profile(100.0, -0.25), "spacing_m"),
        (lambda: random_profile(-100.0), "length_m"),
        (lambda: random_profile(100.0, 1.0), "spacing_m"),  # coarser than 2 m / 4
        (lambda: random_profile(100.0, min_wavelength_m=500.0), "min_wavelength_m"),
        (lambda: random_profile(100.0, min_wavelength_m=600.0), "min_wavelength_m"),
        (lambda: random_profile(100.0, peak_m=-0.008), "peak_m"),
        (lambda: random_profile(100.0, peak_m=0.0), "peak_m"),
        (lambda: sine_profile(100.0, -1, frequency_hz=1, speed_mps=1, amplitude_m=1), "spacing"),
        (lambda: sine_profile(100.0, 1, frequency_hz=-1, speed_mps=1, amplitude_m=1), "frequency"),
        (lambda: sine_profile(100.0, 1, frequency_hz=1, speed_mps=1, amplitude_m=1), "frequency"),
        (lambda: bump_profile(100.0, 0.25, bump_length_m=0.0), "bump_length_m"),
        (lambda: bump_profile(100.0, 0.25, position_m=150.0), "position_m"),
        (lambda: step_profile(100.0, 0.25, ramp_length_m=-1.0), "ramp_length_m"),
        (lambda: elevation_at(np.zeros(3), -1.0, 0.5), "spacing_m"),
        (lambda: GuidewayParams(kind="cobblestones"), "guideway kind"),
        (lambda: GuidewayParams(spacing_m=-0.1), "spacing_m"),
        (lambda: GuidewayParams(spacing_m=1.0), "spacing_m"),
        (lambda: GuidewayParams(peak_m=-0.01), "peak_m"),
        (lambda: GuidewayParams(kind="sine", peak_m=None), "peak_m"),
        (lambda: GuidewayParams(min_wavelength_m=50.0, max_wavelength_m=20.0), "min_wavelength"),
        (lambda: GuidewayParams(speed_kmh=0.0), "speed_kmh"),
        (lambda: make_profile(GuidewayParams(), -1.0), "duration_s"),
    ],
)
def test_bad_parameters_raise_naming_parameter(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_unknown_kind_lists_accepted_values():
    with pytest.raises(ValueError, match="swept_sine"):
        GuidewayParams(kind="nope")
