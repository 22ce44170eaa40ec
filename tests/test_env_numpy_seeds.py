"""The quarter-car envs take a numpy integer seed as they take the int (check_seed accepts both).

Gymnasium's own seeding refuses anything but a Python int (``gymnasium.error.Error``), so an env
that validated a numpy seed and handed it on as it was crashed after accepting it.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the envs)
from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

OPTIONS = {"episode_length_s": 0.5}


@pytest.mark.parametrize("seed", [np.int64(7), np.uint32(7), np.int32(7)])
def test_the_env_takes_a_numpy_integer_seed_as_the_int(seed):
    env = CapsuleSuspensionEnv(**OPTIONS)
    reference = CapsuleSuspensionEnv(**OPTIONS)
    obs, _ = env.reset(seed=seed)
    expected, _ = reference.reset(seed=7)
    np.testing.assert_array_equal(obs, expected)
    np.testing.assert_array_equal(env.np_random.random(3), reference.np_random.random(3))


@pytest.mark.parametrize("masked", [False, True])
def test_the_vector_env_takes_a_numpy_integer_seed_as_the_int(masked):
    env = CapsuleSuspensionVectorEnv(num_envs=2, **OPTIONS)
    reference = CapsuleSuspensionVectorEnv(num_envs=2, **OPTIONS)
    if masked:  # a partial reset re-seeds the masked vehicles
        env.reset(seed=1)
        reference.reset(seed=1)
    options = {"reset_mask": np.array([True, True])} if masked else None
    obs, _ = env.reset(seed=np.int64(7), options=options)
    expected, _ = reference.reset(seed=7, options=options)
    np.testing.assert_array_equal(obs, expected)
    np.testing.assert_array_equal(env.np_random.random(3), reference.np_random.random(3))


def test_gymnasium_make_takes_a_numpy_integer_seed():
    env = gym.make("CapsuleSuspension-v0", **OPTIONS)
    obs, _ = env.reset(seed=np.int64(7))
    expected, _ = gym.make("CapsuleSuspension-v0", **OPTIONS).reset(seed=7)
    np.testing.assert_array_equal(obs, expected)
