"""The surveyed guideway ahead of each bogie of the half-car (``CapsuleHalfRidePreview-v0``).

Independent facts, read from the guideway the contacts then meet (``info``), not from the
preview code:

- a perfect survey (no map error, no position error), points one control step apart: each
  bogie's ``preview_ahead_k`` now is its own contact's elevation ``k`` steps later minus now;
- with the default survey error: the rear bogie's preview, a wheelbase later, is the front's
  (one map, one position error per vehicle); it differs from the true guideway by the map's
  error (millimetres at most, not zero);
- the single env, the native vector env, the SB3 VecEnv and ``gymnasium.make`` of the task
  agree, with the preview in the spaces (+-1 m bounds);
- the survey-preview LQ's gains are Tomizuka's: a finite-horizon brute force on the same
  sampled plant gives the same first move.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401 (registers the tasks)
from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv
from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv

TASK = {"vehicle": "half_car", "setting": "hils", "observation": "measured"}
P = 32
PERFECT = {"survey_offset_m": 0.0, "survey_noise_m": 0.0, "position_error_m": 0.0}
MEASURED_WIDTH = 16  # 8 measured columns per bogie


def _run(env, steps, seed):
    obs, info = env.reset(seed=seed)
    z, o = [info["guideway_elevation_m"]], [obs]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(np.zeros(2))
        assert not (terminated or truncated)
        z.append(info["guideway_elevation_m"])
        o.append(obs)
    return np.array(z), np.array(o)


def test_a_perfect_survey_is_each_bogies_own_guideway_later():
    env = DeclaredVehicleEnv(**TASK, **PERFECT, preview_points=P, preview_horizon_s=P * 0.005,
                             episode_length_s=1.0)  # fmt: skip
    z, obs = _run(env, 80, seed=3)
    for c in range(2):  # front, rear
        cols = obs[:, MEASURED_WIDTH + c * P : MEASURED_WIDTH + (c + 1) * P]
        for t in (0, 7, 40):
            truth = z[t + 1 : t + P + 1, c] - z[t, c]
            assert np.std(truth) > 1e-4
            np.testing.assert_allclose(cols[t], truth, rtol=0, atol=1e-8)  # float32 of mm


def test_the_rear_previews_a_wheelbase_later_what_the_front_previewed():
    """Bogies 22.5 m apart: 0.1 s = 20 control steps at 810 km/h."""
    geometry = {"front_bogie_position_m": 11.25, "rear_bogie_position_m": -11.25}
    env = DeclaredVehicleEnv(**TASK, vehicle_params=geometry, preview_points=P,
                             preview_horizon_s=0.5, episode_length_s=1.0)  # fmt: skip
    z, obs = _run(env, 60, seed=5)
    front = obs[:, MEASURED_WIDTH : MEASURED_WIDTH + P]
    rear = obs[:, MEASURED_WIDTH + P :]
    np.testing.assert_allclose(rear[20:], front[:-20], rtol=0, atol=1e-8)
    perfect = DeclaredVehicleEnv(**TASK, **PERFECT, vehicle_params=geometry, preview_points=P,
                                 preview_horizon_s=0.5, episode_length_s=1.0)  # fmt: skip
    _, ideal = _run(perfect, 60, seed=5)
    error = np.abs(obs[:, MEASURED_WIDTH:] - ideal[:, MEASURED_WIDTH:])
    assert 1e-6 < error.max() < 5e-3  # the map's error (5e-4 offset, 1e-4 noise) and position
    # the measured signals do not depend on the preview
    np.testing.assert_array_equal(obs[:, :MEASURED_WIDTH], ideal[:, :MEASURED_WIDTH])


def test_the_task_the_vector_envs_and_the_spaces_agree():
    env = gym.make("CapsuleHalfRidePreview-v0", episode_length_s=0.5)
    space = env.observation_space
    assert space.shape == (MEASURED_WIDTH + 2 * P,) and env.action_space.shape == (2,)
    assert np.all(space.low[MEASURED_WIDTH:] == -1.0) and np.all(space.high[MEASURED_WIDTH:] == 1.0)
    # the measured columns at the quarter-car's bounds of their quantities (helper 48)
    assert np.all(np.isfinite(space.low[:MEASURED_WIDTH])) and space.low[2] == -100.0
    names = env.unwrapped.observation_names
    assert names[MEASURED_WIDTH] == "front_guideway_preview_ahead_1"
    assert names[-1] == f"rear_guideway_preview_ahead_{P}"
    kwargs = {**TASK, "preview_points": P, "preview_horizon_s": 0.5, "episode_length_s": 0.5}
    vec = DeclaredVectorEnv(2, **kwargs)
    sb3 = DeclaredSB3VecEnv(2, **kwargs)
    sb3.seed(11)
    obs_vec, _ = vec.reset(seed=11)
    obs_sb3 = sb3.reset()
    single, _ = env.reset(seed=11)
    assert sb3.observation_space == vec.single_observation_space == space
    np.testing.assert_array_equal(obs_vec, obs_sb3)
    np.testing.assert_array_equal(obs_vec[0], single)
    assert np.any(single[MEASURED_WIDTH:] != 0.0)  # the first observation has its preview
    for _ in range(5):
        a = np.full((2, 2), 0.3)
        obs_vec = vec.step(a)[0]
        sb3.step_async(a)
        obs_sb3 = sb3.step_wait()[0]
        single = env.step(a[0])[0]
    np.testing.assert_array_equal(obs_vec, obs_sb3)
    np.testing.assert_array_equal(obs_vec[0], single)


def test_the_preview_is_refused_outside_its_range_by_name():
    with pytest.raises(ValueError, match="preview_points"):
        DeclaredVehicleEnv(**TASK, preview_points=65)


def test_the_survey_preview_gains_are_the_finite_horizon_optimum():
    """Brute force: minimise the LQ cost over a long finite horizon with a known rise sequence
    under each contact (zero beyond the window), from rest, with the sampled plant and the
    LQR's cost-to-go at its end; the first force is the law's ``-sum_c K_c d_c``."""
    from capsule_env.agents.controllers.lqr import state_weights
    from capsule_env.agents.controllers.wheelbase import _sampled, survey_preview_gains
    from scipy.linalg import solve_discrete_are

    from capsule_env.vehicles import model_named, relative_model

    weights, n_preview, horizon = (0.001, 0.1, 3e-8), 12, 40
    gains, k_c = survey_preview_gains("half_car", 0.005, *weights, n_preview, delay_steps=0)
    model = model_named("half_car")
    params = model.params()
    a, b, e, c, d = _sampled(model, params, 0.005)
    q = c.T @ c + state_weights(model, relative_model(model, params), weights[0], weights[1])
    r = d.T @ d + weights[2] * np.eye(2)
    s = c.T @ d
    rng = np.random.default_rng(0)
    rises = np.zeros((horizon, 2))
    rises[:n_preview] = rng.normal(0.0, 1e-3, (n_preview, 2))
    # the cost is quadratic in the stacked forces: solve the normal equations
    n, m = a.shape[0], 2
    x_f, x_d = np.zeros((horizon, n, horizon * m)), np.zeros((horizon, n))
    xf, xd = np.zeros((n, horizon * m)), np.zeros(n)
    for t in range(horizon):
        x_f[t], x_d[t] = xf, xd
        xf = a @ xf
        xf[:, t * m : (t + 1) * m] += b
        xd = a @ xd + e @ rises[t]
    h, g = np.zeros((horizon * m, horizon * m)), np.zeros(horizon * m)
    for t in range(horizon):
        sel = np.zeros((m, horizon * m))
        sel[:, t * m : (t + 1) * m] = np.eye(m)
        h += x_f[t].T @ q @ x_f[t] + sel.T @ r @ sel + x_f[t].T @ s @ sel + sel.T @ s.T @ x_f[t]
        g += x_f[t].T @ q @ x_d[t] + sel.T @ s.T @ x_d[t]
    p_end = solve_discrete_are(a, b, q, r, s=s)  # the cost beyond the horizon, no rises
    h += xf.T @ p_end @ xf
    g += xf.T @ p_end @ xd
    first = np.linalg.solve(h, -g)[:m]
    law = -np.einsum("cmj,jc->m", k_c, rises[:n_preview])
    np.testing.assert_allclose(law, first, rtol=1e-4, atol=1e-6 * np.abs(first).max())
    assert gains.k_u.shape == (2, 0)


@pytest.mark.parametrize("argv", [["--episodes", "1"], ["--out", "/no/such/folder/x.json"]])
def test_the_preview_evaluation_refuses_bad_input_in_one_line(argv, capsys, tmp_path):
    from capsule_env.evaluation.half_car_preview import main

    assert main(argv) == 2
    err = capsys.readouterr().err
    prog = "python -m capsule_env.evaluation.half_car_preview: error: "
    assert err.startswith(prog) and err.count("\n") == 1
