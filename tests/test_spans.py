"""Tube spans against Euler-Bernoulli beam solutions computed independently (SciPy's BVP solver)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_bvp

from capsule_env.guideway.spans import SpanParams, span_profile, span_shape


def _beam_deflection(clamped: bool, n: int = 201) -> tuple[np.ndarray, np.ndarray]:
    """EI w'''' = q on [0, 1] (EI = q = 1), w = 0 at both ends and w' = 0 (clamped) or w'' = 0
    (simply supported) there; returns xi and w normalised to 1 at mid-span."""

    def rhs(x, y):
        return np.vstack([y[1], y[2], y[3], np.ones_like(x)])

    def bc(ya, yb):
        k = 1 if clamped else 2
        return np.array([ya[0], yb[0], ya[k], yb[k]])

    xi = np.linspace(0.0, 1.0, n)
    sol = solve_bvp(rhs, bc, xi, np.zeros((4, n)), tol=1e-10)
    assert sol.success
    w = sol.sol(xi)[0]
    return xi, w / sol.sol(0.5)[0]


@pytest.mark.parametrize("shape, clamped", [("continuous", True), ("simply_supported", False)])
def test_sag_shape_is_the_beam_solution(shape, clamped):
    xi, w = _beam_deflection(clamped)
    np.testing.assert_allclose(span_shape(xi, shape), w, atol=1e-8)


def test_profile_sag_settlement_and_spectrum():
    spacing = 0.25
    flat = span_profile(3000.0, spacing, SpanParams(pylon_offset_std_m=0.0))
    # 10 mm (L / 3000) at every mid-span, 0 over every pylon
    assert flat[60] == pytest.approx(-0.01, abs=1e-15)
    assert np.all(np.abs(flat[::120]) < 1e-15)
    # at 810 km/h the sag's fundamental is 225 / 30 = 7.5 Hz
    dt = spacing / 225.0
    spectrum = np.abs(np.fft.rfft(flat - flat.mean()))
    freqs = np.fft.rfftfreq(flat.size, dt)
    assert freqs[np.argmax(spectrum)] == pytest.approx(7.5, abs=0.1)
    # settlement: the pylons' elevations are N(0, 1 mm) draws, linear in between
    settled = span_profile(3000.0, spacing, SpanParams(), seed=4)
    offsets = settled - flat
    assert np.std(offsets[::120]) == pytest.approx(1e-3, rel=0.2)
    np.testing.assert_allclose(offsets[60], 0.5 * (offsets[0] + offsets[120]), atol=1e-15)
    assert np.array_equal(settled, span_profile(3000.0, spacing, SpanParams(), seed=4))


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="span_m"):
        SpanParams(span_m=0.0)
    with pytest.raises(ValueError, match="sag_m"):
        SpanParams(sag_m=-0.01)
    with pytest.raises(ValueError, match="shape"):
        SpanParams(shape="arch")
