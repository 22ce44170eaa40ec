"""Hostile inputs to the half-car's envs and the certified floor (session 12 review): each
refused with one clear error instead of running on silently."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env.bounds import check_floor
from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv
from capsule_env.envs.declared_vector import DeclaredVectorEnv

HALF = {"vehicle": "half_car", "setting": "hils", "observation": "measured"}


def test_sb3_vecenv_refuses_non_finite_actions():
    venv = DeclaredSB3VecEnv(2, **HALF)
    venv.reset()
    for bad in (np.nan, np.inf):
        actions = np.zeros((2, 2))
        actions[1, 0] = bad
        with pytest.raises(ValueError, match="finite"):
            venv.step_async(actions)


def test_batched_envs_refuse_complex_actions():
    venv = DeclaredVectorEnv(2, **HALF)
    venv.reset(seed=0)
    with pytest.raises(TypeError, match="complex"):
        venv.step(np.zeros((2, 2)) + 1j)
    sb3 = DeclaredSB3VecEnv(2, **HALF)
    sb3.reset()
    with pytest.raises(TypeError, match="complex"):
        sb3.step_async(np.zeros((2, 2)) + 1j)


def test_sb3_vecenv_step_before_reset_raises():
    venv = DeclaredSB3VecEnv(2, **HALF)
    with pytest.raises(ResetNeeded):
        venv.step_async(np.zeros((2, 2)))


def test_vector_env_step_before_reset_raises():
    venv = DeclaredVectorEnv(2, **HALF)
    with pytest.raises(ResetNeeded):
        venv.step(np.zeros((2, 2)))
    venv.reset(seed=0)
    venv.step(np.zeros((2, 2)))  # after a reset it steps


def test_single_env_refuses_complex_action():
    env = gym.make("CapsuleHalfRide-v0")
    env.reset(seed=0)
    with pytest.raises(TypeError, match="action"):
        env.step(np.array([0.5 + 1j, 0.0]))


def test_single_env_accepts_numpy_integer_seed():
    env = gym.make("CapsuleHalfRide-v0")
    obs_np, _ = env.reset(seed=np.int64(3))
    obs_int, _ = env.reset(seed=3)
    assert np.array_equal(obs_np, obs_int)


def test_floor_refuses_a_second_episode_length_in_env_kwargs():
    # the env's episode_length_s used to win silently while the result named the argument's
    with pytest.raises(ValueError, match="episode_length_s"):
        check_floor({"setting": "sim", "episode_length_s": 0.2}, [1000], 0.1)
    check_floor({"setting": "sim", "episode_length_s": 0.1}, [1000], 0.1)  # the same: fine


@pytest.mark.parametrize("length", [None, [0.1], "0.1", True])
def test_floor_refuses_a_non_number_episode_length(length):
    with pytest.raises(TypeError, match="episode_length_s"):
        check_floor({"setting": "sim"}, [1000], length)


def test_floor_cli_uses_the_library_default_iterations(monkeypatch, capsys):
    # the CLI ran 100 L-BFGS-B iterations where certified_floor's documented default is 30
    import capsule_env.bounds.__main__ as cli
    from capsule_env.bounds import DEFAULT_OPTIONS

    seen = {}

    def fake(env_kwargs, seeds, length, **options):
        seen.update(options)
        raise ValueError("stop")

    monkeypatch.setattr(cli, "certified_floor", fake)
    with pytest.raises(SystemExit):
        cli.main(["--episodes", "1", "--episode-length", "0.1"])
    assert seen["max_iterations"] == DEFAULT_OPTIONS["max_iterations"] == 30
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    assert "2.2 s" in capsys.readouterr().out  # the length it takes, not just "(0, 10]"
