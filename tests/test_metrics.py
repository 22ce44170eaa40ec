"""Metrics on synthetic signals with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.metrics import (
    amplitude_spectrum,
    band_peak,
    coil_power_w,
    force_tracking_error,
    rms,
    vibration_reduction_effect,
    wk_weighted_rms,
    wk_weighting,
)

from conftest import DT

T = np.arange(0, 10.0, DT)

# ISO 2631-1:1997 Table 3, Wk weighting factors x 1000 (independent published values).
ISO_WK_TABLE = {
    0.5: 418, 0.8: 477, 1.0: 482, 1.6: 494, 2.0: 531, 2.5: 631, 3.15: 804, 4.0: 967,
    5.0: 1039, 6.3: 1054, 8.0: 1036, 10.0: 988, 16.0: 768, 20.0: 636, 31.5: 405, 50.0: 246,
    80.0: 132,
}  # fmt: skip


def test_amplitude_spectrum_of_sines():
    x = 0.003 * np.sin(2 * np.pi * 1.5 * T) + 0.001 * np.cos(2 * np.pi * 5.5 * T) + 0.2
    f, a = amplitude_spectrum(x, DT)
    assert f[1] == pytest.approx(0.1)
    assert band_peak(f, a, (1.0, 3.0)) == pytest.approx(0.003, rel=1e-9)
    assert band_peak(f, a, (4.5, 7.0)) == pytest.approx(0.001, rel=1e-9)
    assert a[0] == pytest.approx(0.0, abs=1e-12)  # mean removed


def test_vibration_reduction_effect_of_scaled_signal():
    passive = 0.004 * np.sin(2 * np.pi * 1.3 * T) + 0.001 * np.sin(2 * np.pi * 5.4 * T)
    controlled = 0.001 * np.sin(2 * np.pi * 1.3 * T) + 0.001 * np.sin(2 * np.pi * 5.4 * T)
    f1 = vibration_reduction_effect(passive, controlled, DT, (1.0, 3.0))
    f2 = vibration_reduction_effect(passive, controlled, DT, (4.5, 7.0))
    assert f1 == pytest.approx(75.0, abs=0.5)  # leakage of 1.3 Hz off-bin, same in both
    assert f2 == pytest.approx(0.0, abs=1e-9)


def test_band_without_lines_raises():
    f, a = amplitude_spectrum(np.sin(T), DT)
    with pytest.raises(ValueError, match="band_hz"):
        band_peak(f, a, (1.01, 1.02))


@pytest.mark.parametrize(("freq", "table"), sorted(ISO_WK_TABLE.items()))
def test_wk_matches_iso_2631_table(freq, table):
    assert abs(wk_weighting(freq)) * 1000 == pytest.approx(table, rel=0.02)


def test_wk_weighted_rms_of_a_sine():
    for f in (1.0, 5.0, 8.0):  # bin-centred sines: exact
        a = 0.7 * np.sin(2 * np.pi * f * T)
        expected = 0.7 / np.sqrt(2) * abs(wk_weighting(f))
        assert wk_weighted_rms(a, DT) == pytest.approx(expected, rel=1e-9)


def test_rms_power_and_tracking():
    assert rms(np.full(10, -3.0)) == pytest.approx(3.0)
    assert rms(np.sin(2 * np.pi * T)) == pytest.approx(1 / np.sqrt(2), rel=1e-9)
    assert coil_power_w(np.full(100, 1.5), resistance_ohm=4.0) == pytest.approx(9.0)
    fd = np.array([0.0, 100.0, -200.0, 0.0])
    f = np.array([50.0, 110.0, -180.0, 0.0])
    expected = np.sqrt(10**2 + 20**2) / np.sqrt(100**2 + 200**2)
    assert force_tracking_error(fd, f) == pytest.approx(expected)
    assert np.isnan(force_tracking_error(np.zeros(3), np.ones(3)))
