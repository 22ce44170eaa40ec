"""The magnet's length (issue 43, item 4): ``magnet_length_m``.

The plant reads the guideway averaged over the magnet; the survey map of the preview and the
per-window scaling keep the true guideway. Checked against the moving average's frequency
response ``sinc(L / lambda)`` (capsule_env.envelope.published.magnet_length_gain, written
apart from the filter), a profile the average leaves as it is (a straight line), the preview
and the scaling of the env without the option, and the default (bit for bit).
"""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.common.units import kmh_to_m_s
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.layout import SIG_GUIDEWAY
from capsule_env.envelope.magnet import magnet_average
from capsule_env.envelope.published import magnet_length_gain

SPEED_KMH = 150.0
AMPLITUDE_M = 0.008  # the sine guideway's default amplitude


def _guideway_seen(wavelength_m: float, magnet_length_m: float | None) -> np.ndarray:
    """The guideway elevation the plant reads over 2 s on a sine guideway of that wavelength."""
    frequency = kmh_to_m_s(SPEED_KMH) / wavelength_m
    config = EnvConfig(guideway="sine", guideway_params={"frequency_hz": frequency},
                       speed_kmh=SPEED_KMH, episode_length_s=2.0,
                       magnet_length_m=magnet_length_m)  # fmt: skip
    batch = CapsuleBatch(config, 1)
    batch.seed(0)
    batch.reset()
    z = []
    for _ in range(batch.max_steps):
        batch.step(np.zeros(1))
        z.append(batch.signals[SIG_GUIDEWAY, 0])
    return np.array(z)


def _fundamental(z: np.ndarray, wavelength_m: float) -> np.ndarray:
    """Least-squares (sine, cosine) coefficients at the wave's frequency, between 0.2 s and
    1.8 s (away from the profile's ends, where the average is cut to the profile)."""
    t = 0.005 * (np.arange(z.size) + 1.0)
    w = 2.0 * np.pi * kmh_to_m_s(SPEED_KMH) / wavelength_m
    part = slice(40, 360)
    basis = np.c_[np.sin(w * t[part]), np.cos(w * t[part])]
    return np.linalg.lstsq(basis, z[part], rcond=None)[0]


@pytest.mark.parametrize("wavelength_m", [2.0, 3.0, 4.0, 10.0, 20.0])
def test_the_plant_reads_each_wave_through_the_magnets_sinc(wavelength_m):
    length = 5.4
    point = _fundamental(_guideway_seen(wavelength_m, None), wavelength_m)
    magnet = _fundamental(_guideway_seen(wavelength_m, length), wavelength_m)
    gain = float(magnet @ point / (point @ point))  # signed: in phase or inverted
    assert gain == pytest.approx(float(magnet_length_gain(wavelength_m, length)), abs=5e-4)


@pytest.mark.parametrize("length_m", [2.7, 5.4])
def test_a_wave_as_long_as_the_magnet_is_removed(length_m):
    z = _guideway_seen(length_m, length_m)[40:360]
    assert np.max(np.abs(z)) < 1e-3 * AMPLITUDE_M
    assert np.max(np.abs(_guideway_seen(length_m, None)[40:360])) > 0.9 * AMPLITUDE_M


def test_the_average_keeps_a_straight_line_and_a_constant():
    x = np.arange(400) * 0.25
    line = np.stack([0.003 * x - 0.1, np.full_like(x, 0.02)])
    out = magnet_average(line, 0.25, 5.4)
    inner = slice(12, -12)  # the windows of these samples and their neighbours lie on it
    np.testing.assert_allclose(out[:, inner], line[:, inner], rtol=0, atol=1e-14)


BANK = {"setting": "hils", "observation": "measured", "preview_points": 8, "speed_kmh": 300.0,
        "levitation": "eds", "spans": "continuous", "episode_length_s": 1.0}  # fmt: skip


def _run(magnet_length_m: float | None, steps: int = 100):
    batch = CapsuleBatch(EnvConfig(**BANK, magnet_length_m=magnet_length_m), 4)
    batch.seed(3)
    batch.reset()
    obs, guideway = [batch.obs.copy()], [batch.signals[SIG_GUIDEWAY].copy()]
    for k in range(steps):
        batch.step(np.full(4, np.sin(0.2 * k)))
        obs.append(batch.obs.copy())
        guideway.append(batch.signals[SIG_GUIDEWAY].copy())
    return batch, np.array(obs), np.array(guideway)


def test_the_survey_and_the_scaling_keep_the_true_guideway():
    """The preview's columns (the survey map ahead, spans included) and each window's scale
    are those of the env without the magnet; the guideway under the magnet is not."""
    plain, obs_p, zg_p = _run(None)
    magnet, obs_m, zg_m = _run(5.4)
    np.testing.assert_array_equal(magnet.gain, plain.gain)
    np.testing.assert_allclose(obs_m[:, :, -8:], obs_p[:, :, -8:], rtol=0, atol=1e-9)
    assert np.max(np.abs(zg_m - zg_p)) > 1e-4  # m: the plant reads another guideway
    spacing = plain.spacing
    np.testing.assert_allclose(magnet.profiles, magnet_average(plain.profiles, spacing, 5.4))
    np.testing.assert_allclose(magnet.offsets, magnet_average(plain.offsets, spacing, 5.4))


def test_the_default_is_the_point_magnet_bit_for_bit():
    plain, obs_p, zg_p = _run(None, 50)
    batch = CapsuleBatch(EnvConfig(**BANK), 4)
    batch.seed(3)
    batch.reset()
    obs = [batch.obs.copy()]
    for k in range(50):
        batch.step(np.full(4, np.sin(0.2 * k)))
        obs.append(batch.obs.copy())
    np.testing.assert_array_equal(np.array(obs), obs_p)
    assert batch.params.survey_bank.size == 0  # the preview reads the plant's bank


@pytest.mark.parametrize(
    ("value", "error"),
    [(0.0, r"in \[0.001, 50.0\]"), (-1.0, r"in \[0.001, 50.0\]"), (60.0, r"in \[0.001, 50.0\]"),
     (float("nan"), "a finite number"), ("long", "a real number"), (True, "a real number")],
)  # fmt: skip
def test_bad_magnet_lengths_are_named(value, error):
    with pytest.raises((ValueError, TypeError), match=f"magnet_length_m must be {error}"):
        EnvConfig(magnet_length_m=value)
    assert EnvConfig(magnet_length_m=5.4).envelope.magnet_length_m == 5.4


def test_declared_vehicles_refuse_the_magnet():
    from capsule_env.envs.declared_vehicle import declared_setup

    with pytest.raises(ValueError, match="magnet_length_m=2.0 is not built for declared"):
        declared_setup("test", {"vehicle": "half_car", "magnet_length_m": 2.0})


@pytest.mark.parametrize("length_m", [0.001, 0.05, 0.1])
@pytest.mark.parametrize("wavelength_m", [2.0, 3.0])
def test_a_magnet_shorter_than_the_spacing_reads_nearly_the_point_magnets_guideway(
    length_m, wavelength_m
):
    """The limit of a short magnet is the point magnet (``sinc -> 1``): the correction of the
    second interpolation fades with the length (a 1 mm magnet read 4.9 % more of a 2 m wave)."""
    point = _fundamental(_guideway_seen(wavelength_m, None), wavelength_m)
    magnet = _fundamental(_guideway_seen(wavelength_m, length_m), wavelength_m)
    gain = float(magnet @ point / (point @ point))
    assert gain == pytest.approx(float(magnet_length_gain(wavelength_m, length_m)), abs=1e-3)


def _cosine_gain(length_m: float, wavelength_m: float, spacing_m: float = 0.25) -> float:
    """The gain of ``magnet_average`` on a sampled cosine, read at a crest far from the ends:
    the average is a symmetric filter there, so it scales every sample of a cosine (and the
    plant's interpolant of them) by its gain at that wavelength."""
    crest = 400  # a sample more than the longest magnet's half-length from either end
    x = (np.arange(2 * crest + 1) - crest) * spacing_m
    return float(
        magnet_average(np.cos(2 * np.pi * x / wavelength_m), spacing_m, length_m)[0, crest]
    )


def test_the_gain_is_the_magnets_sinc_over_the_lengths_and_wavelengths():
    """The figures of docs/envelope.md and the module: 47 lengths from 0.001 to 50 m and 0.5,
    1.35, 2.7, 5.4 m, 30 wavelengths from 2 to 40 m, at the 0.25 m spacing (a constant
    correction weight, 1/12, was 4.9e-2 off at 1 mm)."""
    wavelengths = np.geomspace(2.0, 40.0, 30)
    lengths = [*np.geomspace(0.001, 50.0, 47), 0.5, 1.35, 2.7, 5.4]
    worst = {
        length: max(
            abs(_cosine_gain(length, w) - magnet_length_gain(w, length)) for w in wavelengths
        )
        for length in lengths
    }
    assert max(worst.values()) < 5.2e-3
    assert max(e for length, e in worst.items() if length >= 1.35) < 1.3e-3
    assert max(e for length, e in worst.items() if length >= 5.0) < 5e-4


def test_a_numpy_float32_length_is_taken_as_its_value():
    """``magnet_length_m=np.float32(x)`` is the length ``float(np.float32(x))``, bit for bit (not
    a filter computed in float32 arithmetic)."""
    length = np.float32(5.4)
    numpy = CapsuleBatch(EnvConfig(magnet_length_m=length), 1).profiles
    python = CapsuleBatch(EnvConfig(magnet_length_m=float(length)), 1).profiles
    np.testing.assert_array_equal(numpy, python)
