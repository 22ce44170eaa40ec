"""The guideway preview observation: the surveyed elevation ahead of the bogie.

Facts checked: with a perfect survey and position, the preview is the guideway the vehicle
meets later (read back from the env's own ``info`` when it gets there); a position error shifts
the lookup by exactly that distance; the survey map's error has the documented size and
wavelengths; adding the preview changes nothing else; single, vector and SB3 envs agree.
"""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.batch import CapsuleBatch
from capsule_env.config import SURVEY_NOISE_BAND_M, SURVEY_OFFSET_BAND_M, EnvConfig
from capsule_env.envs import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv
from capsule_env.layout import SIGNAL_NAMES, VF_POSITION_ERROR

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
    offsets = batch.floats[VF_POSITION_ERROR]  # drawn with std position_error_m
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
    from capsule_env.sb3 import CapsuleSuspensionSB3VecEnv  # noqa: PLC0415

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
