"""The reward's Wk-weighted acceleration (``reward_acceleration_filter="wk"``): the digital filter
against the ISO 2631-1 formula, the env's per-step signal against the exact FFT weighting."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy.signal import freqs_zpk, sosfreqz

import capsule_env  # noqa: F401  (registers the env)
from capsule_env import metrics

FREQS_HZ = np.array([0.2, 0.5, 1.0, 1.3, 2.0, 4.0, 8.0, 10.0, 16.0, 20.0])


def _iso_wk(f_hz: np.ndarray) -> np.ndarray:
    """ISO 2631-1 Annex A Wk written out factor by factor (independent of capsule_env)."""
    s = 2j * np.pi * f_hz
    w1, w2, w3, w4, w5, w6 = (2 * np.pi * f for f in (0.4, 100.0, 12.5, 12.5, 2.37, 3.35))
    hh = 1 / (1 + np.sqrt(2) * w1 / s + (w1 / s) ** 2)  # high-pass, Q = 1/sqrt 2
    hl = 1 / (1 + np.sqrt(2) * s / w2 + (s / w2) ** 2)  # low-pass
    ht = (1 + s / w3) / (1 + s / (0.63 * w4) + (s / w4) ** 2)  # a-v transition
    hs = (1 + s / (0.91 * w5) + (s / w5) ** 2) / (1 + s / (0.91 * w6) + (s / w6) ** 2)
    return hh * hl * ht * hs * (w5 / w6) ** 2  # upward step


def test_analog_zpk_is_the_iso_wk():
    zeros, poles, gain = metrics.wk_analog_zpk()
    _, h = freqs_zpk(zeros, poles, gain, worN=2 * np.pi * FREQS_HZ)
    np.testing.assert_allclose(h, _iso_wk(FREQS_HZ), rtol=1e-9)
    assert np.abs(h)[FREQS_HZ == 8.0][0] == pytest.approx(1.0, abs=0.05)  # Wk's plateau


def test_digital_filter_follows_the_analog_one_below_20_hz():
    sos = metrics.wk_filter_sos(0.005)
    _, h = sosfreqz(sos, worN=FREQS_HZ, fs=200.0)
    ratio = np.abs(h) / np.abs(_iso_wk(FREQS_HZ))
    below_10 = FREQS_HZ <= 10.0
    assert np.all(np.abs(ratio[below_10] - 1) < 0.005)  # bilinear warping: 0.25 % at 10 Hz
    assert np.all(np.abs(ratio - 1) < 0.035)  # 3.1 % at 20 Hz
    assert np.all(np.abs(np.roots([1, sos[0, 4], sos[0, 5]])) < 1)  # stable
    with pytest.raises(ValueError, match="dt_s"):
        metrics.wk_filter_sos(0.0)


@pytest.mark.parametrize("setting", ["sim", "hils"])
def test_env_reward_reads_the_wk_weighted_acceleration(setting):
    # Over a 10 s episode, the RMS of the env's per-step Wk-filtered acceleration matches the
    # exact per-FFT-line Wk weighting of the raw acceleration (what the tables report) to 2 %
    # (the causal filter starts from rest, the FFT extends the record periodically: 0.03-1.1 %),
    # and the reward's acceleration cost is its square, scaled.
    env = gym.make("CapsuleSuspension-v0", setting=setting, reward_acceleration_filter="wk")
    env.reset(seed=3)
    raw, weighted, cost = [], [], []
    for _ in range(2000):
        _, _, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        raw.append(info["car_body_acceleration_m_s2"])
        weighted.append(info["reward_acceleration_m_s2"])
        cost.append(info["cost_acceleration"])
        assert not terminated
    raw, weighted, cost = np.array(raw), np.array(weighted), np.array(cost)
    exact = metrics.wk_weighted_rms(raw, 0.005)
    assert np.sqrt(np.mean(weighted**2)) == pytest.approx(exact, rel=0.02)
    assert np.sqrt(np.mean(raw**2)) > 1.2 * exact  # the weighting does something
    np.testing.assert_allclose(cost, (weighted / 0.5) ** 2, rtol=1e-12)


def test_default_reward_reads_the_raw_acceleration():
    env = gym.make("CapsuleSuspension-v0", setting="hils")
    env.reset(seed=0)
    for _ in range(20):
        info = env.step(np.zeros(1, dtype=np.float32))[-1]
        assert info["reward_acceleration_m_s2"] == info["car_body_acceleration_m_s2"]


def test_unknown_filter_is_named():
    with pytest.raises(ValueError, match="reward_acceleration_filter"):
        gym.make("CapsuleSuspension-v0", reward_acceleration_filter="wb")
