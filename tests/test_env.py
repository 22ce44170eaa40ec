"""CapsuleSuspension-v0: registration, API conformance, determinism, vector equivalence.

The SB3 VecEnv's share of these (its checker, its agreement with the native vector env) is in
``test_sb3.py``, skipped without stable-baselines3."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import capsule_env
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.layout import SIGNAL_NAMES
from capsule_env.envs import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

from conftest import ENV_COMBOS as COMBOS
from conftest import ENV_ID


def _rollout(env, actions, seed):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out.append(np.concatenate([obs, [reward, info["damper_force_n"]]]))
        if terminated or truncated:
            break
    return out


def test_registration_is_idempotent_and_make_works():
    capsule_env._register()
    capsule_env._register()
    env = gym.make(ENV_ID)
    assert isinstance(env.unwrapped, CapsuleSuspensionEnv)
    assert env.spec.max_episode_steps == 2000


def test_make_with_module_prefix_in_fresh_interpreter():
    code = (
        f"import gymnasium as gym; env = gym.make('capsule_env:{ENV_ID}');"
        "env.reset(seed=0); print(env.step(env.action_space.sample())[0].shape)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "(5,)"


def test_make_vec_modes():
    vec = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point")
    assert isinstance(vec.unwrapped, CapsuleSuspensionVectorEnv)
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (3, 5)
    sync = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync")
    obs, _ = sync.reset(seed=0)
    obs, reward, term, trunc, info = sync.step(np.zeros((2, 1), dtype=np.float32))
    assert obs.shape == (2, 5) and reward.shape == (2,)
    sync.close()


@pytest.mark.slow
def test_make_vec_async():
    vec = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="async")
    vec.reset(seed=0)
    obs, reward, *_ = vec.step(np.zeros((2, 1), dtype=np.float32))
    assert obs.shape == (2, 5) and np.all(np.isfinite(reward))
    vec.close()


@pytest.mark.parametrize("kwargs", COMBOS)
def test_gymnasium_env_checker_passes_without_warnings(kwargs):
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(ENV_ID, **kwargs).unwrapped)


@pytest.mark.parametrize("kwargs", COMBOS[:4])
def test_same_seed_same_trajectory(kwargs):
    actions = np.random.default_rng(0).uniform(-1, 1, (300, 1)).astype(np.float32)
    a = _rollout(gym.make(ENV_ID, **kwargs), actions, seed=5)
    b = _rollout(gym.make(ENV_ID, **kwargs), actions, seed=5)
    c = _rollout(gym.make(ENV_ID, **kwargs), actions, seed=6)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


@pytest.mark.parametrize("observation", ["sensors", "measured"])
@pytest.mark.parametrize("setting", ["sim", "hils"])
def test_single_and_native_vector_env_agree(setting, observation):
    n, steps, seed = 3, 250, 11
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (steps, n, 1)).astype(np.float32)
    vec = CapsuleSuspensionVectorEnv(num_envs=n, setting=setting, observation=observation)
    vec.reset(seed=seed)
    # Single envs seeded s_k against a vector env seeded with the list [s_0, s_1, ...];
    # and vehicle 0 of the int-seeded vector env is the single env seeded ``seed``.
    listed = CapsuleSuspensionVectorEnv(num_envs=n, setting=setting, observation=observation)
    l_obs, _ = listed.reset(seed=[seed + 100 * k for k in range(n)])
    singles = [CapsuleSuspensionEnv(setting=setting, observation=observation) for _ in range(n)]
    single_obs = [env.reset(seed=seed + 100 * k)[0] for k, env in enumerate(singles)]
    np.testing.assert_array_equal(np.stack(single_obs), l_obs)
    first = CapsuleSuspensionEnv(setting=setting, observation=observation)
    first.reset(seed=seed)
    for t in range(steps):
        v_obs, v_rew, *_ = vec.step(actions[t])
        l_obs, l_rew, *_ = listed.step(actions[t])
        for k, env in enumerate(singles):
            o, r, *_ = env.step(actions[t, k])
            np.testing.assert_array_equal(o, l_obs[k])
            assert r == l_rew[k]
        o, r, *_ = first.step(actions[t, 0])
        np.testing.assert_array_equal(o, v_obs[0])
        assert r == v_rew[0]


def test_parallel_kernel_matches_serial_bit_for_bit():
    config = EnvConfig(setting="hils")
    big = CapsuleBatch(config, 80)  # chunks on threads
    small = [CapsuleBatch(config, 1) for _ in range(3)]
    big.seed([3 + k for k in range(80)])
    big.reset()
    for k, b in enumerate(small):
        b.seed(3 + k)
        b.reset()
    actions = np.random.default_rng(2).uniform(-1, 1, (200, 80))
    for a in actions:
        big.step(a)
        for k, b in enumerate(small):
            b.step(a[k : k + 1])
    for k, b in enumerate(small):
        np.testing.assert_array_equal(big.state[k], b.state[0])


@pytest.mark.parametrize("num_envs", [1, 80])  # the serial and the threaded kernel
def test_a_deep_copy_steps_on_its_own_arrays(num_envs):
    # The kernel is bound to a batch's arrays at its first step (kernels.EnvArgs). A copy
    # made mid-episode has arrays of its own: stepped with the same actions it follows the
    # original bit for bit, and stepping it leaves the original untouched.
    import copy

    batch = CapsuleBatch(EnvConfig(setting="hils"), num_envs)
    batch.seed(5)
    batch.reset()
    actions = np.random.default_rng(4).uniform(-1, 1, (60, num_envs))
    for a in actions[:20]:
        batch.step(a)
    twin = copy.deepcopy(batch)
    for a in actions[20:40]:
        twin.step(a)
    np.testing.assert_array_equal(batch.step_count, 20)  # the original did not move
    for a in actions[20:40]:
        batch.step(a)
    for name in ("state", "obs", "reward", "signals", "step_count"):
        np.testing.assert_array_equal(getattr(twin, name), getattr(batch, name))
    assert twin.state.ctypes.data != batch.state.ctypes.data


def test_a_deep_copy_of_the_single_env_reports_its_own_signals():
    # The single env reuses one signals buffer; the copy's info must follow the copy's kernel
    # (a deep copy turns the view ``signals`` into an array of its own unless rebuilt).
    import copy

    env = CapsuleSuspensionEnv(setting="hils")
    env.reset(seed=2)
    actions = np.random.default_rng(6).uniform(-1, 1, (30, 1)).astype(np.float32)
    for a in actions[:10]:
        env.step(a)
    twin = copy.deepcopy(env)
    for a in actions[10:]:
        *_, info = env.step(a)
        *_, twin_info = twin.step(a)
        assert twin_info == info
    assert info["stroke_m"] != 0.0
    np.testing.assert_array_equal(twin._batch.applied_current, env._batch.applied_current)
    assert twin._batch.applied_current[0] > 0.0


@pytest.mark.parametrize("num_envs", [1, 80])
def test_an_env_pickled_mid_episode_goes_on_bit_for_bit(num_envs):
    # e.g. sent to a worker process: the compiled kernels are not pickled, the copy finds its
    # own (here from the memo or the disk cache)
    import pickle

    env = CapsuleSuspensionVectorEnv(num_envs=num_envs, setting="hils")
    env.reset(seed=9)
    actions = np.random.default_rng(8).uniform(-1, 1, (40, num_envs, 1)).astype(np.float32)
    for a in actions[:20]:
        env.step(a)
    twin = pickle.loads(pickle.dumps(env))
    for a in actions[20:]:
        obs, reward, *_ = env.step(a)
        twin_obs, twin_reward, *_ = twin.step(a)
        np.testing.assert_array_equal(twin_obs, obs)
        np.testing.assert_array_equal(twin_reward, reward)


@pytest.mark.parametrize(
    "name",
    ["params", "plant_params", "env_state", "obs", "reward", "terminated", "plant_out", "state",
     "step_count", "applied_current", "vehicle_params", "sub_table"],
)  # fmt: skip
def test_what_the_kernel_is_bound_to_cannot_be_replaced(name):
    batch = CapsuleBatch(EnvConfig(), 1)
    with pytest.raises(AttributeError, match=name):
        setattr(batch, name, getattr(batch, name))


def test_nan_action_raises_and_out_of_range_is_clipped():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(np.array([np.nan], dtype=np.float32))
    with pytest.raises(ValueError, match="action"):
        env.step(np.array([np.inf], dtype=np.float32))
    a = _rollout(gym.make(ENV_ID, action_mode="current"), [np.array([5.0])] * 50, seed=1)
    b = _rollout(gym.make(ENV_ID, action_mode="current"), [np.array([1.0])] * 50, seed=1)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    vec = CapsuleSuspensionVectorEnv(num_envs=2)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        vec.step(np.array([[0.0], [np.nan]]))


@pytest.mark.parametrize("damper", ["reference", "bouc_wen", "bi_exponential", "tanh", "passive"])
@pytest.mark.parametrize("setting", ["sim", "hils"])
def test_long_random_rollouts_stay_finite(damper, setting):
    vec = CapsuleSuspensionVectorEnv(num_envs=16, damper=damper, setting=setting)
    vec.reset(seed=0)
    space = vec.single_observation_space
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    rng = np.random.default_rng(0)
    for _ in range(2500):  # crosses an episode boundary (autoreset)
        obs, reward, term, trunc, info = vec.step(rng.uniform(-1, 1, (16, 1)))
        # every vehicle inside the (finite) observation bounds: a NaN or inf fails too
        assert np.all((obs >= space.low) & (obs <= space.high))
        assert obs.shape == (16, *space.shape) and obs.dtype == space.dtype
        assert np.isfinite(reward).all()
        assert np.isfinite(info["damper_force_n"]).all()


def test_info_has_signals_and_reward_terms():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.array([0.3], dtype=np.float32))
    for name in SIGNAL_NAMES:
        assert name in info
    assert reward == pytest.approx(
        -(
            info["cost_acceleration"]
            + info["cost_stroke"]
            + info["cost_energy"]
            + info["cost_velocity"]
        )
    )
    cfg = EnvConfig()
    expected = (
        cfg.reward_acceleration_weight
        * (info["car_body_acceleration_m_s2"] / cfg.acceleration_scale_m_s2) ** 2
    )
    assert info["cost_acceleration"] == pytest.approx(expected)
    vel = CapsuleSuspensionEnv(reward_velocity_weight=2.0)
    vel.reset(seed=0)
    _, _, _, _, info = vel.step(np.array([0.3], dtype=np.float32))
    assert info["cost_velocity"] == pytest.approx(
        2.0 * (info["car_body_velocity_m_s"] / cfg.velocity_scale_m_s) ** 2
    )
    # force mode: desired force is the action times the force scale
    assert info["desired_force_n"] == pytest.approx(0.3 * cfg.max_force_n, rel=1e-6)


def test_truncation_and_termination():
    env = gym.make(ENV_ID, episode_length_s=0.5, max_episode_steps=100)
    env.reset(seed=0)
    for k in range(100):
        _, _, terminated, truncated, _ = env.step(np.zeros(1, dtype=np.float32))
        assert not terminated
        assert truncated == (k == 99)
    env = gym.make(ENV_ID, stroke_limit_m=1e-4, action_mode="current")
    env.reset(seed=0)
    for _ in range(2000):
        _, reward, terminated, _, info = env.step(np.array([-1.0], dtype=np.float32))
        if terminated:
            break
    assert terminated and abs(info["stroke_m"]) > 1e-4
    assert reward < -EnvConfig().bump_stop_penalty


def test_vector_autoreset_next_step():
    vec = CapsuleSuspensionVectorEnv(num_envs=2, episode_length_s=0.05)  # 10 steps
    vec.reset(seed=0)
    zeros = np.zeros((2, 1))
    for _ in range(9):
        _, _, _, trunc, _ = vec.step(zeros)
        assert not trunc.any()
    _, _, _, trunc, _ = vec.step(zeros)
    assert trunc.all()
    obs, reward, term, trunc, _ = vec.step(zeros)  # the autoreset step
    assert np.all(reward == 0.0) and not term.any() and not trunc.any()
    assert np.all(vec.batch.step_count == 0)


def test_hils_knobs_are_separate():
    base = EnvConfig(setting="hils")
    assert base.plant_damper_name == "reference"
    assert base.effective_control_delay_steps == 1
    assert base.effective_sensor_noise > 0
    quiet = EnvConfig(setting="hils", sensor_noise=0.0, control_delay_steps=0)
    env = CapsuleSuspensionEnv(setting="hils", sensor_noise=0.0, control_delay_steps=0)
    env.reset(seed=0)
    obs, *_, info = env.step(np.zeros(1, dtype=np.float32))
    assert obs[2] == pytest.approx(info["stroke_m"], rel=1e-6)  # no noise
    assert quiet.effective_coil_time_constant_s == pytest.approx(1 / 190)
    # one-step delay: the first command is applied one step late (0 A applied first)
    delayed = CapsuleSuspensionEnv(setting="hils", action_mode="current")
    delayed.reset(seed=0)
    delayed.step(np.ones(1, dtype=np.float32))
    assert delayed.batch.state[0, 6] == 0.0  # coil current still 0: command not yet applied
    delayed.step(np.ones(1, dtype=np.float32))
    assert delayed.batch.state[0, 6] > 0.0


def test_domain_randomisation():
    env = CapsuleSuspensionEnv(vehicle_randomization=0.2, speed_range_kmh=(600, 900))
    seen = []
    env.reset(seed=0)
    for _ in range(5):
        env.reset()
        seen.append(np.concatenate([env.batch.vehicle_params[0, :4], env.batch.speed]))
    seen = np.array(seen)
    nominal = capsule_env.VehicleParams().as_array()[:4]  # the levitation damping (0) is not drawn
    assert np.all(np.abs(seen[:, :4] / nominal - 1) <= 0.2 + 1e-12)
    assert np.all((seen[:, 4] >= 600 / 3.6) & (seen[:, 4] <= 900 / 3.6))
    assert np.unique(seen[:, 0]).size == 5


def test_bad_arguments_name_the_parameter():
    with pytest.raises(ValueError, match="action_mode"):
        gym.make(ENV_ID, action_mode="torque")
    with pytest.raises(ValueError, match="damper"):
        gym.make(ENV_ID, damper="magic")
    with pytest.raises(ValueError, match="inverse_model"):
        gym.make(ENV_ID, inverse_model="lut")
    with pytest.raises(ValueError, match="unexpected keyword argument 'speed'"):
        gym.make(ENV_ID, speed=3)
    with pytest.raises(ValueError, match="car_body_mass_kg"):
        gym.make(ENV_ID, vehicle_params={"car_body_mass_kg": -1.0})
    with pytest.raises(ValueError, match="unknown guideway 'cobblestones'"):
        gym.make(ENV_ID, guideway="cobblestones")


def test_render_rgb_array():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(1, dtype=np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3  # something is drawn


def test_guideway_window_is_scaled_to_peak():
    batch = CapsuleBatch(EnvConfig(), 4)
    batch.seed(0)
    batch.reset()
    peaks = []
    for k in range(4):
        t = np.arange(0, 10.0, 0.001)
        pos = batch.start_position[k] + batch.speed[k] * t
        prof = batch.profiles[batch.profile_index[k]]
        z = batch.gain[k] * np.interp(pos / batch.spacing, np.arange(prof.size), prof)
        peaks.append(np.abs(z).max())
    np.testing.assert_allclose(peaks, 0.008, rtol=0.01)


def test_sensor_noise_is_white_gaussian_with_the_documented_std():
    # hils, full_state: every observed channel = its true signal + noise of std
    # SENSOR_NOISE_STD * sensor_noise. The residuals must have that std, zero mean, a Gaussian
    # kurtosis (3) and no correlation between channels (noise comes in Box-Muller pairs) or
    # from one step to the next.
    from capsule_env.engine.config import SENSOR_NOISE_STD

    config = EnvConfig(setting="hils", observation="full_state")
    batch = CapsuleBatch(config, 64)
    batch.seed(3)
    batch.reset()
    rng = np.random.default_rng(0)
    truth_rows = {  # observation column -> signal row
        0: "car_body_displacement_m", 1: "car_body_velocity_m_s", 2: "bogie_displacement_m",
        3: "bogie_velocity_m_s", 4: "guideway_elevation_m", 5: "car_body_acceleration_m_s2",
        6: "bogie_acceleration_m_s2", 7: "stroke_m", 8: "stroke_rate_m_s",
    }  # fmt: skip
    channel_of_column = {0: 4, 1: 5, 2: 6, 3: 7, 4: 8, 5: 0, 6: 1, 7: 2, 8: 3}
    residuals = []
    for _ in range(300):
        batch.step(rng.uniform(-1.0, 1.0, 64))
        obs = batch.obs.astype(np.float64)
        res = np.empty((64, 9))
        for col, name in truth_rows.items():
            res[:, channel_of_column[col]] = obs[:, col] - batch.signals[SIGNAL_NAMES.index(name)]
        residuals.append(res)
    r = np.stack(residuals)  # (steps, vehicles, channels)
    std = (SENSOR_NOISE_STD * config.effective_sensor_noise)[:9]
    z = (r / std).reshape(-1, 9)  # 19200 samples per channel
    assert np.all(np.abs(z.mean(axis=0)) < 0.05)
    np.testing.assert_allclose(z.std(axis=0), 1.0, atol=0.03)
    kurtosis = np.mean(z**4, axis=0) / np.mean(z**2, axis=0) ** 2
    np.testing.assert_allclose(kurtosis, 3.0, atol=0.15)
    corr = np.corrcoef(z.T)
    assert np.max(np.abs(corr - np.eye(9))) < 0.04
    lag1 = np.mean(r[1:] * r[:-1], axis=(0, 1)) / np.mean(r**2, axis=(0, 1))
    assert np.max(np.abs(lag1)) < 0.04


def test_measured_set_noise_of_gap_and_current_sensors():
    # hils, measured: the gap sensor reads z_b - z_g and the current sensor the coil current,
    # each with its own documented noise (channels 9 and 10), independent of each other and of
    # the accelerometers.
    from capsule_env.engine.config import SENSOR_NOISE_STD

    config = EnvConfig(setting="hils", observation="measured")
    batch = CapsuleBatch(config, 64)
    batch.seed(4)
    batch.reset()
    rng = np.random.default_rng(1)
    sig = {name: SIGNAL_NAMES.index(name) for name in SIGNAL_NAMES}
    residuals = []
    for _ in range(300):
        batch.step(rng.uniform(-1.0, 1.0, 64))
        obs = batch.obs.astype(np.float64)
        gap = (
            batch.signals[sig["bogie_displacement_m"]] - batch.signals[sig["guideway_elevation_m"]]
        )
        acc = batch.signals[sig["car_body_acceleration_m_s2"]]
        residuals.append(np.stack([obs[:, 4] - gap, obs[:, 5] - batch.signals[sig["coil_current_a"]],
                                   obs[:, 0] - acc], axis=1))  # fmt: skip
    r = np.stack(residuals).reshape(-1, 3)
    std = SENSOR_NOISE_STD[[9, 10, 0]]
    z = r / std
    np.testing.assert_allclose(z.std(axis=0), 1.0, atol=0.03)
    assert np.all(np.abs(z.mean(axis=0)) < 0.05)
    assert np.max(np.abs(np.corrcoef(z.T) - np.eye(3))) < 0.04
