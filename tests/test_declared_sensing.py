"""The declared batch's compiled sensing (:mod:`capsule_env.engine.declared_sensing`) against
the numpy expressions it replaced: the same numbers bit for bit (``==``)."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.engine.declared_batch import N_SLOT_CHANNELS
from capsule_env.engine.declared_sensing import combine_rows, measure_slots
from capsule_env.envs.declared_vector import DeclaredVectorEnv


def _numpy_combine(x, rows):
    out = np.zeros((x.shape[0], rows.shape[0]))
    for j in range(rows.shape[1]):
        out += x[:, j, None] * rows[None, :, j]
    return out


def test_the_row_sums_are_numpys_in_its_order():
    rng = np.random.default_rng(0)
    state = rng.standard_normal((57, 15)) * 10.0 ** rng.integers(-6, 3, (57, 15))
    rows = rng.standard_normal((5, 4)) * np.array([1.0, 0.0, 13.2, -1e-3])
    for x in (state[:, :4], state[:, 4:8], np.ascontiguousarray(state[:, 2:6])):
        got = combine_rows(x, rows, np.empty((x.shape[0], rows.shape[0])))
        expected = _numpy_combine(x, rows)
        assert (got == expected).all()
        assert not (got == x @ rows.T).all()  # a BLAS product sums otherwise: the test can fail


@pytest.mark.parametrize("setting", ["hils", "sim"])  # with and without sensor noise
def test_the_measurements_and_estimates_are_the_numpy_ones(setting):
    env = DeclaredVectorEnv(37, vehicle="half_car", setting=setting, observation="measured")
    env.reset(seed=4)
    rng = np.random.default_rng(2)
    for _ in range(25):
        env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
    batch = env.batch
    n, ns = batch.num_envs, batch.n_slots
    state = batch._estimator_state.copy()
    sig = batch.step(rng.uniform(-1.0, 1.0, (n, ns)))  # the compiled sensing
    # the same step's measurements in numpy, from the estimator's state before it
    ends = sig["slot_end_acceleration_m_s2"].reshape(n, ns, 2)
    true = np.stack([sig["stroke_m"], sig["stroke_rate_m_s"], ends[..., 0], ends[..., 1],
                     sig["gap_m"]], axis=-1).reshape(n, -1)  # fmt: skip
    noisy = batch.noise_level > 0.0
    if noisy:
        expected = true + batch._noise_std * _normals_of(batch, true.shape[1])
        assert not (expected == true).all()
    else:
        expected = true
    assert (batch.measured == expected).all()
    acc = expected.reshape(n, ns, N_SLOT_CHANNELS)[:, :, 2:4]
    b0, b1, b2, a1, a2 = batch._estimator
    s1, s2 = state[..., 0], state[..., 1]
    y = b0 * acc + s1
    assert (batch.estimates == y).all()
    assert (batch._estimator_state[..., 0] == b1 * acc - a1 * y + s2).all()
    assert (batch._estimator_state[..., 1] == b2 * acc - a2 * y).all()
    assert np.abs(y).max() > 0.0


def _normals_of(batch, d):
    from capsule_env.engine.declared_sensing import normals as _normals

    normals = np.empty((batch.num_envs, d + 1))
    _normals(batch.noise_key, batch.step_count, normals)
    return normals[:, :d]


def test_measure_slots_without_noise_copies_the_true_values():
    stroke, rate, gap = (np.full((2, 1), v) for v in (1.0, 2.0, 5.0))
    ends = np.array([[3.0, 4.0], [3.0, 4.0]])
    measured, estimates = np.zeros((2, 5)), np.zeros((2, 1, 2))
    state = np.zeros((2, 1, 2, 2))
    measure_slots((stroke, rate, ends, gap), np.ones(5), np.zeros((0, 0)), False, measured,
                  np.array([0.5, 0.0, 0.0, 0.0, 0.0]), state, estimates)  # fmt: skip
    assert (measured == [[1.0, 2.0, 3.0, 4.0, 5.0]] * 2).all()
    assert (estimates == [[[1.5, 2.0]]] * 2).all()  # b0 times each acceleration
