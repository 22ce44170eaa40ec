"""The policy shipped with the package: its files are there and small, it loads, it is the
saved SB3 model acting on observations normalised with the saved statistics, it acts in the
mode it was trained for, and evaluate.py lists it. Loading and running it needs
stable-baselines3 (skipped without it); the files' checks do not."""

from __future__ import annotations

import hashlib
import json
import pickle
from pathlib import Path

import numpy as np
import pytest
from capsule_env.agents.learning.sb3_policy import ALGORITHMS, SB3Policy, shipped_policy_paths

from capsule_env.envs import CapsuleSuspensionVectorEnv
from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.evaluation import evaluate

from conftest import NO_SB3

SHIPPED = shipped_policy_paths()
#: Each shipped file stays under this size: the package's wheel stays small.
MAX_SHIPPED_BYTES = 1_000_000


def files_of(zip_path: str | Path) -> tuple[Path, Path, Path]:
    """``(NAME.zip, NAME.vecnormalize.pkl, NAME.json)`` of a shipped policy."""
    zip_path = Path(zip_path)
    stem = zip_path.parent / zip_path.stem
    return zip_path, Path(f"{stem}.vecnormalize.pkl"), Path(f"{stem}.json")


def test_shipped_policy_files_exist_and_are_small():
    assert SHIPPED, "no pretrained policy under capsule_env/pretrained"
    for zip_path in SHIPPED:
        for path in files_of(zip_path):
            assert path.is_file(), f"{path.name} is missing"
            assert 0 < path.stat().st_size < MAX_SHIPPED_BYTES, (path.name, path.stat().st_size)
        meta = json.loads(files_of(zip_path)[2].read_text())
        assert meta["algo"] in ALGORITHMS
        assert meta["env_kwargs"]["action_mode"] in ("force", "current")


@pytest.mark.parametrize("path", SHIPPED)
def test_shipped_json_records_the_sizes_and_sha256_by_role(path):
    zip_path, pkl_path, json_path = files_of(path)
    recorded = json.loads(json_path.read_text()).get("digests")
    assert recorded is not None, f"{json_path.name} records no file sizes or SHA-256"
    assert set(recorded) == {"model", "normaliser"}  # by role: the set binds by content
    for role, file in (("model", zip_path), ("normaliser", pkl_path)):
        data = file.read_bytes()
        assert recorded[role]["bytes"] == len(data), role
        assert recorded[role]["sha256"] == hashlib.sha256(data).hexdigest(), role


@pytest.mark.rl
@pytest.mark.parametrize("path", SHIPPED)
def test_shipped_policy_is_the_saved_model_on_normalised_observations(path):
    # Independent of SB3Policy: the SB3 model loaded by SB3 itself, acting on observations
    # normalised by the unpickled VecNormalize's own normalize_obs.
    sb3 = pytest.importorskip("stable_baselines3", reason=NO_SB3)
    zip_path, pkl_path, json_path = files_of(path)
    algo = json.loads(json_path.read_text())["algo"]
    model = getattr(sb3, algo.upper()).load(str(zip_path), device="cpu")
    with pkl_path.open("rb") as fh:
        vec_normalize = pickle.load(fh)
    rms = vec_normalize.obs_rms
    obs = (np.random.default_rng(0).normal(size=(64, rms.mean.shape[0])) * np.sqrt(rms.var)
           + rms.mean).astype(np.float32)  # fmt: skip
    expected, _ = model.predict(vec_normalize.normalize_obs(obs), deterministic=True)
    # two copies, each loaded on its own, act alike and as the saved model does
    first, second = SB3Policy.load(path), SB3Policy.load(path)
    assert first.model is not second.model
    a1, _ = first.predict(obs, deterministic=True)
    a2, _ = second.predict(obs, deterministic=True)
    np.testing.assert_array_equal(a1, a2)
    np.testing.assert_allclose(a1, np.clip(expected, -1.0, 1.0), rtol=1e-6, atol=1e-6)
    slots = model.action_space.shape[0]  # one action per damper slot: 2 on the half-car
    assert a1.shape == (64, slots) and np.all((a1 >= -1.0) & (a1 <= 1.0))
    # its actions depend on the observation: not one constant (nor one saturated) action
    assert np.ptp(a1) > 0.1
    assert np.any(np.abs(a1) < 1.0)


@pytest.mark.rl
@pytest.mark.parametrize("path", SHIPPED)
def test_shipped_policy_acts_in_its_training_mode(path):
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    policy = SB3Policy.load(path)
    assert policy.obs_rms is not None  # its VecNormalize statistics were found and loaded
    declared = "vehicle" in policy.env_kwargs  # a declared vehicle's: its own env
    slots = policy.model.action_space.shape[0]
    for setting in ("sim", "hils"):
        make = DeclaredVectorEnv if declared else CapsuleSuspensionVectorEnv
        env = make(num_envs=4, setting=setting, **policy.env_kwargs)
        obs, _ = env.reset(seed=0)
        actions = []
        for _ in range(200):
            action, _ = policy.predict(obs, deterministic=True)
            assert action.shape == (4, slots) and np.all((action >= -1.0) & (action <= 1.0))
            actions.append(action)
            obs, reward, terminated, _, info = env.step(action)
            assert np.all(np.isfinite(obs)) and not terminated.any()
        # it does something: its actions on its own vehicles change over the 200 steps
        assert np.std(np.concatenate(actions)) > 0.05, setting


@pytest.mark.rl
def test_evaluate_lists_the_shipped_policy(tmp_path):
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    out = tmp_path / "eval.json"
    evaluate.main(["--episodes", "1", "--episode-length", "1", "--setting", "hils",
                   "--controllers", "passive", "--json", str(out)])  # fmt: skip
    names = set(json.loads(out.read_text())["settings"]["hils"]["controllers"])
    # the shipped policies trained in the paper's env; the trip task's own are its
    # evaluation's (test_trip_policy), the half-car's its (test_half_car_policy)
    trip = ("ppo-trip", "residual-ppo-mpc-trip", "residual-ppo-mpc-half-car")  # + the half-car's
    paper = [p for p in SHIPPED if Path(p).stem not in trip]
    shipped = {json.loads(files_of(p)[2].read_text()).get("name", Path(p).stem) for p in paper}
    assert {"ppo-hils", "ppo-measured", "ppo-preview"} <= shipped and shipped <= names
    assert not set(trip) & names


def test_bad_policy_path_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="policy path"):
        SB3Policy.load(tmp_path / "missing.zip")


@pytest.mark.rl
def test_ship_policy_copies_the_set_under_a_new_name(tmp_path):
    from capsule_env.agents.learning.ship import ship_policy

    shipped = ship_policy(SHIPPED[0], "copy-of-it", "a test", folder=tmp_path)
    assert shipped == tmp_path / "copy-of-it.zip"
    meta = json.loads((tmp_path / "copy-of-it.json").read_text())
    assert meta["name"] == "copy-of-it" and meta["selection"] == "a test"
    assert set(meta["digests"]) == {"model", "normaliser"} and "files" not in meta
    assert shipped.read_bytes() == Path(SHIPPED[0]).read_bytes()
    assert SB3Policy.load(shipped).name == "copy-of-it"
    with pytest.raises(ValueError, match="name must be a plain file stem"):
        ship_policy(SHIPPED[0], "../escape", folder=tmp_path)
