"""Residual policies: with a zero residual every wrapper is the classical law itself (checked
against evaluation's own rollout of the law), the sum is clipped, and a zero-initialised SB3
policy starts from the law's behaviour."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.controllers.classical import make_controller
from capsule_env.agents.learning.residual import (
    ResidualEnv,
    ResidualPolicy,
    ResidualVecEnv,
    ResidualVectorEnv,
    combine_actions,
    zero_last_layer,
)

import capsule_env  # noqa: F401
from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, run_episodes

RIDE = {
    "setting": "hils",
    "observation": "measured",
    "episode_length_s": 0.5,
    "guideway_seed": EVALUATION_GUIDEWAY_SEED,
}
PREVIEW = {**RIDE, "preview_points": 32, "preview_horizon_s": 1.0}  # the preview LQ law's


class Zero:
    """A residual policy that always answers 0 (SB3's predict signature)."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.zeros((np.atleast_2d(obs).shape[0], 1), dtype=np.float32), state


def _law_forces(name: str, kwargs: dict, seeds: list[int]) -> np.ndarray:
    options = {k: v for k, v in kwargs.items() if k != "episode_length_s"}
    rollout = run_episodes(make_controller(name), options, seeds=seeds,
                           episode_length_s=kwargs["episode_length_s"])  # fmt: skip
    return rollout.signals["damper_force_n"]


@pytest.mark.parametrize("name, kwargs", [("lqr-clipped-biexp-meas", RIDE),
                                          ("preview-lq-biexp-meas", PREVIEW)])  # fmt: skip
def test_zero_residual_is_the_law(name, kwargs):
    expected = _law_forces(name, kwargs, [3, 4])
    # single env
    env = ResidualEnv(gym.make("CapsuleSuspension-v0", **kwargs), make_controller(name))
    env.reset(seed=3)
    forces = []
    for _ in range(expected.shape[1]):
        *_, info = env.step(np.zeros(1, dtype=np.float32))
        forces.append(info["damper_force_n"])
    assert np.array_equal(np.array(forces), expected[0])
    # native vector env, both autoreset modes (SameStep: the ending step's info is in final_info)
    steps = expected.shape[1]
    for mode in ("NextStep", "SameStep"):
        venv = ResidualVectorEnv(CapsuleSuspensionVectorEnv(num_envs=2, autoreset_mode=mode,
                                                            **kwargs), make_controller(name))  # fmt: skip
        venv.reset(seed=[3, 4])
        record = []
        for _ in range(steps):
            *_, info = venv.step(np.zeros((2, 1), dtype=np.float32))
            record.append(info["final_info"] if "final_info" in info else info)
        assert np.array_equal(np.array([i["damper_force_n"] for i in record]).T, expected)
    # the policy form, through evaluation's own loop
    policy = ResidualPolicy(make_controller(name), Zero())
    options = {k: v for k, v in kwargs.items() if k != "episode_length_s"}
    rollout = run_episodes(policy, options, seeds=[3, 4], episode_length_s=0.5)
    assert np.array_equal(rollout.signals["damper_force_n"], expected)


class Recording(Controller):
    """A law on the measured signals that requests 0 and records its episode_start flags."""

    name = "recording"
    env_kwargs = {"observation": "measured"}

    def __init__(self) -> None:
        self.starts: list[np.ndarray] = []

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.starts.append(np.array(episode_start, dtype=bool))
        return np.zeros((np.atleast_2d(observation).shape[0], 1), dtype=np.float32), state


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_law_sees_each_episode_start_once(mode):
    """Two vehicles, episodes of 100 steps: the law's episode_start is set exactly at the first
    action of each episode (NextStep: the step after the ending one resets and ignores its
    action, so the next episode's first action comes one call later)."""
    law = Recording()
    venv = ResidualVectorEnv(CapsuleSuspensionVectorEnv(num_envs=2, autoreset_mode=mode, **RIDE),
                             law)  # fmt: skip
    venv.reset(seed=[3, 4])
    for _ in range(305):
        venv.step(np.zeros((2, 1), dtype=np.float32))
    starts = np.array(law.starts)[:, 0]
    first = [0, 101, 202, 303] if mode == "NextStep" else [0, 100, 200, 300]
    assert np.flatnonzero(starts).tolist() == first
    assert np.all(np.array(law.starts)[:, 0] == np.array(law.starts)[:, 1])


def test_sb3_wrapper_with_zero_residual_is_the_law():
    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    name = "lqr-clipped-biexp-meas"
    venv = ResidualVecEnv(CapsuleSuspensionSB3VecEnv(num_envs=2, info_signals=True, **RIDE),
                          make_controller(name))  # fmt: skip
    venv.seed(3)
    venv.reset()
    forces = []
    for _ in range(99):  # the 100th step ends the episode and SB3 resets the vehicle at once
        _, _, _, infos = venv.step(np.zeros((2, 1), dtype=np.float32))
        forces.append(infos[0]["damper_force_n"])
    # vehicle 0 of SB3's seed(3) is the single env seeded 3 (capsule_env.engine.batch.vehicle_streams)
    assert np.array_equal(np.array(forces), _law_forces(name, RIDE, [3])[0, :99])


def test_sum_is_scaled_and_clipped():
    np.testing.assert_array_equal(combine_actions(np.array([0.5, -0.9, 0.2]),
                                                  np.array([1.0, -1.0, -0.2]), 0.5),
                                  np.array([1.0, -1.0, 0.1], dtype=np.float32))  # fmt: skip


@pytest.mark.parametrize("algo", ["ppo", "sac", "td3", "tqc", "crossq", "recurrentppo"])
def test_zero_initialised_model_starts_from_the_law(algo):
    """Every algorithm of train.py --algo: after zero_last_layer its deterministic correction
    is exactly 0, so the residual policy starts as the law."""
    import torch
    from capsule_env.agents.learning.algorithms import algorithm_class

    if algo in ("tqc", "crossq", "recurrentppo"):
        pytest.importorskip("sb3_contrib")
    env = ResidualEnv(gym.make("CapsuleSuspension-v0", **RIDE),
                      make_controller("lqr-clipped-biexp-meas"))  # fmt: skip
    policy = "MlpLstmPolicy" if algo == "recurrentppo" else "MlpPolicy"
    model = algorithm_class(algo)(policy, env, seed=0, device="cpu")
    zero_last_layer(model)
    obs = np.random.default_rng(0).normal(size=(16, *env.observation_space.shape))
    action, _ = model.predict(obs.astype(np.float32), deterministic=True)
    assert np.all(action == 0.0)
    target = getattr(model.policy, "actor_target", None)
    if target is not None:  # TD3: the target actor starts as the zeroed actor
        target_action = target(torch.as_tensor(obs, dtype=torch.float32)).detach().numpy()
        assert np.all(target_action == 0.0)


def test_bad_input_is_named():
    env = gym.make("CapsuleSuspension-v0", setting="hils", observation="full_state")
    with pytest.raises(ValueError, match="needs the env option observation='measured'"):
        ResidualEnv(env, make_controller("lqr-clipped-biexp-meas"))
    with pytest.raises(ValueError, match="needs the env option preview_points=32"):
        ResidualEnv(gym.make("CapsuleSuspension-v0", **RIDE),
                    make_controller("preview-lq-biexp-meas"))  # fmt: skip
    # the same 32 points over another horizon: the law would read them at the wrong distances
    with pytest.raises(ValueError, match="needs the env option preview_horizon_s=1.0"):
        ResidualEnv(gym.make("CapsuleSuspension-v0", **{**PREVIEW, "preview_horizon_s": 0.5}),
                    make_controller("preview-lq-biexp-meas"))  # fmt: skip
    with pytest.raises(ValueError, match="scale must be a number in"):
        ResidualEnv(gym.make("CapsuleSuspension-v0", **RIDE),
                    make_controller("lqr-clipped-biexp-meas"), scale=0.0)  # fmt: skip
    with pytest.raises(ValueError, match="law must be a feedback Controller"):
        ResidualEnv(gym.make("CapsuleSuspension-v0", **RIDE), make_controller("passive"))
