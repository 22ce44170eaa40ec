"""An RL user's review of every registered task (session 16, helper 48): inputs the envs took
silently, options refused under the wrong name or set to no effect, where the native vector
envs differed from Gymnasium's SyncVectorEnv, and the half-car's unbounded observations."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv
from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv
from capsule_env.tasks import DECLARED_TASKS, task_named

SHORT = {"episode_length_s": 0.05}
RIDE = {**task_named("CapsuleRide-v0").kwargs, **SHORT}
HALF = {**DECLARED_TASKS[0].kwargs, **SHORT}


def _not_actions(slots: int) -> list[object]:
    """Actions of the right shape that are not real numbers: numpy used to drop the imaginary
    part (with a ComplexWarning) and parse the strings ("0.5" stepped as 0.5)."""
    return [np.full(slots, 0.5 + 0.5j), np.full(slots, "0.5"), [None] * slots]


@pytest.mark.parametrize("env_id", ["CapsuleRide-v0", "CapsuleHalfRide-v0"])
def test_single_env_refuses_actions_that_are_not_real_numbers(env_id):
    env = gym.make(env_id, **SHORT)
    slots = env.action_space.shape[0]
    fresh = gym.make(env_id, **SHORT)
    env.reset(seed=3)
    fresh.reset(seed=3)
    for bad in _not_actions(slots):
        with pytest.raises(TypeError, match="action must be real numbers"):
            env.step(bad)
    # nothing was stepped: the env goes on as one that never saw them
    zero = np.zeros(slots, dtype=np.float32)
    assert np.array_equal(env.step(zero)[0], fresh.step(zero)[0])
    assert env.step(np.ones(slots, dtype=bool))[0].shape == env.observation_space.shape


def test_quarter_car_batched_envs_refuse_actions_that_are_not_real_numbers():
    vec = gym.make_vec("CapsuleRide-v0", 2, vectorization_mode="vector_entry_point", **SHORT)
    vec.reset(seed=0)
    sb3 = CapsuleSuspensionSB3VecEnv(2, **RIDE)
    sb3.reset()
    for bad in _not_actions(2):
        with pytest.raises(TypeError, match="actions must be real numbers"):
            vec.step(np.asarray(bad).reshape(2, 1))
        with pytest.raises(TypeError, match="actions must be real numbers"):
            sb3.step_async(np.asarray(bad).reshape(2, 1))


def test_declared_batched_envs_refuse_string_actions():
    vec = DeclaredVectorEnv(2, **HALF)
    vec.reset(seed=0)
    sb3 = DeclaredSB3VecEnv(2, **HALF)
    sb3.reset()
    strings = np.full((2, 2), "0.5")
    with pytest.raises(TypeError, match="actions must be real numbers"):
        vec.step(strings)
    with pytest.raises(TypeError, match="actions must be real numbers"):
        sb3.step_async(strings)


def test_declared_vector_env_names_render_mode_for_what_it_is():
    # make_vec passes render_mode on; it used to be refused as an unknown argument
    with pytest.raises(ValueError, match="render_mode must be None for a declared vehicle"):
        gym.make_vec(
            "CapsuleHalfRide-v0", 2, vectorization_mode="vector_entry_point",
            render_mode="rgb_array", **SHORT,
        )  # fmt: skip
    venv = DeclaredVectorEnv(2, render_mode=None, **HALF)
    assert venv.render_mode is None
    assert venv.metadata["render_fps"] == 200  # one frame per control step, as the single env


@pytest.mark.parametrize("env_id", ["CapsuleRidePreview-v0", "CapsuleHalfRidePreview-v0"])
def test_vector_entry_point_takes_none_in_a_seed_list_as_sync_does(env_id):
    # Gymnasium's VectorEnv.reset takes seed: list[int | None]; a None sub-env goes on with
    # its own stream. The native vector envs refused None with a TypeError. The preview
    # columns read the guideway window each reset draws, so equal observations mean equal
    # draws.
    native = gym.make_vec(env_id, 3, vectorization_mode="vector_entry_point", **SHORT)
    sync = gym.make_vec(env_id, 3, vectorization_mode="sync", **SHORT)
    for seeds in ([1, 2, 3], [4, None, 6], [None, None, 9], [None, None, None]):
        obs_native, _ = native.reset(seed=seeds)
        obs_sync, _ = sync.reset(seed=seeds)
        assert np.array_equal(obs_native, obs_sync), seeds
    with pytest.raises(TypeError, match=r"seed\[1\]"):
        native.reset(seed=[1, 2.5, None])


def test_reset_mask_with_none_seeds_as_sync_does():
    native = gym.make_vec("CapsuleRidePreview-v0", 3, vectorization_mode="vector_entry_point",
                          autoreset_mode="Disabled", **SHORT)  # fmt: skip
    sync = gym.make_vec("CapsuleRidePreview-v0", 3, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": "Disabled"}, **SHORT)  # fmt: skip
    native.reset(seed=[1, 2, 3])
    sync.reset(seed=[1, 2, 3])
    mask = np.array([True, True, False])
    obs_native, _ = native.reset(seed=[None, 7, None], options={"reset_mask": mask})
    obs_sync, _ = sync.reset(seed=[None, 7, None], options={"reset_mask": mask})
    assert np.array_equal(obs_native, obs_sync)


@pytest.mark.parametrize("make", [lambda: CapsuleSuspensionSB3VecEnv(2, **RIDE),
                                  lambda: DeclaredSB3VecEnv(2, **HALF)])  # fmt: skip
def test_sb3_set_attr_refuses_an_env_option_it_cannot_change(make):
    # get_attr reads the options from the (frozen) config; set_attr used to set a stray
    # attribute on the VecEnv instead: the change did nothing, and get_attr still read the old
    # value (a curriculum through set_attr would have trained on the old reward, silently).
    venv = make()
    before = venv.get_attr("reward_stroke_weight")
    with pytest.raises(ValueError, match="reward_stroke_weight"):
        venv.set_attr("reward_stroke_weight", 5.0)
    assert venv.get_attr("reward_stroke_weight") == before == [0.1, 0.1]
    venv.set_attr("my_counter", 3)  # an attribute of the user's own still round-trips
    assert venv.get_attr("my_counter", indices=[1]) == [3]


@pytest.mark.parametrize("mode", ["human", "rgb", "ansi"])
def test_sb3_vecenv_refuses_a_render_mode_it_does_not_draw(mode):
    # "human" went to SB3's env_method("render"), which drew frames and showed none; "rgb"
    # was taken as given. The frames are "rgb_array"; SB3's render(mode="human") shows them.
    with pytest.raises(ValueError, match="render_mode must be None or 'rgb_array'"):
        CapsuleSuspensionSB3VecEnv(2, render_mode=mode, **RIDE)
    with pytest.raises(ValueError, match="render_mode must be None for a declared vehicle"):
        DeclaredSB3VecEnv(2, render_mode=mode, **HALF)


def test_sb3_vecenvs_take_the_render_modes_they_draw():
    venv = CapsuleSuspensionSB3VecEnv(2, render_mode="rgb_array", **RIDE)
    venv.reset()
    frame = venv.render()  # SB3 tiles the vehicles' frames
    assert frame.ndim == 3 and frame.dtype == np.uint8
    assert DeclaredSB3VecEnv(2, render_mode=None, **HALF).render_mode is None


def _same_infos(a: dict, b: dict) -> bool:
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


def test_declared_vector_env_info_as_sync_gives_it():
    # Gymnasium's vector info: every key with its "_key" mask (SyncVectorEnv's, and the
    # quarter-car's native vector env's); the half-car's native one gave the values only.
    native = gym.make_vec("CapsuleHalfRide-v0", 2, vectorization_mode="vector_entry_point",
                          **SHORT)  # fmt: skip
    sync = gym.make_vec("CapsuleHalfRide-v0", 2, vectorization_mode="sync", **SHORT)
    assert _same_infos(native.reset(seed=[5, 6])[1], sync.reset(seed=[5, 6])[1])
    actions = np.full((2, 2), 0.3, dtype=np.float32)
    for _ in range(12):  # past the end of the 10-step episodes: the autoreset step too
        assert _same_infos(native.step(actions)[4], sync.step(actions)[4])


def test_declared_vector_env_info_when_some_vehicles_restart():
    # a bump stop 2 mm away ends the episodes at different steps: at an autoreset step the
    # restarted vehicles hold their reset info (reward terms 0), as in SyncVectorEnv
    kw = {**SHORT, "stroke_limit_m": 0.002, "episode_length_s": 0.3}
    native = gym.make_vec("CapsuleHalfRide-v0", 3, vectorization_mode="vector_entry_point", **kw)
    sync = gym.make_vec("CapsuleHalfRide-v0", 3, vectorization_mode="sync", **kw)
    native.reset(seed=[1, 2, 3])
    sync.reset(seed=[1, 2, 3])
    rng = np.random.default_rng(0)
    partial, ended = 0, np.zeros(3, dtype=bool)
    for _ in range(60):
        actions = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        partial += 0 < ended.sum() < 3  # some vehicles restart at this step, not all
        _, _, terminated, truncated, info = native.step(actions)
        assert _same_infos(info, sync.step(actions)[4])
        ended = terminated | truncated
    assert partial > 0  # the case this test is for happened


def test_declared_vector_env_seeds_its_own_generator_as_the_quarter_cars():
    # VectorEnv.reset(seed=s) seeds the vector env's np_random (the quarter-car's does); the
    # half-car's left it on fresh entropy, so np_random differed run to run for one seed
    draws = []
    for _ in range(2):
        venv = gym.make_vec("CapsuleHalfRide-v0", 2, vectorization_mode="vector_entry_point",
                            **SHORT)  # fmt: skip
        venv.reset(seed=5)
        assert venv.np_random_seed == 5
        draws.append(venv.np_random.integers(2**62))
    assert draws[0] == draws[1]


@pytest.mark.parametrize("env_id", ["CapsuleRide-v0", "CapsuleHalfRide-v0"])
def test_a_longer_time_limit_is_reported_by_the_wrapper_not_the_env(env_id):
    # docs/env.md: the env's own 0.05 s (10 steps) ends the episode; the TimeLimit of 50 steps
    # is what Gymnasium's wrapper reports as env.spec, the env's own is the unwrapped spec's
    env = gym.make(env_id, max_episode_steps=50, **SHORT)
    assert env.spec.max_episode_steps == 50
    assert env.unwrapped.spec.max_episode_steps == 10
    env.reset(seed=0)
    steps = [env.step(np.zeros(env.action_space.shape, np.float32)) for _ in range(10)]
    assert steps[-1][3] and not any(s[3] for s in steps[:-1])


@pytest.mark.filterwarnings("ignore:.*precision lowered")  # RescaleObservation's own Box
@pytest.mark.parametrize("task", DECLARED_TASKS, ids=lambda t: t.env_id)
def test_half_car_tasks_pass_the_checkers_without_a_warning(task):
    # Their observation space was unbounded but for the preview: Gymnasium's and SB3's
    # check_env warned ("A Box observation space minimum value is -infinity") and Gymnasium's
    # RescaleObservation refused the env. Now bounded as the quarter-car's columns are.
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make(task.env_id, **SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_check(env.unwrapped)
        sb3_check(env.unwrapped)
    space = env.observation_space
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    rescaled = gym.wrappers.RescaleObservation(env, -1.0, 1.0)
    assert rescaled.observation_space.contains(rescaled.reset(seed=0)[0])


def test_half_car_observations_saturate_at_the_quarter_cars_bounds():
    quarter = gym.make("CapsuleRide-v0").observation_space
    half = gym.make("CapsuleHalfRide-v0", guideway_params={"peak_m": 0.5}, stroke_limit_m=1.0,
                    **SHORT)  # fmt: skip
    names = half.unwrapped.observation_names
    space = half.observation_space
    # per quantity the quarter-car's bound (stroke: twice the task's bump stop, 1 m here)
    acc = names.index("front_secondary_damper_upper_acceleration_m_s2")
    assert space.high[acc] == quarter.high[0] == 100.0
    assert space.high[names.index("front_secondary_damper_stroke_m")] == 2.0
    assert space.high[names.index("rear_secondary_damper_last_current_command_a")] == 1.5
    half.reset(seed=0)
    saturated = False
    for _ in range(10):  # a 0.5 m guideway: accelerations past 100 m/s^2
        obs = half.step(np.ones(2, dtype=np.float32))[0]
        assert space.contains(obs)
        saturated |= bool(np.any(np.abs(obs) == space.high))
    assert saturated


@pytest.mark.parametrize("make", [lambda: CapsuleSuspensionSB3VecEnv(3, **RIDE),
                                  lambda: DeclaredSB3VecEnv(3, **HALF)])  # fmt: skip
def test_sb3_set_attr_refuses_some_vehicles_only(make):
    # one object serves every index: set_attr(..., indices=[0]) used to set the attribute of
    # every vehicle, and get_attr(..., indices=[2]) read the value meant for vehicle 0
    venv = make()
    with pytest.raises(ValueError, match="indices"):
        venv.set_attr("difficulty", 2.0, indices=[0])
    venv.set_attr("difficulty", 1.0, indices=[0, 1, 2])  # all of them: one value, fine
    venv.set_attr("difficulty", 3.0, indices=range(3))
    assert venv.get_attr("difficulty") == [3.0, 3.0, 3.0]
