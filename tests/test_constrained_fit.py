"""Tests of capsule_env.identification.constrained against independent facts.

Facts used: a fit over a subset of the free fit's models cannot fit the same loops better
(least squares over a smaller set); loops made by a known Bouc-Wen model that satisfies the
constraints are fitted back to that model (noise-free recovery); the RMSE of the degraded
model, recomputed from its own prediction, is the target; a scale of 1 is the model itself.
"""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.dampers import BoucWenDamper
from capsule_env.identification import fit_bouc_wen, predict_force, reference_loops
from capsule_env.identification.constrained import (
    CURRENT_TERM_SETS,
    SPENCER_SHAPE,
    degrade_bouc_wen,
    fit_bouc_wen_constrained,
    rmse_at_current,
    scale_current_terms,
)

FAST = {"currents": (0.0, 0.5, 1.0, 1.5), "samples_per_cycle": 400}


@pytest.fixture(scope="module")
def loops():
    return reference_loops(**FAST)


@pytest.fixture(scope="module")
def free(loops):
    return fit_bouc_wen(loops)


def _sse(model, loops) -> float:
    return float(sum(np.sum((predict_force(model, lp) - lp.force_n) ** 2) for lp in loops))


@pytest.mark.parametrize("shape", [SPENCER_SHAPE, None], ids=["spencer-shape", "searched-shape"])
@pytest.mark.parametrize("terms", CURRENT_TERM_SETS, ids=["alpha+c0", "alpha", "none"])
def test_constrained_fit_is_no_better_than_the_free_fit(loops, free, shape, terms):
    constrained = fit_bouc_wen_constrained(loops, shape=shape, current_terms=terms)
    # the free fit's multistart search may stop a hair short of its optimum: 0.1 % of SSE
    assert _sse(constrained, loops) >= _sse(free, loops) * (1.0 - 1e-3)
    if "alpha" not in terms:
        assert constrained.alpha_b == 0.0
    if "c0" not in terms:
        assert constrained.c0b == 0.0
    assert constrained.x0 == 0.0


def test_fewer_current_terms_fit_worse_at_high_current(loops):
    errs = [rmse_at_current(fit_bouc_wen_constrained(loops, current_terms=t), loops, 1.5)
            for t in CURRENT_TERM_SETS]  # fmt: skip
    assert errs[0] <= errs[1] <= errs[2]
    # with no current dependence the 1.5 A loop is missed by about half its current-added force
    peak_added = loops[-1].peak_force_n - loops[0].peak_force_n
    assert errs[2] > 0.3 * peak_added


def test_known_constrained_model_is_recovered():
    true = BoucWenDamper(c0a=9000.0, c0b=0.0, alpha_a=1.0e5, alpha_b=3.0e5, k0=12000.0, x0=0.0,
                         **SPENCER_SHAPE)  # fmt: skip
    loops = reference_loops(true, **FAST)
    fitted = fit_bouc_wen_constrained(loops, SPENCER_SHAPE, ("alpha",))
    # the loops are integrated with substeps, the fit's response is the exact update: 0.5 %
    for name in ("c0a", "alpha_a", "alpha_b", "k0"):
        assert getattr(fitted, name) == pytest.approx(getattr(true, name), rel=5e-3), name
    assert fitted.c0b == 0.0


def test_scale_one_is_the_model_and_scale_scales(free):
    assert scale_current_terms(free, 1.0) == free
    half = scale_current_terms(free, 0.5)
    assert half.alpha_b == 0.5 * free.alpha_b and half.c0b == 0.5 * free.c0b
    assert half.alpha_a == free.alpha_a and half.c0a == free.c0a


@pytest.mark.parametrize(("direction", "target"), [("weaker", 1500.0), ("stronger", 3000.0)])
def test_degraded_fit_reaches_its_target(loops, free, direction, target):
    model, s = degrade_bouc_wen(free, loops, target, current_a=1.5, direction=direction)
    assert (s < 1.0) if direction == "weaker" else (s > 1.0)
    lp = [lp for lp in loops if lp.current_a == 1.5][0]
    err = float(np.sqrt(np.mean((predict_force(model, lp) - lp.force_n) ** 2)))
    assert err == pytest.approx(target, abs=1e-3)


def test_degrade_refuses_unreachable_targets(loops, free):
    with pytest.raises(ValueError, match="not above the fit's own RMSE"):
        degrade_bouc_wen(free, loops, 10.0)
    with pytest.raises(ValueError, match="out of reach of a weaker model"):
        degrade_bouc_wen(free, loops, 1e5, direction="weaker")
    with pytest.raises(ValueError, match="direction"):
        degrade_bouc_wen(free, loops, 2000.0, direction="up")


def test_bad_arguments_are_named(loops):
    with pytest.raises(ValueError, match="current_terms"):
        fit_bouc_wen_constrained(loops, current_terms=("k0",))
    with pytest.raises(ValueError, match="shape"):
        fit_bouc_wen_constrained(loops, shape={"a_coef": 1.0})
    with pytest.raises(ValueError, match="current_a"):
        rmse_at_current(BoucWenDamper(), loops, 0.3)
    with pytest.raises(ValueError, match="scale"):
        scale_current_terms(BoucWenDamper(), -1.0)
