"""The completed paper study (issue 43): per-episode intervals, the paper's per-branch ``d``,
the hils Bi-exponential points, and the plant identified from measured loops.

Independent facts: Student's t quantile (2.776 for 4 degrees of freedom) and the paired
interval of a constant shift; a sine's kinematics (the stroke rate is the derivative of the
stroke) and its frequency; loops of the reference damper at known currents, strokes and
frequencies, scaled down as a small damper, from which the capsule-scale plant must meet the
reference damper's own 1.5 A loop; the paper's ``d`` values (15.35 upper, 15.68 lower).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from capsule_env.dampers import TanhDamper
from capsule_env.identification import reference_loops
from capsule_env.identification.loops import Loop
from capsule_env.identification.measured import scale_loop
from capsule_env.sensitivity.intervals import paired_t_interval, t_interval
from capsule_env.sensitivity.measured_plant import identify_measured_plant, loop_shape, select_pair

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "labcontrol-mr-damper"


def test_t_interval_is_students():
    low, high = t_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    half = 2.7764451051977987 * math.sqrt(2.5) / math.sqrt(5.0)  # t(0.975, 4) s / sqrt(n)
    assert (low, high) == pytest.approx((3.0 - half, 3.0 + half), rel=1e-12)
    low90, high90 = t_interval([1.0, 2.0, 3.0, 4.0, 5.0], level=0.9)
    assert low < low90 < 3.0 < high90 < high


def test_paired_interval_removes_the_shared_spread():
    rng = np.random.default_rng(0)
    a = rng.normal(60.0, 10.0, 10)  # a large episode-to-episode spread ...
    b = a + 2.0 + rng.normal(0.0, 0.1, 10)  # ... shared by both pairs
    low, high = paired_t_interval(a, b)
    assert low < np.mean(b - a) < high and high - low < 0.5  # narrow: pairing cancels it
    ua, ub = t_interval(a), t_interval(b)
    assert ua[1] - ua[0] > 10.0 and ub[1] - ub[0] > 10.0
    assert paired_t_interval([1.0, 2.0, 5.0], [4.0, 5.0, 8.0]) == pytest.approx((3.0, 3.0))


@pytest.mark.parametrize(
    "args, match",
    [(([1.0],), "at least 2"), (([1.0, np.nan],), "finite"), (([1.0, 2.0], 1.0), "level")],
)
def test_t_interval_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        t_interval(*args)
    with pytest.raises(ValueError, match="equal lengths"):
        paired_t_interval([1.0, 2.0], [1.0, 2.0, 3.0])


def _sine_loop(amplitude_m: float, frequency_hz: float, force_n: float) -> Loop:
    t = np.arange(0.0, 10.0, 0.01)
    w = 2.0 * np.pi * frequency_hz
    x, v = amplitude_m * np.sin(w * t), amplitude_m * w * np.cos(w * t)
    return Loop(0.0, t, x, v, force_n * np.tanh(v / 0.01), periodic=False, current_known=False)


def test_scale_loop_keeps_the_kinematics():
    loop = _sine_loop(0.01, 0.8, 500.0)
    out = scale_loop(loop, stroke_scale=2.5, time_scale=0.8, force_scale=8.0, current_a=1.5)
    assert out.current_a == 1.5 and out.current_known
    assert np.ptp(out.stroke_m) / 2 == pytest.approx(0.025, rel=1e-3)
    assert loop_shape(out)["frequency_hz"] == pytest.approx(1.0, rel=0.01)  # 0.8 Hz / 0.8
    inner = slice(5, -5)
    deriv = np.gradient(out.stroke_m, out.time_s)
    assert np.max(np.abs(deriv[inner] - out.stroke_rate_m_s[inner])) < 0.01 * 0.157
    assert out.peak_force_n == pytest.approx(8.0 * loop.peak_force_n)
    with pytest.raises(ValueError, match="force_scale"):
        scale_loop(loop, stroke_scale=1.0, time_scale=1.0, force_scale=0.0, current_a=0.0)


def test_select_pair_takes_the_weakest_loop_at_the_strongest_ones_stroke():
    loops = [_sine_loop(0.010, 0.9, 50.0),  # same stroke, less force than the next: not chosen
             _sine_loop(0.010, 0.9, 900.0),  # the most force
             _sine_loop(0.011, 0.95, 40.0),  # same stroke and frequency within tolerance: low
             _sine_loop(0.003, 0.9, 10.0),  # weaker, but another stroke
             _sine_loop(0.010, 0.5, 10.0)]  # weaker, but another frequency  # fmt: skip
    assert select_pair(loops) == (2, 1)
    with pytest.raises(ValueError, match="no low-current pair"):
        select_pair([loops[1], loops[3], loops[4]])


@pytest.fixture(scope="module")
def small_damper_plant():
    """A small damper: the reference damper's +-25 mm, 1 Hz loops at 0 and 1.5 A mapped to
    +-10 mm at 0.8 Hz with 1/8 of the force (so scaling back is the identity), plus a weaker
    loop at another stroke (not chosen)."""
    ref = reference_loops(currents=(0.0, 1.5), samples_per_cycle=250)
    other = reference_loops(currents=(0.0,), amplitude_m=0.005, samples_per_cycle=250)
    small = [scale_loop(lp, 0.4, 1.25, 0.125, 0.0) for lp in ref + other]
    return identify_measured_plant(small), ref


def test_the_measured_plant_meets_the_reference_loops(small_damper_plant):
    from capsule_env.identification.predict import predict_force

    m, ref = small_damper_plant
    assert m["scales"]["stroke_scale"] == pytest.approx(2.5, rel=1e-3)
    assert m["scales"]["time_scale"] == pytest.approx(0.8, rel=1e-3)  # 0.8 Hz becomes 1 Hz
    assert m["scales"]["force_scale"] == pytest.approx(8.0, rel=1e-3)
    # scaled back, the loops are the reference damper's own: it predicts them to the scales'
    # resolution (sampled peaks, about 1e-4)
    assert m["rmse_1p5A_n"]["reference"] < 1e-3 * ref[1].peak_force_n
    plant = TanhDamper(**m["plant"])
    for loop in ref:  # the plant is the reference damper again, to its tanh fit's error
        err = np.sqrt(np.mean((predict_force(plant, loop) - loop.force_n) ** 2))
        assert err < 0.1 * ref[1].peak_force_n, loop.current_a


def test_paper_d_fit_has_the_papers_d_per_branch():
    from capsule_env.sensitivity.points import paper_d_fit

    loops = reference_loops(currents=(0.0, 0.5, 1.0, 1.5), samples_per_cycle=200)
    model = paper_d_fit(loops)
    assert model.upper_d == pytest.approx(15.35, rel=1e-6)
    assert model.lower_d == pytest.approx(15.68, rel=1e-6)


def test_hils_points_change_only_the_bi_exponential_inverse_and_add_the_measured_plant():
    from capsule_env.sensitivity.points import study_points

    params = {"upper_d": 20.0}
    measured = {"plant": {"c_a": 1.0}, "bouc_wen": {"k0": 1.0}, "bi_exponential": {"upper_d": 9.0},
                "rmse_1p5A_n": {"plant": 1.0, "bouc_wen": 2.0, "bi_exponential": 3.0},
                "files": ("low.mat", "high.mat"), "scales": {}}  # fmt: skip
    models = {"bouc_wen": {}, "bi_exponential": {"joint": (params, 1.0)}, "measured": measured}
    pts = {p.label: p for p in study_points(models, ("hils",))}
    joint = pts["joint"]
    assert joint.biexp["env"] == {"inverse_params": params}  # the plant stays the reference
    assert joint.csdc["env"] == {}
    on_measured = pts["pairs fitted to the measured loops"]
    for side, inverse in (("csdc", {"k0": 1.0}), ("biexp", {"upper_d": 9.0})):
        env = getattr(on_measured, side)["env"]
        assert env["damper"] == "tanh" and env["damper_params"] == {"c_a": 1.0}
        assert env["inverse_params"] == inverse
    today = pts["pairs as today (fitted to the reference)"]
    assert "inverse_params" not in today.csdc["env"] and today.biexp["env"]["damper"] == "tanh"
    del models["measured"]
    assert not [p for p in study_points(models, ("hils",)) if p.factor == "measured plant"]


@pytest.mark.skipif(not SHARED.is_dir(), reason="the Labcontrol loops are not at ../shared")
def test_the_labcontrol_plant():
    m = identify_measured_plant(SHARED)
    assert m["files"] == ("ensaio4a.mat", "ensaio.A.2.mat")
    assert 5.0 < m["scales"]["force_scale"] < 12.0  # a ~0.9 kN damper onto ~7.1 kN
    assert m["rmse_1p5A_n"]["plant"] < 0.1 * m["scales"]["reference_peak_force_n"]
