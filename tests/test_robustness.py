"""The env as a hostile user drives it: every case here once returned a wrong number, hung,
crashed or was accepted silently. Each test names the case; the scripts' cases are in
``test_robustness_scripts.py``, the SB3 VecEnv's in ``test_sb3.py``."""

from __future__ import annotations

import math
import multiprocessing as mp

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import capsule_env  # noqa: F401  (registers the env)
from capsule_env.dampers import BiExponentialDamper, TanhDamper
from capsule_env.dampers.inverse import bi_exponential_inverse, tanh_inverse
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

from conftest import ENV_ID


# ------------------------------------------------------------------ 1. episode length
@pytest.mark.parametrize(
    "kwargs", [{"control_rate_hz": 1000.0}, {"episode_length_s": 30.0}, {"episode_length_s": 1.0}]
)
def test_episode_length_is_the_envs_own_everywhere(kwargs):
    expected = EnvConfig(**kwargs).max_episode_steps
    env = gym.make(ENV_ID, **kwargs)
    assert env.spec.max_episode_steps == expected
    env.reset(seed=0)
    steps, done = 0, False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(1, dtype=np.float32))
        steps += 1
        done = terminated or truncated
    assert steps == expected and truncated and not terminated
    vec = gym.make_vec(ENV_ID, num_envs=2, **kwargs)
    vec.reset(seed=0)
    for k in range(expected):
        _, _, terminated, truncated, _ = vec.step(np.zeros((2, 1), dtype=np.float32))
        assert truncated.all() == (k == expected - 1)


def test_a_time_limit_asked_of_gymnasium_make_still_applies():
    env = gym.make(ENV_ID, max_episode_steps=7)
    env.reset(seed=0)
    for _ in range(7):
        *_, truncated, _ = env.step(np.zeros(1, dtype=np.float32))
    assert truncated


# ------------------------------------------------------------------ 2. infos of N = 1
@pytest.mark.parametrize("num_envs", [1, 3])
def test_stored_infos_keep_their_own_step(num_envs):
    env = CapsuleSuspensionVectorEnv(num_envs=num_envs)
    env.reset(seed=0)
    kept, at_the_time = [], []
    for _ in range(5):
        *_, info = env.step(np.full((num_envs, 1), 0.5, dtype=np.float32))
        kept.append(info["car_body_acceleration_m_s2"])  # the info's own array
        at_the_time.append(info["car_body_acceleration_m_s2"].copy())
    assert len({tuple(v) for v in at_the_time}) == 5  # five different steps
    # and the arrays kept from the infos still hold their own step's values, not a later one's
    np.testing.assert_array_equal(np.array(kept), np.array(at_the_time))


# ------------------------------------------------------------------ 3. one source of speed
def test_guideway_speed_cannot_disagree_with_the_vehicle_speed():
    with pytest.raises(ValueError, match=r"guideway_params\['speed_kmh'\].*speed_kmh"):
        gym.make(ENV_ID, guideway_params={"speed_kmh": 100})
    with pytest.raises(ValueError, match=r"guideway_params\['kind'\].*guideway"):
        gym.make(ENV_ID, guideway_params={"kind": "sine"})
    # speed_kmh alone moves both: the guideway window covers the whole episode
    env = CapsuleSuspensionEnv(speed_kmh=100.0)
    env.reset(seed=0)
    elevation = [env.step(np.zeros(1, dtype=np.float32))[4]["guideway_elevation_m"]
                 for _ in range(2000)]  # fmt: skip
    assert np.std(elevation[-400:]) > 0.1 * np.std(elevation)  # still rough after 8 s


# ------------------------------------------------------------------ 5. independent streams
def test_training_seeds_share_no_vehicle_stream():
    def starts(seed: int) -> set[tuple]:
        batch = CapsuleBatch(EnvConfig(vehicle_randomization=0.5), 32)
        batch.seed(seed)
        batch.reset()
        return {tuple(row) for row in batch.vehicle_params}

    a, b, c = starts(0), starts(1), starts(2)
    assert len(a) == 32 and not (a & b) and not (a & c) and not (b & c)


def test_seed_lists_and_bad_seeds():
    env = CapsuleSuspensionVectorEnv(num_envs=3)
    obs, _ = env.reset(seed=[4, 5, 6])
    single = CapsuleSuspensionEnv()
    np.testing.assert_array_equal(single.reset(seed=5)[0], obs[1])
    with pytest.raises(ValueError, match="list of 3 ints"):
        env.reset(seed=[1, 2])
    for bad in (-1, 2**64):
        with pytest.raises(ValueError, match="seed"):
            env.reset(seed=bad)
    for bad in (1.5, "3", True):
        with pytest.raises(TypeError, match="seed"):
            single.reset(seed=bad)


# ------------------------------------------------------------------ 7. zero request, zero current
@pytest.mark.parametrize("damper", [BiExponentialDamper(), TanhDamper()])
def test_a_request_for_no_force_gives_no_current(damper):
    rng = np.random.default_rng(0)
    x, v = rng.uniform(-0.01, 0.01, 10_000), rng.normal(0.0, 1e-3, 10_000)
    inverse = bi_exponential_inverse if isinstance(damper, BiExponentialDamper) else tanh_inverse
    assert np.all(inverse(damper, 0.0, x, v) == 0.0)
    env = gym.make(ENV_ID, setting="hils")  # a zero action is a request for 0 N
    env.reset(seed=0)
    for _ in range(400):
        *_, info = env.step(np.zeros(1, dtype=np.float32))
        assert info["current_command_a"] == 0.0


# ------------------------------------------------------------------ 8, 9. hangs and memory
def test_absurd_vehicles_are_refused_not_integrated_forever():
    with pytest.raises(ValueError, match="bogie_mass_kg"):
        gym.make(ENV_ID, vehicle_params={"bogie_mass_kg": 1e-9})
    with pytest.raises(ValueError, match="substeps per control step"):
        gym.make(ENV_ID, damper_params={"c1a": 1e12, "alpha_a": 1e12}, setting="hils")


@pytest.mark.parametrize(
    "kwargs, names",
    [
        ({"guideway_params": {"spacing_m": 1e-6}}, "spacing_m"),
        ({"episode_length_s": 1e5}, "episode_length_s"),
        ({"guideway_bank_size": 4096, "episode_length_s": 3000.0}, "guideway_bank_size"),
    ],
)
def test_memory_is_checked_before_anything_large_is_allocated(kwargs, names):
    with pytest.raises(ValueError, match=f"memory.*{names}"):
        gym.make(ENV_ID, **kwargs)


def test_a_batch_too_large_for_memory_names_num_envs():
    with pytest.raises(ValueError, match="num_envs"):
        CapsuleSuspensionVectorEnv(num_envs=10**11)


# ------------------------------------------------------------------ 10. fork after threads
def _child_steps(queue):
    env = CapsuleSuspensionVectorEnv(num_envs=80)
    env.reset(seed=0)
    env.step(np.zeros((80, 1), dtype=np.float32))
    queue.put("ok")


def test_a_fork_after_the_threaded_kernel_works():
    env = CapsuleSuspensionVectorEnv(num_envs=80)  # >= 64: split across threads
    env.reset(seed=0)
    env.step(np.zeros((80, 1), dtype=np.float32))
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child_steps, args=(queue,))
    child.start()
    child.join(120)
    assert child.exitcode == 0 and queue.get(timeout=5) == "ok"


# ------------------------------------------------------------------ 17. argument types
@pytest.mark.parametrize(
    "kwargs, error, name",
    [
        ({"max_force_n": "8000"}, TypeError, "max_force_n"),
        ({"control_delay_steps": math.nan}, TypeError, "control_delay_steps"),
        ({"control_delay_steps": True}, TypeError, "control_delay_steps"),
        ({"guideway_seed": None}, TypeError, "guideway_seed"),
        ({"guideway_seed": -1}, ValueError, "guideway_seed"),
        ({"guideway_seed": 1.5}, TypeError, "guideway_seed"),
        ({"guideway_bank_size": 1.5}, TypeError, "guideway_bank_size"),
        ({"speed_range_kmh": (100, math.inf)}, ValueError, "speed_range_kmh"),
        ({"speed_range_kmh": 100}, TypeError, "speed_range_kmh"),
        ({"speed_range_kmh": (100,)}, TypeError, "speed_range_kmh"),
        ({"substeps": 2.5}, TypeError, "substeps"),
        ({"episode_length_s": 0.001}, ValueError, "episode_length_s"),
        ({"setting": 1}, TypeError, "setting"),
        ({"vehicle_params": {"car_body_mass_kg": "6000"}}, TypeError, "car_body_mass_kg"),
        ({"damper_params": {"c0a": None}, "setting": "hils"}, TypeError, "c0a"),
        ({"guideway_params": {"peak_m": "0.01"}}, TypeError, "peak_m"),
    ],
)
def test_bad_argument_types_and_ranges_name_the_argument(kwargs, error, name):
    with pytest.raises(error, match=name):
        gym.make(ENV_ID, **kwargs)


# ------------------------------------------------------------------ 18. shapes and num_envs
def test_actions_of_the_wrong_shape_are_refused():
    env = CapsuleSuspensionEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(1,\)"):
        env.step(np.zeros(2))
    with pytest.raises(TypeError, match="action"):
        env.step("fast")
    env.step(np.zeros(1))  # the action space's shape
    env.step(0.3)  # and a plain number
    vec = CapsuleSuspensionVectorEnv(num_envs=4)
    vec.reset(seed=0)
    for bad in (np.zeros((2, 2)), np.zeros(3), np.zeros((4, 2))):
        with pytest.raises(ValueError, match=r"\(4, 1\)"):
            vec.step(bad)
    vec.step(np.zeros((4, 1)))
    vec.step(np.zeros(4))


@pytest.mark.parametrize("num_envs, error", [(1.5, TypeError), ("4", TypeError), (0, ValueError)])
def test_num_envs_must_be_a_positive_integer(num_envs, error):
    with pytest.raises(error, match="num_envs"):
        CapsuleSuspensionVectorEnv(num_envs=num_envs)


# ------------------------------------------------------------------ 19. order of calls
def test_stepping_before_reset_or_after_the_end_raises():
    env = CapsuleSuspensionEnv(episode_length_s=0.02)
    with pytest.raises(ResetNeeded):
        env.step(np.zeros(1))
    env.reset(seed=0)
    for _ in range(4):
        *_, truncated, _ = env.step(np.zeros(1))
    assert truncated
    with pytest.raises(ResetNeeded):
        env.step(np.zeros(1))
    with pytest.raises(ResetNeeded):
        CapsuleSuspensionVectorEnv(num_envs=2).step(np.zeros((2, 1)))


def test_unknown_reset_options_are_refused():
    with pytest.raises(ValueError, match="unknown reset option"):
        CapsuleSuspensionEnv().reset(seed=0, options={"difficulty": 3})
    with pytest.raises(ValueError, match="unknown reset option"):
        CapsuleSuspensionVectorEnv(num_envs=2).reset(options={"difficulty": 3})


# ------------------------------------------------------------------ 20. the documented space
def test_observation_space_is_bounded_as_documented():
    env = CapsuleSuspensionEnv()
    assert np.all(np.isfinite(env.observation_space.low))
    assert np.all(np.isfinite(env.observation_space.high))
    assert "Box(-inf, inf" not in CapsuleSuspensionEnv.__doc__
