"""The policy shipped with the package loads, acts in the mode it was trained for, and is
listed by evaluate.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

import evaluate
from agents.sb3_policy import SB3Policy, shipped_policy_paths
from capsule_env.envs import CapsuleSuspensionVectorEnv


def test_shipped_policy_exists_and_is_small():
    paths = shipped_policy_paths()
    assert paths, "no pretrained policy under capsule_env/pretrained"
    for path in paths:
        meta = json.loads(open(path.replace(".zip", ".json")).read())
        assert meta["algo"] in ("ppo", "sac", "td3")
        assert meta["env_kwargs"]["action_mode"] in ("force", "current")


@pytest.mark.parametrize("path", shipped_policy_paths())
def test_shipped_policy_acts_in_its_training_mode(path):
    policy = SB3Policy.load(path)
    assert policy.obs_rms is not None  # its VecNormalize statistics were found and loaded
    for setting in ("sim", "hils"):
        env = CapsuleSuspensionVectorEnv(num_envs=4, setting=setting, **policy.env_kwargs)
        obs, _ = env.reset(seed=0)
        for _ in range(200):
            action, _ = policy.predict(obs, deterministic=True)
            assert action.shape == (4, 1) and np.all(np.abs(action) <= 1.0)
            obs, reward, terminated, _, info = env.step(action)
            assert np.all(np.isfinite(obs)) and not terminated.any()
        # it does something: the requested forces are not all the same
        assert np.std(info["desired_force_n"]) > 0.0 or policy.env_kwargs["action_mode"] != "force"
    # deterministic: the same observations give the same actions
    a1, _ = policy.predict(obs)
    a2, _ = policy.predict(obs)
    np.testing.assert_array_equal(a1, a2)


def test_evaluate_lists_the_shipped_policy(tmp_path):
    out = tmp_path / "eval.json"
    evaluate.main(["--episodes", "1", "--episode-length", "1", "--setting", "hils",
                   "--controllers", "passive", "--json", str(out)])  # fmt: skip
    names = set(json.loads(out.read_text())["settings"]["hils"]["controllers"])
    assert "ppo-hils" in names


def test_bad_policy_path_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="policy path"):
        SB3Policy.load(tmp_path / "missing.zip")
