"""The wheelbase-preview law of the half-car (capsule_env.agents.controllers.wheelbase)."""

from __future__ import annotations

import numpy as np
from capsule_env.agents.controllers.wheelbase import (
    WheelbaseExactPreviewLQ,
    WheelbasePreviewLQ,
    wheelbase_gains,
)

from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv

W = (0.1, 10.0, 3e-8)


def test_the_preview_leaves_the_state_feedback_alone():
    """Tomizuka's separation: the window enters the plant and not the other way round, so the
    Riccati solution's plant block, hence the state and in-flight gains, are the plain LQR's
    (two SciPy/LAPACK Riccati solves of different sizes: equal to 1e-8 of the largest gain, the
    last bits differing across CPUs; observed 2e-12)."""
    with_p = wheelbase_gains("half_car", 0.005, 225.0, *W)
    without = wheelbase_gains("half_car", 0.005, 225.0, *W, preview=False)
    np.testing.assert_allclose(
        with_p.k_x, without.k_x, rtol=1e-8, atol=1e-8 * abs(without.k_x).max()
    )
    np.testing.assert_allclose(
        with_p.k_u, without.k_u, rtol=1e-8, atol=1e-8 * abs(without.k_u).max()
    )
    assert without.k_p.shape == (2, 0) and with_p.k_p.shape == (2, 18)  # 88.9 ms / 5 ms -> 18


def test_the_window_is_wired_to_the_rears_delay():
    """At 250 m/s the 20 m wheelbase is exactly 16 intervals: the rear's rise now is the
    window's second entry, and its first, 17 intervals old, reaches nothing."""
    g = wheelbase_gains("half_car", 0.005, 250.0, *W)
    assert abs(g.frac) < 1e-12 and g.k_p.shape == (2, 17)
    assert np.all(np.abs(g.k_p[:, 0]) <= 1e-9 * np.abs(g.k_p).max())
    assert np.all(np.abs(g.k_p[:, 1]) > 1e-3 * np.abs(g.k_p).max())


def test_the_front_guideway_is_estimated_from_the_measured_signals():
    """Without sensor noise, the rise estimated from the gap and the bogie's velocity estimate
    follows the front contact's true rise (observed: correlation 0.999, 5 % RMS error, the
    velocity estimate's high-pass at 0.1 Hz missing the guideway's longest waves)."""
    law = WheelbasePreviewLQ(*W)
    exact = WheelbaseExactPreviewLQ(*W)
    env = DeclaredVehicleEnv(vehicle="half_car", observation="measured", episode_length_s=10.0)
    twin = DeclaredVehicleEnv(vehicle="half_car", observation="full_state", episode_length_s=10.0)
    obs, _ = env.reset(seed=5)
    full, _ = twin.reset(seed=5)
    est, true = [], []
    for _ in range(1999):
        law.act(obs[None, :].astype(np.float64))
        est.append(law._memory["window"][0, -1])
        exact.act(full[None, :].astype(np.float64))
        true.append(exact._memory["window"][0, -1])
        action = np.array([0.2, -0.1])
        obs, *_ = env.step(action)
        full, *_ = twin.step(action)
    est, true = np.array(est[400:]), np.array(true[400:])  # after the estimator's start
    assert np.corrcoef(est, true)[0, 1] > 0.99
    assert np.sqrt(np.mean((est - true) ** 2)) <= 0.1 * np.sqrt(np.mean(true**2))
