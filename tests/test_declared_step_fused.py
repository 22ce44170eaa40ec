"""A declared vector env's step with its sensing, reward and observations in one compiled call
(:meth:`DeclaredBatch.step_scored`, :func:`capsule_env.engine.declared_sensing.sense_scored`)
against the same step as it ran before (commit acacaf2: the commands vehicle by vehicle, the
signals, the measurements, the reward and the observations in numpy, kept below as the
reference): the same observations, rewards, flags and info arrays bit for bit, over autoresets,
on both half-car tasks, ``full_state`` under ``sim``, ``sensors`` in current mode and the
quarter-car's declaration."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env._jit import specialised
from capsule_env.dampers.inverse import INVERSE_CODES, affine_in_current, invert_affine
from capsule_env.engine.declared_batch import N_SLOT_CHANNELS
from capsule_env.engine.declared_sensing import mean_row, reward_terms
from capsule_env.engine.declared_sensing import normals as _normals
from capsule_env.envs.declared_vector import DeclaredVectorEnv

CASES = {
    "CapsuleHalfRide-v0": ("CapsuleHalfRide-v0", {"max_episode_steps": 31}),
    "CapsuleHalfRidePreview-v0": ("CapsuleHalfRidePreview-v0", {"max_episode_steps": 29}),
    "full_state, sim": ("CapsuleHalfRide-v0", {"observation": "full_state", "setting": "sim",
                                               "max_episode_steps": 23}),
    "sensors, current mode": ("CapsuleHalfRide-v0", {"observation": "sensors",
                                                     "action_mode": "current",
                                                     "max_episode_steps": 17}),
    "quarter_car, measured": (None, {"vehicle": "quarter_car", "setting": "hils",
                                     "observation": "measured", "max_episode_steps": 19}),
}  # fmt: skip


# ------------------------------------------------------------------ the reference (acacaf2)
@specialised("code")
def _invert_before(code, p, force_n, stroke, rate, i_max, out):
    c = code

    def impl(code, p, force_n, stroke, rate, i_max, out):
        for n in range(out.shape[0]):
            for s in range(out.shape[1]):
                f0, slope = affine_in_current(c, p, stroke[n, s], rate[n, s], 0.0)
                out[n, s] = invert_affine(force_n[n, s], f0, slope, rate[n, s], i_max)

    return impl


def _commands(b, actions):
    if b.config.action_mode == "current":
        return 0.5 * (actions + 1.0) * b.i_max
    meas = b.measured.reshape(b.num_envs, b.n_slots, N_SLOT_CHANNELS)
    out = np.empty(actions.shape)
    _invert_before(INVERSE_CODES[b.config.inverse_model], b.inverse.as_array(),
                   actions * b.config.max_force_n, np.ascontiguousarray(meas[:, :, 0]),
                   np.ascontiguousarray(meas[:, :, 1]), b.i_max, out)  # fmt: skip
    return out


def _combine(x, rows):
    out = np.zeros((x.shape[0], rows.shape[0]))
    for j in range(rows.shape[1]):
        out += x[:, j, None] * rows[None, :, j]
    return out


def _signals(b):
    ns, nc = b.n_slots, b.n_coords
    q, v = b.state[:, :nc], b.state[:, nc : 2 * nc]
    acc, zg = b.out[:, ns : ns + nc], b.out[:, ns + nc :]
    return {
        "stroke_m": _combine(q, b.stroke_rows),
        "stroke_rate_m_s": _combine(v, b.stroke_rows),
        "damper_force_n": b.out[:, :ns].copy(),
        "coil_current_a": b.state[:, 2 * nc + 2 : 2 * nc + 3 * ns : 3].copy(),
        "current_command_a": b.requested.copy(),
        "comfort_acceleration_m_s2": _combine(acc, b.comfort_rows),
        "slot_end_acceleration_m_s2": _combine(acc, b.end_rows),
        "guideway_elevation_m": zg.copy(),
        "gap_m": _combine(q, b.gap_rows) - _combine(zg, b.gap_contacts),
    }


def _measure(b, sig):
    n, ns = b.num_envs, b.n_slots
    ends = sig["slot_end_acceleration_m_s2"].reshape(n, ns, 2)
    true = np.stack([sig["stroke_m"], sig["stroke_rate_m_s"], ends[..., 0], ends[..., 1],
                     sig["gap_m"]], axis=-1).reshape(n, -1)  # fmt: skip
    if b.noise_level > 0.0:
        normals = np.empty((n, true.shape[1] + 1))
        _normals(b.noise_key, b.step_count, normals)
        true = true + b._noise_std * normals[:, : true.shape[1]]
    b.measured[:] = true
    acc = true.reshape(n, ns, N_SLOT_CHANNELS)[:, :, 2:4]
    b0, b1, b2, a1, a2 = b._estimator
    s1, s2 = b._estimator_state[..., 0], b._estimator_state[..., 1]
    y = b0 * acc + s1
    s1[...] = b1 * acc - a1 * y + s2
    s2[...] = b2 * acc - a2 * y
    b.estimates[:] = y


def _reward(b, sig):
    cfg = b.config
    acc = sig["comfort_acceleration_m_s2"] / cfg.acceleration_scale_m_s2
    stroke = sig["stroke_m"] / cfg.stroke_scale_m
    current = sig["coil_current_a"] / b.i_max if b.i_max > 0.0 else 0.0 * stroke
    costs = {
        "cost_acceleration": cfg.reward_acceleration_weight * np.mean(acc * acc, axis=1),
        "cost_stroke": cfg.reward_stroke_weight * np.mean(stroke * stroke, axis=1),
        "cost_energy": cfg.reward_energy_weight * np.mean(current * current, axis=1),
    }
    hit = np.any(np.abs(sig["stroke_m"]) > cfg.stroke_limit_m, axis=1)
    reward = -(costs["cost_acceleration"] + costs["cost_stroke"] + costs["cost_energy"])
    return reward - np.where(hit, cfg.bump_stop_penalty, 0.0), hit, costs


def _observe(b, sig):
    n, ns, nc = b.num_envs, b.n_slots, b.n_coords
    if b.config.observation in ("sensors", "measured"):
        meas = b.measured.reshape(n, ns, N_SLOT_CHANNELS)
        parts = [meas[:, :, :4]]
        if b.config.observation == "measured":
            parts += [meas[:, :, 4:], b.estimates]
        obs = np.concatenate([*parts, b.requested[:, :, None]], axis=2).reshape(n, -1)
    else:
        qv = np.stack([b.state[:, :nc], b.state[:, nc : 2 * nc]], axis=2).reshape(n, -1)
        obs = np.concatenate([qv, sig["stroke_m"], sig["stroke_rate_m_s"],
                              sig["comfort_acceleration_m_s2"], sig["guideway_elevation_m"]],
                             axis=1)  # fmt: skip
    obs = obs.astype(np.float32)
    if b.preview is None:
        return obs
    cols = b.preview.columns(b.profiles, b.route, b.state[:, -1], b.plant.contact_offsets_m)
    return np.concatenate([obs, cols.astype(np.float32)], axis=1)


def _step_before(env, actions):
    """``DeclaredVectorEnv.step`` at acacaf2 (the action checks aside)."""
    b = env.batch
    b.commands = lambda a: _commands(b, a)  # the kernel call as now (tests/test_declared_lanes)
    restart = env._autoreset.copy()
    b._advance(np.clip(np.asarray(actions, dtype=np.float64), -1.0, 1.0))
    sig = _signals(b)
    _measure(b, sig)
    reward, terminated, costs = _reward(b, sig)
    truncated = b.step_count >= b.max_steps
    if restart.any():
        b.reset(np.flatnonzero(restart))
        sig = _signals(b)
        reward[restart], terminated[restart], truncated[restart] = 0.0, False, False
    env._autoreset = terminated | truncated
    return _observe(b, sig), reward, terminated, truncated, {**sig, **costs}


# ------------------------------------------------------------------ the tests
def _make(case, n):
    env_id, kwargs = CASES[case]
    if env_id is None:
        return DeclaredVectorEnv(n, **kwargs)
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                        **kwargs).unwrapped  # fmt: skip


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


@pytest.mark.parametrize("case", list(CASES))
def test_the_fused_step_is_the_numpy_step_bit_for_bit(case):
    n = 70  # above the threaded kernel's threshold (64)
    new, old = _make(case, n), _make(case, n)
    (obs_new, info_new), (obs_old, info_old) = new.reset(seed=11), old.reset(seed=11)
    assert _same(obs_new, obs_old) and info_old.keys() <= info_new.keys()  # + costs, masks
    rng = np.random.default_rng(5)
    restarts, largest = 0, 0.0
    for _ in range(60):
        a = rng.uniform(-1.2, 1.2, new.action_space.shape).astype(np.float32)
        restart = old._autoreset.copy()
        got, expected = new.step(a), _step_before(old, a)
        for x, y in zip(got[:4], expected[:4], strict=True):
            assert _same(x, y)
        info = {k: v for k, v in got[4].items() if not k.startswith("_")}  # less the masks
        assert list(info) == list(expected[4])  # the same names, in the same order
        for name, want in expected[4].items():  # a restarted vehicle's reward terms are 0 now
            want = np.where(restart, 0.0, want) if name.startswith("cost_") else want
            assert _same(info[name], want), name
        restarts += int(np.count_nonzero(got[2] | got[3]))
        largest = max(largest, np.abs(got[1]).min(), np.abs(got[4]["stroke_m"]).min())
    assert restarts >= n  # every vehicle's episode ended at least once
    assert largest > 0.0  # rewards and strokes, not zeros


def test_a_steps_arrays_are_its_own():
    """Observations and info arrays are new each step (as before): a later step leaves them."""
    env = _make("CapsuleHalfRidePreview-v0", 7)
    env.reset(seed=3)
    first = env.step(np.full(env.action_space.shape, 0.5))
    kept = [first[0].copy(), first[1].copy(), {k: v.copy() for k, v in first[4].items()}]
    for _ in range(3):
        env.step(np.full(env.action_space.shape, -0.5))
    assert _same(first[0], kept[0]) and _same(first[1], kept[1])
    for name, value in kept[2].items():
        assert _same(first[4][name], value), name
    assert not np.array_equal(env.step(np.zeros(env.action_space.shape))[0], kept[0])


@pytest.mark.parametrize("n", [1, 2, 3, 7, 8, 9, 16, 17, 127, 128, 129, 300, 1000])
def test_the_row_mean_is_numpys(n):
    """numpy's mean sums below 8 terms with one accumulator, then with 8 (pairwise beyond 128):
    the compiled mean follows it (a plain running sum differs from 8 terms on)."""
    rng = np.random.default_rng(n)
    x = rng.standard_normal((40, n)) ** 2 * 10.0 ** rng.integers(-9, 9, (40, n))
    expected = np.mean(x, axis=1)
    assert _same(np.array([mean_row(row) for row in x]), expected)
    running = np.cumsum(x, axis=1)[:, -1] / n
    if n >= 8:
        assert not np.array_equal(running, expected)  # the test can tell the two apart


@pytest.mark.parametrize("width", [1, 3, 8, 12])
def test_the_reward_terms_are_numpys_for_any_number_of_points(width):
    """The reward's means over comfort points and slots, below and from 8 columns; a zero
    ``i_max`` (the energy term of zero currents) and the bump stop."""
    rng = np.random.default_rng(width)
    comfort = rng.standard_normal((50, width)) * 3.0
    stroke = rng.standard_normal((50, width)) * 0.01
    current = rng.uniform(0.0, 2.0, (50, width))
    for i_max in (1.5, 0.0):
        p = (0.7, 0.02, i_max, 1.0, 0.3, 0.05, 0.015, 10.0)
        reward, hit, *costs = reward_terms(comfort, stroke, current, p)
        a, s = comfort / p[0], stroke / p[1]
        c = current / i_max if i_max > 0.0 else 0.0 * s
        terms = [w * np.mean(x * x, axis=1) for w, x in zip(p[3:6], (a, s, c), strict=True)]
        expected_hit = np.any(np.abs(stroke) > p[6], axis=1)
        assert _same(hit, expected_hit) and 0 < expected_hit.sum() < 50
        for got, want in zip(costs, terms, strict=True):
            assert _same(got, want)
        assert _same(reward, -(terms[0] + terms[1] + terms[2]) - np.where(hit, p[7], 0.0))
