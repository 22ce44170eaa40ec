"""The stable-baselines3 VecEnv (capsule_env.envs.sb3): SB3's checker, the native vector env's
trajectories bit for bit, the env's own episode length, and the hostile-user cases of
``test_robustness.py`` that concern it. Skipped as a whole without stable-baselines3."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

from conftest import ENV_COMBOS, ENV_ID, NO_SB3

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from stable_baselines3.common.env_checker import check_env  # noqa: E402

import capsule_env  # noqa: E402, F401  (registers the env)
from capsule_env.engine.config import EnvConfig  # noqa: E402
from capsule_env.envs import CapsuleSuspensionVectorEnv  # noqa: E402
from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv  # noqa: E402

pytestmark = pytest.mark.rl


@pytest.mark.parametrize("kwargs", ENV_COMBOS)
def test_sb3_env_checker_passes_without_warnings(kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(ENV_ID, **kwargs), warn=True)


@pytest.mark.parametrize("observation", ["sensors", "measured"])
@pytest.mark.parametrize("setting", ["sim", "hils"])
def test_sb3_vec_env_agrees_with_the_native_vector_env(setting, observation):
    # The native vector env and the SB3 VecEnv seeded with the same int: the same vehicles.
    n, steps, seed = 3, 250, 11
    actions = np.random.default_rng(1).uniform(-1, 1, (steps, n, 1)).astype(np.float32)
    vec = CapsuleSuspensionVectorEnv(num_envs=n, setting=setting, observation=observation)
    sb3 = CapsuleSuspensionSB3VecEnv(num_envs=n, setting=setting, observation=observation)
    sb3.seed(seed)
    v_obs, _ = vec.reset(seed=seed)
    s_obs = sb3.reset()
    np.testing.assert_array_equal(v_obs, s_obs)
    for t in range(steps):
        v_obs, v_rew, *_ = vec.step(actions[t])
        s_obs, s_rew, _, _ = sb3.step(actions[t])
        np.testing.assert_array_equal(v_obs, s_obs)
        np.testing.assert_allclose(v_rew, s_rew, rtol=1e-6)  # SB3 rewards are float32
    assert np.ptp(v_obs[:, 0]) > 0.0  # the vehicles really differ


# ------------------------------------------------------ test_robustness.py 1. episode length
@pytest.mark.parametrize(
    "kwargs", [{"control_rate_hz": 1000.0}, {"episode_length_s": 30.0}, {"episode_length_s": 1.0}]
)
def test_sb3_episode_length_is_the_envs_own(kwargs):
    expected = EnvConfig(**kwargs).max_episode_steps
    sb3 = CapsuleSuspensionSB3VecEnv(2, **kwargs)
    sb3.reset()
    for k in range(expected):
        _, _, dones, infos = sb3.step(np.zeros((2, 1), dtype=np.float32))
        assert dones.all() == (k == expected - 1)
    assert infos[0]["TimeLimit.truncated"]


# ------------------------------------------------- test_robustness.py 18, 19. num_envs, order
@pytest.mark.parametrize("num_envs, error", [(1.5, TypeError), ("4", TypeError), (0, ValueError)])
def test_sb3_num_envs_must_be_a_positive_integer(num_envs, error):
    with pytest.raises(error, match="num_envs"):
        CapsuleSuspensionSB3VecEnv(num_envs)


def test_sb3_stepping_before_reset_raises():
    with pytest.raises(ResetNeeded):
        CapsuleSuspensionSB3VecEnv(2).step(np.zeros((2, 1)))
