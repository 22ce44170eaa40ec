"""The preview LQ law against a brute-force solution of the finite-horizon problem it solves."""

from __future__ import annotations

import numpy as np
import pytest
from capsule_env.agents.controllers.preview_lq import (
    plant_matrices,
    preview_lq_gains,
    preview_rises,
)
from scipy.linalg import expm

from capsule_env.vehicles import VehicleParams

DT = 0.005
WEIGHTS = {"q_stroke": 1.0e3, "q_gap": 1.0e4, "r_force": 1.0e-9}


def _brute_force_first_force(vehicle, x0, in_flight, rises, delay, horizon):
    """The first force of the deterministic optimum over ``horizon`` intervals (a least-squares
    problem in all the forces at once), for a guideway with the given ``rises`` then level,
    built from the continuous-time plant (its own discretisation, not plant_matrices')."""
    mc, mb = vehicle.car_body_mass_kg, vehicle.bogie_mass_kg
    ks, kp = vehicle.secondary_stiffness_n_per_m, vehicle.levitation_stiffness_n_per_m
    a_c = np.array([[0, 1, 0, -1], [-ks / mc, 0, 0, 0], [0, 0, 0, 1], [ks / mb, 0, -kp / mb, 0]])
    inputs = np.array([[0, 0], [-1 / mc, 0], [0, -1], [1 / mb, 0]])  # [F, guideway velocity]
    aug = np.zeros((6, 6))
    aug[:4, :4], aug[:4, 4:] = a_c, inputs
    phi = expm(aug * DT)
    a, b, e = phi[:4, :4], phi[:4, 4], phi[:4, 5] / DT
    d = np.zeros(horizon)
    d[: len(rises)] = rises
    applied_known = list(reversed(in_flight))  # oldest first: applied at k = 0, 1, ...
    # x_k = a^k x0 + sum_j a^(k-1-j) (b F_applied_j + e d_j): affine in the requests
    n_u = horizon
    x_const = np.zeros((horizon + 1, 4))
    x_lin = np.zeros((horizon + 1, 4, n_u))
    x_const[0] = x0
    f_const, f_lin = np.zeros(horizon), np.zeros((horizon, n_u))
    for k in range(horizon):  # the force applied at k
        if k < delay:
            f_const[k] = applied_known[k]
        else:
            f_lin[k, k - delay] = 1.0
    for k in range(horizon):
        x_const[k + 1] = a @ x_const[k] + b * f_const[k] + e * d[k]
        x_lin[k + 1] = a @ x_lin[k] + np.outer(b, f_lin[k])
    rows, rhs = [], []
    for k in range(horizon):
        acc_lin = (-ks / mc) * x_lin[k, 0] - f_lin[k] / mc
        acc_const = (-ks / mc) * x_const[k, 0] - f_const[k] / mc
        rows += [acc_lin, np.sqrt(WEIGHTS["q_stroke"]) * x_lin[k, 0]]
        rhs += [-acc_const, -np.sqrt(WEIGHTS["q_stroke"]) * x_const[k, 0]]
        rows += [np.sqrt(WEIGHTS["q_gap"]) * x_lin[k, 2]]
        rhs += [-np.sqrt(WEIGHTS["q_gap"]) * x_const[k, 2]]
        unit = np.zeros(n_u)
        unit[k] = np.sqrt(WEIGHTS["r_force"])
        rows.append(unit)
        rhs.append(0.0)
    forces = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
    return forces[0]


@pytest.mark.parametrize("delay", [0, 1])
def test_preview_law_is_the_finite_horizon_optimum(delay):
    vehicle = VehicleParams()
    n_preview = 60
    gains = preview_lq_gains(vehicle, DT, n_preview, delay_steps=delay, **WEIGHTS)
    rng = np.random.default_rng(5)
    x0 = np.array([2e-3, 0.02, -1e-3, -0.05])
    in_flight = rng.normal(0, 500.0, delay)
    rises = rng.normal(0, 2e-4, n_preview)  # a rough guideway for 0.3 s, then level
    law = -(gains.state_gain @ x0 + gains.delay_gain @ in_flight + gains.preview_gain @ rises)
    best = _brute_force_first_force(vehicle, x0, in_flight, rises, delay, horizon=700)
    assert law == pytest.approx(best, rel=1e-6, abs=1e-6)
    # the preview matters: without it the first force differs
    assert abs(law + gains.state_gain @ x0 + gains.delay_gain @ in_flight) > 0.05 * abs(law)


@pytest.mark.parametrize("delay", [0, 2])
def test_preview_gains_solve_the_augmented_riccati_equation(delay):
    # The law's per-point recursion against the Riccati equation of the whole augmented
    # system [plant; requests in flight; preview window] solved at once (built here).
    from scipy.linalg import solve_discrete_are

    vehicle, n_preview = VehicleParams(), 30
    q_s, q_g, r_f = WEIGHTS["q_stroke"], WEIGHTS["q_gap"], WEIGHTS["r_force"]
    gains = preview_lq_gains(vehicle, DT, n_preview, q_s, q_g, r_f, delay_steps=delay)
    a, b, e, c, d = plant_matrices(vehicle, DT)
    size = 4 + delay + n_preview
    big_a, big_b = np.zeros((size, size)), np.zeros(size)
    big_a[:4, :4] = a
    if delay:
        big_a[:4, 4 + delay - 1] = b
        for i in range(1, delay):
            big_a[4 + i, 4 + i - 1] = 1.0
        big_b[4] = 1.0
    else:
        big_b[:4] = b
    big_a[:4, 4 + delay] = e
    for i in range(n_preview - 1):
        big_a[4 + delay + i, 4 + delay + i + 1] = 1.0
    out = np.zeros(size)  # body acceleration = out @ X + d_direct F
    out[:4] = c
    d_direct = d
    if delay:
        out[4 + delay - 1], d_direct = d, 0.0
    q = np.outer(out, out)
    q[0, 0] += q_s
    q[2, 2] += q_g
    r = np.array([[d_direct**2 + r_f]])
    cross = (out * d_direct)[:, None]
    p = solve_discrete_are(big_a, big_b[:, None], q, r, s=cross)
    k = (big_b @ p @ big_a + cross[:, 0]) / (r[0, 0] + big_b @ p @ big_b)
    np.testing.assert_allclose(gains.state_gain, k[:4], rtol=1e-7)
    np.testing.assert_allclose(gains.delay_gain, k[4 : 4 + delay], rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(gains.preview_gain, k[4 + delay :], rtol=1e-6,
                               atol=1e-9 * np.abs(k).max())  # fmt: skip


def test_preview_gain_fades_ahead_and_zero_window_is_plain_lqr():
    vehicle = VehicleParams()
    long = preview_lq_gains(vehicle, DT, 200, **WEIGHTS)
    none = preview_lq_gains(vehicle, DT, 0, **WEIGHTS)
    np.testing.assert_allclose(long.state_gain, none.state_gain, rtol=1e-9)
    magnitude = np.abs(long.preview_gain)
    assert magnitude[-20:].max() < 0.05 * magnitude.max()  # 1 s ahead hardly matters
    # the sampled plant is exact: two intervals of dt are one of 2 dt (semigroup), and a rise
    # held over an interval lowers the gap by about that rise
    a, b, e, _, _ = plant_matrices(vehicle, DT)
    a2, b2, _, _, _ = plant_matrices(vehicle, 2 * DT)
    np.testing.assert_allclose(a @ a, a2, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(a @ b + b, b2, rtol=1e-10, atol=1e-14)
    assert e[2] == pytest.approx(-1.0, rel=1e-2)


def test_preview_rises_interpolate_the_survey_points():
    # a ramp of 2 mm/s sampled at 12 points 0.02 s apart: every 5 ms rise is 10 um, and beyond
    # the last point (0.24 s) the elevation is held, so the rises are zero
    slope, step = 2e-3, 0.02
    preview = slope * step * np.arange(1, 13)[None, :].repeat(3, axis=0)
    rises = preview_rises(preview, step, DT, 60)
    assert rises.shape == (3, 60)
    np.testing.assert_allclose(rises[:, :48], slope * DT, rtol=1e-9)
    np.testing.assert_allclose(rises[:, 48:], 0.0, atol=1e-15)


def test_bad_weights_are_named():
    with pytest.raises(ValueError, match="r_force"):
        preview_lq_gains(VehicleParams(), DT, 10, 1.0, 1.0, 0.0)


def test_controller_applies_the_gains_and_remembers_its_requests():
    from capsule_env.agents.controllers.preview_lq import PreviewLQController

    ctrl = PreviewLQController(q_stroke=10.0, q_levitation=100.0, r_force=1e-8,
                               preview_points=8, preview_horizon_s=0.2)  # fmt: skip
    gains = preview_lq_gains(VehicleParams(), DT, 40, 10.0, 100.0, 1e-8, delay_steps=1)
    rng = np.random.default_rng(1)
    obs = rng.normal(0.0, 0.01, (3, 9 + 8))
    names = ("stroke_m", "car_body_velocity_estimate_m_s", "levitation_gap_m",
             "bogie_velocity_estimate_m_s")  # fmt: skip
    from capsule_env.agents.controllers.base import MEAS

    x = obs[:, [MEAS[n] for n in names]]
    rises = preview_rises(obs[:, 9:], 0.2 / 8, DT, 40)
    first = -(x @ gains.state_gain + rises @ gains.preview_gain)  # nothing in flight yet
    np.testing.assert_allclose(ctrl.desired_force(obs), first, rtol=1e-12)
    second = first - np.clip(first, -8000, 8000) * gains.delay_gain[0]
    np.testing.assert_allclose(ctrl.desired_force(obs), second, rtol=1e-12)
    # a vehicle whose episode starts again forgets what it had in flight
    ctrl.predict(obs, episode_start=np.array([True, False, False]))
    assert ctrl._in_flight[0, 0] == pytest.approx(np.clip(first[0], -8000, 8000) / 1.0)
    assert ctrl.preview and ctrl.env_kwargs["preview_points"] == 8


def test_preview_helps_on_a_bump_with_the_same_weights():
    # Ideal sensors, sim: on a long bump (150 m, 0.67 s at 810 km/h, near the body mode) the
    # preview law (same weights as the clipped LQR) lowers the RMS body acceleration by ~11 %:
    # it starts acting before the bogie reaches the bump. (On a short, sharp bump it cannot: a
    # semi-active damper makes no force before the stroke moves, so the two laws tie there.)
    from capsule_env.agents.controllers.lqr import ClippedOptimalController
    from capsule_env.agents.controllers.preview_lq import PreviewLQController

    from capsule_env.evaluation.episodes import run_episodes

    weights = {"q_stroke": 2.0, "q_levitation": 100.0, "r_force": 3e-8}
    env = {"setting": "sim", "guideway": "bump",
           "guideway_params": {"bump_length_m": 150.0, "position_m": 50.0}}  # fmt: skip
    rms = {}
    for name, ctrl in (
        ("lqr", ClippedOptimalController(observation="full_state", **weights)),
        ("preview", PreviewLQController(observation="full_state", delay_steps=0, **weights)),
    ):
        roll = run_episodes(ctrl, {**ctrl.env_kwargs, **env}, episodes=1, episode_length_s=3.0)
        rms[name] = float(np.sqrt(np.mean(roll.signals["car_body_acceleration_m_s2"] ** 2)))
    assert rms["preview"] < 0.93 * rms["lqr"], rms


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"preview_horizon_s": 0.0}, "preview_horizon_s"),
        ({"preview_points": 0}, "preview_points"),
        ({"delay_steps": -1}, "delay_steps"),
        ({"dt_s": float("nan")}, "dt_s"),
    ],
)
def test_bad_preview_arguments_are_named(kwargs, match):
    from capsule_env.agents.controllers.preview_lq import PreviewLQController

    with pytest.raises(ValueError, match=match):
        PreviewLQController(**kwargs)
