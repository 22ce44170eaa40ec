"""Time integration of the 1/4-car plant with its secondary damper: one batched kernel.

The plant state of each vehicle is a float64 row of length :data:`STATE_SIZE`:

| index | name | unit |
| --- | --- | --- |
| 0 | car body displacement z_c | m |
| 1 | car body velocity z_c' | m/s |
| 2 | bogie displacement z_b | m |
| 3 | bogie velocity z_b' | m/s |
| 4 | damper hysteretic variable z (Bouc-Wen / Spencer) | m |
| 5 | damper internal displacement y (Spencer) | m |
| 6 | actual coil current i (after the coil lag) | A |
| 7 | time since the start of the run t | s |

The guideway is a set of elevation profiles sampled in space (``profiles[k, j]`` at
``j * spacing``); vehicle ``n`` reads profile ``profile_index[n]`` at
``start_position[n] + speed[n] * t`` with linear interpolation.

Scheme (per substep ``h``): classical RK4 on ``[z_c, z_c', z_b, z_b', y]``, with the stiff
hysteretic variable taken at every stage from the exact closed-form Bouc-Wen update over the
stage's deformation increment (:mod:`capsule_env.hysteresis`), and the first-order coil lag
``i' = (i_cmd - i)/tau`` solved exactly. What remains for RK4 is the pre-yield coupling of the
damper's stiffness alpha*A with its dashpots, whose rate ``alpha A / (c0 + c1)`` (about 1.6e3 1/s
for the reference damper at 1.5 A) and the plant's modes set the substep:
:func:`substep_table` keeps ``|lambda| h <= 2`` for the highest current in each control interval (at
1.5 A: 5 substeps of 1 ms at 200 Hz; at low current fewer).

One kernel serves a single vehicle and thousands: :func:`step_batch` advances every row by one
control interval, in parallel threads for large batches (:mod:`capsule_env._threads`). Pure numba/numpy, no Gym import.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from capsule_env._fastmath import FAST, fast_exp, fast_log, fast_tanh_nonneg
from capsule_env._threads import parallel_kernel, run_batched
from capsule_env.dampers import (
    BI_EXPONENTIAL,
    BOUC_WEN,
    N_DAMPER_PARAMS,
    PASSIVE,
    REFERENCE,
    TANH,
    DamperParams,
    bi_exponential_branch,
    branch_weight,
    damper_eval,
    hysteresis_params,
)
from capsule_env.hysteresis import hysteresis_update
from capsule_env.vehicle import VehicleParams

__all__ = [
    "STATE_SIZE",
    "OUTPUT_NAMES",
    "default_substeps",
    "substep_table",
    "substep_tables",
    "stiffness_rates",
    "step_batch",
    "initial_state",
    "simulate",
    "simulate_damper",
    "sinusoidal_stroke",
]

STATE_SIZE = 8
BODY_DISP, BODY_VEL, BOGIE_DISP, BOGIE_VEL, HYST_Z, DAMPER_Y, COIL_CURRENT, TIME = range(8)
#: Columns of the per-step output array written by :func:`step_batch`.
OUTPUT_NAMES = ("damper_force_n", "body_acc_m_s2", "bogie_acc_m_s2", "guideway_m")
N_OUTPUTS = len(OUTPUT_NAMES)
_I_MAX, _COIL_TAU, _BLEND = 14, 15, 16


@njit(cache=True, inline="always")
def _guideway(profiles, k, spacing, position):
    n = profiles.shape[1]
    s = position / spacing
    if s <= 0.0:
        return profiles[k, 0]
    j = int(s)
    if j >= n - 1:
        return profiles[k, n - 1]
    f = s - j
    return profiles[k, j] * (1.0 - f) + profiles[k, j + 1] * f


@njit(cache=True, inline="always")
def _derivs(model, dp, mc, mb, ks, kp, zc, vc, zb, vb, y, z, i, zg):
    x = zc - zb
    force, y_dot, _ = damper_eval(model, dp, x, vc - vb, y, z, i)
    secondary = ks * x + force
    return vc, -secondary / mc, vb, (secondary - kp * (zb - zg)) / mb, y_dot, force


@njit(cache=True, inline="always")
def _row16(a, n):
    """Row ``n`` of a (N, N_DAMPER_PARAMS) array as a tuple: a value, so no array view is
    created (views in the per-vehicle loop cost reference-count updates)."""
    return (
        a[n, 0], a[n, 1], a[n, 2], a[n, 3], a[n, 4], a[n, 5], a[n, 6], a[n, 7], a[n, 8], a[n, 9],
        a[n, 10], a[n, 11], a[n, 12], a[n, 13], a[n, 14], a[n, 15], a[n, 16],
    )  # fmt: skip


@njit(cache=True, inline="always")
def _advance(model, dp, mc, mb, ks, kp, s, i_cmd, profiles, k, spacing, x_start, speed, gain, dt,
             sub_table, row):  # fmt: skip
    """Advance one vehicle by ``dt`` with RK4 substeps; pure function of values.

    ``dp``: the packed damper parameters as a tuple; ``s``: the 8-tuple state row. Returns
    ``(new_state, (force, body_acc, bogie_acc, guideway))``. The guideway elevation is
    ``gain * profiles[k](x_start + speed * t)``. The number of substeps is
    ``sub_table[row, bin]`` for the bin of the highest current in the interval (the damper's stiffness grows with
    current; see :func:`substep_table`). Values in and out, no array rows: handing arrays to an
    inlined function costs numba reference-count updates per vehicle.
    """
    a_coef, gamma, beta = hysteresis_params(model, dp)
    hysteretic = a_coef > 0.0
    i_max = dp[_I_MAX]
    i_cmd = min(max(i_cmd, 0.0), i_max) if model != PASSIVE else 0.0
    tau = dp[_COIL_TAU]
    n_bins = sub_table.shape[1]
    i_high = max(i_cmd, s[6]) if tau > 0.0 else i_cmd
    b = int(i_high / i_max * n_bins) if i_max > 0.0 else 0
    n_sub = sub_table[row, min(max(b, 0), n_bins - 1)]
    h = dt / n_sub
    if tau > 0.0:
        e_half = math.exp(-0.5 * h / tau)
    else:
        e_half = 0.0
    zc, vc, zb, vb, z, y, ic, t = s
    if tau <= 0.0:
        ic = i_cmd
    zg0 = gain * _guideway(profiles, k, spacing, x_start + speed * t)
    for _ in range(n_sub):
        zg_half = gain * _guideway(profiles, k, spacing, x_start + speed * (t + 0.5 * h))
        zg1 = gain * _guideway(profiles, k, spacing, x_start + speed * (t + h))
        ic_half = i_cmd + (ic - i_cmd) * e_half
        ic1 = i_cmd + (ic_half - i_cmd) * e_half
        u0 = zc - zb - y
        # stage 1
        d1 = _derivs(model, dp, mc, mb, ks, kp, zc, vc, zb, vb, y, z, ic, zg0)
        # stage 2
        a0 = zc + 0.5 * h * d1[0]
        a1 = vc + 0.5 * h * d1[1]
        a2 = zb + 0.5 * h * d1[2]
        a3 = vb + 0.5 * h * d1[3]
        a4 = y + 0.5 * h * d1[4]
        zs = hysteresis_update(z, a0 - a2 - a4 - u0, a_coef, gamma, beta) if hysteretic else z
        d2 = _derivs(model, dp, mc, mb, ks, kp, a0, a1, a2, a3, a4, zs, ic_half, zg_half)
        # stage 3
        a0 = zc + 0.5 * h * d2[0]
        a1 = vc + 0.5 * h * d2[1]
        a2 = zb + 0.5 * h * d2[2]
        a3 = vb + 0.5 * h * d2[3]
        a4 = y + 0.5 * h * d2[4]
        zs = hysteresis_update(z, a0 - a2 - a4 - u0, a_coef, gamma, beta) if hysteretic else z
        d3 = _derivs(model, dp, mc, mb, ks, kp, a0, a1, a2, a3, a4, zs, ic_half, zg_half)
        # stage 4
        a0 = zc + h * d3[0]
        a1 = vc + h * d3[1]
        a2 = zb + h * d3[2]
        a3 = vb + h * d3[3]
        a4 = y + h * d3[4]
        zs = hysteresis_update(z, a0 - a2 - a4 - u0, a_coef, gamma, beta) if hysteretic else z
        d4 = _derivs(model, dp, mc, mb, ks, kp, a0, a1, a2, a3, a4, zs, ic1, zg1)
        w = h / 6.0
        zc += w * (d1[0] + 2.0 * d2[0] + 2.0 * d3[0] + d4[0])
        vc += w * (d1[1] + 2.0 * d2[1] + 2.0 * d3[1] + d4[1])
        zb += w * (d1[2] + 2.0 * d2[2] + 2.0 * d3[2] + d4[2])
        vb += w * (d1[3] + 2.0 * d2[3] + 2.0 * d3[3] + d4[3])
        y_new = y + w * (d1[4] + 2.0 * d2[4] + 2.0 * d3[4] + d4[4])
        if hysteretic:
            z = hysteresis_update(z, zc - zb - y_new - u0, a_coef, gamma, beta)
        y = y_new
        ic = ic1
        t += h
        zg0 = zg1
    d = _derivs(model, dp, mc, mb, ks, kp, zc, vc, zb, vb, y, z, ic, zg0)
    return (zc, vc, zb, vb, z, y, ic, t), (d[5], d[1], d[3], zg0)


@njit(cache=True, inline="always")
def _row8(a, n):
    return (a[n, 0], a[n, 1], a[n, 2], a[n, 3], a[n, 4], a[n, 5], a[n, 6], a[n, 7])


@njit(cache=True)
def _step_range(lo, hi, model, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed, gain, dt,
                table, out):  # fmt: skip
    for n in range(lo, hi):
        new, outputs = _advance(
            model, _row16(dp, n), vp[n, 0], vp[n, 1], vp[n, 2], vp[n, 3], _row8(state, n),
            i_cmd[n], profiles, idx[n], spacing, x0[n], speed[n], gain[n], dt, table, n,
        )  # fmt: skip
        for j in range(8):
            state[n, j] = new[j]
        for j in range(4):
            out[n, j] = outputs[j]


# ---------------------------------------------------------------------------------------------
# Vectorised (SIMD) block kernel
#
# The scalar kernel above advances one vehicle at a time; its RK4 stages wait on each other, so
# a core spends most of its time waiting on the latency of divisions and libm calls. The block
# kernel below does the same arithmetic with the vehicles of a block (up to BLOCK) side by side:
# the state of the block is copied into a scratch array with one row per quantity and one
# column per vehicle, and each RK4 substep is a loop over the columns whose body makes no calls
# (exp/tanh from capsule_env._fastmath), which LLVM vectorises (4 or 8 vehicles per
# instruction). Vehicles with different substep counts are sorted by that count, so substep s
# loops only over those that still need it: nothing is computed and thrown away. Each vehicle's
# result does not depend on which other vehicles share its block or which SIMD lane it lands
# in (the same operations in the same order), so a batch of one and a batch of thousands agree
# bit for bit. Models: reference (Spencer), bi-exponential, tanh, passive; Bouc-Wen (its
# unloading branch needs tan/atan) and Spencer parameters with gamma > beta use the scalar
# kernel (see :func:`block_kernel_mode`).
# ---------------------------------------------------------------------------------------------

#: Vehicles per block of the vectorised kernel.
BLOCK = 64
#: :func:`block_kernel_mode` results.
KERNEL_SCALAR, KERNEL_BLOCK, KERNEL_BLOCK_TANH_UNLOAD = 0, 1, 2
#: Flag added to a block mode when every row has the same damper parameters (an env's plant):
#: the kernel then reads them as constants instead of copying them into every vehicle's lane.
KERNEL_UNIFORM = 4

# scratch rows: the state, then per-vehicle constants of the interval
(_W_ZC, _W_VC, _W_ZB, _W_VB, _W_Z, _W_Y, _W_I, _W_T, _W_H, _W_ICMD, _W_EHALF, _W_INV_MC,
 _W_INV_MB, _W_KS, _W_KP, _W_ZG0, _W_ZGH, _W_ZG1, _W_A, _W_INV_A, _W_RL, _W_INV_RL, _W_KL,
 _W_RU, _W_INV_RU, _W_KU, _W_INV_KU) = range(27)  # fmt: skip
_W_P = 27  # N_DAMPER_PARAMS packed damper parameters
_W_ROWS = _W_P + N_DAMPER_PARAMS
#: The scratch array holds two halves (even and odd sorted ranks), rows HALF apart.
HALF = BLOCK // 2
_W_HALF_SIZE = _W_ROWS * HALF


def block_kernel_mode(damper_code: int, damper_params: np.ndarray) -> int:
    """Which kernel :func:`step_batch` uses for these damper rows: ``KERNEL_SCALAR`` (Bouc-Wen,
    or Spencer rows whose unloading branch is not of tanh/linear form, or rows that disagree),
    ``KERNEL_BLOCK`` or ``KERNEL_BLOCK_TANH_UNLOAD`` (Spencer with beta > gamma), plus
    ``KERNEL_UNIFORM`` when all rows are equal (the same numbers, fewer copies)."""
    mode = _block_kernel_family(damper_code, damper_params)
    p = np.asarray(damper_params).reshape(-1, np.shape(damper_params)[-1])
    if mode != KERNEL_SCALAR and np.all(p == p[:1]):
        mode |= KERNEL_UNIFORM
    return mode


def _block_kernel_family(damper_code: int, damper_params: np.ndarray) -> int:
    if damper_code in (BI_EXPONENTIAL, TANH, PASSIVE):
        return KERNEL_BLOCK
    if damper_code != REFERENCE:
        return KERNEL_SCALAR
    p = np.asarray(damper_params).reshape(-1, damper_params.shape[-1])
    a_coef, gamma, beta = p[:, 11], p[:, 9], p[:, 10]
    if np.any(a_coef <= 0.0) or np.any(gamma < 0.0) or np.any(gamma + beta <= 0.0):
        return KERNEL_SCALAR
    unload = beta - gamma
    if np.all(unload == 0.0):
        return KERNEL_BLOCK
    if np.all(unload > 0.0):
        return KERNEL_BLOCK_TANH_UNLOAD
    return KERNEL_SCALAR


#: Columns of :func:`block_constants`: A, 1/A, r_l, 1/r_l, k_l, r_u, 1/r_u, k_u, 1/k_u (the
#: scratch rows _W_A .. _W_INV_KU, in order), then the coil-lag factor exp(-h / (2 tau)) of
#: each substep-table bin.
_D_EHALF = 9


def block_constants(
    damper_code: int, damper_params: np.ndarray, dt_s: float, table: np.ndarray
) -> np.ndarray:
    """Per-vehicle constants of the block kernel, computed once rather than every step: the
    Riccati constants of the Spencer hysteresis (``r = sqrt(A/p)``, ``k = sqrt(A p)`` of the
    loading ``p = gamma + beta`` and unloading ``p = beta - gamma`` branches; 1 where unused)
    and the coil-lag factor ``exp(-h / (2 tau))`` at each table bin's substep ``h = dt / n``
    (0 without coil lag). ``table``: one (bins,) table for every row, or (N, bins)."""
    p = np.atleast_2d(np.asarray(damper_params, dtype=float))
    out = np.ones((p.shape[0], _D_EHALF + np.shape(table)[-1]))
    if damper_code == REFERENCE:
        a, gamma, beta = p[:, 11], p[:, 9], p[:, 10]
        load = gamma + beta
        unload = np.where(beta - gamma > 0.0, beta - gamma, 1.0)
        r_l, r_u = np.sqrt(a / load), np.sqrt(a / unload)
        k_l, k_u = np.sqrt(a * load), np.sqrt(a * unload)
        cols = (a, 1.0 / a, r_l, 1.0 / r_l, k_l, r_u, 1.0 / r_u, k_u, 1.0 / k_u)
        out[:, :_D_EHALF] = np.stack(cols, axis=1)
    tau = p[:, _COIL_TAU][:, None]
    h = dt_s / np.broadcast_to(np.asarray(table, dtype=float), (p.shape[0], np.shape(table)[-1]))
    lag = tau > 0.0
    out[:, _D_EHALF:] = np.where(lag, np.exp(-0.5 * h / np.where(lag, tau, 1.0)), 0.0)
    return np.ascontiguousarray(out)


@njit(**FAST)
def _hysteresis_fast(z0, du, a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u, k_u, inv_k_u,
                     tanh_unload):  # fmt: skip
    """:func:`capsule_env.hysteresis.hysteresis_update` without branches or library calls, for
    ``A > 0``, ``gamma + beta > 0`` and an unloading coefficient ``beta - gamma`` that is 0
    (``tanh_unload`` False: linear) or positive (True). ``r, k = sqrt(A/p), sqrt(A p)`` of the
    loading (``_l``) and unloading (``_u``) Riccati equations; increments are written as
    ``q + r T (1 - t0^2) / (1 + t0 T)`` (``T = tanh(k m)``, ``t0 = q / r``), so that a zero
    increment returns ``z0`` exactly, with T's own division folded into that one."""
    s = 1.0 if du >= 0.0 else -1.0
    m = abs(du)
    q = s * z0
    if tanh_unload:
        t0u = q * inv_r_u
        eu = fast_exp(-2.0 * k_u * m)  # tanh(k_u m) = (1 - eu) / (1 + eu)
        q_unload = q + r_u * (1.0 - t0u * t0u) * (1.0 - eu) / ((1.0 + eu) + t0u * (1.0 - eu))
        xz = min(max(-t0u, 0.0), 1.0 - 1e-12)
        m_zero = 0.5 * fast_log((1.0 + xz) / (1.0 - xz)) * inv_k_u
    else:
        q_unload = q + a * m
        m_zero = -q * inv_a
    unloading = q < 0.0
    stays = unloading and m <= m_zero
    q_start = 0.0 if unloading else q
    m_load = max(m - m_zero, 0.0) if unloading else m
    t0 = q_start * inv_r_l
    el = fast_exp(-2.0 * k_l * m_load)  # tanh(k_l m) = (1 - el) / (1 + el): one division
    q_load = q_start + r_l * (1.0 - t0 * t0) * (1.0 - el) / ((1.0 + el) + t0 * (1.0 - el))
    return s * (q_unload if stays else q_load)


@njit(**FAST)
def _inv_dashpots(model, p, i):
    """``1 / (c0 + c1)`` of the Spencer damper at current ``i`` (1 for other models)."""
    if model == REFERENCE:
        return 1.0 / ((p[0] + p[1] * i) + (p[2] + p[3] * i))
    return 1.0


@njit(**FAST)
def _force_fast(model, p, x, v, y, z, i, inv_c):
    """:func:`capsule_env.dampers.damper_eval` without branches or library calls: ``(F, y')``.
    ``p``: the 16 packed parameters as a tuple; ``model`` a compile-time constant; ``inv_c``:
    :func:`_inv_dashpots` at ``i`` (computed ahead, off the stages' dependency chain)."""
    if model == REFERENCE:
        c0 = p[0] + p[1] * i
        c1 = p[2] + p[3] * i
        alpha = p[4] + p[5] * i
        y_dot = (alpha * z + c0 * v + p[6] * (x - y)) * inv_c
        return c1 * y_dot + p[7] * (x - p[8]), y_dot
    if model == BI_EXPONENTIAL:
        a0, a1, b0, b1, c0, c1, d = bi_exponential_branch(p, x)
        mag = 1.0 - fast_exp(-d * abs(v))
        s_d = mag if v >= 0.0 else -mag
        return (a0 + a1 * i) * s_d + (b0 + b1 * i) * v + c0 + c1 * i, 0.0
    if model == TANH:
        sx = 2.0 * branch_weight(x, p[_BLEND]) - 1.0
        arg = p[8] * v + p[9] * sx
        th = fast_tanh_nonneg(abs(arg))
        th = th if arg >= 0.0 else -th
        force = (p[0] + p[1] * i) * v + (p[2] + p[3] * i) * x + (p[4] + p[5] * i) * th
        return force + p[6] + p[7] * i, 0.0
    return p[0] * v, 0.0


@njit(**FAST)
def _guideway_fast(profiles, k, spacing, last, position):
    """:func:`_guideway` with clamps instead of branches (the same value)."""
    s = min(max(position / spacing, 0.0), last)
    j = min(int(s), int(last) - 1)
    f = s - j
    return profiles[k, j] * (1.0 - f) + profiles[k, j + 1] * f


@njit(**FAST)
def _slot(rank):
    """Flat offset of the sorted vehicle ``rank`` in the scratch array: even ranks in the first
    half, odd ranks in the second, ``rank // 2`` within it (rows ``HALF`` apart)."""
    return (rank & 1) * _W_HALF_SIZE + (rank >> 1)


@njit(**FAST, inline="always")
def _lane_values(wv, j):
    """The scratch values of one vehicle (rows 0 .. _W_ZG1) as a tuple (offset ``j``)."""
    return (
        wv[j], wv[j + HALF], wv[j + 2 * HALF], wv[j + 3 * HALF], wv[j + 4 * HALF],
        wv[j + 5 * HALF], wv[j + 6 * HALF], wv[j + 7 * HALF], wv[j + 8 * HALF],
        wv[j + 9 * HALF], wv[j + 10 * HALF], wv[j + 11 * HALF], wv[j + 12 * HALF],
        wv[j + 13 * HALF], wv[j + 14 * HALF], wv[j + 15 * HALF], wv[j + 16 * HALF],
        wv[j + 17 * HALF],
    )  # fmt: skip


@njit(**FAST, inline="always")
def _lane_constants(wv, j):
    """The 9 hysteresis constants of one vehicle (rows _W_A .. _W_INV_KU) from the view."""
    b = j + _W_A * HALF
    return (
        wv[b], wv[b + HALF], wv[b + 2 * HALF], wv[b + 3 * HALF], wv[b + 4 * HALF],
        wv[b + 5 * HALF], wv[b + 6 * HALF], wv[b + 7 * HALF], wv[b + 8 * HALF],
    )  # fmt: skip


@njit(**FAST, inline="always")
def _row_params(dp, n):
    """The 16 damper parameters of row ``n`` as a tuple (constants of a uniform batch)."""
    return (
        dp[n, 0], dp[n, 1], dp[n, 2], dp[n, 3], dp[n, 4], dp[n, 5], dp[n, 6], dp[n, 7],
        dp[n, 8], dp[n, 9], dp[n, 10], dp[n, 11], dp[n, 12], dp[n, 13], dp[n, 14], dp[n, 15],
        dp[n, 16],
    )  # fmt: skip


@njit(**FAST, inline="always")
def _row_constants(derived, n):
    """The 9 hysteresis constants of :func:`block_constants` row ``n`` as a tuple."""
    return (
        derived[n, 0], derived[n, 1], derived[n, 2], derived[n, 3], derived[n, 4],
        derived[n, 5], derived[n, 6], derived[n, 7], derived[n, 8],
    )  # fmt: skip


@njit(**FAST, inline="always")
def _lane_params(wv, j):
    """The 16 packed damper parameters of one vehicle from the scratch view."""
    b = j + _W_P * HALF
    return (
        wv[b], wv[b + HALF], wv[b + 2 * HALF], wv[b + 3 * HALF], wv[b + 4 * HALF],
        wv[b + 5 * HALF], wv[b + 6 * HALF], wv[b + 7 * HALF], wv[b + 8 * HALF],
        wv[b + 9 * HALF], wv[b + 10 * HALF], wv[b + 11 * HALF], wv[b + 12 * HALF],
        wv[b + 13 * HALF], wv[b + 14 * HALF], wv[b + 15 * HALF], wv[b + 16 * HALF],
    )  # fmt: skip


@njit(**FAST, inline="always")
def _rk4_lane(model, tanh_unload, v, p, hc):
    """One RK4 substep of one vehicle from its scratch values ``v``, damper parameters ``p``
    and hysteresis constants ``hc`` (tuples): returns the new
    ``(z_c, z_c', z_b, z_b', z, y, i, t, z_g)``."""
    zc, vc, zb, vb, z, y, ic, t, h, i_cmd, e_half = v[0:11]
    inv_mc, inv_mb, ks, kp, zg0, zgh, zg1 = v[11:18]
    a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u, k_u, inv_k_u = hc
    ic_half = i_cmd + (ic - i_cmd) * e_half
    ic1 = i_cmd + (ic_half - i_cmd) * e_half
    inv_c0 = _inv_dashpots(model, p, ic)
    inv_ch = _inv_dashpots(model, p, ic_half)
    inv_c1 = _inv_dashpots(model, p, ic1)
    u0 = zc - zb - y
    # stage 1
    f1, y1 = _force_fast(model, p, zc - zb, vc - vb, y, z, ic, inv_c0)
    sec = ks * (zc - zb) + f1
    k10, k11, k12, k13 = vc, -sec * inv_mc, vb, (sec - kp * (zb - zg0)) * inv_mb
    # stage 2
    a0, a1 = zc + 0.5 * h * k10, vc + 0.5 * h * k11
    a2, a3, a4 = zb + 0.5 * h * k12, vb + 0.5 * h * k13, y + 0.5 * h * y1
    zs = z
    if model == REFERENCE:
        zs = _hysteresis_fast(z, a0 - a2 - a4 - u0, a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u,
                              k_u, inv_k_u, tanh_unload)  # fmt: skip
    f2, y2 = _force_fast(model, p, a0 - a2, a1 - a3, a4, zs, ic_half, inv_ch)
    sec = ks * (a0 - a2) + f2
    k20, k21, k22, k23 = a1, -sec * inv_mc, a3, (sec - kp * (a2 - zgh)) * inv_mb
    # stage 3
    a0, a1 = zc + 0.5 * h * k20, vc + 0.5 * h * k21
    a2, a3, a4 = zb + 0.5 * h * k22, vb + 0.5 * h * k23, y + 0.5 * h * y2
    if model == REFERENCE:
        zs = _hysteresis_fast(z, a0 - a2 - a4 - u0, a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u,
                              k_u, inv_k_u, tanh_unload)  # fmt: skip
    f3, y3 = _force_fast(model, p, a0 - a2, a1 - a3, a4, zs, ic_half, inv_ch)
    sec = ks * (a0 - a2) + f3
    k30, k31, k32, k33 = a1, -sec * inv_mc, a3, (sec - kp * (a2 - zgh)) * inv_mb
    # stage 4
    a0, a1 = zc + h * k30, vc + h * k31
    a2, a3, a4 = zb + h * k32, vb + h * k33, y + h * y3
    if model == REFERENCE:
        zs = _hysteresis_fast(z, a0 - a2 - a4 - u0, a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u,
                              k_u, inv_k_u, tanh_unload)  # fmt: skip
    f4, y4 = _force_fast(model, p, a0 - a2, a1 - a3, a4, zs, ic1, inv_c1)
    sec = ks * (a0 - a2) + f4
    k40, k41, k42, k43 = a1, -sec * inv_mc, a3, (sec - kp * (a2 - zg1)) * inv_mb
    wt = h / 6.0
    zc = zc + wt * (k10 + 2.0 * k20 + 2.0 * k30 + k40)
    vc = vc + wt * (k11 + 2.0 * k21 + 2.0 * k31 + k41)
    zb = zb + wt * (k12 + 2.0 * k22 + 2.0 * k32 + k42)
    vb = vb + wt * (k13 + 2.0 * k23 + 2.0 * k33 + k43)
    y_new = y + wt * (y1 + 2.0 * y2 + 2.0 * y3 + y4)
    if model == REFERENCE:
        z = _hysteresis_fast(z, zc - zb - y_new - u0, a, inv_a, r_l, inv_r_l, k_l, r_u,
                             inv_r_u, k_u, inv_k_u, tanh_unload)  # fmt: skip
    return zc, vc, zb, vb, z, y_new, ic1, t + h, zg1


@njit(**FAST, inline="always")
def _store_lane(wv, j, new, active):
    """Write a vehicle's new state (rows ZC .. T and ZG0) if ``active`` (a select, no branch)."""
    wv[j + 0 * HALF] = new[0] if active else wv[j + 0 * HALF]
    wv[j + 1 * HALF] = new[1] if active else wv[j + 1 * HALF]
    wv[j + 2 * HALF] = new[2] if active else wv[j + 2 * HALF]
    wv[j + 3 * HALF] = new[3] if active else wv[j + 3 * HALF]
    wv[j + 4 * HALF] = new[4] if active else wv[j + 4 * HALF]
    wv[j + 5 * HALF] = new[5] if active else wv[j + 5 * HALF]
    wv[j + 6 * HALF] = new[6] if active else wv[j + 6 * HALF]
    wv[j + 7 * HALF] = new[7] if active else wv[j + 7 * HALF]
    wv[j + _W_ZG0 * HALF] = new[8] if active else wv[j + _W_ZG0 * HALF]


@njit(cache=True, error_model="numpy")
def _guideway_lanes(w, first, nb, order, profiles, idx, spacing, x0, speed, gain):
    """Guideway elevation at the midpoint and end of the substep of sorted vehicles
    ``first .. nb-1`` (a gather from the profile bank, kept out of the SIMD loop)."""
    last = profiles.shape[1] - 1.0
    for rank in range(first, nb):
        n = order[rank]
        o = _slot(rank)
        t, h = w[o + _W_T * HALF], w[o + _W_H * HALF]
        k, g, p0, sp = idx[n], gain[n], x0[n], speed[n]
        w[o + _W_ZGH * HALF] = g * _guideway_fast(
            profiles, k, spacing, last, p0 + sp * (t + 0.5 * h)
        )
        w[o + _W_ZG1 * HALF] = g * _guideway_fast(profiles, k, spacing, last, p0 + sp * (t + h))


@njit(cache=True, error_model="numpy")
def _substep_lanes(model, mode, w, first, nb, p_uniform, hc_uniform):
    """One RK4 substep of the sorted vehicles ``first .. nb-1``: the SIMD loop.

    Each iteration advances two vehicles, one from each half of the scratch array (even and
    odd ranks): two independent dependency chains, so the core overlaps their latencies (an RK4
    substep is one long chain of dependent operations). A vehicle outside ``first .. nb-1``
    that shares an iteration is computed and not stored (a select). The view starts at the
    first column and every access is a constant offset from it, so LLVM sees no negative
    indices and no overlap and vectorises the loop (4 vehicle pairs per instruction).
    With ``KERNEL_UNIFORM`` in ``mode`` the damper parameters and hysteresis constants are
    ``p_uniform`` and ``hc_uniform`` (loop constants) instead of scratch rows.
    """
    tanh_unload = (mode & ~KERNEL_UNIFORM) == KERNEL_BLOCK_TANH_UNLOAD  # ``mode``: a literal
    uniform = (mode & KERNEL_UNIFORM) != 0
    col0 = first >> 1
    first_a = (first + 1) >> 1  # first active column of the even half
    end = (nb + 1) >> 1
    end_b = nb >> 1  # odd half: columns < end_b are vehicles
    wv = w[col0:]  # one view: the odd half sits at the constant offset _W_HALF_SIZE
    # A multiple of 4 iterations: a partial SIMD group runs as masked lanes rather than as the
    # loop's scalar remainder (4x slower per vehicle). Lanes past the end only read (padding).
    for j in range((end - col0 + 3) & -4):
        col = col0 + j
        jb = j + _W_HALF_SIZE
        if uniform:
            p_a, p_b, hc_a, hc_b = p_uniform, p_uniform, hc_uniform, hc_uniform
        else:
            p_a, p_b = _lane_params(wv, j), _lane_params(wv, jb)
            hc_a, hc_b = _lane_constants(wv, j), _lane_constants(wv, jb)
        new_a = _rk4_lane(model, tanh_unload, _lane_values(wv, j), p_a, hc_a)
        new_b = _rk4_lane(model, tanh_unload, _lane_values(wv, jb), p_b, hc_b)
        _store_lane(wv, j, new_a, col >= first_a and col < end)
        _store_lane(wv, jb, new_b, col < end_b)


@njit(cache=True, error_model="numpy")
def _output_lanes(model, mode, wv, count, p_uniform):
    """Force and accelerations at the end of the interval (into rows ZGH, ZG1, H) of the first
    ``count`` columns of one half."""
    for j in range(count):
        v = _lane_values(wv, j)
        p = p_uniform if (mode & KERNEL_UNIFORM) != 0 else _lane_params(wv, j)
        zc, vc, zb, vb, z, y, ic = v[0:7]
        ks, kp, inv_mc, inv_mb, zg0 = v[_W_KS], v[_W_KP], v[_W_INV_MC], v[_W_INV_MB], v[_W_ZG0]
        force, _ = _force_fast(model, p, zc - zb, vc - vb, y, z, ic, _inv_dashpots(model, p, ic))
        sec = ks * (zc - zb) + force
        wv[j + _W_ZGH * HALF] = force
        wv[j + _W_ZG1 * HALF] = -sec * inv_mc
        wv[j + _W_H * HALF] = (sec - kp * (zb - zg0)) * inv_mb


@njit(cache=True, error_model="numpy")
def _integrate_block(model, mode, w, nb, nsub, order, profiles, idx, spacing, x0, speed,
                     gain, p_uniform, hc_uniform):  # fmt: skip
    """RK4 substeps of the sorted vehicles ``0 .. nb-1`` (ascending ``nsub``): substep ``s``
    advances the tail of vehicles that need more than ``s`` substeps."""
    first = 0
    s = 0
    while first < nb:
        _guideway_lanes(w, first, nb, order, profiles, idx, spacing, x0, speed, gain)
        _substep_lanes(model, mode, w, first, nb, p_uniform, hc_uniform)
        s += 1
        while first < nb and nsub[first] <= s:
            first += 1
    _output_lanes(model, mode, w[:_W_HALF_SIZE], min(HALF, (((nb + 1) >> 1) + 3) & -4), p_uniform)
    _output_lanes(model, mode, w[_W_HALF_SIZE:], min(HALF, ((nb >> 1) + 3) & -4), p_uniform)


@njit(cache=True, error_model="numpy")
def _plant_block(model, mode, lo, hi, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed,
                 gain, dt, table, derived, out):  # fmt: skip
    """Advance vehicles ``lo .. hi-1`` (at most BLOCK) by ``dt``: the vectorised kernel."""
    nb = hi - lo
    # flat: two halves of _W_ROWS rows, each HALF long, + padding read by masked SIMD lanes.
    # The columns that only masked lanes read are zeroed, so that no lane ever computes on
    # denormal garbage (slow on x86); the rest is written below.
    w = np.empty(2 * _W_HALF_SIZE + 8)
    w[2 * _W_HALF_SIZE :] = 0.0
    end = (nb + 1) >> 1
    for col in range(end, min(end + 3, HALF)):
        for r in range(_W_ROWS):
            w[r * HALF + col] = 0.0
            w[_W_HALF_SIZE + r * HALF + col] = 0.0
    nsub_of = np.empty(BLOCK, dtype=np.int64)
    bin_of = np.empty(BLOCK, dtype=np.int64)
    nsub = np.empty(BLOCK, dtype=np.int64)
    order = np.empty(BLOCK, dtype=np.int64)
    n_bins = table.shape[1]
    lo_sub, hi_sub = 1 << 62, 1
    for m in range(nb):  # substeps per vehicle (from the highest current of the interval)
        n = lo + m
        i_max, tau = dp[n, _I_MAX], dp[n, _COIL_TAU]
        cmd = min(max(i_cmd[n], 0.0), i_max) if model != PASSIVE else 0.0
        i_high = max(cmd, state[n, COIL_CURRENT]) if tau > 0.0 else cmd
        b = int(i_high / i_max * n_bins) if i_max > 0.0 else 0
        b = min(max(b, 0), n_bins - 1)
        ns = table[n, b]
        nsub_of[m] = ns
        bin_of[m] = b
        lo_sub, hi_sub = min(lo_sub, ns), max(hi_sub, ns)
    # counting sort by substeps (stable), so substep s loops over a contiguous tail
    if hi_sub - lo_sub < 64:
        count = np.zeros(66, dtype=np.int64)
        for m in range(nb):
            count[nsub_of[m] - lo_sub + 1] += 1
        for c in range(1, 66):
            count[c] += count[c - 1]
        for m in range(nb):
            c = nsub_of[m] - lo_sub
            order[count[c]] = lo + m
            count[c] += 1
    else:  # a hand-made table with widely spread entries: a stable sort
        ranks = np.argsort(nsub_of[:nb], kind="mergesort")
        for m in range(nb):
            order[m] = lo + ranks[m]
    last = profiles.shape[1] - 1.0
    for rank in range(nb):
        n = order[rank]
        o = _slot(rank)
        ns = nsub_of[n - lo]
        nsub[rank] = ns
        i_max, tau = dp[n, _I_MAX], dp[n, _COIL_TAU]
        cmd = min(max(i_cmd[n], 0.0), i_max) if model != PASSIVE else 0.0
        h = dt / ns
        for j in range(STATE_SIZE):
            w[o + j * HALF] = state[n, j]
        if tau <= 0.0:
            w[o + _W_I * HALF] = cmd
        w[o + _W_H * HALF] = h
        w[o + _W_ICMD * HALF] = cmd
        w[o + _W_EHALF * HALF] = derived[n, _D_EHALF + bin_of[n - lo]]
        w[o + _W_INV_MC * HALF] = 1.0 / vp[n, 0]
        w[o + _W_INV_MB * HALF] = 1.0 / vp[n, 1]
        w[o + _W_KS * HALF] = vp[n, 2]
        w[o + _W_KP * HALF] = vp[n, 3]
        position = x0[n] + speed[n] * w[o + _W_T * HALF]
        w[o + _W_ZG0 * HALF] = gain[n] * _guideway_fast(profiles, idx[n], spacing, last, position)
        if (mode & KERNEL_UNIFORM) == 0:  # else read as constants (_substep_lanes)
            for j in range(N_DAMPER_PARAMS):
                w[o + (_W_P + j) * HALF] = dp[n, j]
            for j in range(_D_EHALF):  # hysteresis constants, computed once per batch
                w[o + (_W_A + j) * HALF] = derived[n, j]
    if nb & 1:  # the odd half's last column has no vehicle: give it real numbers to chew on
        src, dst = _slot(nb - 1), _slot(nb)
        for j in range(_W_ROWS):
            w[dst + j * HALF] = w[src + j * HALF]
    _integrate_block(model, mode, w, nb, nsub, order, profiles, idx, spacing, x0, speed, gain,
                     _row_params(dp, lo), _row_constants(derived, lo))  # fmt: skip
    for rank in range(nb):
        n = order[rank]
        o = _slot(rank)
        for j in range(STATE_SIZE):
            state[n, j] = w[o + j * HALF]
        out[n, 0] = w[o + _W_ZGH * HALF]
        out[n, 1] = w[o + _W_ZG1 * HALF]
        out[n, 2] = w[o + _W_H * HALF]
        out[n, 3] = w[o + _W_ZG0 * HALF]


@njit(cache=True)
def _step_chunk(mode, lo, hi, model, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed,
                gain, dt, table, derived, out):  # fmt: skip
    if mode == KERNEL_SCALAR:
        _step_range(lo, hi, model, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed, gain,
                    dt, table, out)  # fmt: skip
        return
    for b in range(lo, hi, BLOCK):
        _plant_block(model, mode, b, min(hi, b + BLOCK), dp, vp, state, i_cmd, profiles, idx,
                     spacing, x0, speed, gain, dt, table, derived, out)  # fmt: skip


def _make_step_kernels(mode: int, model: int) -> tuple[Any, Any]:
    """``(serial, parallel)`` plant kernels for one (kernel mode, damper model):
    ``serial(lo, hi, ...)`` advances vehicles ``lo .. hi-1``, ``parallel(n, ...)`` all of
    ``[0, n)`` on all cores (:mod:`capsule_env._threads`).

    ``mode`` and ``model`` are closure constants: numba compiles each pair separately (the
    branches for other models are pruned), so only the models in use are compiled.
    """

    @njit(cache=True)
    def serial(lo, hi, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed, gain, dt, table,
               derived, out):  # fmt: skip
        _step_chunk(mode, lo, hi, model, dp, vp, state, i_cmd, profiles, idx, spacing, x0,
                    speed, gain, dt, table, derived, out)  # fmt: skip

    return serial, parallel_kernel(serial)


_STEP_KERNELS: dict[tuple[int, int], tuple[Any, Any]] = {}


def step_kernels(mode: int, model: int) -> tuple[Any, Any]:
    """``(serial, parallel)`` compiled plant kernels for a kernel mode and damper model
    (memoised)."""
    key = (int(mode), int(model))
    if key not in _STEP_KERNELS:
        _STEP_KERNELS[key] = _make_step_kernels(*key)
    return _STEP_KERNELS[key]


def step_batch(
    damper_code: int,
    damper_params: np.ndarray,
    vehicle_params: np.ndarray,
    state: np.ndarray,
    current_command_a: np.ndarray,
    profiles: np.ndarray,
    profile_index: np.ndarray,
    spacing_m: float,
    start_position_m: np.ndarray,
    speed_mps: np.ndarray,
    dt_s: float,
    substeps: int | np.ndarray,
    out: np.ndarray,
    guideway_gain: np.ndarray | None = None,
) -> None:
    """Advance ``N`` vehicles in place by one control interval ``dt_s``.

    Parameters
    ----------
    damper_code : the damper model code (``damper.code``), shared by the batch.
    damper_params : (N, N_DAMPER_PARAMS) packed damper parameters, one row per vehicle.
    vehicle_params : (N, 4) packed ``[m_c, m_b, k_s, k_p]``.
    state : (N, STATE_SIZE) float64 plant state, updated in place.
    current_command_a : (N,) commanded coil current (A), held over the interval and clipped to
        ``[0, i_max]``; the actual current follows it through the coil lag.
    profiles : (K, L) guideway elevation profiles (m) sampled every ``spacing_m``.
    profile_index, start_position_m, speed_mps : (N,) which profile, where on it at t = 0 (m)
        and the vehicle speed (m/s).
    dt_s : control interval (s).
    substeps : RK4 substeps per interval: an int, or a :func:`substep_table` (bins,) shared by
        every vehicle, or :func:`substep_tables` (N, bins), that picks the number from the
        highest coil current in the interval.
    out : (N, N_OUTPUTS) written with :data:`OUTPUT_NAMES` at the end of the interval.
    guideway_gain : (N,) factor on each vehicle's profile (default 1).

    All arrays must be C-contiguous with the dtypes above (float64, int64 for the index).
    """
    if guideway_gain is None:
        guideway_gain = np.ones(state.shape[0])
    table = _as_table(substeps, state.shape[0])
    kernels = step_kernels(block_kernel_mode(damper_code, damper_params), damper_code)
    derived = block_constants(damper_code, damper_params, dt_s, table)
    run_batched(
        *kernels, state.shape[0], damper_params, vehicle_params, state, current_command_a, profiles, profile_index,
        spacing_m, start_position_m, speed_mps, guideway_gain, dt_s, table, derived, out,
    )  # fmt: skip


#: Highest angular frequency of the default guideway input (rad/s): the 2 m shortest
#: wavelength of the random profile at 810 km/h (225 m/s).
DEFAULT_INPUT_RATE = 2.0 * math.pi * 225.0 / 2.0
#: Current bins of a :func:`substep_table`.
SUBSTEP_BINS = 16
#: Largest ``|Re lambda| h`` for the decay rates of the linearised plant (Spencer's pre-yield
#: relaxation, the damper's dashpot on the relative mass). RK4 is stable to 2.785 on the real
#: axis, but the transient that every current change kicks is followed accurately only well
#: inside that: the force is sampled right after it.
MAX_LAMBDA_H = 1.0
#: Largest ``omega h`` for the oscillations of the linearised plant (its modes, the pre-yield
#: springs of Spencer's and Bouc-Wen's models on light vehicles, the branch blend of the
#: sign-of-stroke models).
MAX_OMEGA_H = 0.15
#: Largest ``omega h`` for the guideway input's highest angular frequency (the plant filters it:
#: this bound only keeps the stages sampling the profile).
MAX_INPUT_OMEGA_H = 2.0
#: Most substeps per control interval the automatic rule may choose; a configuration that needs
#: more is refused (``EnvConfig`` says which parameters make it so stiff).
MAX_AUTO_SUBSTEPS = 1024


def _linearised_damper(damper: DamperParams, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """The damper near ``x = v = 0`` in each of its regimes, as ``(c, k, K, C)`` arrays over the
    currents ``i``: ``F = c x' + k x`` for the algebraic models (``C = 0``); for Spencer's
    model ``y' = (K (x - y) + c x') / C`` and ``F = (C - c) y' + k x``. Regimes: pre-yield (the
    hysteretic variable follows the deformation, ``z = A u``: the stiffest) and yielded (``z``
    saturated)."""
    p = damper.as_array()
    zero = 0.0 * i
    code = damper.code
    if code == REFERENCE:
        c0, c1, alpha = p[0] + p[1] * i, p[2] + p[3] * i, p[4] + p[5] * i
        pre_yield = (c0, p[7] + zero, alpha * p[11] + p[6], c0 + c1)
        return [pre_yield, (c0, p[7] + zero, p[6] + zero, c0 + c1)]
    if code == BOUC_WEN:
        c0, alpha = p[0] + p[1] * i, p[2] + p[3] * i
        return [(c0, p[4] + np.abs(alpha) * p[8], zero, zero), (c0, p[4] + zero, zero, zero)]
    if code == TANH:
        alpha = np.abs(p[4] + p[5] * i)
        c = np.abs(p[0] + p[1] * i) + alpha * p[8]
        # the branch blend: d/dx of alpha tanh(beta v + delta sgn_w(x)), sgn_w' <= 1.5 / width
        k = np.abs(p[2] + p[3] * i) + alpha * abs(p[9]) * 1.5 / p[_BLEND]
        return [(c, k, zero, zero)]
    if code == BI_EXPONENTIAL:
        slopes = [
            np.abs(p[o] + p[o + 1] * i) * p[o + 6] + np.abs(p[o + 2] + p[o + 3] * i) for o in (0, 7)
        ]
        # the force step between the branches (at |v| <= 1 m/s) over the blend, whose weight
        # rises with slope at most 0.75 / width
        step = (
            np.abs((p[4] - p[11]) + (p[5] - p[12]) * i)
            + np.abs((p[0] - p[7]) + (p[1] - p[8]) * i)
            + np.abs((p[2] - p[9]) + (p[3] - p[10]) * i)
        )
        return [(np.maximum(*slopes), step * 0.75 / p[_BLEND], zero, zero)]
    return [(p[0] + zero, zero, zero, zero)]  # passive


def stiffness_rates(
    damper: DamperParams, vehicle_params: np.ndarray, current_a: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """``(rate, omega)``: per vehicle (rows of the packed ``vehicle_params``, ``[m_c, m_b, k_s,
    k_p]``) and current (columns), the largest ``|Re lambda|`` (1/s) and ``|Im lambda|``
    (rad/s) over the eigenvalues of the plant with its damper linearised near rest in each of
    its regimes (:func:`_linearised_damper`). A light vehicle turns Spencer's pre-yield
    relaxation into a lightly damped oscillation: hence two numbers and two bounds."""
    vp = np.atleast_2d(np.asarray(vehicle_params, dtype=float))
    mc, mb, ks, kp = (vp[:, j, None] for j in range(4))
    i = np.atleast_1d(np.asarray(current_a, dtype=float))[None, :]
    shape = np.broadcast_shapes(mc.shape, i.shape)
    rate, omega = np.zeros(shape), np.zeros(shape)
    for c, k, big_k, big_c in _linearised_damper(damper, i):
        # states [z_c, z_c', z_b, z_b', y]; the damper force F = fx x + fv x' + fy y
        spencer = big_c > 0.0
        inv_c = np.where(spencer, 1.0 / np.where(spencer, big_c, 1.0), 0.0)
        c1 = big_c - c
        fx = k + c1 * big_k * inv_c
        fv = np.where(spencer, c1 * c * inv_c, c)
        fy = -c1 * big_k * inv_c
        m = np.zeros((*shape, 5, 5))
        m[..., 0, 1] = m[..., 2, 3] = 1.0
        for row, sign, mass in ((1, -1.0, mc), (3, 1.0, mb)):
            m[..., row, 0] = sign * (ks + fx) / mass
            m[..., row, 2] = -sign * (ks + fx) / mass
            m[..., row, 1] = sign * fv / mass
            m[..., row, 3] = -sign * fv / mass
            m[..., row, 4] = sign * fy / mass
        m[..., 3, 2] -= kp / mb
        m[..., 4, 0] = big_k * inv_c
        m[..., 4, 2] = -big_k * inv_c
        m[..., 4, 1] = c * inv_c
        m[..., 4, 3] = -c * inv_c
        m[..., 4, 4] = np.where(spencer, -big_k * inv_c, 0.0)  # y unused: an eigenvalue 0
        lam = np.linalg.eigvals(m)
        rate = np.maximum(rate, np.abs(lam.real).max(axis=-1))
        omega = np.maximum(omega, np.abs(lam.imag).max(axis=-1))
    return rate, omega


def substep_tables(
    damper: DamperParams,
    dt_s: float,
    vehicle_params: np.ndarray,
    input_rate_rad_s: np.ndarray | float = DEFAULT_INPUT_RATE,
    bins: int = SUBSTEP_BINS,
) -> np.ndarray:
    """Substeps per control interval, per vehicle (rows of the packed ``vehicle_params``) and
    coil-current bin (columns), from each vehicle's own parameters: ``rate h <= MAX_LAMBDA_H``
    and ``omega h <= MAX_OMEGA_H`` (:func:`stiffness_rates`) at the highest current of the bin
    and of every lower bin, and ``input_rate h <= MAX_INPUT_OMEGA_H`` for the guideway input
    (``input_rate_rad_s``: 2 pi speed / shortest wavelength, per vehicle or shared).

    ``tests/test_substeps.py`` checks that this keeps the damper force within 0.5 % RMS of a
    run 10 times finer (at least 100 substeps) for every vehicle, for every damper model, both
    settings, control rates 50-1000 Hz and vehicle randomisation up to 0.9. The kernels pick the
    bin from ``max(command, current at the start)`` (with coil lag), not from the highest current
    the lag actually reaches in the interval, which would save substeps at a measured cost in
    accuracy under bang-bang commands. Entries above :data:`MAX_AUTO_SUBSTEPS` are returned as
    they are; ``EnvConfig`` refuses them.
    """
    i_max = float(getattr(damper, "max_current_a", 0.0))
    currents = i_max * np.arange(1, bins + 1) / bins
    rate, omega = stiffness_rates(damper, vehicle_params, currents)
    input_rate = np.asarray(input_rate_rad_s, dtype=float).reshape(-1, 1)
    need = np.maximum.reduce(
        [
            np.ceil(rate * dt_s / MAX_LAMBDA_H),
            np.ceil(omega * dt_s / MAX_OMEGA_H),
            np.ceil(input_rate * dt_s / MAX_INPUT_OMEGA_H) + 0.0 * rate,
            np.ones_like(rate),
        ]
    )
    need = np.maximum.accumulate(need, axis=1)
    return np.ascontiguousarray(np.minimum(need, np.iinfo(np.int32).max).astype(np.int64))


def substep_table(
    damper: DamperParams,
    dt_s: float,
    vehicle: VehicleParams | None = None,
    bins: int = SUBSTEP_BINS,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> np.ndarray:
    """:func:`substep_tables` of one vehicle (default :class:`VehicleParams`): a (bins,) array."""
    vehicle = vehicle or VehicleParams()
    return substep_tables(damper, dt_s, vehicle.as_array(), input_rate_rad_s, bins)[0]


def default_substeps(
    damper: DamperParams,
    dt_s: float,
    vehicle: VehicleParams | None = None,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> int:
    """The largest entry of :func:`substep_table`: substeps at the maximum current."""
    return int(substep_table(damper, dt_s, vehicle, input_rate_rad_s=input_rate_rad_s).max())


def _as_table(substeps: int | np.ndarray, n: int) -> np.ndarray:
    """``substeps`` (an int, a (bins,) table or an (n, bins) table) as an (n, bins) table."""
    if np.ndim(substeps) == 0:
        if int(substeps) != substeps or int(substeps) < 1:
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        return np.full((n, SUBSTEP_BINS), int(substeps), dtype=np.int64)
    table = np.asarray(substeps)
    if table.ndim == 1:
        table = np.broadcast_to(table, (n, table.shape[0]))
    if table.ndim != 2 or table.shape[0] != n or np.any(table < 1):
        raise ValueError(
            f"substeps must be an int >= 1 or a table of them, got shape {table.shape}"
        )
    return np.ascontiguousarray(table, dtype=np.int64)


def initial_state(n: int = 1) -> np.ndarray:
    """Plant at rest on a level guideway: an (n, STATE_SIZE) array of zeros."""
    return np.zeros((n, STATE_SIZE))


def simulate(
    damper: DamperParams,
    profile_m: np.ndarray,
    spacing_m: float,
    speed_mps: float,
    current_command_a: np.ndarray | float,
    duration_s: float,
    dt_s: float = 0.005,
    substeps: int | np.ndarray | None = None,
    vehicle: VehicleParams | None = None,
    state0: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Open-loop run of one vehicle over a guideway profile; returns time series.

    ``substeps``: None (the default :func:`substep_table`, adaptive to the current), a fixed
    number per control interval, or a table.

    ``current_command_a`` is a scalar or one value per control interval. The returned dict has
    ``time_s`` (samples at the end of each interval, plus t = 0 first) and the columns
    ``car_body_displacement_m``, ``car_body_velocity_m_s``, ``bogie_displacement_m``,
    ``bogie_velocity_m_s``, ``stroke_m``, ``stroke_rate_m_s``, ``coil_current_a`` and the
    :data:`OUTPUT_NAMES` (with NaN at t = 0 where not defined).
    """
    vehicle = vehicle or VehicleParams()
    n_steps = int(round(duration_s / dt_s))
    commands = np.broadcast_to(np.asarray(current_command_a, float), (n_steps,))
    table = substep_table(damper, dt_s, vehicle) if substeps is None else substeps
    table = _as_table(table, 1)
    state = initial_state(1) if state0 is None else np.array(state0, float).reshape(1, STATE_SIZE)
    dp = damper.as_array()[None, :]
    vp = vehicle.as_array()[None, :]
    profiles = np.ascontiguousarray(np.asarray(profile_m, float)[None, :])
    zero_i = np.zeros(1, dtype=np.int64)
    x0 = np.zeros(1)
    speed = np.array([float(speed_mps)])
    states = np.empty((n_steps + 1, STATE_SIZE))
    outputs = np.full((n_steps + 1, N_OUTPUTS), np.nan)
    states[0] = state[0]
    out = np.empty((1, N_OUTPUTS))
    cmd = np.empty(1)
    for step in range(n_steps):
        cmd[0] = commands[step]
        step_batch(damper.code, dp, vp, state, cmd, profiles, zero_i, spacing_m, x0, speed,
                   dt_s, table, out)  # fmt: skip
        states[step + 1] = state[0]
        outputs[step + 1] = out[0]
    result = {
        "time_s": states[:, TIME],
        "car_body_displacement_m": states[:, BODY_DISP],
        "car_body_velocity_m_s": states[:, BODY_VEL],
        "bogie_displacement_m": states[:, BOGIE_DISP],
        "bogie_velocity_m_s": states[:, BOGIE_VEL],
        "stroke_m": states[:, BODY_DISP] - states[:, BOGIE_DISP],
        "stroke_rate_m_s": states[:, BODY_VEL] - states[:, BOGIE_VEL],
        "coil_current_a": states[:, COIL_CURRENT],
        "hysteretic_z_m": states[:, HYST_Z],
    }
    for j, name in enumerate(OUTPUT_NAMES):
        result[name] = outputs[:, j]
    return result


@njit(cache=True)
def _damper_response(model, dp, t, x, v, i_cmd, n_sub, force, z_out, y_out, i_out):
    a_coef, gamma, beta = hysteresis_params(model, dp)
    hysteretic = a_coef > 0.0
    tau = dp[_COIL_TAU]
    z = 0.0
    y = 0.0
    ic = i_cmd[0]
    for k in range(t.shape[0]):
        if k > 0:
            dt = t[k] - t[k - 1]
            h = dt / n_sub
            e_half = math.exp(-0.5 * h / tau) if tau > 0.0 else 0.0
            cmd = i_cmd[k - 1]
            for j in range(n_sub):
                f0 = j / n_sub
                fm = (j + 0.5) / n_sub
                f1 = (j + 1.0) / n_sub
                xa = x[k - 1] + f0 * (x[k] - x[k - 1])
                xm = x[k - 1] + fm * (x[k] - x[k - 1])
                xb = x[k - 1] + f1 * (x[k] - x[k - 1])
                va = v[k - 1] + f0 * (v[k] - v[k - 1])
                vm = v[k - 1] + fm * (v[k] - v[k - 1])
                vb = v[k - 1] + f1 * (v[k] - v[k - 1])
                ic_half = cmd + (ic - cmd) * e_half
                ic1 = cmd + (ic_half - cmd) * e_half
                u0 = xa - y
                _, d1, _ = damper_eval(model, dp, xa, va, y, z, ic)
                ys = y + 0.5 * h * d1
                zs = hysteresis_update(z, xm - ys - u0, a_coef, gamma, beta) if hysteretic else z
                _, d2, _ = damper_eval(model, dp, xm, vm, ys, zs, ic_half)
                ys = y + 0.5 * h * d2
                zs = hysteresis_update(z, xm - ys - u0, a_coef, gamma, beta) if hysteretic else z
                _, d3, _ = damper_eval(model, dp, xm, vm, ys, zs, ic_half)
                ys = y + h * d3
                zs = hysteresis_update(z, xb - ys - u0, a_coef, gamma, beta) if hysteretic else z
                _, d4, _ = damper_eval(model, dp, xb, vb, ys, zs, ic1)
                y_new = y + h / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
                if hysteretic:
                    z = hysteresis_update(z, xb - y_new - u0, a_coef, gamma, beta)
                y = y_new
                ic = ic1 if tau > 0.0 else cmd
        force[k], _, _ = damper_eval(model, dp, x[k], v[k], y, z, ic)
        z_out[k] = z
        y_out[k] = y
        i_out[k] = ic


def simulate_damper(
    damper: DamperParams,
    time_s: np.ndarray,
    stroke_m: np.ndarray,
    stroke_rate_m_s: np.ndarray,
    current_a: np.ndarray | float,
    substeps: int = 4,
) -> dict[str, np.ndarray]:
    """Damper alone under a prescribed stroke (the loops of a damper test rig).

    The stroke and its rate are sampled at ``time_s`` and interpolated linearly between
    samples; ``current_a`` (scalar or per sample) is the commanded current, followed through the
    model's coil lag. Internal states start at zero. Returns ``force_n``, ``hysteretic_z_m``,
    ``internal_displacement_m`` and ``coil_current_a`` per sample.
    """
    t = np.ascontiguousarray(time_s, dtype=float)
    x = np.ascontiguousarray(np.broadcast_to(np.asarray(stroke_m, float), t.shape))
    v = np.ascontiguousarray(np.broadcast_to(np.asarray(stroke_rate_m_s, float), t.shape))
    i = np.ascontiguousarray(np.broadcast_to(np.asarray(current_a, float), t.shape))
    i_max = getattr(damper, "max_current_a", np.inf)
    if not np.all(np.isfinite(i)) or i.min() < 0.0 or i.max() > i_max:
        raise ValueError(f"current_a must be finite and in [0, {i_max}] A")
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0.0):
        raise ValueError("time_s must be a 1-D strictly increasing array of at least 2 samples")
    force, z, y, ic = (np.empty_like(t) for _ in range(4))
    _damper_response(damper.code, damper.as_array(), t, x, v, i, int(substeps), force, z, y, ic)
    return {
        "force_n": force,
        "hysteretic_z_m": z,
        "internal_displacement_m": y,
        "coil_current_a": ic,
    }


def sinusoidal_stroke(
    frequency_hz: float, amplitude_m: float, cycles: float, samples_per_cycle: int = 2000
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time_s, stroke_m, stroke_rate_m_s)`` of ``x = amplitude sin(2 pi f t)``."""
    n = int(round(cycles * samples_per_cycle)) + 1
    t = np.linspace(0.0, cycles / frequency_hz, n)
    w = 2.0 * np.pi * frequency_hz
    return t, amplitude_m * np.sin(w * t), amplitude_m * w * np.cos(w * t)
