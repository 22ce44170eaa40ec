"""experiments/spectrum_peak.py: the evaluation spectra's 0.6 Hz peak is the guideway's longest
waves passed through the suspension (the explanation on the results page)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.modes import frequency_response

from conftest import load_script


@pytest.fixture(scope="module")
def peak():
    return load_script("experiments/spectrum_peak.py")


def spectra(peak, max_wavelength_m: float):
    args = argparse.Namespace(setting="hils", episodes=4, seed=1000, episode_length=10.0,
                              max_wavelength=max_wavelength_m)  # fmt: skip
    return peak.mean_spectra(args)


def test_low_peak_is_the_guideway_through_the_suspension(peak):
    f, s = spectra(peak, 500.0)
    zg, body, bogie = (s[k] for k in peak.SIGNALS)
    below_body_mode = (f > 0.0) & (f < 1.0)
    k = np.flatnonzero(below_body_mode)[np.argmax(zg[below_body_mode])]
    # the guideway's largest line lies just above its lowest frequency, 225 m/s / 500 m
    assert 0.45 <= f[k] <= 0.7
    assert bogie[k] == np.max(bogie[f <= 10.0])  # the bogie's largest line, too
    h = np.abs(
        frequency_response(
            f[k], secondary_damping_n_s_per_m=VehicleParams().passive_damping_n_s_per_m
        )
    )[0]
    # the linear plant's transmissibility reproduces the simulated lines within 10 % (the
    # episodes are finite and start from rest: a transient and leakage, not a model error)
    assert body[k] == pytest.approx(h[0] * zg[k], rel=0.1)
    assert bogie[k] == pytest.approx(h[2] * zg[k], rel=0.1)


def test_cutting_the_long_waves_removes_the_peak(peak):
    f, s = spectra(peak, 150.0)  # lowest input 1.5 Hz
    zg, body = s["guideway_elevation_m"], s["car_body_displacement_m"]
    line = np.argmin(np.abs(f - 0.6))
    assert zg[line] < 0.1 * np.max(zg)
    assert body[line] < 0.1 * np.max(body[f <= 10.0])
