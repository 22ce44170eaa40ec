"""The per-step sensing of :class:`capsule_env.engine.declared_batch.DeclaredBatch`, compiled:
the same operations in the same order as the numpy expressions they replace, so the same bits
(``tests/test_declared_lanes.py`` and ``tests/test_declared_step_fused.py`` compare them with
``==``), without numpy's per-call cost on small arrays (a step of 1024 half-cars made about
twenty numpy calls of a few microseconds each here; then the reward and the observations in
numpy and the signals' copies: 0.24 ms of its 1.2 ms with the measurements, 2026-11-29).
:func:`sense_scored` is a whole step's sensing, reward and observations in one call.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from capsule_env._fastmath import FAST
from capsule_env.engine.env_kernel import gaussian_pair

__all__ = [
    "SIGNAL_NAMES",
    "combine_rows",
    "mean_row",
    "measure_slots",
    "normals",
    "observe_set",
    "reward_terms",
    "sense",
    "sense_scored",
    "signal_arrays",
]

#: The signals' names, in the order of :func:`signal_arrays`'s arrays (``DeclaredBatch.signals``).
SIGNAL_NAMES = ("stroke_m", "stroke_rate_m_s", "damper_force_n", "coil_current_a",
                "current_command_a", "comfort_acceleration_m_s2", "slot_end_acceleration_m_s2",
                "guideway_elevation_m", "gap_m")  # fmt: skip
#: Positions of :func:`signal_arrays`'s arrays, by :data:`SIGNAL_NAMES`.
_STROKE, _RATE, _CURRENT, _COMFORT, _ENDS, _ELEVATION, _GAP = (
    SIGNAL_NAMES.index(name) for name in ("stroke_m", "stroke_rate_m_s", "coil_current_a",
                                          "comfort_acceleration_m_s2",
                                          "slot_end_acceleration_m_s2", "guideway_elevation_m",
                                          "gap_m"))  # fmt: skip
#: The observation sets' codes for :func:`observe_set`.
OBSERVATION_CODES = {"full_state": 0, "sensors": 1, "measured": 2}
#: A slot's observation columns: the first ``_SENSED`` measured channels (stroke, stroke rate,
#: the two accelerations), with ``measured`` the gap and the two velocity estimates, then the
#: last command (``DeclaredBatch._set_names``).
_SENSED = 4
_SENSORS_PER_SLOT, _MEASURED_PER_SLOT = _SENSED + 1, _SENSED + 1 + 2 + 1
#: The state after ``q`` and ``q'``: per slot the Bouc-Wen ``z``, the dashpot's ``y`` and the
#: coil current (``capsule_env/plant/declared.py``), then the time.
_SLOT_STATES, _COIL = 3, 2


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
    """Each slot's measurements and velocity estimates (:func:`sense`'s, a step's).

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


@njit(**FAST)
def normals(keys, steps, out):  # pragma: no cover - numba
    """Standard normals per vehicle and channel from the counter-based hash of ``(key, step,
    pair)`` (the quarter-car env's sensor noise: independent of the batch). Pair by pair, the
    vehicles innermost into a row of their own (a loop that vectorises), then into ``out``."""
    rows = np.empty((2, out.shape[0]))
    for pair in range(out.shape[1] // 2):
        first, second = rows[0], rows[1]
        for n in range(out.shape[0]):
            first[n], second[n] = gaussian_pair(keys[n], steps[n], pair)
        for n in range(out.shape[0]):
            out[n, 2 * pair], out[n, 2 * pair + 1] = first[n], second[n]


@njit(**FAST)
def signal_arrays(state, out, requested, rows, ns, nc):  # pragma: no cover - numba
    """``DeclaredBatch.signals``'s arrays, each new, in :data:`SIGNAL_NAMES`' order; ``rows``:
    the stroke, comfort, slot-end, gap and gap-contact rows (each sum :func:`combine_rows`)."""
    stroke_rows, comfort_rows, end_rows, gap_rows, gap_contacts = rows
    n, base = state.shape[0], 2 * nc
    q, v = state[:, :nc], state[:, nc:base]
    acc, zg = out[:, ns : ns + nc], out[:, ns + nc :]
    stroke = combine_rows(q, stroke_rows, np.empty((n, ns)))
    rate = combine_rows(v, stroke_rows, np.empty((n, ns)))
    comfort = combine_rows(acc, comfort_rows, np.empty((n, comfort_rows.shape[0])))
    ends = combine_rows(acc, end_rows, np.empty((n, end_rows.shape[0])))
    gap = combine_rows(q, gap_rows, np.empty((n, ns)))
    ground = combine_rows(zg, gap_contacts, np.empty((n, ns)))
    current = np.empty((n, ns))
    for i in range(n):
        for s in range(ns):
            gap[i, s] = gap[i, s] - ground[i, s]
            current[i, s] = state[i, base + _COIL + _SLOT_STATES * s]
    return (
        stroke,
        rate,
        out[:, :ns].copy(),
        current,
        requested.copy(),
        comfort,
        ends,
        zg.copy(),
        gap,
    )


@njit(**FAST)
def mean_row(x):  # pragma: no cover - numba
    """``np.mean`` of a row, bit for bit: numpy's sum (its pairwise summation,
    ``DOUBLE_pairwise_sum``: one accumulator below 8 terms, 8 up to 128, halves beyond) over
    the count."""
    n = x.shape[0]
    return (_block_sum(x, 0, n) if n <= 128 else _halves_sum(x)) / n


@njit(**FAST)
def _block_sum(x, lo, n):  # pragma: no cover - numba
    """numpy's pairwise sum of ``x[lo : lo + n]``, ``n <= 128``."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += x[i]
        return res
    r0, r1, r2, r3 = x[lo], x[lo + 1], x[lo + 2], x[lo + 3]
    r4, r5, r6, r7 = x[lo + 4], x[lo + 5], x[lo + 6], x[lo + 7]
    i = lo + 8
    while i < lo + n - n % 8:
        r0, r1, r2, r3 = r0 + x[i], r1 + x[i + 1], r2 + x[i + 2], r3 + x[i + 3]
        r4, r5, r6, r7 = r4 + x[i + 4], r5 + x[i + 5], r6 + x[i + 6], r7 + x[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for j in range(i, lo + n):
        res += x[j]
    return res


@njit(**FAST)
def _halves_sum(x):  # pragma: no cover - numba
    """numpy's pairwise sum beyond 128 terms: the sum of the halves' sums (the first half's
    length a multiple of 8), each likewise, without recursion (numba cannot cache a recursive
    function): a stack of ranges, each with its stage (0: neither half summed, 1: the first)."""
    lo, length = np.zeros(64, np.int64), np.zeros(64, np.int64)
    stage, first = np.zeros(64, np.int64), np.zeros(64)
    top, length[0], carry = 0, x.shape[0], 0.0
    while top >= 0:
        n, half = length[top], length[top] // 2 - length[top] // 2 % 8
        if n <= 128 or stage[top] == 2:
            carry = _block_sum(x, lo[top], n) if n <= 128 else first[top] + carry
            top -= 1
            continue
        if stage[top] == 1:
            first[top] = carry
        stage[top] += 1
        lo[top + 1] = lo[top] + (0 if stage[top] == 1 else half)
        length[top + 1], stage[top + 1] = (half if stage[top] == 1 else n - half), 0
        top += 1
    return carry


@njit(**FAST)
def reward_terms(comfort, stroke, current, p):  # pragma: no cover - numba
    """``DeclaredBatch.reward``'s ``(reward, hit, cost_acceleration, cost_stroke, cost_energy)``
    (each (N,), new) from the signals, numpy's operations in its order; ``p``: the acceleration
    and stroke scales, ``i_max``, the three weights, the stroke limit and the bump-stop
    penalty (a tuple). Column by column, the vehicles innermost (loops that vectorise)."""
    acc_scale, stroke_scale, i_max, w_acc, w_stroke, w_energy, limit, penalty = p
    n, ns = stroke.shape
    sq_a, sq_s, sq_e = np.empty(comfort.shape), np.empty((n, ns)), np.empty((n, ns))
    hit = np.zeros(n, np.bool_)
    for j in range(comfort.shape[1]):
        for i in range(n):
            a = comfort[i, j] / acc_scale
            sq_a[i, j] = a * a
    for s in range(ns):
        for i in range(n):
            x = stroke[i, s] / stroke_scale
            c = current[i, s] / i_max if i_max > 0.0 else 0.0 * x
            sq_s[i, s], sq_e[i, s] = x * x, c * c
            hit[i] = hit[i] or abs(stroke[i, s]) > limit
    cost_a, cost_s, cost_e = _means(sq_a), _means(sq_s), _means(sq_e)
    reward = np.empty(n)
    for i in range(n):
        cost_a[i], cost_s[i], cost_e[i] = (
            w_acc * cost_a[i],
            w_stroke * cost_s[i],
            w_energy * cost_e[i],
        )
        reward[i] = -(cost_a[i] + cost_s[i] + cost_e[i]) - (penalty if hit[i] else 0.0)
    return reward, hit, cost_a, cost_s, cost_e


@njit(**FAST)
def _means(x):  # pragma: no cover - numba
    """``np.mean(x, axis=1)`` of a C-contiguous (N, w) array, bit for bit (:func:`mean_row`;
    below 8 columns numpy's sum is one accumulator from -0.0: vehicles innermost)."""
    n, w = x.shape
    out = np.empty(n)
    if w >= 8:
        for i in range(n):
            out[i] = mean_row(x[i])
        return out
    out[:] = -0.0
    for j in range(w):
        for i in range(n):
            out[i] += x[i, j]
    for i in range(n):
        out[i] = out[i] / w
    return out


@njit(**FAST)
def observe_set(
    code, width, state, sig, measured, estimates, requested
):  # pragma: no cover - numba
    """The observation set's columns (:data:`OBSERVATION_CODES` ``code``) of a new (N,
    ``width``) float32 array (numpy's cast); the columns after the set's are left for the
    preview. ``sig``: :func:`signal_arrays`'s arrays; ``requested``: the last commands."""
    stroke, rate, comfort, zg = sig[_STROKE], sig[_RATE], sig[_COMFORT], sig[_ELEVATION]
    n, ns = stroke.shape
    obs = np.empty((n, width), np.float32)
    if code == 0:
        nc = (state.shape[1] - _SLOT_STATES * ns - 1) // 2  # q, v, the slots, the time
        for i in range(n):
            for j in range(nc):
                obs[i, 2 * j], obs[i, 2 * j + 1] = state[i, j], state[i, nc + j]
            k = _put(obs, i, 2 * nc, stroke)
            k = _put(obs, i, _put(obs, i, k, rate), comfort)
            _put(obs, i, k, zg)
        return obs
    per = _SENSORS_PER_SLOT if code == 1 else _MEASURED_PER_SLOT
    nch = measured.shape[1] // ns
    for i in range(n):
        for s in range(ns):
            k, m = s * per, s * nch
            for c in range(_SENSED):
                obs[i, k + c] = measured[i, m + c]
            if code == 2:
                obs[i, k + _SENSED] = measured[i, m + _SENSED]  # the gap
                obs[i, k + _SENSED + 1] = estimates[i, s, 0]
                obs[i, k + _SENSED + 2] = estimates[i, s, 1]
            obs[i, k + per - 1] = requested[i, s]
    return obs


@njit(**FAST)
def _put(obs, i, k, x):  # pragma: no cover - numba
    for j in range(x.shape[1]):
        obs[i, k + j] = x[i, j]
    return k + x.shape[1]


@njit(**FAST)
def sense(state, out, requested, rows, noise, measured, estimator, est_state,
          estimates):  # fmt: skip  # pragma: no cover - numba
    """The signals (:func:`signal_arrays`) and the measurements (:func:`measure_slots`, with
    the :func:`normals` of ``noise``: ``(keys, steps, noise_std, noisy)``)."""
    keys, steps, noise_std, noisy = noise
    ns, nc = requested.shape[1], rows[0].shape[1]
    sig = signal_arrays(state, out, requested, rows, ns, nc)
    draws = np.empty((state.shape[0], measured.shape[1] + 1) if noisy else (0, 0))
    if noisy:
        normals(keys, steps, draws)
    measure_slots((sig[_STROKE], sig[_RATE], sig[_ENDS], sig[_GAP]), noise_std, draws, noisy, measured, estimator,
                  est_state, estimates)  # fmt: skip
    return sig


@njit(**FAST)
def sense_scored(state, out, requested, rows, noise, measured, estimator, est_state, estimates,
                 reward_p, code, width):  # fmt: skip  # pragma: no cover - numba
    """:func:`sense`, then the reward (:func:`reward_terms`) and the observation set
    (:func:`observe_set`): a step's sensing in one call."""
    sig = sense(state, out, requested, rows, noise, measured, estimator, est_state, estimates)
    terms = reward_terms(sig[_COMFORT], sig[_STROKE], sig[_CURRENT], reward_p)
    return sig, terms, observe_set(code, width, state, sig, measured, estimates, requested)
