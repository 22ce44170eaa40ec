"""``N`` capsule vehicles stepped together by one compiled kernel (no Gym import).

:class:`CapsuleBatch` is what every flavour of the env runs on: the single Gymnasium env is a
batch of one; the native vector env and the SB3 ``VecEnv`` are batches of ``N``: same kernel,
same numbers. It holds the named structures the kernel takes (:class:`EnvParams`,
:class:`PlantParams`, :class:`EnvState`; layouts in :mod:`capsule_env.engine.layout`), draws each
vehicle's episode at its reset and calls the kernel of :mod:`capsule_env.engine.kernels`.

Randomness is per vehicle: vehicle ``n`` owns a ``numpy.random.Generator`` (stream ``n`` of
``numpy.random.SeedSequence(seed)``, :func:`vehicle_streams`) used only at reset (guideway
window, domain randomisation, the noise key), and sensor noise is a counter-based hash of
``(noise key, step, channel)``. So a trajectory depends only on the seed and the actions, never
on the batch size, the batch position or threading.
"""

from __future__ import annotations

import math
from operator import attrgetter
from typing import Any

import numpy as np
from numba import njit

from capsule_env.engine.config import (
    SURVEY_NOISE_BAND_M,
    SURVEY_OFFSET_BAND_M,
    EnvConfig,
    check_num_envs,
    check_seed,
)
from capsule_env.engine.env_kernel import command_path, sense_flags
from capsule_env.engine.env_params import EnvParams, EnvState
from capsule_env.engine.kernels import ENV, BatchedKernel, env_args
from capsule_env.engine.layout import (
    BODY_DISP,
    BOGIE_DISP,
    DAMP_LEVITATION,
    MASS_BODY,
    MASS_BOGIE,
    N_PLANT_OUTPUTS,
    N_SIGNALS,
    N_VEHICLE_PARAMS,
    SIG_BODY_DISP,
    SIG_BOGIE_DISP,
    SIG_GUIDEWAY,
    STIFF_LEVITATION,
)
from capsule_env.engine.observations import rest_observation
from capsule_env.envelope.kernel import ENV_LIMIT, ENV_SPEED, ENV_START, ENV_T0
from capsule_env.envelope.magnet import magnet_average
from capsule_env.envelope.trips import draw_window_start_s, trip_acceleration_m_s2, trip_speed_m_s
from capsule_env.guideway import make_profile, random_profile
from capsule_env.guideway.params import profile_length_m
from capsule_env.guideway.sampling import n_samples
from capsule_env.guideway.spans import span_profile
from capsule_env.plant.block import block_constants, block_kernel_mode, levitation_damped
from capsule_env.plant.params import PlantParams, Route

__all__ = ["CapsuleBatch", "survey_error", "vehicle_streams"]

#: Signal rows are padded by this many values: rows a multiple of 4 KiB apart would all map to
#: the same L1 cache set (measured: ~60 ns per vehicle-step).
_SIGNAL_PADDING = 8


def vehicle_streams(seed: Any, num_envs: int) -> list[np.random.Generator]:
    """One random generator per vehicle, used at its resets.

    - ``seed`` an int: ``numpy.random.SeedSequence(seed).spawn(num_envs)``: independent streams,
      and two batches seeded differently share none (vehicle ``n`` of seed ``s`` is *not*
      vehicle ``n - 1`` of seed ``s + 1``). Vehicle 0 is the single env seeded ``s``.
    - a sequence of ``num_envs`` ints: vehicle ``n`` gets the stream of the single env seeded
      ``seed[n]`` (to reproduce individual episodes).
    - None: fresh entropy.
    """
    if seed is None:
        return [np.random.default_rng(s) for s in np.random.SeedSequence().spawn(num_envs)]
    if isinstance(seed, (list, tuple, np.ndarray)):
        seeds = list(np.asarray(seed, dtype=object).reshape(-1))
        if len(seeds) != num_envs:
            raise ValueError(f"seed must be an int or a list of {num_envs} ints, got {len(seeds)}")
        return [
            np.random.default_rng(np.random.SeedSequence(check_seed(f"seed[{k}]", s)).spawn(1)[0])
            for k, s in enumerate(seeds)
        ]
    root = np.random.SeedSequence(check_seed("seed", seed))
    return [np.random.default_rng(s) for s in root.spawn(num_envs)]


@njit(cache=True)
def _clip_actions(actions, out):
    """Clip ``actions`` to [-1, 1] into ``out``; True if any is NaN or infinite."""
    bad = False
    for k in range(actions.shape[0]):
        x = float(actions[k])
        bad |= not math.isfinite(x)
        out[k] = min(max(x, -1.0), 1.0)
    return bad


def _bound(name: str, doc: str) -> property:
    """A read-only attribute for an array the kernel is bound to (stored as ``_<name>``; a C
    getter, about as fast as a plain attribute)."""
    return property(attrgetter(f"_{name}"), doc=f"{doc} (read-only: the kernel is bound to it)")


class CapsuleBatch:
    """``N`` capsule vehicles stepped together by one compiled kernel.

    Parameters
    ----------
    config : the environment options.
    num_envs : batch size N.
    fresh_signals : give ``signals`` a new buffer every step, so that rows handed out as
        ``info`` arrays keep their values (the vector envs); the single env copies them.

    Notes
    -----
    Public attributes (arrays, one row or entry per vehicle): ``state`` (N, STATE_SIZE) plant
    state; ``signals`` (N_SIGNALS, N) this step's signals; ``obs``, ``reward``,
    ``terminated``, ``step_count``; ``applied_current``; the route ``profile_index``,
    ``start_position``, ``speed``, ``gain`` over the guideway bank ``profiles`` (spacing
    ``spacing``); ``vehicle_params``, ``damper_params``, ``sub_table``. The kernel is bound to
    these arrays and to its named structures ``params``, ``plant_params``, ``env_state``
    (:class:`capsule_env.engine.kernels.EnvArgs`, made at the first step): they are read-only
    attributes. Change values in place; never resize them.
    """

    profiles = _bound("profiles", "(K, L) guideway bank (m) as the plant reads it (with "
                      "magnet_length_m, averaged over the magnet; the survey map and the "
                      "scaling read the true one)")  # fmt: skip
    offsets = _bound("offsets", "(K, L) the tube's spans added after the gain (m), or (0, 0) "
                     "(with magnet_length_m, averaged over the magnet)")  # fmt: skip
    damper_params = _bound("damper_params", "(N, N_DAMPER_PARAMS) each vehicle's packed damper")
    vehicle_params = _bound("vehicle_params", "(N, 4) each vehicle's packed masses, stiffnesses")
    speed = _bound(
        "speed",
        "(N,) each vehicle's speed (m/s); on a trip, the slope of the "
        "current interval's route (its chord)",
    )
    sub_table = _bound("sub_table", "(N, SUBSTEP_BINS) RK4 substeps per vehicle, current bin")
    block_constants = _bound("block_constants", "(N, ...) the block kernel's constants")
    state = _bound("state", "(N, STATE_SIZE) plant state, columns layout.STATE_NAMES")
    profile_index = _bound("profile_index", "(N,) int64 each vehicle's profile in the bank")
    start_position = _bound(
        "start_position",
        "(N,) each vehicle's start on its profile (m); on a "
        "trip, the intercept of the current interval's route",
    )
    gain = _bound("gain", "(N,) each vehicle's profile scale")
    step_count = _bound("step_count", "(N,) int64 steps since each vehicle's reset")
    noise_key = _bound("noise_key", "(N,) uint64 each episode's sensor-noise key")
    measured = _bound("measured", "(N_MEASUREMENTS, N) rows layout.MEASUREMENT_NAMES")
    delay_buf = _bound("delay_buf", "(N, delay + 1) ring buffer of current commands (A)")
    obs = _bound("obs", "(N, obs_dim) float32 observations")
    reward = _bound("reward", "(N,) this step's rewards")
    terminated = _bound("terminated", "(N,) bool: bump stop hit this step")
    plant_out = _bound("plant_out", "(N, N_PLANT_OUTPUTS) the plant kernel's outputs")

    def __init__(self, config: EnvConfig, num_envs: int = 1, fresh_signals: bool = True) -> None:
        self.config = config
        self.num_envs = n = check_num_envs(num_envs)
        config.check_memory(n)  # before anything large is allocated
        self.vehicle = config.vehicle_parameters
        self.plant = config.plant_damper
        self.inverse = config.inverse_damper
        self.i_max = config.max_current_a
        self.dt = config.dt_s
        self.max_steps = config.max_episode_steps
        self.obs_dim = len(config.observation_names)
        self.guideway = config.guideway_spec
        self.spacing = self.guideway.spacing_m
        self._profiles = self._build_bank()
        self._offsets = self._build_offsets()
        self._true_profiles, self._true_offsets = self._profiles, self._offsets
        if config.magnet_length_m is not None:  # the plant reads the guideway under the magnet
            self._profiles, self._offsets = (
                magnet_average(bank, self.spacing, config.magnet_length_m) if bank.size else bank
                for bank in (self._profiles, self._offsets)
            )
        self.rngs = vehicle_streams(None, n)
        self._nominal_vehicle = config.packed_vehicle
        self._fresh_signals = bool(fresh_signals)
        # the columns equal to the start elevation in a reset observation (the rest are 0)
        self._rest_columns = np.flatnonzero(rest_observation(config.observation, 1.0))
        filtered = self._profiles is not self._true_profiles
        self._params = EnvParams.from_config(config, self._build_survey_error(),
                                             self._true_profiles if filtered else None)  # fmt: skip
        self.envelope = config.envelope
        self._build_plant()
        self._build_state()
        self._build_outputs()
        self.kernel_mode = block_kernel_mode(
            self.plant.code, self.damper_params, self.envelope.damped or levitation_damped(
                self.vehicle_params)
        )  # fmt: skip
        self._kernel = BatchedKernel(
            ENV, self.plant.code, self.kernel_mode, n,
            command_path(self.params.current_mode, self.params.inverse_code),
            preview=config.preview_points > 0, envelope=self.envelope.flags,
            sense=sense_flags(self.params),
        )  # fmt: skip

    def _build_plant(self) -> None:
        """What each vehicle's plant is made of (vehicles may differ, after their resets)."""
        config, n = self.config, self.num_envs
        self._damper_params = np.ascontiguousarray(np.tile(self.plant.as_array(), (n, 1)))
        self._vehicle_params = np.ascontiguousarray(np.tile(self._nominal_vehicle, (n, 1)))
        self._speed = np.full(n, config.speed_m_s)
        # substeps per vehicle and current bin, and the block kernel's per-vehicle constants;
        # recomputed at each vehicle's reset when vehicles differ (config.randomizes_substeps)
        stiffest = self._stiffest(self.vehicle_params[:1].copy())
        self._sub_table = np.ascontiguousarray(
            np.tile(config.substep_tables(stiffest, self.speed[:1]), (n, 1))
        )
        self._block_constants = block_constants(
            self.plant.code, self.damper_params, self.dt, self.sub_table
        )
        self._plant_params = PlantParams(
            self.damper_params, self.vehicle_params, self.sub_table, self.block_constants,
            self.profiles, float(self.spacing), self.offsets,
        )  # fmt: skip

    def _build_state(self) -> None:
        """What evolves, per vehicle (one contiguous row per quantity for the SIMD loops)."""
        n = self.num_envs
        self._profile_index = np.zeros(n, dtype=np.int64)
        self._start_position = np.zeros(n)
        self._gain = np.ones(n)
        route = Route(self.profile_index, self.start_position, self.speed, self.gain)
        delay = self.config.effective_control_delay_steps
        self._env_state = state = EnvState.allocate(n, delay, route)
        self._vehicle_floats = state.vehicle_floats  # the block of its named groups
        self._state, self._step_count = state.plant, state.step_count
        self._noise_key, self._measured, self._delay_buf = (
            state.noise_key,
            state.measured,
            state.delay,
        )

    def _build_outputs(self) -> None:
        """What a step writes."""
        n = self.num_envs
        self._obs = np.zeros((n, self.obs_dim), dtype=np.float32)
        self._reward = np.zeros(n)
        self._terminated = np.zeros(n, dtype=bool)
        self._plant_out = np.zeros((n, N_PLANT_OUTPUTS))
        self._new_signals(np.zeros)
        self._action_buf = np.zeros(n)
        self._env_args: Any = None  # the kernel's EnvArgs, made at the first step (_run)

    @property
    def applied_current(self) -> np.ndarray:
        """(N,) the current command applied this step, after the control delay (A)."""
        return self._env_state.applied_current

    @property
    def params(self) -> EnvParams:
        """The options as the kernel reads them (read-only)."""
        return self._params

    @property
    def plant_params(self) -> PlantParams:
        """Each vehicle's plant (read-only; its arrays change in place at resets)."""
        return self._plant_params

    @property
    def env_state(self) -> EnvState:
        """What evolves, per vehicle (read-only; its arrays change in place)."""
        return self._env_state

    def _new_signals(self, allocate: Any) -> None:
        self._signals_buf = allocate((N_SIGNALS, self.num_envs + _SIGNAL_PADDING))
        self.signals = self._signals_buf[:, : self.num_envs]

    # ---------------------------------------------------------------- guideway bank
    def _build_offsets(self) -> np.ndarray:
        """The tube's spans on the bank's grid, one row per profile, added to the guideway
        after the route's gain (so that the random irregularity keeps its peak and the sag
        its size): the same spans on every profile with its own pylons' settlement, drawn
        from a stream of the guideway seed (:func:`capsule_env.guideway.spans.span_profile`);
        an empty (0, 0) array without spans."""
        span = self.config.envelope.span
        if span is None:
            return np.zeros((0, 0))
        bank = self.profiles
        seeds = np.random.SeedSequence([self.config.guideway_seed, 2]).generate_state(len(bank))
        length = (bank.shape[1] - 1) * self.spacing
        rows = [span_profile(length, self.spacing, span, int(s))[: bank.shape[1]] for s in seeds]
        return np.ascontiguousarray(np.stack(rows))

    def _build_bank(self) -> np.ndarray:
        cfg, gw = self.config, self.guideway
        if gw.kind == "random":
            length = 4.0 * cfg.window_m
            seeds = np.random.SeedSequence(cfg.guideway_seed).generate_state(cfg.guideway_bank_size)
            bank = [
                random_profile(
                    length,
                    gw.spacing_m,
                    int(s),
                    peak_m=None,
                    min_wavelength_m=gw.min_wavelength_m,
                    max_wavelength_m=gw.max_wavelength_m,
                    psd=gw.psd,
                )  # fmt: skip
                for s in seeds
            ]
            return np.ascontiguousarray(np.stack(bank))
        # a finite profile: the preview looks past its end, where the guideway continues
        duration = cfg.window_m / cfg.speed_m_s
        profile = make_profile(gw, duration, extend_m=self._preview_reach_m())
        return np.ascontiguousarray(profile[None, :])

    def _preview_reach_m(self) -> float:
        """How far past the end of a run the preview looks (m): 0 without preview, else the
        horizon at the highest speed plus 6 standard deviations of the position error."""
        cfg = self.config
        if cfg.preview_points == 0:
            return 0.0
        top = cfg.envelope.highest_speed_m_s(cfg.speed_range_mps[1])  # a trip's cruise
        return top * cfg.preview_horizon_s + 6.0 * cfg.position_error_m

    def _run_samples(self) -> int:
        """Samples of a bank profile that runs drive over (all but a deterministic profile's
        continuation for the preview, :meth:`_preview_reach_m`)."""
        cfg, gw = self.config, self.guideway
        if gw.kind == "random":
            return self.profiles.shape[1]
        duration = cfg.window_m / cfg.speed_m_s
        return n_samples(profile_length_m(gw, duration), gw.spacing_m)

    def _build_survey_error(self) -> np.ndarray:
        """The survey map's error on the bank's grid (:func:`survey_error`; a (1, 1) zero array
        without preview)."""
        if self.config.preview_points == 0:
            return np.zeros((1, 1))
        error = survey_error(self.config, self.profiles, self._run_samples())
        if self._offsets is not self._true_offsets:  # the survey map has the true spans
            error += self._true_offsets - self._offsets
        return error

    # ---------------------------------------------------------------- seeding / reset
    def seed(self, seed: int | list[int] | None) -> None:
        """Re-seed every vehicle's generator (:func:`vehicle_streams`)."""
        self.rngs = vehicle_streams(seed, self.num_envs)

    def detach_signals(self) -> None:
        """Give ``signals`` a buffer of its own, a copy of the current one: arrays handed out as
        ``info`` (rows of the buffer) keep their values when a masked :meth:`reset` outside
        :meth:`step` then writes the reset vehicles' rows."""
        old = self.signals
        self._new_signals(np.empty)
        self.signals[:] = old

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Start new episodes for the vehicles in ``mask`` (all if None)."""
        ids = range(self.num_envs) if mask is None else np.flatnonzero(mask)
        if mask is None:  # see _run: info arrays handed out stay intact
            self._new_signals(np.zeros)
        cfg, gw = self.config, self.guideway
        n_samples = self.profiles.shape[1]
        window_samples = int(math.ceil(cfg.window_m / self.spacing)) + 1
        lo, hi = cfg.speed_range_mps
        for n in ids:
            rng = self.rngs[n]
            k = int(rng.integers(self.profiles.shape[0]))
            u_offset, u_speed = rng.random(2)
            factors = np.ones(N_VEHICLE_PARAMS)  # four drawn: the levitation damping is not
            factors[:4] += cfg.vehicle_randomization * rng.uniform(-1.0, 1.0, 4)
            self.noise_key[n] = np.uint64(rng.integers(0, 2**63 - 1))
            self.speed[n] = lo + (hi - lo) * u_speed
            self.vehicle_params[n] = self._nominal_vehicle * factors
            self.profile_index[n] = k
            if gw.kind == "random":
                j0 = int(u_offset * (n_samples - window_samples))
                self.start_position[n] = j0 * self.spacing
                window = self._true_profiles[k, j0 : j0 + window_samples]  # the true guideway's
                self.gain[n] = 1.0 if gw.peak_m is None else gw.peak_m / np.max(np.abs(window))
                zg0 = self.gain[n] * self.profiles[k, j0]
                if self.offsets.size:  # the spans, after the gain
                    zg0 += self.offsets[k, j0]
            else:
                self.start_position[n] = 0.0
                self.gain[n] = 1.0
                zg0 = self.profiles[k, 0] + (self.offsets[k, 0] if self.offsets.size else 0.0)
            self.state[n] = 0.0
            self.state[n, BODY_DISP] = zg0  # static equilibrium over the start elevation
            self.state[n, BOGIE_DISP] = zg0
            self.step_count[n] = 0
            self._vehicle_floats[:, n] = 0.0
            self.measured[:, n] = 0.0
            self.delay_buf[n] = 0.0
            self.terminated[n] = False
            self.signals[:, n] = 0.0
            self.signals[SIG_BODY_DISP, n] = self.signals[SIG_BOGIE_DISP, n] = zg0
            self.signals[SIG_GUIDEWAY, n] = zg0
            self.obs[n] = 0.0
            self.obs[n, self._rest_columns] = zg0  # observations.rest_observation
            if cfg.payload_range is not None:  # a stream of the noise key, as the trip's
                u = np.random.default_rng([int(self.noise_key[n]), 2]).uniform(*cfg.payload_range)
                self.vehicle_params[n, MASS_BODY] *= 1.0 + u
            if self.envelope.coil is not None or self.envelope.trip is not None:
                self._reset_envelope(n)
            if cfg.preview_points:  # from the episode's noise key: the vehicle's own stream
                # gives the same episodes with or without preview
                draw = np.random.default_rng(int(self.noise_key[n])).standard_normal()
                self.env_state.position_error[n] = cfg.position_error_m * draw
                self._reset_preview(n)
        if cfg.randomizes_substeps:
            rows = np.fromiter(ids, dtype=np.int64)
            stiffest = self._stiffest(self.vehicle_params[rows].copy(), rows)
            self.sub_table[rows] = cfg.substep_tables(stiffest, self.speed[rows])
            self.block_constants[rows] = block_constants(
                self.plant.code, self.damper_params[rows], self.dt, self.sub_table[rows]
            )

    def _stiffest(self, vehicle_rows: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Packed vehicles as stiff as they get (the substep tables' rows): with EDS
        levitation, ``k_p`` at its limit ``K_inf`` (from the vehicles' stored limits, or the
        nominal one before any reset) and ``c_p`` at its largest, ``K_inf tau`` (0 km/h)."""
        coil = self.envelope.coil
        if coil is not None:
            if rows is None:
                vehicle_rows[:, STIFF_LEVITATION] /= self.envelope.reference_shape
            else:
                vehicle_rows[:, STIFF_LEVITATION] = self.env_state.envelope[ENV_LIMIT, rows]
            vehicle_rows[:, DAMP_LEVITATION] = (
                vehicle_rows[:, STIFF_LEVITATION] * coil.time_constant_s
            )
        return vehicle_rows

    def _reset_envelope(self, n: int) -> None:
        """Vehicle ``n``'s trip window (its start drawn from a stream of the episode's noise
        key: the vehicle's own stream draws what it draws without a trip) and EDS levitation
        (``k_p``, ``c_p`` at its speed now)."""
        env, envelope = self.env_state.envelope, self.envelope
        if envelope.coil is not None:
            env[ENV_LIMIT, n] = self.vehicle_params[n, STIFF_LEVITATION] / envelope.reference_shape
        if envelope.trip is not None:
            rng = np.random.default_rng([int(self.noise_key[n]), 1])
            own = None  # with lift_off='payload', the windows where it is at or above its own
            if envelope.payload_lift_off:
                own = envelope.vehicle_lift_off_m_s(self.vehicle_params[n, MASS_BODY],
                                                    self.vehicle_params[n, MASS_BOGIE],
                                                    env[ENV_LIMIT, n])  # fmt: skip
            t0 = draw_window_start_s(rng, self.config.episode_length_s, envelope.trip, own)
            env[ENV_T0, n] = t0
            env[ENV_START, n] = self.start_position[n]
            env[ENV_SPEED, n] = self.speed[n] = float(trip_speed_m_s(t0, envelope.trip))
            column = self.params.trip_column
            self.obs[n, column] = self.speed[n]
            self.obs[n, column + 1] = float(trip_acceleration_m_s2(t0, envelope.trip))
        if envelope.coil is not None:
            k_p, c_p = envelope.levitation_at(env[ENV_LIMIT, n], self.speed[n])
            self.vehicle_params[n, STIFF_LEVITATION] = k_p
            self.vehicle_params[n, DAMP_LEVITATION] = c_p

    def _reset_preview(self, n: int) -> None:
        """The first observation's preview columns (the kernel writes them at every step)."""
        from capsule_env.engine.env_kernel import reset_preview

        reset_preview(n, self.params, self.plant_params, self.env_state, self.obs)

    # ---------------------------------------------------------------- step
    def step(self, actions: np.ndarray) -> None:
        """Advance every vehicle by one control interval; results in ``obs``, ``reward``,
        ``terminated``, ``signals``. ``actions`` are (N,) in [-1, 1] (clipped here); NaN or
        infinite actions raise ``ValueError``."""
        a = np.asarray(actions)
        if a.dtype != np.float32 and a.dtype != np.float64:
            a = a.astype(np.float64)
        if a.size != self.num_envs:
            raise ValueError(f"actions must have {self.num_envs} entries, got shape {a.shape}")
        a = a.reshape(self.num_envs)
        if _clip_actions(a, self._action_buf):  # one compiled pass: clip and check
            raise ValueError(
                "action must be finite numbers in [-1, 1]; got NaN or inf at index "
                f"{np.flatnonzero(~np.isfinite(a)).tolist()}"
            )
        self._run()

    def step_one(self, action: float) -> None:
        """Fast path of :meth:`step` for a batch of one (a Python float action)."""
        if not math.isfinite(action):
            raise ValueError(f"action must be a finite number in [-1, 1]; got {action!r}")
        self._action_buf[0] = min(max(action, -1.0), 1.0)
        self._run()

    def _run(self) -> None:
        if self._fresh_signals:
            # A fresh signals buffer every step (the kernel writes every entry): the vector
            # envs hand its rows out as ``info`` arrays without copying them, so infos kept
            # from earlier steps keep their values (for any number of vehicles, one included).
            self._new_signals(np.empty)
        args = self._env_args
        if args is None:  # boxed once: a call then unboxes one object (kernels.EnvArgs)
            args = self._env_args = env_args(
                self.params, self.plant_params, self.env_state, self.obs, self.reward,
                self.terminated, self.plant_out,
            )  # fmt: skip
        self._kernel(self._action_buf, self._signals_buf, args)

    def __getstate__(self) -> dict[str, Any]:
        # A copy (copy.deepcopy: new arrays) makes its own EnvArgs at its first step.
        state = self.__dict__.copy()
        state["_env_args"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        # copy.deepcopy copies a view as an array of its own: make signals a view of the
        # copy's buffer again (the one its kernel writes)
        self.__dict__.update(state)
        self.signals = self._signals_buf[:, : self.num_envs]

    @property
    def truncated(self) -> np.ndarray:
        """Vehicles whose episode reached its time limit (``max_episode_steps``)."""
        return self.step_count >= self.max_steps


def survey_error(config: EnvConfig, profiles: np.ndarray, run_samples: int) -> np.ndarray:
    """The survey map's error on the grid of the bank ``profiles`` (K, L), one row per profile:
    a long-wavelength offset and a short-wavelength error, each a random FRA-shaped profile in
    its band (``config.SURVEY_OFFSET_BAND_M``, ``SURVEY_NOISE_BAND_M``) scaled to its standard
    deviation over the ``run_samples`` runs drive over (continued beyond, periodic), from a
    stream of the guideway seed (the map belongs to the guideway, not to a vehicle)."""
    cfg, spacing = config, config.guideway_spec.spacing_m
    run = run_samples
    length = (run - 1) * spacing
    extend_m = (profiles.shape[1] - run) * spacing
    seeds = np.random.SeedSequence([cfg.guideway_seed, 1]).generate_state(2 * profiles.shape[0])
    rows = []
    for k in range(profiles.shape[0]):
        error = np.zeros(profiles.shape[1])
        for seed, std, band in (
            (seeds[2 * k], cfg.survey_offset_m, SURVEY_OFFSET_BAND_M),
            (seeds[2 * k + 1], cfg.survey_noise_m, SURVEY_NOISE_BAND_M),
        ):
            if std > 0.0:
                part = random_profile(
                    length, spacing, int(seed), peak_m=None, min_wavelength_m=band[0],
                    max_wavelength_m=band[1], extend_m=extend_m,
                )[: error.size]  # fmt: skip
                error[: part.size] += std * part / np.std(part[:run])
        rows.append(error)
    return np.ascontiguousarray(np.stack(rows))
