"""The per-step sensing of :class:`capsule_env.engine.declared_batch.DeclaredBatch`, compiled:
the same operations in the same order as the numpy expressions they replace, so the same bits
(``tests/test_declared_lanes.py`` compares them with ``==``), without numpy's per-call cost on
small arrays (a step of 1024 half-cars made about twenty numpy calls of a few microseconds
each here).
"""

from __future__ import annotations

from numba import njit

from capsule_env._fastmath import FAST

__all__ = ["combine_rows", "measure_slots"]


@njit(**FAST)
def combine_rows(x, rows, out):  # pragma: no cover - numba
    """``out = x @ rows.T`` ((N, R)) summed coordinate by coordinate from 0.0, in order: numpy's
    ``out = 0; for j: out += x[:, j, None] * rows[None, :, j]``."""
    for n in range(x.shape[0]):
        for r in range(rows.shape[0]):
            s = 0.0
            for j in range(rows.shape[1]):
                s += x[n, j] * rows[r, j]
            out[n, r] = s
    return out


@njit(**FAST)
def measure_slots(sig, noise_std, normals, noisy, measured, estimator, state, estimates):
    """Each slot's measurements and velocity estimates (``DeclaredBatch._measure``).

    ``sig``: the (N, slots) stroke, stroke rate and gap and the (N, 2 slots) accelerations of
    each slot's upper and lower end, the true values, channel by channel
    (:data:`capsule_env.engine.declared_batch.SLOT_CHANNELS`); with ``noisy``, plus
    ``noise_std`` (slots * channels) times the first ``normals`` of each vehicle; into
    ``measured`` (N, slots * channels). The measured accelerations through the estimator
    ``(b0, b1, b2, a1, a2)`` (transposed direct form II, ``state`` (N, slots, 2, 2)) into
    ``estimates`` (N, slots, 2)."""
    stroke, rate, ends, gap = sig
    b0, b1, b2, a1, a2 = estimator[0], estimator[1], estimator[2], estimator[3], estimator[4]
    ns, nch = stroke.shape[1], measured.shape[1] // stroke.shape[1]
    for n in range(stroke.shape[0]):
        for s in range(ns):
            true = (stroke[n, s], rate[n, s], ends[n, 2 * s], ends[n, 2 * s + 1], gap[n, s])
            for c in range(nch):
                j = s * nch + c
                measured[n, j] = true[c] + noise_std[j] * normals[n, j] if noisy else true[c]
            for e in range(2):
                acc = measured[n, s * nch + 2 + e]
                y = b0 * acc + state[n, s, e, 0]
                state[n, s, e, 0] = b1 * acc - a1 * y + state[n, s, e, 1]
                state[n, s, e, 1] = b2 * acc - a2 * y
                estimates[n, s, e] = y
