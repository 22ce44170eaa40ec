"""Autoreset modes of the native vector env (NEXT_STEP, SAME_STEP, DISABLED).

Two independent references: (1) the three modes against each other, episode by episode (the
modes only move where the resets fall, so each vehicle's episodes must agree bit for bit once
the reset timing is aligned); (2) Gymnasium's own ``SyncVectorEnv`` over the single env in the
same mode, step by step: observations, rewards, flags, infos, ``final_obs`` and
``final_info`` in Gymnasium's layout. Episodes end at different times (bump-stop terminations
and truncations), so resets of some vehicles fall while others keep running.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import capsule_env  # noqa: F401  (registers the env)
from capsule_env.engine.layout import SIGNAL_NAMES
from capsule_env.envs import CapsuleSuspensionVectorEnv
from capsule_env.envs._compat import (
    GYMNASIUM_HAS_AUTORESET_MODE,
    AutoresetMode,
    check_autoreset_mode,
)

from conftest import ENV_ID

N = 4
SEEDS = [7, 8, 9, 10]
# hils with a bump stop at 3 mm and random coil currents: episodes of 40 steps at most, many
# ended earlier by the bump stop, at different steps on different vehicles.
KW = dict(setting="hils", action_mode="current", stroke_limit_m=0.003, episode_length_s=0.2)
MODES = ("NextStep", "SameStep", "Disabled")
NEEDS_GYM_MODES = pytest.mark.skipif(
    not GYMNASIUM_HAS_AUTORESET_MODE,
    reason="gymnasium < 1.1 has no AutoresetMode (SyncVectorEnv is NEXT_STEP only)",
)
# ACTIONS[n, e, t]: the action of vehicle n at step t of its episode e (the same in every mode)
ACTIONS = np.random.default_rng(0).uniform(-1.0, 1.0, (N, 12, 41))
FORCE = SIGNAL_NAMES.index("damper_force_n")


def _entry(obs, reward, term, trunc, force):
    return (np.asarray(obs).tobytes(), float(reward), bool(term), bool(trunc), float(force))


def _episodes(mode: str, n_steps: int = 160) -> list[list[list[tuple]]]:
    """Each vehicle's episodes: [reset entry, step entries...], driven by ``ACTIONS``."""
    vec = CapsuleSuspensionVectorEnv(num_envs=N, autoreset_mode=mode, **KW)
    obs, info = vec.reset(seed=SEEDS)
    eps = [[[_entry(obs[n], 0.0, False, False, info["damper_force_n"][n])]] for n in range(N)]
    fresh = np.zeros(N, dtype=bool)  # NEXT_STEP: this step resets the vehicle
    for _ in range(n_steps):
        a = np.array([ACTIONS[n, len(eps[n]) - 1, len(eps[n][-1]) - 1] for n in range(N)])
        a[fresh] = 0.0  # ignored: the step that resets the vehicle
        obs, reward, term, trunc, info = vec.step(a[:, None])
        ended = term | trunc
        for n in range(N):
            if fresh[n]:
                assert reward[n] == 0.0 and not ended[n]
                eps[n].append([_entry(obs[n], 0.0, False, False, info["damper_force_n"][n])])
            elif mode == "SameStep" and ended[n]:
                final = info["final_info"]["damper_force_n"][n]
                eps[n][-1].append(_entry(info["final_obs"][n], reward[n], term[n], trunc[n], final))
                eps[n].append([_entry(obs[n], 0.0, False, False, info["damper_force_n"][n])])
            else:
                eps[n][-1].append(_entry(obs[n], reward[n], term[n], trunc[n],
                                         info["damper_force_n"][n]))  # fmt: skip
        if mode == "NextStep":
            fresh = ended
        elif mode == "Disabled" and ended.any():
            obs, info = vec.reset(options={"reset_mask": ended})
            for n in np.flatnonzero(ended):
                eps[n].append([_entry(obs[n], 0.0, False, False, info["damper_force_n"][n])])
    return [[ep for ep in vehicle if ep[-1][2] or ep[-1][3]] for vehicle in eps]  # complete


def test_modes_give_the_same_episodes_bit_for_bit():
    runs = {mode: _episodes(mode) for mode in MODES}
    for n in range(N):
        counts = [len(runs[mode][n]) for mode in MODES]
        k = min(counts)
        assert k >= 3, counts  # several complete episodes per vehicle in each mode
        lengths = [len(ep) for ep in runs["SameStep"][n][:k]]
        for mode in ("NextStep", "Disabled"):
            assert runs[mode][n][:k] == runs["SameStep"][n][:k], (mode, n)
    # the test covers both endings, at different steps on different vehicles
    ends = [(ep[-1][2], len(ep)) for vehicle in runs["SameStep"] for ep in vehicle]
    assert any(t for t, _ in ends) and any(not t for t, _ in ends)
    assert len({length for _, length in ends}) > 3, lengths


def _assert_infos_equal(ours: dict, theirs: dict) -> None:
    assert set(ours) == set(theirs)
    for key, value in theirs.items():
        if isinstance(value, dict):
            _assert_infos_equal(ours[key], value)
        elif value.dtype == object:  # final_obs: None or an observation per sub-env
            for a, b in zip(ours[key], value, strict=True):
                assert (a is None and b is None) or np.array_equal(a, b), key
        else:
            np.testing.assert_array_equal(ours[key], value, err_msg=key)


@pytest.mark.parametrize(
    "mode", [pytest.param(m, marks=NEEDS_GYM_MODES) if m != "NextStep" else m for m in MODES]
)
def test_native_vector_env_matches_gymnasium_sync_vector_env(mode):
    ours = gym.make_vec(ENV_ID, num_envs=N, vectorization_mode="vector_entry_point",
                        autoreset_mode=mode, **KW)  # fmt: skip
    kwargs = {} if mode == "NextStep" else {"vector_kwargs": {"autoreset_mode": mode}}
    sync = gym.make_vec(ENV_ID, num_envs=N, vectorization_mode="sync", **kwargs, **KW)
    assert ours.metadata["autoreset_mode"] == sync.metadata.get("autoreset_mode", ours.metadata[
        "autoreset_mode"])  # fmt: skip
    o1, i1 = ours.reset(seed=SEEDS)
    o2, i2 = sync.reset(seed=SEEDS)
    np.testing.assert_array_equal(o1, o2)
    _assert_infos_equal(i1, i2)
    rng = np.random.default_rng(1)
    n_final = n_masked = 0
    for _ in range(150):
        a = rng.uniform(-1.0, 1.0, (N, 1)).astype(np.float32)
        r1, r2 = ours.step(a), sync.step(a)
        for x, y in zip(r1[:4], r2[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        _assert_infos_equal(r1[4], r2[4])
        n_final += int("final_obs" in r2[4])
        ended = r2[2] | r2[3]
        if mode == "Disabled" and ended.any():
            o1, i1 = ours.reset(options={"reset_mask": ended})
            o2, i2 = sync.reset(options={"reset_mask": ended.copy()})
            np.testing.assert_array_equal(o1, o2)
            _assert_infos_equal(i1, i2)
            n_masked += 1
    assert (n_final > 3) == (mode == "SameStep")
    assert (n_masked > 3) == (mode == "Disabled")
    sync.close()


def test_autoreset_mode_attribute_metadata_and_argument_forms():
    for given in (AutoresetMode.SAME_STEP, "SameStep", "SAME_STEP", "same_step"):
        vec = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point",
                           autoreset_mode=given)  # fmt: skip
        assert vec.autoreset_mode is AutoresetMode.SAME_STEP
        assert vec.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    default = CapsuleSuspensionVectorEnv(num_envs=2)
    assert default.autoreset_mode is AutoresetMode.NEXT_STEP
    assert default.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert CapsuleSuspensionVectorEnv.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    if GYMNASIUM_HAS_AUTORESET_MODE:  # the very enum Gymnasium's clients compare against
        from gymnasium.vector import AutoresetMode as GymAutoresetMode

        assert default.autoreset_mode is GymAutoresetMode.NEXT_STEP
    # the instance's mode does not leak into the class or another instance
    assert CapsuleSuspensionVectorEnv(num_envs=1, autoreset_mode="Disabled").metadata[
        "autoreset_mode"] is AutoresetMode.DISABLED  # fmt: skip
    assert default.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP


def test_bad_autoreset_mode_and_reset_mask_are_named():
    with pytest.raises(ValueError, match=r"autoreset_mode 'LaterStep'.*SameStep"):
        CapsuleSuspensionVectorEnv(num_envs=2, autoreset_mode="LaterStep")
    with pytest.raises(TypeError, match="autoreset_mode"):
        check_autoreset_mode(1)
    vec = CapsuleSuspensionVectorEnv(num_envs=3, autoreset_mode="Disabled")
    with pytest.raises(ResetNeeded, match="reset_mask"):  # a partial reset needs a full one
        vec.reset(options={"reset_mask": np.array([True, False, False])})
    vec.reset(seed=0)
    for bad, err in (
        ([True, False, False], TypeError),
        (np.array([1, 0, 0]), TypeError),
        (np.array([True, False]), ValueError),
        (np.zeros(3, dtype=bool), ValueError),
    ):
        with pytest.raises(err, match=r"options\['reset_mask'\].*shape \(3,\)"):
            vec.reset(options={"reset_mask": bad})
    with pytest.raises(ValueError, match="unknown reset option"):
        vec.reset(options={"mask": np.ones(3, dtype=bool)})


def test_disabled_refuses_to_step_a_finished_vehicle_until_it_is_reset():
    vec = CapsuleSuspensionVectorEnv(num_envs=3, autoreset_mode="Disabled", episode_length_s=0.05)
    vec.reset(seed=0)
    zeros = np.zeros((3, 1))
    for _ in range(10):
        *_, trunc, info = vec.step(zeros)
    assert trunc.all()
    with pytest.raises(ResetNeeded, match=r"vehicles \[0, 1, 2\].*reset_mask"):
        vec.step(zeros)
    step_count = vec.batch.step_count.copy()
    np.testing.assert_array_equal(step_count, 10)  # the refused step advanced nothing
    kept = info["damper_force_n"].copy()
    obs, info2 = vec.reset(options={"reset_mask": np.array([True, False, True])})
    np.testing.assert_array_equal(vec.batch.step_count, [0, 10, 0])
    np.testing.assert_array_equal(info["damper_force_n"], kept)  # last step's info intact
    np.testing.assert_array_equal(info2["_damper_force_n"], [True, False, True])
    with pytest.raises(ResetNeeded, match=r"vehicles \[1\]"):
        vec.step(zeros)
    vec.reset(options={"reset_mask": np.array([False, True, False])})
    vec.step(zeros)
    np.testing.assert_array_equal(vec.batch.step_count, 1)


def test_masked_reset_with_seed_gives_the_streams_of_a_full_reset():
    a = CapsuleSuspensionVectorEnv(num_envs=3, setting="hils")
    b = CapsuleSuspensionVectorEnv(num_envs=3, setting="hils")
    full, _ = a.reset(seed=5)
    b.reset(seed=1)
    b.step(np.zeros((3, 1)))
    part, _ = b.reset(seed=5, options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(part[1], full[1])
    np.testing.assert_array_equal(b.batch.start_position[1], a.batch.start_position[1])
    assert b.batch.start_position[0] != a.batch.start_position[0]  # vehicle 0 not reset
    for _ in range(20):
        act = np.full((3, 1), 0.3)
        oa, *_ = a.step(act)
        ob, *_ = b.step(act)
        np.testing.assert_array_equal(oa[1], ob[1])
