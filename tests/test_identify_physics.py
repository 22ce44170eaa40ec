"""Identification accepts only what a damper does (issue 40 item 6).

Before: a loop whose force was sign-flipped fitted a negative damping without a word, pure noise
fitted with an RMSE of 56 % of its peak, and the env took such energy-injecting parameters as its
plant damper (the capsule then hit its bump stop at 1 A). The independent fact checked here is
the work per cycle: a damper's force takes energy from the stroke, ``integral F v dt > 0``; for a
viscous force ``F = c v`` it is exactly ``rms(F) rms(v) T`` (ratio 1), for ``-c v`` exactly -1,
and for a force independent of the stroke about 0.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the env)
from capsule_env.dampers import DAMPER_NAMES, BiExponentialDamper, make_damper
from capsule_env.dampers.rig import (
    MIN_DISSIPATION_RATIO,
    check_dissipative,
    dissipation_ratio,
    sinusoidal_stroke,
)
from capsule_env.identification import cli as identify
from capsule_env.identification import identify_loops, identify_measured, reference_loops
from capsule_env.identification.plausibility import MAX_FIT_RMSE_FRACTION, check_fit_quality

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "labcontrol-mr-damper"


def test_the_dissipation_ratio_of_known_forces():
    # tolerance: the trapezoidal work against the samples' rms, 2000 samples a cycle (2.5e-4)
    t, x, v = sinusoidal_stroke(1.0, 0.02, cycles=2.0)
    assert dissipation_ratio(t, 3e4 * v, v) == pytest.approx(1.0, abs=1e-3)
    assert dissipation_ratio(t, -3e4 * v, v) == pytest.approx(-1.0, abs=1e-3)
    assert dissipation_ratio(t, 5e5 * x, v) == pytest.approx(0.0, abs=1e-3)  # a spring


def test_a_sign_flipped_loop_is_refused_naming_dissipation():
    flipped = [dataclasses.replace(lp, force_n=-lp.force_n) for lp in reference_loops()]
    with pytest.raises(ValueError, match=r"does not dissipate: its work per cycle is -0\.9\d.*"
                                         r"sign flipped"):  # fmt: skip
        identify_loops(flipped)


def test_pure_noise_is_refused():
    rng = np.random.default_rng(0)
    noise = [dataclasses.replace(lp, force_n=rng.uniform(-5e3, 5e3, lp.force_n.shape))
             for lp in reference_loops()]  # fmt: skip
    with pytest.raises(ValueError, match="does not dissipate.*noise"):
        identify_loops(noise)


def test_a_dissipating_but_unfittable_loop_needs_allow_poor_fit():
    # a viscous force buried in uniform noise: ratio (A/sqrt 2) / sqrt(A^2/2 + b^2/3) = 0.63,
    # dissipating, but every model's RMSE is the noise's (b / sqrt 3 = 0.87 A) against a peak of
    # about A + b = 2.5 A: 35 % of the peak
    rng = np.random.default_rng(1)
    loops = []
    for lp in reference_loops(currents=[0.0, 1.5]):
        amplitude = np.max(np.abs(lp.force_n))
        force = amplitude * lp.stroke_rate_m_s / np.max(np.abs(lp.stroke_rate_m_s))
        force = force + rng.uniform(-1.5 * amplitude, 1.5 * amplitude, force.shape)
        assert dissipation_ratio(lp.time_s, force, lp.stroke_rate_m_s) > MIN_DISSIPATION_RATIO
        loops.append(dataclasses.replace(lp, force_n=force))
    with pytest.raises(ValueError, match=r"no model fits: the best, \w+, is off by RMSE .* "
                                         r"of the peak force \(accepted: <= 25 %"):  # fmt: skip
        identify_loops(loops)
    result = identify_loops(loops, allow_poor_fit=True)
    best = min(m.rmse_n for m in result.models.values())
    assert best / result.peak_force_n > MAX_FIT_RMSE_FRACTION


def test_a_fitted_model_that_feeds_energy_in_is_refused():
    result = identify_loops(reference_loops(currents=[0.0, 1.5]))
    fit = result.models["bi_exponential"]
    flipped = {f.name: -getattr(fit.damper, f.name) for f in dataclasses.fields(fit.damper)
               if f.name[-2:] in ("a0", "a1", "b0", "b1")}  # fmt: skip
    bad = dataclasses.replace(fit, damper=dataclasses.replace(fit.damper, **flipped))
    result.models["bi_exponential"] = bad
    with pytest.raises(ValueError, match="fitted bi_exponential model does not dissipate"):
        check_fit_quality(result, "test", allow_poor_fit=True)


def test_the_reference_loops_and_every_built_in_damper_pass():
    identify_loops(reference_loops(currents=[0.0, 0.75, 1.5]))
    for name in DAMPER_NAMES:
        check_dissipative(make_damper(name), name)


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/labcontrol-mr-damper is absent")
def test_measured_loops_pass_and_their_flip_is_refused(tmp_path):
    good = identify_measured(DATA / "ensaio8.mat")  # the measured file fitted worst (14 %)
    assert min(m.rmse_n for m in good.models.values()) / good.peak_force_n < 0.15
    (loop,) = good.loops
    csv = tmp_path / "flipped.csv"
    np.savetxt(csv, np.column_stack([loop.time_s, loop.stroke_m, -loop.force_n]),
               delimiter=",", header="time,displacement,force", comments="")  # fmt: skip
    assert identify.main(["--data", str(csv)]) == 2


def test_the_env_refuses_an_energy_injecting_plant_damper():
    defaults = BiExponentialDamper()
    negative = {f"{side}_{k}": -getattr(defaults, f"{side}_{k}") for side in ("upper", "lower")
                for k in ("a0", "a1", "b0", "b1")}  # fmt: skip
    with pytest.raises(ValueError, match=r"^damper_params: the bi_exponential plant damper "
                                         "does not dissipate"):  # fmt: skip
        gym.make("CapsuleSuspension-v0", setting="sim", damper_params=negative)
    env = gym.make("CapsuleSuspension-v0", setting="sim", damper_params={"upper_b0": 8000.0})
    env.reset(seed=0)
