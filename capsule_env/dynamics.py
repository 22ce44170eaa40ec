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
control interval, in parallel threads for large batches. Pure numba/numpy, no Gym import.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from capsule_env.dampers import (
    BI_EXPONENTIAL,
    BOUC_WEN,
    PASSIVE,
    REFERENCE,
    TANH,
    DamperParams,
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
    "stiffness_bound",
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
_I_MAX, _COIL_TAU = 14, 15


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
    """Row ``n`` of a (N, 16) array as a tuple: a value, so no array view is created (views in
    the per-vehicle loop cost reference-count updates)."""
    return (
        a[n, 0], a[n, 1], a[n, 2], a[n, 3], a[n, 4], a[n, 5], a[n, 6], a[n, 7], a[n, 8], a[n, 9],
        a[n, 10], a[n, 11], a[n, 12], a[n, 13], a[n, 14], a[n, 15],
    )  # fmt: skip


@njit(cache=True, inline="always")
def _advance(model, dp, mc, mb, ks, kp, s, i_cmd, profiles, k, spacing, x_start, speed, gain, dt,
             sub_table):  # fmt: skip
    """Advance one vehicle by ``dt`` with RK4 substeps; pure function of values.

    ``dp``: the packed damper parameters as a tuple; ``s``: the 8-tuple state row. Returns
    ``(new_state, (force, body_acc, bogie_acc, guideway))``. The guideway elevation is
    ``gain * profiles[k](x_start + speed * t)``. The number of substeps is ``sub_table[bin]``
    for the bin of the highest current in the interval (the damper's stiffness grows with
    current; see :func:`substep_table`). Values in and out, no array rows: handing arrays to an
    inlined function costs numba reference-count updates per vehicle.
    """
    a_coef, gamma, beta = hysteresis_params(model, dp)
    hysteretic = a_coef > 0.0
    i_max = dp[_I_MAX]
    i_cmd = min(max(i_cmd, 0.0), i_max) if model != PASSIVE else 0.0
    tau = dp[_COIL_TAU]
    n_bins = sub_table.shape[0]
    i_high = max(i_cmd, s[6]) if tau > 0.0 else i_cmd
    b = int(i_high / i_max * n_bins) if i_max > 0.0 else 0
    n_sub = sub_table[min(max(b, 0), n_bins - 1)]
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
            i_cmd[n], profiles, idx[n], spacing, x0[n], speed[n], gain[n], dt, table,
        )  # fmt: skip
        for j in range(8):
            state[n, j] = new[j]
        for j in range(4):
            out[n, j] = outputs[j]


@njit(cache=True)
def _step_serial(model, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed, gain, dt, table,
                 out):  # fmt: skip
    _step_range(0, state.shape[0], model, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed,
                gain, dt, table, out)  # fmt: skip


_CHUNK = 32


@njit(cache=True, parallel=True)
def _step_parallel(model, dp, vp, state, i_cmd, profiles, idx, spacing, x0, speed, gain, dt,
                   table, out):  # fmt: skip
    n = state.shape[0]
    for c in prange((n + _CHUNK - 1) // _CHUNK):
        _step_range(c * _CHUNK, min(n, (c + 1) * _CHUNK), model, dp, vp, state, i_cmd, profiles,
                    idx, spacing, x0, speed, gain, dt, table, out)  # fmt: skip


#: Batches at least this large are stepped by the multi-threaded kernel.
PARALLEL_THRESHOLD = 64


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
    substeps : RK4 substeps per interval: an int, or a :func:`substep_table` (int64 array) that
        picks the number from the highest coil current in the interval.
    out : (N, N_OUTPUTS) written with :data:`OUTPUT_NAMES` at the end of the interval.
    guideway_gain : (N,) factor on each vehicle's profile (default 1).

    All arrays must be C-contiguous with the dtypes above (float64, int64 for the index).
    """
    if guideway_gain is None:
        guideway_gain = np.ones(state.shape[0])
    table = _as_table(substeps)
    kernel = _step_parallel if state.shape[0] >= PARALLEL_THRESHOLD else _step_serial
    kernel(
        damper_code, damper_params, vehicle_params, state, current_command_a, profiles,
        profile_index, spacing_m, start_position_m, speed_mps, guideway_gain, dt_s, table, out,
    )  # fmt: skip


#: Highest angular frequency of the default guideway input (rad/s): the 2 m shortest
#: wavelength of the random profile at 810 km/h (225 m/s).
DEFAULT_INPUT_RATE = 2.0 * math.pi * 225.0 / 2.0


def stiffness_bound(
    damper: DamperParams,
    vehicle: VehicleParams | None = None,
    current_a: float | None = None,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> float:
    """Upper bound (1/s) on the rates the RK4 stages must resolve.

    The plant's fastest mode, the damper's pre-yield rate ``(alpha A + k0)/(c0 + c1)`` (Spencer)
    or its pre-yield stiffness ``alpha A`` acting on the relative mass (Bouc-Wen), and the
    slope ``dF/dv`` at ``v = 0`` on the relative mass (algebraic models), at ``current_a``
    (default: the maximum current); and the highest frequency of the guideway input
    ``input_rate_rad_s`` (2 pi speed / shortest wavelength).
    """
    vehicle = vehicle or VehicleParams()
    mc, mb = vehicle.car_body_mass_kg, vehicle.bogie_mass_kg
    ks, kp = vehicle.secondary_stiffness_n_per_m, vehicle.levitation_stiffness_n_per_m
    relative_mass = mc * mb / (mc + mb)
    rates = [math.sqrt((ks + kp) / mb), math.sqrt(ks / relative_mass), input_rate_rad_s]
    p = damper.as_array()
    i = p[_I_MAX] if current_a is None else float(current_a)
    code = damper.code
    if code == REFERENCE:
        c0, c1, alpha = p[0] + p[1] * i, p[2] + p[3] * i, p[4] + p[5] * i
        rates.append((alpha * p[11] + p[6]) / (c0 + c1))
        rates.append(c0 * c1 / (c0 + c1) / relative_mass)
    elif code == BOUC_WEN:
        alpha, c0 = p[2] + p[3] * i, p[0] + p[1] * i
        rates.append(math.sqrt(abs(alpha) * p[8] / relative_mass) + abs(c0) / relative_mass)
    elif code == TANH:
        slope = abs(p[0] + p[1] * i) + abs(p[4] + p[5] * i) * p[8]
        rates.append(slope / relative_mass)
    elif code == BI_EXPONENTIAL:
        for o in (0, 7):
            slope = abs(p[o] + p[o + 1] * i) * p[o + 6] + abs(p[o + 2] + p[o + 3] * i)
            rates.append(slope / relative_mass)
    elif code == PASSIVE:
        rates.append(p[0] / relative_mass)
    return max(rates)


#: Current bins of a :func:`substep_table`.
SUBSTEP_BINS = 16


def substep_table(
    damper: DamperParams,
    dt_s: float,
    vehicle: VehicleParams | None = None,
    max_lambda_h: float = 2.0,
    bins: int = SUBSTEP_BINS,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> np.ndarray:
    """Substeps per control interval for each current bin, so that ``stiffness_bound * h <=
    max_lambda_h`` at the highest current of the bin (and of every lower bin).

    The default 2.0 stays inside RK4's real-axis stability interval (2.785); on the reference
    damper it keeps the force within 0.5 % RMS of a 10x finer step (``tests/test_dynamics.py``;
    measured 0.03-0.4 % over 10 s of random guideway at constant and random currents).
    A vehicle whose coil current stays low is integrated with fewer, longer substeps.
    """
    i_max = float(getattr(damper, "max_current_a", 0.0))
    table = np.empty(bins, dtype=np.int64)
    worst = 0
    for b in range(bins):
        bound = stiffness_bound(damper, vehicle, i_max * (b + 1) / bins, input_rate_rad_s)
        worst = max(worst, math.ceil(bound * dt_s / max_lambda_h))
        table[b] = max(1, worst)
    return table


def default_substeps(
    damper: DamperParams,
    dt_s: float,
    vehicle: VehicleParams | None = None,
    max_lambda_h: float = 2.0,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> int:
    """The largest entry of :func:`substep_table`: substeps at the maximum current."""
    return int(
        substep_table(damper, dt_s, vehicle, max_lambda_h, input_rate_rad_s=input_rate_rad_s).max()
    )


def _as_table(substeps: int | np.ndarray) -> np.ndarray:
    if np.ndim(substeps) == 0:
        if int(substeps) < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps!r}")
        return np.full(SUBSTEP_BINS, int(substeps), dtype=np.int64)
    return np.ascontiguousarray(substeps, dtype=np.int64)


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
    table = substep_table(damper, dt_s, vehicle) if substeps is None else _as_table(substeps)
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
