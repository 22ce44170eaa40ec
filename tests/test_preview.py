"""The guideway preview observation: the surveyed elevation ahead of the bogie.

Facts checked: with a perfect survey and position, the preview is the guideway the vehicle
meets later (read back from the env's own ``info`` when it gets there); a position error shifts
the lookup by exactly that distance; the survey map's error has the documented size and
wavelengths; adding the preview changes nothing else; single, vector and SB3 envs agree.
"""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import SURVEY_NOISE_BAND_M, SURVEY_OFFSET_BAND_M, EnvConfig
from capsule_env.engine.layout import SIGNAL_NAMES
from capsule_env.envs import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

GUIDEWAY = SIGNAL_NAMES.index("guideway_elevation_m")
PERFECT = {"survey_offset_m": 0.0, "survey_noise_m": 0.0, "position_error_m": 0.0}


def test_a_perfect_preview_is_the_guideway_the_vehicle_meets_later():
    # 5 points 2 steps (10 ms) apart: point k is the elevation 2k steps later, relative to now.
    n, steps, points = 6, 400, 5
    batch = CapsuleBatch(EnvConfig(setting="hils", observation="measured", preview_points=points,
                                   preview_horizon_s=0.05, **PERFECT), n)  # fmt: skip
    batch.seed(1)
    batch.reset()
    preview, elevation = [], []
    rng = np.random.default_rng(0)
    for _ in range(steps):
        batch.step(rng.uniform(-1, 1, n))
        preview.append(batch.obs[:, -points:].astype(np.float64))
        elevation.append(batch.signals[GUIDEWAY].copy())
    preview, elevation = np.array(preview), np.array(elevation)
    for k in range(1, points + 1):
        later = elevation[2 * k :] - elevation[: -2 * k]
        np.testing.assert_allclose(preview[: -2 * k, :, k - 1], later, atol=1e-8)  # float32
    assert np.abs(preview).max() > 1e-4  # the guideway really moves over 50 ms at 225 m/s


def test_a_position_error_shifts_the_lookup_by_that_distance():
    points, error_m = 4, 3.0
    config = EnvConfig(setting="sim", preview_points=points, preview_horizon_s=0.2,
                       survey_offset_m=0.0, survey_noise_m=0.0, position_error_m=error_m)  # fmt: skip
    batch = CapsuleBatch(config, 3)
    batch.seed(2)
    batch.reset()
    batch.step(np.zeros(3))
    offsets = batch.env_state.position_error  # drawn with std position_error_m
    assert np.all(offsets != 0.0)
    for n in range(3):
        prof = batch.profiles[batch.profile_index[n]] * batch.gain[n]
        x = batch.start_position[n] + batch.speed[n] * batch.state[n, -1] + offsets[n]

        def z(pos, prof=prof):
            return np.interp(pos / batch.spacing, np.arange(prof.size), prof)

        ahead = x + batch.speed[n] * 0.05 * np.arange(1, points + 1)
        np.testing.assert_allclose(batch.obs[n, -points:], z(ahead) - z(x), atol=1e-8)


@pytest.mark.parametrize(
    "offset_m, noise_m, band_m",
    [(1e-3, 0.0, SURVEY_OFFSET_BAND_M), (0.0, 2e-4, SURVEY_NOISE_BAND_M)],
)
def test_the_survey_error_has_the_documented_size_and_wavelengths(offset_m, noise_m, band_m):
    config = EnvConfig(preview_points=2, survey_offset_m=offset_m, survey_noise_m=noise_m)
    err = CapsuleBatch(config, 1).params.survey_error
    assert err.shape[0] == config.guideway_bank_size
    assert np.std(err) == pytest.approx(offset_m + noise_m, rel=0.02)
    f = np.fft.rfftfreq(err.shape[1], config.guideway_spec.spacing_m)  # cycles per metre
    window = np.hanning(err.shape[1])  # the records are not periodic: taper them
    power = np.mean(np.abs(np.fft.rfft((err - err.mean(axis=1, keepdims=True)) * window)) ** 2,
                    axis=0)  # fmt: skip
    inside = (f >= 0.8 / band_m[1]) & (f <= 1.25 / band_m[0])  # the band, and a little leakage
    assert power[inside].sum() / power.sum() > 0.99


def test_no_preview_no_survey_map():
    assert not np.any(CapsuleBatch(EnvConfig(preview_points=0), 1).params.survey_error)


def test_the_preview_changes_nothing_else():
    kwargs = {"setting": "hils", "observation": "measured"}
    plain = CapsuleSuspensionVectorEnv(num_envs=4, **kwargs)
    ahead = CapsuleSuspensionVectorEnv(num_envs=4, preview_points=8, **kwargs)
    a, _ = plain.reset(seed=5)
    b, _ = ahead.reset(seed=5)
    rng = np.random.default_rng(3)
    for _ in range(2500):  # past the end of the first episode: the next resets agree too
        act = rng.uniform(-1, 1, (4, 1))
        a, ra, *_ = plain.step(act)
        b, rb, *_ = ahead.step(act)
        np.testing.assert_array_equal(a, b[:, :-8])
        np.testing.assert_array_equal(ra, rb)


def test_single_vector_and_sb3_agree_with_preview():
    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv  # noqa: PLC0415

    kwargs = {"setting": "hils", "observation": "measured", "preview_points": 6}
    vec = CapsuleSuspensionVectorEnv(num_envs=3, **kwargs)
    sb3 = CapsuleSuspensionSB3VecEnv(3, **kwargs)
    single = CapsuleSuspensionEnv(**kwargs)
    v, _ = vec.reset(seed=9)
    sb3.seed(9)
    s = sb3.reset()
    o, _ = single.reset(seed=9)
    np.testing.assert_array_equal(v, s)
    np.testing.assert_array_equal(v[0], o)
    rng = np.random.default_rng(4)
    for _ in range(300):
        act = rng.uniform(-1, 1, (3, 1)).astype(np.float32)
        v, *_ = vec.step(act)
        s, *_ = sb3.step(act)
        o, *_ = single.step(act[0])
        np.testing.assert_array_equal(v, s)
        np.testing.assert_array_equal(v[0], o)


@pytest.mark.parametrize(
    "kwargs, name",
    [({"preview_points": -1}, "preview_points"), ({"preview_points": 2.5}, "preview_points"),
     ({"preview_horizon_s": 0.0}, "preview_horizon_s"), ({"survey_noise_m": -1e-3}, "survey_noise_m"),
     ({"position_error_m": float("nan")}, "position_error_m")],
)  # fmt: skip
def test_bad_preview_arguments_name_the_argument(kwargs, name):
    with pytest.raises((TypeError, ValueError), match=name):
        EnvConfig(**kwargs)


# ----------------------------------------------------------------------------- finite guideways
def _perfect_preview_run(guideway: str, points: int, horizon_s: float, length_s: float, **kw):
    """One vehicle over a deterministic guideway with a perfect survey and position: the
    preview columns and the vehicle's position at every step."""
    config = EnvConfig(setting="sim", guideway=guideway, preview_points=points,
                       preview_horizon_s=horizon_s, episode_length_s=length_s, **PERFECT, **kw)  # fmt: skip
    batch = CapsuleBatch(config, 1)
    batch.seed(0)
    batch.reset()
    preview, position = [], []
    for _ in range(batch.max_steps):
        batch.step(np.zeros(1))
        preview.append(batch.obs[0, -points:].astype(np.float64))
        position.append(batch.start_position[0] + batch.speed[0] * batch.state[0, -1])
    return np.array(preview), np.array(position), batch


def test_the_preview_of_a_sine_continues_its_period_to_the_end_of_the_episode():
    """A sine guideway is z(x) = A sin(2 pi f x / V) everywhere (docs: the profile kinds): the
    preview of every step, the last preview horizon of the episode included (past the profile
    the run needs), is that formula ahead minus under the bogie; it used to hold the profile's
    last sample there, every preview column the same value at the last step."""
    points, horizon_s = 8, 0.5
    preview, x, batch = _perfect_preview_run("sine", points, horizon_s, 2.0)
    gw = batch.config.guideway_spec
    speed = gw.speed_kmh / 3.6

    def z(position):
        return gw.peak_m * np.sin(2.0 * np.pi * gw.frequency_hz * position / speed)

    ahead = x[:, None] + speed * horizon_s / points * np.arange(1, points + 1)
    # float32 observations (~1e-9 m at 16 mm) and the linear interpolation between the
    # 0.25 m samples of a 173 m wavelength (A (2 pi dx / L)^2 / 8 ~ 8e-8 m): 1e-6 m bounds both
    np.testing.assert_allclose(preview, z(ahead) - z(x)[:, None], rtol=0, atol=1e-6)
    assert np.ptp(preview[-1]) > 1e-3  # the last step's columns are not one held value


@pytest.mark.parametrize("guideway", ["sine", "swept_sine", "bump", "step"])
def test_the_continuation_changes_nothing_a_run_drives_over(guideway):
    """What the vehicle drives over is the same with or without preview (the plant's
    trajectory bit for bit: a continued profile's first samples are the ones without the
    continuation), and the survey map over it does not depend on how far the preview looks."""
    kwargs = {"setting": "hils", "observation": "measured", "guideway": guideway,
              "episode_length_s": 2.0}  # fmt: skip
    plain = CapsuleSuspensionVectorEnv(num_envs=2, **kwargs)
    ahead = CapsuleSuspensionVectorEnv(
        num_envs=2, preview_points=4, preview_horizon_s=1.0, **kwargs
    )
    a, _ = plain.reset(seed=5)
    b, _ = ahead.reset(seed=5)
    rng = np.random.default_rng(3)
    for _ in range(plain.batch.max_steps):
        act = rng.uniform(-1, 1, (2, 1))
        a, ra, *_, info_a = plain.step(act)
        b, rb, *_, info_b = ahead.step(act)
        np.testing.assert_array_equal(a, b[:, :-4])
        np.testing.assert_array_equal(ra, rb)
        np.testing.assert_array_equal(
            info_a["guideway_elevation_m"], info_b["guideway_elevation_m"]
        )
    run = plain.batch.profiles.shape[1]
    np.testing.assert_array_equal(ahead.batch.profiles[:, :run], plain.batch.profiles)
    near = CapsuleBatch(EnvConfig(**kwargs, preview_points=4, preview_horizon_s=0.01), 1)
    far = ahead.batch.params.survey_error
    assert far.shape[1] > near.params.survey_error.shape[1] > run
    np.testing.assert_array_equal(far[:, :run], near.params.survey_error[:, :run])


@pytest.mark.parametrize("kind", ["sine", "swept_sine", "bump", "step"])
def test_a_continued_profile_is_the_guideway_beyond_its_length(kind):
    from capsule_env.guideway import GuidewayParams, make_profile

    gw = GuidewayParams(kind=kind, speed_kmh=810.0)
    base = make_profile(gw, 1.0)
    longer = make_profile(gw, 1.0, extend_m=100.0)
    assert longer.size == base.size + 400  # 100 m of 0.25 m samples
    np.testing.assert_array_equal(longer[: base.size], base)
    x = np.arange(longer.size) * gw.spacing_m
    t = x / gw.speed_mps
    if kind == "sine":  # its period, from the formula
        expected = gw.peak_m * np.sin(2 * np.pi * gw.frequency_hz * t)
    elif kind == "swept_sine":  # the chirp at the same rate past its sweep time (1 s here)
        f0, f1 = gw.start_hz, gw.stop_hz
        expected = gw.peak_m * np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t * t / 2.0))
    elif kind == "bump":  # flat (0) past the bump at 50-60 m
        inside = np.abs(x - 55.0) <= 5.0
        expected = np.where(inside, gw.peak_m / 2 * (1 - np.cos(2 * np.pi * (x - 50) / 10)), 0)
    else:  # the height past the ramp at 50-51 m
        ramp = 0.5 * gw.peak_m * (1 - np.cos(np.pi * np.clip(x - 50.0, 0.0, 1.0)))
        expected = np.where(x >= 51.0, gw.peak_m, ramp)
    # sin of arguments up to ~1e3 rad: a few ulps of the argument; 1e-12 m is far above that
    np.testing.assert_allclose(longer, expected, rtol=0, atol=1e-12)


def test_a_continued_random_profile_repeats_its_synthesis_period():
    """The spectral synthesis is periodic (its FFT period, here 100 m: 20 longest wavelengths
    of 5 m); continued past it, a random profile repeats it, with the peak scale of the
    samples asked for, which stay those without the continuation."""
    from capsule_env.guideway import random_profile

    band = {"min_wavelength_m": 1.0, "max_wavelength_m": 5.0}
    base = random_profile(30.0, 0.25, 3, **band)
    longer = random_profile(30.0, 0.25, 3, extend_m=200.0, **band)
    assert (base.size, longer.size) == (121, 921)
    np.testing.assert_array_equal(longer[:121], base)
    np.testing.assert_array_equal(longer[400:800], longer[:400])  # the period, repeated
    period = random_profile(99.75, 0.25, 3, peak_m=None, **band)  # 400 samples: one period
    scale = 0.008 / np.max(np.abs(period[:121]))
    np.testing.assert_allclose(longer[:400], scale * period, rtol=1e-12, atol=0)
