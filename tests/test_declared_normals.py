"""The declared batch's sensor noise (``declared_sensing.normals``) is the counter-based hash of
``(key, step, pair)`` of the quarter-car env (``env_kernel.gaussian_pair``), vehicle by vehicle
and pair by pair, bit for bit, whatever the batch; a last odd column is left as it was."""

from __future__ import annotations

import numpy as np

from capsule_env.engine.declared_sensing import normals as _normals
from capsule_env.engine.env_kernel import gaussian_pair


def test_normals_are_the_hash_of_key_step_and_pair_bit_for_bit():
    rng = np.random.default_rng(4)
    n, columns = 37, 11
    keys = rng.integers(0, 2**63 - 1, n).astype(np.uint64)
    steps = rng.integers(0, 10_000, n)
    out = np.full((n, columns), 7.0)
    _normals(keys, steps, out)
    for v in range(n):
        for pair in range(columns // 2):
            a, b = gaussian_pair(keys[v], steps[v], pair)
            assert out[v, 2 * pair] == a and out[v, 2 * pair + 1] == b
    assert (out[:, -1] == 7.0).all()
    one = np.full((1, columns), 7.0)
    _normals(keys[5:6], steps[5:6], one)
    assert (one.view(np.int64) == out[5:6].view(np.int64)).all()
