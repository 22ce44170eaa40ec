"""capsule_env.envs.rllib: the env creator, its Ray Tune registration (scale extra) and a short RLlib
PPO run on the native vector env (rllib extra)."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.envs import rllib
from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

NO_RAY = (
    "Ray Tune is not installed (optional, in the scale extra: pip install 'capsule-env[scale]')"
)
NO_RLLIB = (
    "ray[rllib] is not installed (optional, in the rllib extra: pip install "
    "'capsule-env[rllib]'; it pins its own Gymnasium version, so it is not in [scale])"
)


def test_env_creator_makes_the_single_or_the_vector_env():
    single = rllib.env_creator({"episode_length_s": 1.0})
    assert isinstance(single, CapsuleSuspensionEnv)
    vector = rllib.env_creator({"num_envs": 3, "episode_length_s": 1.0, "setting": "sim"})
    assert isinstance(vector, CapsuleSuspensionVectorEnv) and vector.num_envs == 3
    assert vector.config.setting == "sim"
    single.close()
    vector.close()


@pytest.mark.scale
def test_register_puts_the_creator_in_rays_registry():
    pytest.importorskip("ray.tune", reason=NO_RAY)
    from ray.tune.registry import ENV_CREATOR, _global_registry

    assert rllib.register() == "CapsuleSuspension-v0"
    assert rllib.register("capsule-test") == "capsule-test"
    creator = _global_registry.get(ENV_CREATOR, "capsule-test")
    # what RLlib's SingleAgentEnvRunner calls: creator(env_config | {"num_envs": n})
    env = creator({"episode_length_s": 1.0} | {"num_envs": 4})
    assert isinstance(env, CapsuleSuspensionVectorEnv) and env.num_envs == 4
    obs, _ = env.reset(seed=0)
    assert obs.shape == (4, *env.single_observation_space.shape)
    env.close()


@pytest.mark.scale
def test_rllib_ppo_runs_on_the_native_vector_env():
    """Two PPO iterations of 256 samples (4 vehicles x 64 steps), 0.5 s episodes, on the
    native vector env where the installed RLlib supports it."""
    try:
        from ray.rllib.algorithms.ppo import PPOConfig
    except ImportError:
        pytest.skip(NO_RLLIB)
    import ray

    native = rllib.supports_vector_entry_point()  # Ray >= 2.52
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=2, include_dashboard=False)
    try:
        config = (
            PPOConfig()
            .environment(rllib.register(), env_config={"episode_length_s": 0.5})
            .env_runners(
                num_env_runners=0,
                num_envs_per_env_runner=4,
                rollout_fragment_length=64,
                **rllib.vector_env_runner_kwargs(),
            )
            .training(train_batch_size_per_learner=256, minibatch_size=64, num_epochs=1)
            .rl_module(model_config={"fcnet_hiddens": [16, 16]})
            .debugging(seed=0)
        )
        algo = config.build_algo() if hasattr(config, "build_algo") else config.build()
        try:
            env = algo.env_runner.env.unwrapped
            assert env.num_envs == 4
            if native:  # one kernel call for the 4 vehicles
                assert isinstance(env, CapsuleSuspensionVectorEnv)
            else:  # older RLlib: Gymnasium's SyncVectorEnv of single envs
                assert all(isinstance(e.unwrapped, CapsuleSuspensionEnv) for e in env.envs)
            results = [algo.train() for _ in range(2)]
        finally:
            algo.stop()
    finally:
        if started:
            ray.shutdown()
    runners = results[-1]["env_runners"]
    assert runners["num_env_steps_sampled_lifetime"] == 512
    # each vehicle ended one 100-step episode in its 128 steps (RLlib 2.60 reports their
    # length as 101, with Gymnasium's SyncVectorEnv of single envs as well)
    assert runners["num_episodes"] == 4
    assert runners["episode_len_mean"] in (100, 101)
    assert np.isfinite(runners["episode_return_mean"]) and runners["episode_return_mean"] < 0
