"""rliable's statistics through capsule_env.rl_statistics, against independent computations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

pytest.importorskip("rliable")

from capsule_env.rl_statistics import (  # noqa: E402
    iqm,
    iqm_curves,
    normalised_scores,
    probability_of_improvement,
)


def test_iqm_is_the_quarter_trimmed_mean_and_its_interval_covers_it():
    rng = np.random.default_rng(0)
    scores = {"a": rng.normal(0.4, 0.1, size=(10, 3)), "b": rng.normal(0.6, 0.1, size=(8, 3))}
    result = iqm(scores, reps=2000)
    for name, s in scores.items():
        # scipy's 25 % trimmed mean of all runs x tasks scores (40 values: exact quartiles)
        if s.size % 4 == 0:
            assert result[name].value == pytest.approx(stats.trim_mean(s.ravel(), 0.25), rel=1e-12)
        assert result[name].low < result[name].value < result[name].high
    assert result["a"].high < result["b"].low  # 0.2 apart with sd 0.1 and 24-30 runs: separated
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    assert iqm(scores, reps=2000) == result  # reproducible
    assert np.array_equal(np.random.get_state()[1], before)  # noqa: NPY002  (restored)


def test_probability_of_improvement_is_the_mann_whitney_statistic():
    rng = np.random.default_rng(1)
    x, y = rng.normal(0.5, 0.1, size=(10, 1)), rng.normal(0.45, 0.1, size=(10, 1))
    u = stats.mannwhitneyu(x[:, 0], y[:, 0]).statistic / (10 * 10)
    est = probability_of_improvement(x, y, reps=2000)
    assert est.value == pytest.approx(u, abs=1e-12)
    assert est.low <= est.value <= est.high
    assert probability_of_improvement(x + 10, x, reps=200).value == 1.0
    assert probability_of_improvement(x, x, reps=200).value == 0.5


def test_curves_and_normalisation():
    rng = np.random.default_rng(2)
    curve = rng.normal(size=(6, 2, 4)) + np.arange(4)
    out = iqm_curves({"a": curve}, reps=500)["a"]
    assert out.shape == (3, 4)
    for k in range(4):
        assert out[0, k] == pytest.approx(stats.trim_mean(curve[..., k].ravel(), 0.25), rel=1e-12)
    assert np.all(out[1] <= out[0]) and np.all(out[0] <= out[2])
    wk = np.array([[0.2596, 0.2116], [0.2399, 0.2356]])
    scores = normalised_scores(wk, np.array([0.2596, 0.2596]), np.array([0.2116, 0.2116]))
    np.testing.assert_allclose(scores, [[0.0, 1.0], [0.41041666666666, 0.5]], rtol=1e-12)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match=r"scores\['a'\] must be a finite \(runs, tasks\)"):
        iqm({"a": np.ones(5)})
    with pytest.raises(ValueError, match="x and y must score the same tasks"):
        probability_of_improvement(np.ones((3, 2)), np.ones((3, 1)))
    with pytest.raises(ValueError, match="passive_m_s2 must exceed oracle_m_s2"):
        normalised_scores(np.ones((2, 1)), np.array([0.2]), np.array([0.3]))
