"""The vectorised (SIMD) block kernel: up to :data:`BLOCK` vehicles advanced side by side.

A core spends most of an RK4 substep waiting on the latency of divisions and exponentials,
because the stages depend on each other. This kernel does the same arithmetic with the vehicles
of a block side by side: their state is copied into a scratch array with one row per quantity
and one column per vehicle, and each RK4 substep is a loop over the columns whose body makes no
calls (:mod:`capsule_env._fastmath`), which LLVM vectorises, two vehicles per iteration (two
dependency chains). Vehicles are sorted by their number of substeps, so substep ``s`` loops only
over those that still need it. Each vehicle's result does not depend on its block mates or its
SIMD lane (the same operations in the same order): a batch of one and a batch of thousands
agree bit for bit.

Models: reference (Spencer), Bi-exponential, tanh, passive. Bouc-Wen (its unloading branch
needs tan/atan) and Spencer parameters with ``gamma > beta`` use the scalar kernel
(:func:`block_kernel_mode`). The damper model and the kernel variant are compile-time constants
(:func:`block_step`, :func:`substep_lanes` and :func:`output_lanes` are specialised on them),
so only the code of the model in use compiles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from capsule_env._fastmath import BORROWED, FAST
from capsule_env._jit import specialised
from capsule_env.dampers.hysteresis import N_RICCATI_CONSTANTS, riccati_constants
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.layout import (
    COIL_CURRENT,
    COIL_TAU,
    DAMP_LEVITATION,
    I_MAX,
    MASS_BODY,
    MASS_BOGIE,
    N_DAMPER_PARAMS,
    OUT_BODY_ACC,
    OUT_BOGIE_ACC,
    OUT_FORCE,
    OUT_GUIDEWAY,
    STATE_SIZE,
    STIFF_LEVITATION,
    STIFF_SECONDARY,
    TIME,
)
from capsule_env.plant.rk4 import (
    HYST_FAST_LINEAR_UNLOAD,
    HYST_FAST_TANH_UNLOAD,
    HYST_NONE,
    LANE_INPUT_NAMES,
    plant_outputs,
    rk4_substep,
)

__all__ = [
    "BLOCK",
    "KERNEL_SCALAR",
    "KERNEL_BLOCK",
    "KERNEL_BLOCK_TANH_UNLOAD",
    "KERNEL_UNIFORM",
    "KERNEL_LEVITATION_DAMPED",
    "KERNEL_FLAGS",
    "kernel_family",
    "levitation_damped",
    "block_constants",
    "block_kernel_mode",
    "guideway_elevation",
]

#: Vehicles per block of the vectorised kernel.
BLOCK = 64
#: :func:`block_kernel_mode` results.
KERNEL_SCALAR, KERNEL_BLOCK, KERNEL_BLOCK_TANH_UNLOAD = 0, 1, 2
#: Flag added to a block mode when every row has the same damper parameters (an env's plant):
#: the kernel then reads them as constants instead of copying them into every vehicle's lane.
KERNEL_UNIFORM = 4
#: Flag added to a kernel mode when the levitation has damping (``c_p``, a vehicle parameter):
#: its term is compiled only into those kernels, so the paper's undamped plant runs the
#: arithmetic it always ran.
KERNEL_LEVITATION_DAMPED = 8
#: The flags of a kernel mode (the rest is its family).
KERNEL_FLAGS = KERNEL_UNIFORM | KERNEL_LEVITATION_DAMPED

# Scratch rows of one half of a block: the state, then the per-vehicle values of the interval,
# the Riccati constants and the damper parameters (each row HALF long).
# The first rows are an RK4 substep's inputs (rk4.LANE_INPUT_NAMES: the plant state in
# STATE_NAMES order, then the interval's values).
_SCRATCH_ROWS = LANE_INPUT_NAMES
(_W_ZC, _W_VC, _W_ZB, _W_VB, _W_Z, _W_Y, _W_I, _W_T, _W_H, _W_ICMD, _W_EHALF, _W_INV_MC,
 _W_INV_MB, _W_KS, _W_KP, _W_CP, _W_ZG0, _W_ZGH, _W_ZG1) = (_SCRATCH_ROWS.index(n)
                                                           for n in _SCRATCH_ROWS)  # fmt: skip
#: After the last substep, the plant's outputs go into rows the substeps no longer read.
_W_OUT_FORCE, _W_OUT_ACC_C, _W_OUT_ACC_B = _W_ZGH, _W_ZG1, _W_H
_W_A = len(_SCRATCH_ROWS)  # N_RICCATI_CONSTANTS rows
_W_P = _W_A + N_RICCATI_CONSTANTS  # N_DAMPER_PARAMS rows
_W_ROWS = _W_P + N_DAMPER_PARAMS
#: The scratch array holds two halves (even and odd sorted ranks), rows HALF apart.
HALF = BLOCK // 2
_W_HALF_SIZE = _W_ROWS * HALF
#: Scratch of :func:`block_step`, given by its caller (one per kernel call, reused block after
#: block): the lanes' working array (two halves of ``_W_ROWS`` rows, plus the padding that
#: masked SIMD lanes read), and ``COUNT_ROWS`` int64 rows of ``BLOCK + 1``.
LANES_SIZE = 2 * _W_HALF_SIZE + 8
COUNT_ROWS = 5
_C_NSUB_OF, _C_BIN_OF, _C_NSUB, _C_ORDER, _C_START = range(COUNT_ROWS)
#: Columns of :func:`block_constants`: the Riccati constants, then the coil-lag factor
#: ``exp(-h / (2 tau))`` of each substep-table bin.
_D_EHALF = N_RICCATI_CONSTANTS


def block_kernel_mode(
    damper_code: int, damper_params: np.ndarray, levitation_damped: bool = False
) -> int:
    """Which kernel steps these damper rows: ``KERNEL_SCALAR`` (Bouc-Wen, or Spencer rows whose
    unloading branch is not of tanh/linear form, or rows that disagree on it),
    ``KERNEL_BLOCK`` or ``KERNEL_BLOCK_TANH_UNLOAD`` (Spencer with beta > gamma), plus
    ``KERNEL_UNIFORM`` when all rows are equal (the same numbers, fewer copies), plus
    ``KERNEL_LEVITATION_DAMPED`` when ``levitation_damped`` (a vehicle's ``c_p`` may be
    non-zero)."""
    mode = _block_kernel_family(damper_code, damper_params)
    p = np.asarray(damper_params).reshape(-1, np.shape(damper_params)[-1])
    if mode != KERNEL_SCALAR and np.all(p == p[:1]):
        mode |= KERNEL_UNIFORM
    if levitation_damped:
        mode |= KERNEL_LEVITATION_DAMPED
    return mode


def levitation_damped(vehicle_params: np.ndarray) -> bool:
    """Whether any of these packed vehicles (rows ``layout.VEHICLE_PARAM_NAMES``) has a
    levitation damping ``c_p`` other than 0 (its kernels then compile the damping term)."""
    return bool(np.any(np.atleast_2d(vehicle_params)[:, DAMP_LEVITATION] != 0.0))


def kernel_family(mode: int) -> int:
    """The family of a kernel mode (``KERNEL_SCALAR``, ``KERNEL_BLOCK`` or
    ``KERNEL_BLOCK_TANH_UNLOAD``), without its flags."""
    return mode & ~KERNEL_FLAGS


def _block_kernel_family(damper_code: int, damper_params: np.ndarray) -> int:
    hyst = model_of_code(damper_code).hysteresis
    if hyst is None:
        return KERNEL_BLOCK
    if not hyst.fast:
        return KERNEL_SCALAR
    p = np.asarray(damper_params).reshape(-1, damper_params.shape[-1])
    a_coef, gamma, beta = p[:, hyst.a_coef], p[:, hyst.gamma], p[:, hyst.beta]
    if np.any(a_coef <= 0.0) or np.any(gamma < 0.0) or np.any(gamma + beta <= 0.0):
        return KERNEL_SCALAR
    unload = beta - gamma
    if np.all(unload == 0.0):
        return KERNEL_BLOCK
    if np.all(unload > 0.0):
        return KERNEL_BLOCK_TANH_UNLOAD
    return KERNEL_SCALAR


def block_constants(
    damper_code: int, damper_params: np.ndarray, dt_s: float, table: np.ndarray
) -> np.ndarray:
    """Per-vehicle constants of the block kernel, computed once rather than every step: the
    Riccati constants of the Spencer hysteresis (1 where unused; ``hysteresis.riccati_constants``)
    and the coil-lag factor ``exp(-h / (2 tau))`` at each table bin's substep ``h = dt / n``
    (0 without coil lag). ``table``: one (bins,) table for every row, or (N, bins)."""
    p = np.atleast_2d(np.asarray(damper_params, dtype=float))
    out = np.ones((p.shape[0], _D_EHALF + np.shape(table)[-1]))
    hyst = model_of_code(damper_code).hysteresis
    if hyst is not None and hyst.fast:
        out[:, :_D_EHALF] = riccati_constants(p[:, hyst.a_coef], p[:, hyst.gamma], p[:, hyst.beta])
    tau = p[:, COIL_TAU][:, None]
    h = dt_s / np.broadcast_to(np.asarray(table, dtype=float), (p.shape[0], np.shape(table)[-1]))
    lag = tau > 0.0
    out[:, _D_EHALF:] = np.where(lag, np.exp(-0.5 * h / np.where(lag, tau, 1.0)), 0.0)
    return np.ascontiguousarray(out)


# The elevation lookups are inlined by LLVM (forceinline), not by numba: numba's inlining
# copies their IR into every call site (route_elevation's two lookups at each of its own)
# before typing and lowering each copy.
@njit(**FAST, **BORROWED, forceinline=True)
def guideway_elevation(profiles, k, spacing, last, position):
    """Profile ``k`` at ``position`` (m), linear between samples, held beyond both ends
    (``last = profiles.shape[1] - 1.0``); clamps instead of branches."""
    s = min(max(position / spacing, 0.0), last)
    j = min(int(s), int(last) - 1)
    f = s - j
    return profiles[k, j] * (1.0 - f) + profiles[k, j + 1] * f


@njit(**FAST, **BORROWED, forceinline=True)
def route_elevation(profiles, offsets, k, gain, spacing, last, position):
    """The guideway under a vehicle: ``gain`` times profile ``k`` at ``position`` (m), plus the
    offsets' row ``k`` there when the plant has offsets (the tube's spans)."""
    z = gain * guideway_elevation(profiles, k, spacing, last, position)
    if offsets.shape[0] > 0:
        z += guideway_elevation(offsets, k, spacing, last, position)
    return z


@njit(**FAST, inline="always")
def _slot(rank):
    """Flat offset of the sorted vehicle ``rank`` in the scratch array: even ranks in the first
    half, odd ranks in the second, ``rank // 2`` within it (rows ``HALF`` apart)."""
    return (rank & 1) * _W_HALF_SIZE + (rank >> 1)


# The lane accessors are inlined by LLVM (forceinline), not by numba: numba's inlining copies
# their IR into the loop at every call site (two vehicles per iteration: twice) before typing
# and lowering it, which made the loop the costliest function of a first step to compile.
@njit(**FAST, **BORROWED, forceinline=True)
def _lane_values(wv, j):
    """The scratch values of one vehicle (rows z_c .. zg_end) as a tuple (offset ``j``)."""
    return (
        wv[j], wv[j + HALF], wv[j + 2 * HALF], wv[j + 3 * HALF], wv[j + 4 * HALF],
        wv[j + 5 * HALF], wv[j + 6 * HALF], wv[j + 7 * HALF], wv[j + 8 * HALF],
        wv[j + 9 * HALF], wv[j + 10 * HALF], wv[j + 11 * HALF], wv[j + 12 * HALF],
        wv[j + 13 * HALF], wv[j + 14 * HALF], wv[j + 15 * HALF], wv[j + 16 * HALF],
        wv[j + 17 * HALF], wv[j + 18 * HALF],
    )  # fmt: skip


@njit(**FAST, **BORROWED, forceinline=True)
def _lane_constants(wv, j):
    """The Riccati constants of one vehicle from the scratch view."""
    b = j + _W_A * HALF
    return (
        wv[b], wv[b + HALF], wv[b + 2 * HALF], wv[b + 3 * HALF], wv[b + 4 * HALF],
        wv[b + 5 * HALF], wv[b + 6 * HALF], wv[b + 7 * HALF], wv[b + 8 * HALF],
    )  # fmt: skip


@njit(**FAST, **BORROWED, forceinline=True)
def _lane_params(wv, j):
    """The packed damper parameters of one vehicle from the scratch view."""
    b = j + _W_P * HALF
    return (
        wv[b], wv[b + HALF], wv[b + 2 * HALF], wv[b + 3 * HALF], wv[b + 4 * HALF],
        wv[b + 5 * HALF], wv[b + 6 * HALF], wv[b + 7 * HALF], wv[b + 8 * HALF],
        wv[b + 9 * HALF], wv[b + 10 * HALF], wv[b + 11 * HALF], wv[b + 12 * HALF],
        wv[b + 13 * HALF], wv[b + 14 * HALF], wv[b + 15 * HALF], wv[b + 16 * HALF],
    )  # fmt: skip


@njit(**FAST, inline="always")
def row_params(dp, n):
    """Row ``n`` of the packed damper parameters as a tuple (a value: no array view, whose
    reference counting costs in a per-vehicle loop; and loop constants of a uniform batch)."""
    return (
        dp[n, 0], dp[n, 1], dp[n, 2], dp[n, 3], dp[n, 4], dp[n, 5], dp[n, 6], dp[n, 7],
        dp[n, 8], dp[n, 9], dp[n, 10], dp[n, 11], dp[n, 12], dp[n, 13], dp[n, 14], dp[n, 15],
        dp[n, 16],
    )  # fmt: skip


@njit(**FAST, inline="always")
def _row_constants(derived, n):
    """The Riccati constants of :func:`block_constants` row ``n`` as a tuple."""
    return (
        derived[n, 0], derived[n, 1], derived[n, 2], derived[n, 3], derived[n, 4],
        derived[n, 5], derived[n, 6], derived[n, 7], derived[n, 8],
    )  # fmt: skip


@njit(**FAST, **BORROWED, forceinline=True)
def _store_lane(wv, j, new, active):
    """Write a vehicle's new state (rows z_c .. t and zg_start) if ``active`` (a select)."""
    wv[j + 0 * HALF] = new[0] if active else wv[j + 0 * HALF]
    wv[j + 1 * HALF] = new[1] if active else wv[j + 1 * HALF]
    wv[j + 2 * HALF] = new[2] if active else wv[j + 2 * HALF]
    wv[j + 3 * HALF] = new[3] if active else wv[j + 3 * HALF]
    wv[j + 4 * HALF] = new[4] if active else wv[j + 4 * HALF]
    wv[j + 5 * HALF] = new[5] if active else wv[j + 5 * HALF]
    wv[j + 6 * HALF] = new[6] if active else wv[j + 6 * HALF]
    wv[j + 7 * HALF] = new[7] if active else wv[j + 7 * HALF]
    wv[j + _W_ZG0 * HALF] = new[8] if active else wv[j + _W_ZG0 * HALF]


@njit(**FAST, **BORROWED)
def _guideway_lanes(w, first, nb, order, profiles, offsets, spacing, route):
    """Guideway elevation at the middle and end of the substep of the sorted vehicles
    ``first .. nb-1`` (a gather from the profile bank, kept out of the SIMD loop)."""
    last = profiles.shape[1] - 1.0
    for rank in range(first, nb):
        n = order[rank]
        o = _slot(rank)
        t, h = w[o + _W_T * HALF], w[o + _W_H * HALF]
        k, g, p0, sp = route.profile[n], route.gain[n], route.start_m[n], route.speed_mps[n]
        w[o + _W_ZGH * HALF] = route_elevation(
            profiles, offsets, k, g, spacing, last, p0 + sp * (t + 0.5 * h)
        )
        w[o + _W_ZG1 * HALF] = route_elevation(
            profiles, offsets, k, g, spacing, last, p0 + sp * (t + h)
        )


@specialised("model", "hysteresis", "uniform", "damped", plain=("first",))
def substep_lanes(model, hysteresis, uniform, damped, w, first, nb, p_uniform, hc_uniform):
    """One RK4 substep of the sorted vehicles ``first .. nb-1``: the SIMD loop.

    Each iteration advances two vehicles, one from each half of the scratch array (even and odd
    ranks): two independent dependency chains, so the core overlaps their latencies. A vehicle
    outside ``first .. nb-1`` that shares an iteration is computed and not stored (a select).
    The view starts at the first column and every access is a constant offset from it, so LLVM
    sees no negative indices and no overlap and vectorises the loop. With ``uniform`` the damper
    parameters and Riccati constants are ``p_uniform``/``hc_uniform`` (loop constants) instead of
    scratch rows. ``damped``: the levitation has damping. Compiled once per (model,
    hysteresis, uniform, damped)."""
    m, hyst, uni, dmp = model, hysteresis, uniform, damped

    def impl(model, hysteresis, uniform, damped, w, first, nb, p_uniform, hc_uniform):
        col0 = first >> 1
        first_a = (first + 1) >> 1  # first active column of the even half
        end = (nb + 1) >> 1
        end_b = nb >> 1  # odd half: columns < end_b are vehicles
        wv = w[col0:]  # one view: the odd half sits at the constant offset _W_HALF_SIZE
        # A multiple of 4 iterations: a partial SIMD group runs as masked lanes rather than as
        # the loop's scalar remainder (4x slower per vehicle). Lanes past the end only read.
        for j in range((end - col0 + 3) & -4):
            col = col0 + j
            jb = j + _W_HALF_SIZE
            if uni:
                p_a, p_b, hc_a, hc_b = p_uniform, p_uniform, hc_uniform, hc_uniform
            else:
                p_a, p_b = _lane_params(wv, j), _lane_params(wv, jb)
                hc_a, hc_b = _lane_constants(wv, j), _lane_constants(wv, jb)
            new_a = rk4_substep(m, hyst, dmp, _lane_values(wv, j), p_a, hc_a)
            new_b = rk4_substep(m, hyst, dmp, _lane_values(wv, jb), p_b, hc_b)
            _store_lane(wv, j, new_a, col >= first_a and col < end)
            _store_lane(wv, jb, new_b, col < end_b)

    return impl


@specialised("model", "uniform", "damped")
def output_lanes(model, uniform, damped, wv, count, p_uniform):
    """Force and accelerations at the end of the interval (into the output rows) of the first
    ``count`` columns of one half; with ``damped``, the guideway's rate is its mean over the
    last half substep. Compiled once per (model, uniform, damped)."""
    m, uni, dmp = model, uniform, damped

    def impl(model, uniform, damped, wv, count, p_uniform):
        for j in range(count):
            v = _lane_values(wv, j)
            p = p_uniform if uni else _lane_params(wv, j)
            vehicle = (v[_W_INV_MC], v[_W_INV_MB], v[_W_KS], v[_W_KP], v[_W_CP])
            zg_rate = (v[_W_ZG1] - v[_W_ZGH]) * 2.0 / v[_W_H] if dmp else 0.0
            force, acc_c, acc_b = plant_outputs(m, dmp, p, v[0:7], v[_W_ZG0], zg_rate, vehicle)
            wv[j + _W_OUT_FORCE * HALF] = force
            wv[j + _W_OUT_ACC_C * HALF] = acc_c
            wv[j + _W_OUT_ACC_B * HALF] = acc_b

    return impl


@njit(inline="always")
def block_scratch():
    """``(lanes, counts)``: the scratch :func:`block_step` takes, for its caller to make once
    per kernel call (inlined: no function of its own)."""
    return np.empty(LANES_SIZE), np.empty((COUNT_ROWS, BLOCK + 1), np.int64)


@njit(**FAST, **BORROWED)
def _sort_by_substeps(nsub_of, nb, lo, order, start):
    """Stable sort of the block's vehicles by their substep count: ``order[rank]`` = vehicle
    index (``start``: ``BLOCK + 1`` int64 of scratch). A counting sort (the counts span a few
    values): linear in the block size whatever the order. (An insertion sort, used for a
    while, moves O(nb^2) entries when the currents, and so the counts, are random from vehicle
    to vehicle: 10 % of a ``hils`` step.) Counts spread over ``BLOCK`` or more values (a
    hand-made table) take a stable insertion sort: the same order, rare, and no allocation."""
    lo_sub, hi_sub = nsub_of[0], nsub_of[0]
    for m in range(1, nb):
        lo_sub, hi_sub = min(lo_sub, nsub_of[m]), max(hi_sub, nsub_of[m])
    if hi_sub - lo_sub < BLOCK:
        start[:] = 0  # start[c]: first rank of count lo_sub + c
        for m in range(nb):
            start[nsub_of[m] - lo_sub + 1] += 1
        for c in range(1, BLOCK + 1):
            start[c] += start[c - 1]
        for m in range(nb):
            c = nsub_of[m] - lo_sub
            order[start[c]] = lo + m
            start[c] += 1
    else:  # a hand-made table with widely spread entries
        for m in range(nb):
            r = m
            while r > 0 and nsub_of[order[r - 1] - lo] > nsub_of[m]:
                order[r] = order[r - 1]
                r -= 1
            order[r] = lo + m


@specialised("model", "mode")
def block_step(model, mode, lo, hi, plant, x, i_cmd, route, dt, out, lanes, counts):
    """Advance vehicles ``lo .. hi-1`` (at most BLOCK) by ``dt`` with the vectorised kernel
    (``mode`` a block mode of :func:`block_kernel_mode`). ``lanes`` (``LANES_SIZE``,) float64
    and ``counts`` (``COUNT_ROWS``, ``BLOCK + 1``) int64 are scratch from the caller: this
    function allocates nothing. Compiled once per (model, mode)."""
    m, md = model, mode
    damper = model_of_code(m)
    uses_current = damper.uses_current
    uni = (md & KERNEL_UNIFORM) != 0
    damped = (md & KERNEL_LEVITATION_DAMPED) != 0
    family = md & ~KERNEL_FLAGS
    if damper.hysteresis is None:
        hyst = HYST_NONE
    elif family == KERNEL_BLOCK_TANH_UNLOAD:
        hyst = HYST_FAST_TANH_UNLOAD
    else:
        hyst = HYST_FAST_LINEAR_UNLOAD

    def impl(model, mode, lo, hi, plant, x, i_cmd, route, dt, out, lanes, counts):
        nb = hi - lo
        w, order, nsub = lanes, counts[_C_ORDER], counts[_C_NSUB]
        _clear_padding(w, nb)
        _count_substeps(lo, nb, plant, x, i_cmd, uses_current, counts)
        _sort_by_substeps(counts[_C_NSUB_OF], nb, lo, order, counts[_C_START])
        _load_lanes(w, lo, nb, plant, x, i_cmd, route, dt, uses_current, uni, counts)
        p_uniform = row_params(plant.damper, lo)
        hc_uniform = _row_constants(plant.constants, lo)
        # substep s advances the tail of the vehicles that need more than s substeps
        # an int64 from the start: a literal 0 would first type the calls below with
        # Literal[int](0) and compile _guideway_lanes a second time for it
        first = np.int64(0)
        s = 0
        while first < nb:
            _guideway_lanes(
                w, first, nb, order, plant.profiles, plant.offsets, plant.spacing_m, route
            )
            substep_lanes(m, hyst, uni, damped, w, first, nb, p_uniform, hc_uniform)
            s += 1
            while first < nb and nsub[first] <= s:
                first += 1
        half_a, half_b = w[:_W_HALF_SIZE], w[_W_HALF_SIZE:]
        output_lanes(m, uni, damped, half_a, min(HALF, (((nb + 1) >> 1) + 3) & -4), p_uniform)
        output_lanes(m, uni, damped, half_b, min(HALF, ((nb >> 1) + 3) & -4), p_uniform)
        _store_results(w, nb, order, x, out)

    return impl


@njit(**FAST, **BORROWED)
def _clear_padding(w, nb):
    """Zero the scratch columns that only masked SIMD lanes read, so that no lane computes on
    denormal garbage (slow on x86); the rest is written by :func:`_load_lanes`."""
    w[2 * _W_HALF_SIZE :] = 0.0
    end = (nb + 1) >> 1
    for col in range(end, min(end + 3, HALF)):
        for r in range(_W_ROWS):
            w[r * HALF + col] = 0.0
            w[_W_HALF_SIZE + r * HALF + col] = 0.0


@njit(**FAST, **BORROWED, forceinline=True)
def _applied_command(dp, i_cmd, n, uses_current):
    """The current command vehicle ``n``'s damper follows, clipped to its range (0 for a
    damper the current does not change)."""
    return min(max(i_cmd[n], 0.0), dp[n, I_MAX]) if uses_current else 0.0


@njit(**FAST, **BORROWED)
def _count_substeps(lo, nb, plant, x, i_cmd, uses_current, counts):
    """Substeps and table bin of vehicles ``lo .. lo+nb-1`` (rows ``_C_NSUB_OF``,
    ``_C_BIN_OF``), from the highest current of the interval."""
    dp, table = plant.damper, plant.substeps
    nsub_of, bin_of = counts[_C_NSUB_OF], counts[_C_BIN_OF]
    n_bins = table.shape[1]
    for j in range(nb):
        n = lo + j
        i_max, tau = dp[n, I_MAX], dp[n, COIL_TAU]
        cmd = _applied_command(dp, i_cmd, n, uses_current)
        i_high = max(cmd, x[n, COIL_CURRENT]) if tau > 0.0 else cmd
        b = int(i_high / i_max * n_bins) if i_max > 0.0 else 0
        b = min(max(b, 0), n_bins - 1)
        nsub_of[j] = table[n, b]
        bin_of[j] = b


@njit(**FAST, **BORROWED)
def _load_lanes(w, lo, nb, plant, x, i_cmd, route, dt, uses_current, uniform, counts):
    """Copy the sorted vehicles into their scratch columns: the state, the interval's values
    (:data:`LANE_INPUT_NAMES`), and unless ``uniform`` the Riccati constants and damper
    parameters; the odd half's last column, which has no vehicle, gets real numbers too."""
    dp, vp, derived = plant.damper, plant.vehicle, plant.constants
    profiles, spacing = plant.profiles, plant.spacing_m
    order, nsub_of, bin_of, nsub = (
        counts[_C_ORDER],
        counts[_C_NSUB_OF],
        counts[_C_BIN_OF],
        counts[_C_NSUB],
    )
    last = profiles.shape[1] - 1.0
    for rank in range(nb):
        n = order[rank]
        o = _slot(rank)
        ns = nsub_of[n - lo]
        nsub[rank] = ns
        cmd = _applied_command(dp, i_cmd, n, uses_current)
        for j in range(STATE_SIZE):
            w[o + j * HALF] = x[n, j]
        if dp[n, COIL_TAU] <= 0.0:
            w[o + COIL_CURRENT * HALF] = cmd
        w[o + _W_H * HALF] = dt / ns
        w[o + _W_ICMD * HALF] = cmd
        w[o + _W_EHALF * HALF] = derived[n, _D_EHALF + bin_of[n - lo]]
        w[o + _W_INV_MC * HALF] = 1.0 / vp[n, MASS_BODY]
        w[o + _W_INV_MB * HALF] = 1.0 / vp[n, MASS_BOGIE]
        w[o + _W_KS * HALF] = vp[n, STIFF_SECONDARY]
        w[o + _W_KP * HALF] = vp[n, STIFF_LEVITATION]
        w[o + _W_CP * HALF] = vp[n, DAMP_LEVITATION]
        position = route.start_m[n] + route.speed_mps[n] * w[o + TIME * HALF]
        w[o + _W_ZG0 * HALF] = route_elevation(
            profiles, plant.offsets, route.profile[n], route.gain[n], spacing, last, position
        )
        if not uniform:  # else read as loop constants
            for j in range(N_DAMPER_PARAMS):
                w[o + (_W_P + j) * HALF] = dp[n, j]
            for j in range(_D_EHALF):
                w[o + (_W_A + j) * HALF] = derived[n, j]
    if nb & 1:
        src, dst = _slot(nb - 1), _slot(nb)
        for j in range(_W_ROWS):
            w[dst + j * HALF] = w[src + j * HALF]


@njit(**FAST, **BORROWED)
def _store_results(w, nb, order, x, out):
    """Copy the sorted vehicles' new state and the plant's outputs back from the scratch."""
    for rank in range(nb):
        n = order[rank]
        o = _slot(rank)
        for j in range(STATE_SIZE):
            x[n, j] = w[o + j * HALF]
        out[n, OUT_FORCE] = w[o + _W_OUT_FORCE * HALF]
        out[n, OUT_BODY_ACC] = w[o + _W_OUT_ACC_C * HALF]
        out[n, OUT_BOGIE_ACC] = w[o + _W_OUT_ACC_B * HALF]
        out[n, OUT_GUIDEWAY] = w[o + _W_ZG0 * HALF]
