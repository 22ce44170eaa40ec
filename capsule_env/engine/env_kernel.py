"""The env's per-step work around the plant: commands in, sensors, reward and observation out.

For a block of vehicles, :func:`env_commands` turns actions into coil-current commands (through
the inverse model in force mode) and applies the control delay; the plant kernel advances the
vehicles (:mod:`capsule_env.plant`); :func:`env_sense` draws the sensor noise, measures, and
writes the reward, the signals (``info``) and the observations; :func:`env_preview` adds the
guideway preview columns where the configuration has them. The arguments are named
structures (:class:`EnvParams`, :class:`EnvState`, :class:`EnvOutputs`) whose arrays have the
layouts of :mod:`capsule_env.engine.layout`. Pure numba/numpy, no Gym import.

Sensor noise is a counter-based hash of ``(vehicle key, step, channel)`` turned into normals by
Box-Muller pairs: it depends on nothing else, so a vehicle's trajectory is the same whatever
its batch, its position in it or the threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from capsule_env._fastmath import BORROWED, FAST, fast_cos_2pi, fast_log
from capsule_env._jit import specialised
from capsule_env.dampers.inverse import affine_in_current, csdc_z_update, invert_affine
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.env_params import (
    CSDC_STROKE,
    CSDC_Z,
    EST_BODY,
    EST_BOGIE,
    HIGH,
    LOW,
    OBS_FULL_STATE,
    OBS_MEASURED,
    OBS_SENSORS,
    OBSERVATION_CODES,
    EnvOutputs,
    EnvParams,
    EnvState,
    applied_current,
    csdc,
    estimator,
    noise_pairs,
    position_error,
    reward_filter,
)
from capsule_env.engine.layout import (
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    MEAS_BODY_ACC,
    MEAS_BOGIE_ACC,
    MEAS_STROKE,
    MEAS_STROKE_RATE,
    N_NOISE_CHANNELS,
    N_SIGNALS,
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
    SIGNAL_NAMES,
    TIME,
)
from capsule_env.engine.observations import (
    COLUMN_MEASUREMENTS,
    COLUMN_NOISE,
    COLUMN_SOURCES,
    MEASUREMENT_NOISE,
    MEASUREMENT_SOURCES,
    QUANTITIES,
)
from capsule_env.plant.block import BLOCK, guideway_elevation, route_elevation, row_params

__all__ = [
    "env_commands",
    "env_sense",
    "env_sense_variant",
    "sense_flags",
    "SENSE_NOISE",
    "SENSE_FILTER",
    "SENSE_ALL",
    "env_preview",
    "SENSE_SCRATCH_SHAPE",
    "COMMAND_CURRENT",
    "command_path",
    # the named structures, from capsule_env.engine.env_params (their home since issue 26)
    "EnvParams",
    "EnvState",
    "EnvOutputs",
    "OBSERVATION_CODES",
    "OBS_SENSORS",
    "OBS_FULL_STATE",
    "OBS_MEASURED",
    "noise_pairs",
]

#: The quantities the kernel computes into its scratch (those no ``info`` signal holds), one
#: row each after the noise rows.
_SCRATCH_QUANTITIES = tuple(q.name for q in QUANTITIES if q.signal is None)
Q_GAP = _SCRATCH_QUANTITIES.index("levitation_gap_m")
#: Rows of the scratch before the quantities: one per noise channel, and one for the second
#: member of the last Box-Muller pair when the channels are odd in number.
_NOISE_ROWS = N_NOISE_CHANNELS + 1
#: Shape of :func:`env_sense`'s scratch: a row per noise channel, then a row per quantity of
#: its own, a column per vehicle of a block.
SENSE_SCRATCH_SHAPE = (_NOISE_ROWS + len(_SCRATCH_QUANTITIES), BLOCK)


def _kernel_sources(quantities: np.ndarray) -> np.ndarray:
    """Where the kernel reads each quantity (indices in ``observations.QUANTITY_NAMES``): its
    ``info`` signal's row, or ``N_SIGNALS +`` its scratch row."""
    rows = []
    for k in quantities:
        q = QUANTITIES[k]
        if q.signal:
            rows.append(SIGNAL_NAMES.index(q.signal))
        else:
            rows.append(N_SIGNALS + _SCRATCH_QUANTITIES.index(q.name))
    return np.array(rows, dtype=np.int64)


#: The column maps of the observation sets (``observations.COLUMN_SOURCES``, ``COLUMN_NOISE``,
#: ``COLUMN_MEASUREMENTS``), one ``(3, width)`` int64 block per set, by observation code
#: (``OBSERVATION_CODES``): row ``_MAP_MEASUREMENT`` the measurement each column equals (-1:
#: none), ``_MAP_SOURCE`` where it reads its quantity (:func:`_kernel_sources`),
#: ``_MAP_CHANNEL`` its noise channel (-1: none); ``_COLUMN_COUNTS`` the set's number of
#: columns (the rest of its block is padding, -1).
_MAP_MEASUREMENT, _MAP_SOURCE, _MAP_CHANNEL = range(3)


def _column_maps() -> tuple[np.ndarray, np.ndarray]:
    """:data:`_COLUMN_MAPS` and :data:`_COLUMN_COUNTS` from the observation table."""
    names = sorted(OBSERVATION_CODES, key=OBSERVATION_CODES.get)
    counts = np.array([len(COLUMN_SOURCES[name]) for name in names], dtype=np.int64)
    maps = np.full((len(names), 3, int(counts.max())), -1, dtype=np.int64)
    for code, name in enumerate(names):
        rows = (COLUMN_MEASUREMENTS[name], _kernel_sources(COLUMN_SOURCES[name]),
                COLUMN_NOISE[name])  # fmt: skip
        for row, values in zip((_MAP_MEASUREMENT, _MAP_SOURCE, _MAP_CHANNEL), rows):
            maps[code, row, : counts[code]] = values
    return maps, counts


_COLUMN_MAPS, _COLUMN_COUNTS = _column_maps()
#: ... and of the measurements (``observations.MEASUREMENT_SOURCES``, ``MEASUREMENT_NOISE``).
_MEAS_SOURCE, _MEAS_NOISE = _kernel_sources(MEASUREMENT_SOURCES), MEASUREMENT_NOISE
#: Coefficients of ``EnvParams.estimator``: ``(b0, b1, b2, a1, a2)`` of a biquad.
EST_B0, EST_B1, EST_B2, EST_A1, EST_A2 = range(5)


#: :func:`command_path` of current mode (force mode's is the inverted model's damper code).
COMMAND_CURRENT = -1


def command_path(current_mode: bool, inverse_code: int) -> int:
    """How the env turns actions into current commands, a compile-time constant of its kernel:
    :data:`COMMAND_CURRENT` in current mode, else the damper code of the inverted model
    (Bouc-Wen's: the CSDC inverse with its hysteresis estimate; the Bi-exponential's and
    tanh's: the algebraic inverses)."""
    return COMMAND_CURRENT if current_mode else int(inverse_code)


#: Rows of ``EnvParams.obs_bounds``.


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


@specialised("inv_code")
def _inverse_lanes(inv_code, inv_p, actions, stroke, rate, max_force, i_max, i_command, f_desired):
    """Force mode through an algebraic inverse model, one block of vehicles (a SIMD loop).
    ``inv_code`` is a literal: only its model's inverse compiles (a closure constant below,
    which numba's branch pruning sees through the inlined :func:`affine_in_current`).

    The parameters are read into a tuple first: ``p[k] if up else p[j]`` on an array is a
    conditional load, which LLVM does not vectorise (the loop ran 3x slower); on a tuple it is
    a select between two values."""
    code = inv_code

    def impl(inv_code, inv_p, actions, stroke, rate, max_force, i_max, i_command, f_desired):
        p = row_params(inv_p.reshape(1, -1), 0)
        for j in range(actions.shape[0]):
            f_d = actions[j] * max_force
            f0, slope = affine_in_current(code, p, stroke[j], rate[j], 0.0)
            i_command[j] = invert_affine(f_d, f0, slope, rate[j], i_max)
            f_desired[j] = f_d

    return impl


@specialised("command", plain=("lo",))
def env_commands(command, lo, hi, actions, params, state, out):
    """Vehicles ``lo .. hi-1``: action -> current command (directly in current mode, through
    the inverse model on this step's measurements in force mode), then the control delay: the
    command written into each vehicle's ring buffer, the one from ``control_delay_steps`` ago
    applied. ``command`` (:func:`command_path`) is a compile-time constant: only the path in
    use compiles (the unused ones were a sixth of a first step's compile time). An inverse
    that keeps a hysteresis estimate (the registry's ``inverse_name == "csdc"``, Bouc-Wen's)
    runs per vehicle with its estimate; the algebraic ones by :func:`_inverse_lanes`."""
    cmd = command
    stateful = cmd != COMMAND_CURRENT and model_of_code(cmd).inverse_name == "csdc"

    def impl(command, lo, hi, actions, params, state, out):
        sig, meas, csdc_state = out.signals, state.measured, csdc(state)
        i_max = params.i_max_a
        f_desired, i_command = sig[SIG_DESIRED_FORCE, lo:hi], sig[SIG_CURRENT_COMMAND, lo:hi]
        if cmd == COMMAND_CURRENT:
            _current_lanes(actions[lo:hi], i_max, i_command, f_desired)
        elif stateful:  # CSDC: a hysteresis estimate per vehicle, scalar
            inv_p = params.inverse_params
            for n in range(lo, hi):
                f_d = actions[n] * params.max_force_n
                x_m, v_m = meas[MEAS_STROKE, n], meas[MEAS_STROKE_RATE, n]
                z_est = csdc_z_update(
                    inv_p, csdc_state[CSDC_Z, n], x_m - csdc_state[CSDC_STROKE, n]
                )
                csdc_state[CSDC_Z, n] = z_est
                csdc_state[CSDC_STROKE, n] = x_m
                f0, slope = affine_in_current(cmd, inv_p, x_m, v_m, z_est)
                sig[SIG_DESIRED_FORCE, n] = f_d
                sig[SIG_CURRENT_COMMAND, n] = invert_affine(f_d, f0, slope, v_m, i_max)
        else:
            _inverse_lanes(cmd, params.inverse_params, actions[lo:hi],
                           meas[MEAS_STROKE, lo:hi], meas[MEAS_STROKE_RATE, lo:hi],
                           params.max_force_n, i_max, i_command, f_desired)  # fmt: skip
        _delay(lo, hi, sig[SIG_CURRENT_COMMAND], state)

    return impl


@njit(**FAST, **BORROWED)
def _delay(lo, hi, command, state):
    """The control delay, a ring of ``size = control_delay_steps + 1`` commands per vehicle
    indexed by its step count ``k``: this step's command written at ``k mod size``, the one
    from ``size - 1`` steps ago read at ``(k + 1) mod size`` (zero until the ring has filled
    since the reset, which zeroes it), then the step count advanced. The kernel owns both: the
    same commands as a ring position kept by Python, whatever the vehicle's resets."""
    ring, size = state.delay, state.delay.shape[1]
    count, applied = state.step_count, applied_current(state)
    for n in range(lo, hi):
        k = count[n]
        ring[n, k % size] = command[n]
        applied[n] = ring[n, (k + 1) % size]
        count[n] = k + 1


# ----------------------------------------------------------------------------- sensing
#: Flags of :func:`env_sense_variant`: the parts of sensing a kernel compiles, for the
#: configurations that use them (:func:`sense_flags`): the sensor noise, the reward's
#: acceleration filter. ``SENSE_ALL``: both, each decided at run time (:func:`env_sense`).
SENSE_NOISE, SENSE_FILTER = 1, 2
SENSE_ALL = SENSE_NOISE | SENSE_FILTER


def sense_flags(params: EnvParams) -> int:
    """The :func:`env_sense_variant` flags of a configuration's ``EnvParams``: the sensor noise
    where any channel is noisy, the reward filter where it has sections."""
    noise = SENSE_NOISE if params.noisy else 0
    return noise | (SENSE_FILTER if params.reward_filter.shape[0] > 0 else 0)


@njit(**FAST, **BORROWED)
def env_sense(lo, hi, params, plant, state, out, scratch):
    """Vehicles ``lo .. hi-1`` (at most ``BLOCK``) after the plant step: sensor noise,
    quantities, measurements, velocity estimates, the reward's acceleration filter, reward and
    bump stop, signals and observations (clipped to where the sensors saturate; the guideway
    preview columns are :func:`env_preview`'s). ``scratch`` of :data:`SENSE_SCRATCH_SHAPE`
    comes from the caller (this function allocates nothing): its noise rows, then its
    quantity rows. Any configuration (:func:`env_sense_variant` with ``SENSE_ALL``); the
    kernels compile the variant of their configuration."""
    env_sense_variant(SENSE_ALL, lo, hi, params, plant, state, out, scratch)


@specialised("flags", plain=("lo",))
def env_sense_variant(flags, lo, hi, params, plant, state, out, scratch):
    """:func:`env_sense` compiled with the parts of ``flags`` (a compile-time constant,
    :func:`sense_flags` of the configuration it runs): without ``SENSE_NOISE`` the noise is
    zero (``params.noisy`` false), without ``SENSE_FILTER`` the reward reads the acceleration
    itself (no filter sections): the same numbers as :func:`env_sense` for such a
    configuration, without compiling the noise generator or the filter (about a tenth of a
    noise-free first step's compile time)."""
    noisy, filtered = (flags & SENSE_NOISE) != 0, (flags & SENSE_FILTER) != 0

    def impl(flags, lo, hi, params, plant, state, out, scratch):
        noise, q = scratch[:_NOISE_ROWS], scratch[_NOISE_ROWS:]
        if noisy:
            _draw_noise(lo, hi, params, state, noise)
        else:
            noise[:] = 0.0
        _quantities(lo, hi, state.plant, out, q)
        _measure(lo, hi, params.noise_std, out.signals, q, noise, state.measured)
        _estimate_velocities(lo, hi, params.estimator, state, out)
        if filtered:
            _filter_reward_acceleration(lo, hi, params.reward_filter, reward_filter(state), out)
        else:
            _reward_acceleration(lo, hi, out)
        _reward(lo, hi, params, state, out)
        _observe(lo, hi, params, out.signals, q, noise, state.measured, out.obs)

    return impl


@njit(**FAST, **BORROWED)
def _draw_noise(lo, hi, params, state, noise):
    """Sensor noise of the block, one Box-Muller pair of channels at a time (only the pairs the
    observation set reads: their rows' first ``hi - lo`` columns); all zero without noise."""
    if not params.noisy:
        noise[:] = 0.0
        return
    keys, steps = state.noise_key[lo:hi], state.step_count[lo:hi]
    for pair in params.noise_pairs:
        _noise_lanes(keys, steps, pair, hi - lo, noise[2 * pair], noise[2 * pair + 1])


@njit(**FAST, **BORROWED)
def _quantities(lo, hi, x, out, q):
    """The block's true quantities (``observations.QUANTITIES``) from the plant's state and
    outputs: into their ``info`` signals, the others into ``q`` (the scratch's quantity rows);
    the estimates are :func:`_estimate_velocities`', the command
    :func:`env_commands`'. A new quantity is a line here."""
    plant_out, sig = out.plant, out.signals
    for n in range(lo, hi):
        zc, zb, zg = x[n, BODY_DISP], x[n, BOGIE_DISP], plant_out[n, OUT_GUIDEWAY]
        vc, vb = x[n, BODY_VEL], x[n, BOGIE_VEL]
        sig[SIG_BODY_DISP, n], sig[SIG_BOGIE_DISP, n], sig[SIG_GUIDEWAY, n] = zc, zb, zg
        sig[SIG_BODY_VEL, n], sig[SIG_BOGIE_VEL, n] = vc, vb
        sig[SIG_BODY_ACC, n] = plant_out[n, OUT_BODY_ACC]
        sig[SIG_BOGIE_ACC, n] = plant_out[n, OUT_BOGIE_ACC]
        sig[SIG_STROKE, n], sig[SIG_STROKE_RATE, n] = zc - zb, vc - vb
        sig[SIG_FORCE, n] = plant_out[n, OUT_FORCE]
        sig[SIG_COIL_CURRENT, n] = x[n, COIL_CURRENT]
        q[Q_GAP, n - lo] = zb - zg


@njit(**FAST, **BORROWED, inline="always")
def _quantity(source, n, m, sig, q):
    """Vehicle ``n``'s (block column ``m``'s) value of a quantity where the kernel reads it
    (:func:`_kernel_sources`)."""
    return sig[source, n] if source < N_SIGNALS else q[source - N_SIGNALS, m]


@njit(**FAST, **BORROWED)
def _measure(lo, hi, std, sig, q, noise, meas):
    """The measurements (rows of ``meas``, ``layout.MEASUREMENT_NAMES``): each its quantity
    plus its channel's noise (``observations.MEASUREMENT_SOURCES``, ``MEASUREMENT_NOISE``)."""
    for n in range(lo, hi):
        m = n - lo
        for k in range(_MEAS_SOURCE.shape[0]):
            v = _quantity(_MEAS_SOURCE[k], n, m, sig, q)
            c = _MEAS_NOISE[k]
            if c >= 0:
                v += std[c] * noise[c, m]
            meas[k, n] = v


@njit(**FAST, **BORROWED)
def _estimate_velocities(lo, hi, est, state, out):
    """The on-board absolute velocity estimates (their ``info`` signals): each accelerometer's
    measurement through the estimator's biquad (transposed direct form II)."""
    b0, b1, b2, a1, a2 = est[EST_B0], est[EST_B1], est[EST_B2], est[EST_A1], est[EST_A2]
    meas, s, sig = state.measured, estimator(state), out.signals
    for acc_row, first, sig_row in ((MEAS_BODY_ACC, EST_BODY, SIG_BODY_VEL_EST),
                                    (MEAS_BOGIE_ACC, EST_BOGIE, SIG_BOGIE_VEL_EST)):  # fmt: skip
        acc, s1, s2, v = meas[acc_row], s[first], s[first + 1], sig[sig_row]
        for n in range(lo, hi):
            a = acc[n]
            y = b0 * a + s1[n]
            s1[n] = b1 * a - a1 * y + s2[n]
            s2[n] = b2 * a - a2 * y
            v[n] = y


@njit(**FAST, **BORROWED)
def _reward_acceleration(lo, hi, out):
    """The car-body acceleration the reward reads (signal ``reward_acceleration_m_s2``): the
    plant's, unfiltered."""
    acc = out.signals[SIG_REWARD_ACC]
    for n in range(lo, hi):
        acc[n] = out.plant[n, OUT_BODY_ACC]


@njit(**FAST, **BORROWED)
def _filter_reward_acceleration(lo, hi, sos, states, out):
    """The car-body acceleration the reward reads (signal ``reward_acceleration_m_s2``): the
    plant's (:func:`_reward_acceleration`) through the reward filter's second-order sections
    (transposed direct form II; none: the acceleration itself)."""
    _reward_acceleration(lo, hi, out)
    acc = out.signals[SIG_REWARD_ACC]
    for k in range(sos.shape[0]):
        f_b0, f_b1, f_b2, f_a1, f_a2 = sos[k, 0], sos[k, 1], sos[k, 2], sos[k, 4], sos[k, 5]
        s1, s2 = states[2 * k], states[2 * k + 1]
        for n in range(lo, hi):
            u = acc[n]
            y = f_b0 * u + s1[n]
            s1[n] = f_b1 * u - f_a1 * y + s2[n]
            s2[n] = f_b2 * u - f_a2 * y
            acc[n] = y


@njit(**FAST, **BORROWED)
def _reward(lo, hi, params, state, out):
    """Reward, its cost terms (signals) and the bump stop. Every parameter is read into a local
    first, so no load in the loop is conditional (``x * x``, not ``x ** 2``: numba lowers the
    power to a slow libm call)."""
    acc_ref, stroke_ref = params.acceleration_scale_m_s2, params.stroke_scale_m
    vel_ref, i_max = params.velocity_scale_m_s, params.i_max_a
    w_acc, w_stroke = params.reward_acceleration_weight, params.reward_stroke_weight
    w_energy, w_vel = params.reward_energy_weight, params.reward_velocity_weight
    stroke_limit, penalty = params.stroke_limit_m, params.bump_stop_penalty
    has_current = i_max > 0.0
    sig, applied, acc_reward = out.signals, applied_current(state), out.signals[SIG_REWARD_ACC]
    for n in range(lo, hi):
        stroke = sig[SIG_STROKE, n]
        acc_rel = acc_reward[n] / acc_ref
        stroke_rel = stroke / stroke_ref
        current_rel = applied[n] / i_max if has_current else 0.0
        vel_rel = sig[SIG_BODY_VEL, n] / vel_ref
        c_acc = w_acc * acc_rel * acc_rel
        c_stroke = w_stroke * stroke_rel * stroke_rel
        c_energy = w_energy * current_rel * current_rel
        c_vel = w_vel * vel_rel * vel_rel
        hit = abs(stroke) > stroke_limit
        out.terminated[n] = hit
        out.reward[n] = -(c_acc + c_stroke + c_energy + c_vel) - (penalty if hit else 0.0)
        sig[SIG_COST_ACC, n], sig[SIG_COST_STROKE, n] = c_acc, c_stroke
        sig[SIG_COST_ENERGY, n], sig[SIG_COST_VEL, n] = c_energy, c_vel


@njit(**FAST, **BORROWED)
def _observe(lo, hi, params, sig, q, noise, meas, obs):
    """The observation set's columns (float32; the sensors saturate at the observation-space
    bounds), column by column, by the set's column map (:data:`_COLUMN_MAPS`, read at run
    time: one loop compiled for every set, where a copy per set was a tenth of a first step's
    compile time): each column its measurement (the same bits as its quantity plus its
    noise), or its quantity plus its channel's noise, clipped."""
    code, std, bounds = params.observation, params.noise_std, params.obs_bounds
    for j in range(_COLUMN_COUNTS[code]):
        k, c = _COLUMN_MAPS[code, _MAP_MEASUREMENT, j], _COLUMN_MAPS[code, _MAP_CHANNEL, j]
        source = _COLUMN_MAPS[code, _MAP_SOURCE, j]
        # the block's values of the column's measurement or quantity (:func:`_kernel_sources`)
        if k >= 0:
            values = meas[k, lo:hi]
        elif source < N_SIGNALS:
            values = sig[source, lo:hi]
        else:
            values = q[source - N_SIGNALS, : hi - lo]
        if k < 0 and c >= 0:
            _noisy_column(obs, j, values, std[c], noise[c], lo, bounds)
        else:
            _clip_column(obs, j, values, lo, bounds)


# The column loops are inlined by LLVM (forceinline) into _observe's loop over the columns.
@njit(**FAST, **BORROWED, forceinline=True)
def _clip_column(obs, j, values, lo, bounds):
    """Column ``j`` of vehicles ``lo ..``: ``values`` (one per vehicle) clipped to the column's
    bounds (the clip in float64 before the float32 store gives the bits of a clip after it:
    rounding is monotonic and the bounds are float32 values)."""
    low, high = bounds[LOW, j], bounds[HIGH, j]
    for m in range(values.shape[0]):
        obs[lo + m, j] = min(max(values[m], low), high)


@njit(**FAST, **BORROWED, forceinline=True)
def _noisy_column(obs, j, values, std, noise, lo, bounds):
    """Column ``j`` of vehicles ``lo ..``: ``values`` (one per vehicle) plus ``std`` times the
    channel's ``noise``, clipped to the column's bounds."""
    low, high = bounds[LOW, j], bounds[HIGH, j]
    for m in range(values.shape[0]):
        obs[lo + m, j] = min(max(values[m] + std * noise[m], low), high)


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
    estimated position (the true one plus its episode's position error). The true profile is
    the plant's bank unless the plant reads a filtered one (``params.survey_bank``)."""
    bank, spacing, err = params.survey_bank, plant.spacing_m, params.survey_error
    profiles = plant.profiles if bank.shape[0] == 0 else bank
    last = profiles.shape[1] - 1.0
    route = state.route
    first = obs.shape[1] - params.preview_points
    k, g, speed = route.profile[n], route.gain[n], route.speed_mps[n]
    here = route.start_m[n] + speed * state.plant[n, TIME] + position_error(state)[n]
    ref = route_elevation(profiles, plant.offsets, k, g, spacing, last, here)
    ref += guideway_elevation(err, k, spacing, last, here)
    for j in range(params.preview_points):
        ahead = here + speed * (j + 1) * params.preview_step_s
        z = route_elevation(profiles, plant.offsets, k, g, spacing, last, ahead)
        obs[n, first + j] = z + guideway_elevation(err, k, spacing, last, ahead) - ref


@njit(cache=True, error_model="numpy", no_cfunc_wrapper=True)
def reset_preview(n, params, plant, state, obs):
    """:func:`preview_row` called from Python (a vehicle's first observation at its reset): a
    function of its own, compiled only where preview is used (the CPython wrapper of a function
    taking the env's named structures is a large part of its compile time)."""
    preview_row(n, params, plant, state, obs)
