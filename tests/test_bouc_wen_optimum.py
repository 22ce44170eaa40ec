"""``fit_bouc_wen``'s default search (the 3 best of its 18 grid points) ends at the Bouc-Wen
form's least-squares optimum: checked against an independent scan of the two shape parameters
(the linear coefficients solved by :func:`scipy.optimize.lsq_linear` under the fitter's bounds),
on Spencer-damper loops (no data needed) and on the scaled Labcontrol pair that the measured
plant of docs/paper-reproduction.md is fitted to (skipped without ../shared). The scaled pair's
948 N at 1.5 A is the form's limit there, not a local optimum; the reference (Spencer) damper's
747 N on that loop is a model of another form, 1044 N off the 0 A loop."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from capsule_env.dampers import ReferenceDamper
from capsule_env.identification.bouc_wen import BoucWenSequences, fit_bouc_wen
from capsule_env.identification.constrained import rmse_at_current
from capsule_env.identification.loops import reference_loops
from capsule_env.identification.predict import predict_force

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "labcontrol-mr-damper"


def _sse(model, loops) -> float:
    return float(sum(np.sum((predict_force(model, lp) - lp.force_n) ** 2) for lp in loops))


def _scan_min_sse(loops, n_zy: int = 30, n_ratio: int = 21) -> float:
    """The least SSE over a grid of yield displacements (1e-5..10 x the largest stroke) and
    shape ratios (-0.999..0.999), the force's linear part solved with the fitter's bounds
    (damping, stiffness and alpha terms >= 0, a free offset)."""
    seq = BoucWenSequences(loops)
    parts = [(lp.stroke_m, lp.stroke_rate_m_s, lp.force_n, np.full(lp.force_n.size, lp.current_a))
             for lp in loops]  # fmt: skip
    x, v, f, i = (np.concatenate(c) for c in zip(*parts, strict=True))
    x_ref = float(np.max(np.abs(x)))
    best = math.inf
    for zy in np.geomspace(1e-5 * x_ref, 10.0 * x_ref, n_zy):
        for ratio in np.linspace(-0.999, 0.999, n_ratio):
            total = 1.0 / zy**2  # gamma + beta for A = 1
            z = seq.z(1.0, 0.5 * (1.0 - ratio) * total, 0.5 * (1.0 + ratio) * total)
            phi = np.column_stack([v, i * v, z, i * z, x, np.ones_like(v)])
            scale = np.linalg.norm(phi, axis=0)
            lower = np.r_[np.zeros(5), -np.inf]
            sol = lsq_linear(phi / scale, f, bounds=(lower, np.inf), method="bvls")
            best = min(best, 2.0 * sol.cost)
    return best


def test_the_default_fit_of_spencer_loops_is_the_scanned_optimum():
    loops = reference_loops(ReferenceDamper(), currents=(0.0, 0.75, 1.5), samples_per_cycle=400)
    fitted = fit_bouc_wen(loops)
    assert _sse(fitted, loops) <= _scan_min_sse(loops) * (1.0 + 1e-6)
    # every grid point as a start finds nothing better than the default three
    assert _sse(fitted, loops) <= _sse(fit_bouc_wen(loops, starts=18), loops) * (1.0 + 1e-6)


@pytest.mark.skipif(not SHARED.is_dir(), reason="the Labcontrol loops are not at ../shared")
def test_the_measured_pairs_948_n_is_the_bouc_wen_optimum_not_a_local_one():
    from capsule_env.identification.measured import (
        load_measured_loop,
        measured_files,
        scale_loop,
    )
    from capsule_env.sensitivity.measured_plant import capsule_scales, select_pair

    loops = [load_measured_loop(f) for f in measured_files(SHARED)]
    low, high = select_pair(loops)
    kw = capsule_scales(loops[high])
    kw = {k: kw[k] for k in ("stroke_scale", "time_scale", "force_scale")}
    pair = [scale_loop(loops[low], current_a=0.0, **kw),
            scale_loop(loops[high], current_a=1.5, **kw)]  # fmt: skip
    fitted = fit_bouc_wen(pair)
    assert _sse(fitted, pair) <= _scan_min_sse(pair) * (1.0 + 1e-6)
    assert _sse(fitted, pair) <= _sse(fit_bouc_wen(pair, starts=18), pair) * (1.0 + 1e-6)
    # abs=0.5 N on these SciPy fits: the optimiser's end point moves in its last digits with
    # BLAS and the CPU; 0.5 N (0.05 %) still tells 948 N from the 747 N in question
    assert rmse_at_current(fitted, pair, 1.5) == pytest.approx(948.3, abs=0.5)
    assert rmse_at_current(fitted, pair, 0.0) == pytest.approx(86.4, abs=0.5)
    # a Bouc-Wen fitted to the 1.5 A loop alone, from every start, gets no nearer to 747 N
    alone = fit_bouc_wen([pair[1]], starts=18)
    assert rmse_at_current(alone, pair, 1.5) == pytest.approx(947.2, abs=0.5)
    # the reference damper's 747 N is another form's, and it misses the 0 A loop
    assert rmse_at_current(ReferenceDamper(), pair, 1.5) == pytest.approx(747.4, abs=0.5)
    assert rmse_at_current(ReferenceDamper(), pair, 0.0) == pytest.approx(1043.7, abs=0.5)
