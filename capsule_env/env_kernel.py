"""The env's per-step work around the plant: commands in, sensors, reward and observation out.

For a block of vehicles, :func:`env_commands` turns actions into coil-current commands (through
the inverse model in force mode) and applies the control delay; the plant kernel advances the
vehicles (:mod:`capsule_env.plant`); :func:`env_sense` draws the sensor noise, measures, and
writes the reward, the signals (``info``) and the observations; :func:`env_preview` adds the
guideway preview columns where the configuration has them. The arguments are named
structures (:class:`EnvParams`, :class:`EnvState`, :class:`EnvOutputs`) whose arrays have the
layouts of :mod:`capsule_env.layout`. Pure numba/numpy, no Gym import.

Sensor noise is a counter-based hash of ``(vehicle key, step, channel)`` turned into normals by
Box-Muller pairs: it depends on nothing else, so a vehicle's trajectory is the same whatever
its batch, its position in it or the threads.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.extending import overload

from capsule_env._fastmath import BORROWED, FAST, fast_cos_2pi, fast_log
from capsule_env.dampers import BOUC_WEN
from capsule_env.inverse import affine_in_current, csdc_z_update, invert_affine
from capsule_env.layout import (
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    MEAS_BODY_ACC,
    MEAS_BOGIE_ACC,
    MEAS_COMMAND,
    MEAS_STROKE,
    MEAS_STROKE_RATE,
    N_NOISE_CHANNELS,
    NOISE_BODY_ACC,
    NOISE_BODY_DISP,
    NOISE_BODY_VEL,
    NOISE_BOGIE_ACC,
    NOISE_BOGIE_DISP,
    NOISE_BOGIE_VEL,
    NOISE_CURRENT,
    NOISE_GAP,
    NOISE_GUIDEWAY,
    NOISE_STROKE,
    NOISE_STROKE_RATE,
    OUT_BODY_ACC,
    OUT_BOGIE_ACC,
    OUT_FORCE,
    OUT_GUIDEWAY,
    SIG_BODY_ACC,
    SIG_BODY_DISP,
    SIG_BODY_VEL,
    SIG_BODY_VEL_EST,
    SIG_BOGIE_ACC,
    SIG_BOGIE_DISP,
    SIG_BOGIE_VEL,
    SIG_BOGIE_VEL_EST,
    SIG_COIL_CURRENT,
    SIG_COST_ACC,
    SIG_COST_ENERGY,
    SIG_COST_STROKE,
    SIG_COST_VEL,
    SIG_CURRENT_COMMAND,
    SIG_DESIRED_FORCE,
    SIG_FORCE,
    SIG_GUIDEWAY,
    SIG_REWARD_ACC,
    SIG_STROKE,
    SIG_STROKE_RATE,
    TIME,
    VF_APPLIED,
    VF_CSDC_STROKE,
    VF_CSDC_Z,
    VF_EST_BODY_1,
    VF_EST_BODY_2,
    VF_EST_BOGIE_1,
    VF_EST_BOGIE_2,
    VF_POSITION_ERROR,
    VF_REWARD_FILTER,
)
from capsule_env.plant.block import BLOCK, guideway_elevation, row_params
from capsule_env.plant.params import Route

__all__ = [
    "EnvParams",
    "EnvState",
    "EnvOutputs",
    "OBS_SENSORS",
    "OBS_FULL_STATE",
    "OBS_MEASURED",
    "OBSERVATION_CODES",
    "noise_pairs",
    "NOISE_SCRATCH_SHAPE",
    "COMMAND_CURRENT",
    "command_path",
]

#: Observation sets (``EnvParams.observation``), by the names of ``EnvConfig.observation``.
OBS_SENSORS, OBS_FULL_STATE, OBS_MEASURED = 0, 1, 2
OBSERVATION_CODES = {"sensors": OBS_SENSORS, "full_state": OBS_FULL_STATE, "measured": OBS_MEASURED}
#: Noise channels each observation set reads (the rest are not drawn).
_CHANNELS_READ = {
    OBS_SENSORS: (NOISE_BODY_ACC, NOISE_BOGIE_ACC, NOISE_STROKE, NOISE_STROKE_RATE),
    OBS_FULL_STATE: tuple(range(NOISE_GAP)),
    OBS_MEASURED: (
        NOISE_BODY_ACC,
        NOISE_BOGIE_ACC,
        NOISE_STROKE,
        NOISE_STROKE_RATE,
        NOISE_GAP,
        NOISE_CURRENT,
    ),  # fmt: skip
}
#: Shape of :func:`env_sense`'s scratch: a row per noise channel, a column per vehicle of a block.
NOISE_SCRATCH_SHAPE = (N_NOISE_CHANNELS + 1, BLOCK)
#: Coefficients of ``EnvParams.estimator``: ``(b0, b1, b2, a1, a2)`` of a biquad.
EST_B0, EST_B1, EST_B2, EST_A1, EST_A2 = range(5)


#: :func:`command_path` of current mode (force mode's is the inverted model's damper code).
COMMAND_CURRENT = -1


def command_path(current_mode: bool, inverse_code: int) -> int:
    """How the env turns actions into current commands, a compile-time constant of its kernel:
    :data:`COMMAND_CURRENT` in current mode, else the damper code of the inverted model
    (``BOUC_WEN``: the CSDC inverse with its hysteresis estimate; ``BI_EXPONENTIAL``, ``TANH``:
    the algebraic inverses)."""
    return COMMAND_CURRENT if current_mode else int(inverse_code)


def noise_pairs(observation: int) -> np.ndarray:
    """The Box-Muller pairs an observation set needs drawn (pair ``c // 2`` for channel ``c``)."""
    return np.array(sorted({c // 2 for c in _CHANNELS_READ[observation]}), dtype=np.int64)


#: Rows of ``EnvParams.obs_bounds``.
LOW, HIGH = 0, 1
#: Rows of ``EnvState.delay_slots``: where this step's command is written in the delay ring,
#: and where the command applied now is read.
DELAY_WRITE, DELAY_READ = 0, 1


class EnvParams(NamedTuple):
    """What stays fixed for a batch: the env's options, as the kernel reads them."""

    max_force_n: float  # force-mode scale of the action
    i_max_a: float  # the plant damper's maximum current
    dt_s: float  # control interval
    reward_acceleration_weight: float
    acceleration_scale_m_s2: float
    reward_stroke_weight: float
    stroke_scale_m: float
    reward_energy_weight: float
    reward_velocity_weight: float
    velocity_scale_m_s: float
    stroke_limit_m: float
    bump_stop_penalty: float
    current_mode: bool  # action_mode == "current"
    inverse_code: int  # damper code of the model the controller inverts
    observation: int  # OBS_SENSORS, OBS_FULL_STATE or OBS_MEASURED
    noisy: bool  # any sensor noise
    inverse_params: np.ndarray  # (N_DAMPER_PARAMS,) the inverted model's packed parameters
    noise_std: np.ndarray  # (N_NOISE_CHANNELS,) standard deviation of each channel
    noise_pairs: np.ndarray  # (k,) int64: the Box-Muller pairs the observation set reads
    obs_bounds: np.ndarray  # (2, obs_dim) rows LOW, HIGH: where the sensors saturate
    estimator: np.ndarray  # (5,) the velocity estimator's biquad, rows EST_B0 .. EST_A2
    preview_points: int  # guideway preview columns after the observation set's (0: none)
    preview_step_s: float  # time between preview points
    survey_error: np.ndarray  # (K, L) the survey map's error, on the profiles' grid (m)
    reward_filter: np.ndarray  # (S, 6) second-order sections of the reward's acceleration filter


class EnvState(NamedTuple):
    """What evolves, per vehicle."""

    plant: np.ndarray  # (N, STATE_SIZE)
    route: Route
    floats: np.ndarray  # (N_VEHICLE_FLOATS, N), rows layout.VEHICLE_FLOAT_NAMES
    step_count: np.ndarray  # (N,) int64 steps since the reset
    noise_key: np.ndarray  # (N,) uint64 drawn at the reset
    measured: np.ndarray  # (N_MEASUREMENTS, N), rows layout.MEASUREMENT_NAMES
    delay: np.ndarray  # (N, control_delay_steps + 1) ring buffer of commands
    delay_slots: np.ndarray  # (2,) int64: DELAY_WRITE, DELAY_READ


class EnvOutputs(NamedTuple):
    """What one step writes."""

    obs: np.ndarray  # (N, obs_dim) float32
    reward: np.ndarray  # (N,)
    terminated: np.ndarray  # (N,) bool
    signals: np.ndarray  # (N_SIGNALS, N + padding), rows layout.SIGNAL_NAMES
    plant: np.ndarray  # (N, N_PLANT_OUTPUTS) the plant kernel's outputs


# ----------------------------------------------------------------------------- noise
@njit(**FAST, inline="always")
def _mix(x):
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


@njit(**FAST, inline="always")
def gaussian_pair(key, step, pair):
    """Two independent standard normals from a counter-based hash of ``(key, step, pair)``
    (splitmix64, then Box-Muller: ``R cos(2 pi u2)`` and ``R sin(2 pi u2)``), with the log and
    cosine of :mod:`capsule_env._fastmath` so that the loop over vehicles vectorises."""
    base = (
        key
        + np.uint64(step) * np.uint64(0x9E3779B97F4A7C15)
        + np.uint64(pair) * np.uint64(0xD1B54A32D192ED03)
    )
    u1 = ((_mix(base) >> np.uint64(11)) + np.uint64(1)) * (1.0 / 9007199254740993.0)
    u2 = (_mix(base + np.uint64(0x632BE59BD9B4E019)) >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    radius = math.sqrt(-2.0 * fast_log(u1))
    return radius * fast_cos_2pi(u2), radius * fast_cos_2pi(u2 - 0.25)


@njit(**FAST, **BORROWED)
def _noise_lanes(keys, steps, pair, nb, out_a, out_b):
    """Sensor noise of channels ``2 pair`` and ``2 pair + 1`` for ``nb`` vehicles (a SIMD loop:
    the views start at the block's first vehicle)."""
    for j in range(nb):
        out_a[j], out_b[j] = gaussian_pair(keys[j], steps[j], pair)


# ----------------------------------------------------------------------------- commands
@njit(**FAST, **BORROWED)
def _current_lanes(actions, i_max, i_command, f_desired):
    """Current mode: action in [-1, 1] -> command in [0, i_max] (no force request)."""
    for j in range(actions.shape[0]):
        i_command[j] = 0.5 * (actions[j] + 1.0) * i_max
        f_desired[j] = 0.0


def _inverse_lanes(inv_code, inv_p, actions, stroke, rate, max_force, i_max, i_command, f_desired):
    """Force mode through an algebraic inverse model, one block of vehicles (a SIMD loop).
    ``inv_code`` is a literal: only its model's inverse compiles (a closure constant below,
    which numba's branch pruning sees through the inlined :func:`affine_in_current`).

    The parameters are read into a tuple first: ``p[k] if up else p[j]`` on an array is a
    conditional load, which LLVM does not vectorise (the loop ran 3x slower); on a tuple it is
    a select between two values."""
    raise NotImplementedError  # pragma: no cover - compiled from the overload


@overload(_inverse_lanes, prefer_literal=True, jit_options={**FAST, **BORROWED})
def _inverse_lanes_impl(inv_code, inv_p, actions, stroke, rate, max_force, i_max, i_command,
                        f_desired):  # fmt: skip
    if not isinstance(inv_code, types.IntegerLiteral):
        return None
    code = inv_code.literal_value

    def impl(inv_code, inv_p, actions, stroke, rate, max_force, i_max, i_command, f_desired):
        p = row_params(inv_p.reshape(1, -1), 0)
        for j in range(actions.shape[0]):
            f_d = actions[j] * max_force
            f0, slope = affine_in_current(code, p, stroke[j], rate[j], 0.0)
            i_command[j] = invert_affine(f_d, f0, slope, rate[j], i_max)
            f_desired[j] = f_d

    return impl


def env_commands(command, lo, hi, actions, params, state, out):
    """Vehicles ``lo .. hi-1``: action -> current command (directly in current mode, through
    the inverse model on this step's measurements in force mode), then the control delay: the
    command written into each vehicle's ring buffer, the one from ``control_delay_steps`` ago
    applied. ``command`` (:func:`command_path`) is a compile-time constant: only the path in
    use compiles (the unused ones were a sixth of a first step's compile time)."""
    raise NotImplementedError  # pragma: no cover - compiled from the overload


@overload(env_commands, prefer_literal=True, jit_options={**FAST, **BORROWED})
def _env_commands(command, lo, hi, actions, params, state, out):
    if not isinstance(command, types.IntegerLiteral) or isinstance(lo, types.Literal):
        return None  # specialise on the command path only
    cmd = command.literal_value

    def impl(command, lo, hi, actions, params, state, out):
        sig, meas, vf = out.signals, state.measured, state.floats
        i_max = params.i_max_a
        f_desired, i_command = sig[SIG_DESIRED_FORCE, lo:hi], sig[SIG_CURRENT_COMMAND, lo:hi]
        if cmd == COMMAND_CURRENT:
            _current_lanes(actions[lo:hi], i_max, i_command, f_desired)
        elif cmd == BOUC_WEN:  # CSDC: a hysteresis estimate per vehicle, scalar
            inv_p = params.inverse_params
            for n in range(lo, hi):
                f_d = actions[n] * params.max_force_n
                x_m, v_m = meas[MEAS_STROKE, n], meas[MEAS_STROKE_RATE, n]
                z_est = csdc_z_update(inv_p, vf[VF_CSDC_Z, n], x_m - vf[VF_CSDC_STROKE, n])
                vf[VF_CSDC_Z, n] = z_est
                vf[VF_CSDC_STROKE, n] = x_m
                f0, slope = affine_in_current(BOUC_WEN, inv_p, x_m, v_m, z_est)
                sig[SIG_DESIRED_FORCE, n] = f_d
                sig[SIG_CURRENT_COMMAND, n] = invert_affine(f_d, f0, slope, v_m, i_max)
        else:
            _inverse_lanes(cmd, params.inverse_params, actions[lo:hi],
                           meas[MEAS_STROKE, lo:hi], meas[MEAS_STROKE_RATE, lo:hi],
                           params.max_force_n, i_max, i_command, f_desired)  # fmt: skip
        write, read = state.delay_slots[DELAY_WRITE], state.delay_slots[DELAY_READ]
        for n in range(lo, hi):
            state.delay[n, write] = sig[SIG_CURRENT_COMMAND, n]
            vf[VF_APPLIED, n] = state.delay[n, read]
            state.step_count[n] += 1

    return impl


# ----------------------------------------------------------------------------- sensing
@njit(**FAST, **BORROWED)
def env_sense(lo, hi, params, plant, state, out, noise):
    """Vehicles ``lo .. hi-1`` (at most ``BLOCK``) after the plant step: sensor noise,
    measurements, reward, bump stop, signals and observations (clipped to where the sensors
    saturate; the guideway preview columns are :func:`env_preview`'s). ``noise`` is scratch
    of :data:`NOISE_SCRATCH_SHAPE` from the caller (this function allocates nothing)."""
    x, meas, sig, plant_out = state.plant, state.measured, out.signals, out.plant
    std = params.noise_std
    nb = hi - lo
    # 1. sensor noise, one Box-Muller pair of channels at a time across the block
    # rows that are read get written (their first nb columns)
    if not params.noisy:
        noise[:] = 0.0
    else:
        keys, steps = state.noise_key[lo:hi], state.step_count[lo:hi]
        for pair in params.noise_pairs:
            _noise_lanes(keys, steps, pair, nb, noise[2 * pair], noise[2 * pair + 1])
    # 2. sensors, reward, signals: one loop over the block (one contiguous row of meas and sig
    # per channel; every parameter is read into a local first, so no load is conditional)
    s_acc_c, s_acc_b = std[NOISE_BODY_ACC], std[NOISE_BOGIE_ACC]
    s_stroke, s_rate = std[NOISE_STROKE], std[NOISE_STROKE_RATE]
    acc_ref, stroke_ref = params.acceleration_scale_m_s2, params.stroke_scale_m
    vel_ref, i_max = params.velocity_scale_m_s, params.i_max_a
    w_acc, w_stroke = params.reward_acceleration_weight, params.reward_stroke_weight
    w_energy, w_vel = params.reward_energy_weight, params.reward_velocity_weight
    stroke_limit, penalty = params.stroke_limit_m, params.bump_stop_penalty
    has_current = i_max > 0.0
    vf = state.floats
    applied = vf[VF_APPLIED]
    est = params.estimator
    e_b0, e_b1, e_b2, e_a1, e_a2 = est[EST_B0], est[EST_B1], est[EST_B2], est[EST_A1], est[EST_A2]
    # the car-body acceleration the reward reads, through the reward filter's sections
    # (transposed direct form II; none: the acceleration itself)
    acc_reward = sig[SIG_REWARD_ACC]
    for n in range(lo, hi):
        acc_reward[n] = plant_out[n, OUT_BODY_ACC]
    sos = params.reward_filter
    for k in range(sos.shape[0]):
        f_b0, f_b1, f_b2, f_a1, f_a2 = sos[k, 0], sos[k, 1], sos[k, 2], sos[k, 4], sos[k, 5]
        s1, s2 = vf[VF_REWARD_FILTER + 2 * k], vf[VF_REWARD_FILTER + 2 * k + 1]
        for n in range(lo, hi):
            u = acc_reward[n]
            y = f_b0 * u + s1[n]
            s1[n] = f_b1 * u - f_a1 * y + s2[n]
            s2[n] = f_b2 * u - f_a2 * y
            acc_reward[n] = y
    for n in range(lo, hi):
        m = n - lo
        zc, vc = x[n, BODY_DISP], x[n, BODY_VEL]
        zb, vb = x[n, BOGIE_DISP], x[n, BOGIE_VEL]
        stroke = zc - zb
        rate = vc - vb
        force, acc_c = plant_out[n, OUT_FORCE], plant_out[n, OUT_BODY_ACC]
        acc_b, zg = plant_out[n, OUT_BOGIE_ACC], plant_out[n, OUT_GUIDEWAY]
        meas[MEAS_BODY_ACC, n] = acc_c + s_acc_c * noise[NOISE_BODY_ACC, m]
        meas[MEAS_BOGIE_ACC, n] = acc_b + s_acc_b * noise[NOISE_BOGIE_ACC, m]
        meas[MEAS_STROKE, n] = stroke + s_stroke * noise[NOISE_STROKE, m]
        meas[MEAS_STROKE_RATE, n] = rate + s_rate * noise[NOISE_STROKE_RATE, m]
        meas[MEAS_COMMAND, n] = sig[SIG_CURRENT_COMMAND, n]
        # on-board velocity estimates: the accelerometers through the estimator's biquad
        ab, s1, s2 = meas[MEAS_BODY_ACC, n], vf[VF_EST_BODY_1, n], vf[VF_EST_BODY_2, n]
        v_body = e_b0 * ab + s1
        vf[VF_EST_BODY_1, n] = e_b1 * ab - e_a1 * v_body + s2
        vf[VF_EST_BODY_2, n] = e_b2 * ab - e_a2 * v_body
        ab, s1, s2 = meas[MEAS_BOGIE_ACC, n], vf[VF_EST_BOGIE_1, n], vf[VF_EST_BOGIE_2, n]
        v_bogie = e_b0 * ab + s1
        vf[VF_EST_BOGIE_1, n] = e_b1 * ab - e_a1 * v_bogie + s2
        vf[VF_EST_BOGIE_2, n] = e_b2 * ab - e_a2 * v_bogie
        sig[SIG_BODY_VEL_EST, n] = v_body
        sig[SIG_BOGIE_VEL_EST, n] = v_bogie
        # reward (x * x, not x ** 2: numba lowers the power to a slow libm call)
        acc_rel = acc_reward[n] / acc_ref
        stroke_rel = stroke / stroke_ref
        current_rel = applied[n] / i_max if has_current else 0.0
        c_acc = w_acc * acc_rel * acc_rel
        c_stroke = w_stroke * stroke_rel * stroke_rel
        c_energy = w_energy * current_rel * current_rel
        vel_rel = vc / vel_ref
        c_vel = w_vel * vel_rel * vel_rel
        hit = abs(stroke) > stroke_limit
        out.terminated[n] = hit
        out.reward[n] = -(c_acc + c_stroke + c_energy + c_vel) - (penalty if hit else 0.0)
        sig[SIG_BODY_DISP, n] = zc
        sig[SIG_BOGIE_DISP, n] = zb
        sig[SIG_BODY_VEL, n] = vc
        sig[SIG_BOGIE_VEL, n] = vb
        sig[SIG_BODY_ACC, n] = acc_c
        sig[SIG_BOGIE_ACC, n] = acc_b
        sig[SIG_STROKE, n] = stroke
        sig[SIG_STROKE_RATE, n] = rate
        sig[SIG_FORCE, n] = force
        sig[SIG_COIL_CURRENT, n] = x[n, COIL_CURRENT]
        sig[SIG_GUIDEWAY, n] = zg
        sig[SIG_COST_ACC, n] = c_acc
        sig[SIG_COST_STROKE, n] = c_stroke
        sig[SIG_COST_ENERGY, n] = c_energy
        sig[SIG_COST_VEL, n] = c_vel
    # 3. observations (float32 rows; sensors saturate at the observation-space bounds)
    obs, bounds = out.obs, params.obs_bounds
    if params.observation == OBS_FULL_STATE:
        for n in range(lo, hi):
            m = n - lo
            obs[n, 0] = x[n, BODY_DISP] + std[NOISE_BODY_DISP] * noise[NOISE_BODY_DISP, m]
            obs[n, 1] = x[n, BODY_VEL] + std[NOISE_BODY_VEL] * noise[NOISE_BODY_VEL, m]
            obs[n, 2] = x[n, BOGIE_DISP] + std[NOISE_BOGIE_DISP] * noise[NOISE_BOGIE_DISP, m]
            obs[n, 3] = x[n, BOGIE_VEL] + std[NOISE_BOGIE_VEL] * noise[NOISE_BOGIE_VEL, m]
            obs[n, 4] = sig[SIG_GUIDEWAY, n] + std[NOISE_GUIDEWAY] * noise[NOISE_GUIDEWAY, m]
            for j in range(MEAS_STROKE_RATE + 1):  # the same (noisy) measurements as the inverse
                obs[n, 5 + j] = meas[j, n]
            obs[n, 9] = x[n, COIL_CURRENT]
    elif params.observation == OBS_MEASURED:
        s_gap, s_current = std[NOISE_GAP], std[NOISE_CURRENT]
        for n in range(lo, hi):
            m = n - lo
            for j in range(MEAS_STROKE_RATE + 1):  # accelerations, stroke and its rate
                obs[n, j] = meas[j, n]
            gap = x[n, BOGIE_DISP] - sig[SIG_GUIDEWAY, n]
            obs[n, 4] = gap + s_gap * noise[NOISE_GAP, m]
            obs[n, 5] = x[n, COIL_CURRENT] + s_current * noise[NOISE_CURRENT, m]
            obs[n, 6] = meas[MEAS_COMMAND, n]
            obs[n, 7] = sig[SIG_BODY_VEL_EST, n]
            obs[n, 8] = sig[SIG_BOGIE_VEL_EST, n]
    else:
        for n in range(lo, hi):
            for j in range(MEAS_COMMAND + 1):
                obs[n, j] = meas[j, n]
    # the preview columns (the last preview_points) are env_preview's
    for n in range(lo, hi):
        for j in range(obs.shape[1] - params.preview_points):
            obs[n, j] = min(max(obs[n, j], bounds[LOW, j]), bounds[HIGH, j])


@njit(**FAST, **BORROWED)
def env_preview(lo, hi, params, plant, state, obs):
    """Vehicles ``lo .. hi-1`` after :func:`env_sense`: the guideway preview columns of their
    observations (:func:`preview_row`), clipped to the observation space. Called by the
    kernels of configurations with preview only (not compiled for the others)."""
    bounds = params.obs_bounds
    for n in range(lo, hi):
        preview_row(n, params, plant, state, obs)
    for n in range(lo, hi):
        for j in range(obs.shape[1] - params.preview_points, obs.shape[1]):
            obs[n, j] = min(max(obs[n, j], bounds[LOW, j]), bounds[HIGH, j])


@njit(**FAST, **BORROWED)
def preview_row(n, params, plant, state, obs):
    """The guideway preview columns of vehicle ``n`` (the last ``preview_points`` of its
    observation, clipped by the caller): the surveyed elevation ``k * preview_step_s`` ahead of
    the bogie, ``k = 1 .. preview_points``, relative to the surveyed elevation under it now,
    looked up in the survey map (the true profile plus the survey's error) at the vehicle's
    estimated position (the true one plus its episode's position error)."""
    profiles, spacing, err = plant.profiles, plant.spacing_m, params.survey_error
    last = profiles.shape[1] - 1.0
    route, vf = state.route, state.floats
    first = obs.shape[1] - params.preview_points
    k, g, speed = route.profile[n], route.gain[n], route.speed_mps[n]
    here = route.start_m[n] + speed * state.plant[n, TIME] + vf[VF_POSITION_ERROR, n]
    ref = g * guideway_elevation(profiles, k, spacing, last, here)
    ref += guideway_elevation(err, k, spacing, last, here)
    for j in range(params.preview_points):
        ahead = here + speed * (j + 1) * params.preview_step_s
        z = g * guideway_elevation(profiles, k, spacing, last, ahead)
        obs[n, first + j] = z + guideway_elevation(err, k, spacing, last, ahead) - ref


@njit(cache=True, error_model="numpy", no_cfunc_wrapper=True)
def reset_preview(n, params, plant, state, obs):
    """:func:`preview_row` called from Python (a vehicle's first observation at its reset): a
    function of its own, compiled only where preview is used (the CPython wrapper of a function
    taking the env's named structures is a large part of its compile time)."""
    preview_row(n, params, plant, state, obs)
