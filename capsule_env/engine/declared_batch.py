"""``N`` vehicles of any declared form, stepped by the declared plant
(:mod:`capsule_env.plant.declared`): the episodes, the commands, the reward and the
observations of :class:`capsule_env.envs.declared_vehicle.DeclaredVehicleEnv` (no Gym import).

The episode is drawn as ``CapsuleBatch`` draws it (the same stream per vehicle, the same draws
in the same order: a profile of the bank, a start along it, the speed), so a vehicle declared
with the quarter-car's form meets the guideway the quarter-car env meets for the same seed. The
vehicle starts at rest in static equilibrium over its contacts' first elevations (``K q = K_g
z_g``: every body at the guideway's elevation for one contact).

Every step: the commands (current mode, or the inverse model on each slot's measured stroke and
stroke rate), the control delay, one call of the compiled plant for the whole batch (on all
cores from 64 vehicles), the sensors (each slot's :data:`SLOT_CHANNELS` with noise where the
options ask). Each vehicle's numbers do not depend on its batch.

The reward generalises the quarter-car's (``reward_velocity_weight`` and the reward filter are
not offered)::

    r = -( w_acc mean_p (a_p / a_ref)^2 + w_stroke mean_s (x_s / x_ref)^2
           + w_energy mean_s (i_s / i_max)^2 ) - penalty [any |x_s| > stroke_limit]

over the comfort points ``p`` and the damper slots ``s``: for one point and one slot it is the
quarter-car env's reward term for term.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from capsule_env._jit import specialised
from capsule_env.dampers.inverse import INVERSE_CODES, affine_in_current, invert_affine
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.batch import vehicle_streams
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.declared_preview import DeclaredPreview, preview_reach_m
from capsule_env.engine.declared_sensing import (
    OBSERVATION_CODES,
    SIGNAL_NAMES,
    observe_set,
    reward_terms,
    sense,
    sense_scored,
    signal_arrays,
)
from capsule_env.engine.kernels import PARALLEL_THRESHOLD
from capsule_env.engine.observations import NOISE_CHANNELS, declared_bounds
from capsule_env.guideway import make_profile, random_profile
from capsule_env.plant.declared_build import (
    declared_output_names,
    declared_plant,
    declared_state_names,
)
from capsule_env.plant.declared_lanes import lanes_step, lanes_step_parallel, plant_form
from capsule_env.plant.params import Route
from capsule_env.plant.substeps import MAX_AUTO_SUBSTEPS
from capsule_env.vehicles.declaration import SPRING, VehicleModel
from capsule_env.vehicles.linear import absolute_model, mechanical_matrices

_NOISE_STD = {c.name: c.std for c in NOISE_CHANNELS}

__all__ = ["DeclaredBatch", "DECLARED_OBSERVATIONS", "SLOT_CHANNELS", "SLOT_NOISE_STD"]

#: What each damper slot's sensors read: its stroke (LVDT), stroke rate, the accelerations of
#: its upper and lower ends (the car body's accelerometer over the bogie, the bogie's), and the
#: gap of the spring from its lower end to the guideway (the levitation gap sensor; 0 where the
#: lower end stands on none).
SLOT_CHANNELS = ("stroke_m", "stroke_rate_m_s", "upper_acceleration_m_s2",
                 "lower_acceleration_m_s2", "gap_m")  # fmt: skip
N_SLOT_CHANNELS = len(SLOT_CHANNELS)
#: The measured stroke's and stroke rate's positions among a slot's channels.
_STROKE, _RATE = SLOT_CHANNELS.index("stroke_m"), SLOT_CHANNELS.index("stroke_rate_m_s")
#: Their noise at ``sensor_noise=1``: the quarter-car's channels of the same sensors
#: (:data:`capsule_env.engine.observations.NOISE_CHANNELS`) [reconstructed].
SLOT_NOISE_STD = np.array([
    _NOISE_STD[name] for name in ("stroke_m", "stroke_rate_m_s", "car_body_acceleration_m_s2",
                                  "bogie_acceleration_m_s2", "levitation_gap_m")
])  # fmt: skip

#: Observation sets of a declared vehicle: ``full_state`` (every coordinate and rate, each
#: slot's stroke and stroke rate, each comfort point's acceleration and each contact's
#: elevation; true values), ``sensors`` (each slot's stroke, stroke rate and end accelerations,
#: with the sensor noise of the options, and its last current command) and ``measured``
#: (``sensors`` plus each slot's gap and the on-board estimates of its two ends' absolute
#: velocities from their accelerometers: the quarter-car's ``measured`` per bogie).
DECLARED_OBSERVATIONS = ("full_state", "sensors", "measured")
#: Columns per slot of ``measured``, after the :data:`SLOT_CHANNELS`.
ESTIMATE_CHANNELS = ("upper_velocity_estimate_m_s", "lower_velocity_estimate_m_s")
#: The reward's cost terms, by name (:meth:`DeclaredBatch.reward`).
COST_NAMES = ("cost_acceleration", "cost_stroke", "cost_energy")


class DeclaredBatch:
    """``N`` vehicles of ``model`` with the common options of ``config`` (an
    :class:`EnvConfig` whose vehicle options are ignored: ``model`` and ``params`` are the
    vehicle)."""

    def __init__(self, config: EnvConfig, model: VehicleModel, params: Any, num_envs: int = 1):
        self.config, self.model, self.num_envs = config, model, int(num_envs)
        self.params = params
        self.values = model.values(params)
        self.damper = config.plant_damper
        self.inverse = config.inverse_damper
        self.i_max, self.dt = config.max_current_a, config.dt_s
        self.max_steps = config.max_episode_steps
        self.guideway = config.guideway_spec
        self.n_slots, self.n_coords = len(model.dampers), len(model.coordinates)
        offsets_m = model.contact_offsets_m(params)  # the contacts' stretch of guideway
        span_m = float(np.ptp(np.r_[offsets_m, 0.0])) + preview_reach_m(config)
        self.profiles = _bank(config, span_m)
        speed = config.speed_m_s
        rate = float(np.asarray(config.input_rate_rad_s(speed)).reshape(-1)[0])
        self.plant = declared_plant(model, [self.values] * self.num_envs, self.damper,
                                    self.profiles, self.guideway.spacing_m, self.dt,
                                    substeps=config.substeps, input_rate_rad_s=rate)  # fmt: skip
        need = int(self.plant.substeps.max())
        if need > MAX_AUTO_SUBSTEPS:
            raise ValueError(f"vehicle {model.name!r} needs {need} RK4 substeps per control step "
                             f"(more than {MAX_AUTO_SUBSTEPS}): too stiff for control_rate_hz="
                             f"{config.control_rate_hz:g}; raise it or set substeps")  # fmt: skip
        self.state_names = declared_state_names(model)
        self.output_names = declared_output_names(model)
        n = self.num_envs
        self.state = np.zeros((n, len(self.state_names)))
        self.out = np.zeros((n, len(self.output_names)))
        self.command = np.zeros((n, self.n_slots))
        self.route = Route(np.zeros(n, np.int64), np.zeros(n), np.full(n, speed), np.ones(n))
        self.requested = np.zeros((n, self.n_slots))
        self.delay_steps = config.effective_control_delay_steps
        self.delay = np.zeros((n, max(self.delay_steps, 1), self.n_slots))
        self.noise_level = config.effective_sensor_noise
        self.measured = np.zeros((n, self.n_slots * N_SLOT_CHANNELS))
        self._noise_std = self.noise_level * np.tile(SLOT_NOISE_STD, self.n_slots)
        self.estimates = np.zeros((n, self.n_slots, 2))  # upper and lower velocity estimates
        self._estimator_state = np.zeros((n, self.n_slots, 2, 2))
        self._estimator = config.velocity_estimator_coefficients()
        self.noise_key = np.zeros(n, dtype=np.uint64)
        self.step_count = np.zeros(n, dtype=np.int64)
        self.rngs = vehicle_streams(None, n)
        self.preview = (None if not config.preview_points else
                        DeclaredPreview(config, self.profiles, tuple(c.name for c in model.contacts), n))  # fmt: skip
        self._geometry()
        self._width = len(self.observation_names())
        self._obs_low, self._obs_high = (b.astype(np.float32) for b in self.observation_bounds())

    def _geometry(self) -> None:
        """The rows the observations and the reward read, and the static equilibrium."""
        lin = absolute_model(self.model, self.params)
        self.stroke_rows = np.array([lin.stroke[s][0::2] for s in range(self.n_slots)])
        values, model = self.values, self.model
        self.comfort_rows = np.array([model.point_row(p, values) for p in model.comfort_points])
        ends = [(model.point_row(d.upper, values), model.point_row(d.lower, values))
                for d in model.dampers]  # fmt: skip
        self.end_rows = np.array([row for pair in ends for row in pair]).reshape(-1, self.n_coords)
        m, k, _ = mechanical_matrices(model, self.params)
        k_g = lin.e[1::2] * np.diag(m)[:, None]  # lin.e: K_g over the inertias
        self._equilibrium = np.linalg.solve(k, k_g)  # q at rest = this @ z_g
        self.gap_rows, self.gap_contacts = _gap_rows(model, values, self.n_slots, self.n_coords)
        # a contact behind the reference point reads the bank from its first sample on
        offsets = self.plant.contact_offsets_m
        self._lead_m = max(0.0, -float(offsets.min(initial=0.0)))
        length_m = self._lead_m + max(0.0, float(offsets.max(initial=0.0)))
        self._length_samples = int(math.ceil(length_m / self.guideway.spacing_m))

    # ------------------------------------------------------------------ episodes
    def seed(self, seed: Any) -> None:
        self.rngs = vehicle_streams(seed, self.num_envs)

    def reset(self, ids: Any = None) -> None:
        """New episodes for vehicles ``ids`` (an index, indices, or None: all), each drawn as
        the quarter-car env draws it (its draws, in its order)."""
        ids = range(self.num_envs) if ids is None else np.atleast_1d(ids)
        for n in ids:
            self._reset_one(int(n))

    def _reset_one(self, n: int) -> None:
        cfg, rng = self.config, self.rngs[n]
        k = int(rng.integers(self.profiles.shape[0]))
        u_offset, _ = rng.random(2)
        rng.uniform(-1.0, 1.0, 4)  # the quarter-car's vehicle randomisation draw (unused)
        self.noise_key[n] = np.uint64(rng.integers(0, 2**63 - 1))
        spacing = self.guideway.spacing_m
        window = int(math.ceil(cfg.window_m / spacing)) + 1
        self.route.profile[n] = k
        if self.guideway.kind == "random":
            j0 = int(u_offset * (self.profiles.shape[1] - window - self._length_samples))
            self.route.start_m[n] = j0 * spacing + self._lead_m
            seg = self.profiles[k, j0 : j0 + window + self._length_samples]  # every contact's
            peak = self.guideway.peak_m
            self.route.gain[n] = 1.0 if peak is None else peak / np.max(np.abs(seg))
        else:
            self.route.start_m[n], self.route.gain[n] = self._lead_m, 1.0
        self.state[n] = 0.0
        zg = self._contact_elevations(n, 0.0)
        self.state[n, : self.n_coords] = self._equilibrium @ zg
        self.command[n] = self.requested[n] = self.delay[n] = 0.0
        self.step_count[n] = 0
        self.out[n] = 0.0
        self.out[n, self.n_slots + self.n_coords :] = zg
        self.measured[n] = 0.0  # at rest: no stroke, no acceleration, no gap change
        self.estimates[n] = self._estimator_state[n] = 0.0
        if self.preview is not None:
            self.preview.reset(n, self.noise_key[n])

    def _contact_elevations(self, n: int, t: float) -> np.ndarray:
        pos = self.route.start_m[n] + self.route.speed_mps[n] * t + self.plant.contact_offsets_m[n]
        grid = np.arange(self.profiles.shape[1]) * self.guideway.spacing_m
        return self.route.gain[n] * np.interp(pos, grid, self.profiles[self.route.profile[n]])

    # ------------------------------------------------------------------ stepping
    def commands(self, actions: np.ndarray) -> np.ndarray:
        """Coil-current commands (A), (N, slots), for actions in [-1, 1]: directly (current
        mode) or through the inverse model on each slot's *measured* stroke and stroke rate
        (force mode: the action times ``max_force_n`` is the force asked for)."""
        if self.config.action_mode == "current":
            return 0.5 * (actions + 1.0) * self.i_max
        code = INVERSE_CODES[self.config.inverse_model]
        meas = self.measured.reshape(self.num_envs, self.n_slots, N_SLOT_CHANNELS)
        out = np.empty(actions.shape)
        _invert(code, self.inverse.as_array(), actions * self.config.max_force_n, meas,
                self.i_max, out)  # fmt: skip
        return out

    def step(self, actions: np.ndarray) -> dict[str, np.ndarray]:
        """Every vehicle by one control step: commands, the control delay, the plant, the
        sensors; returns the signals after it (:meth:`signals`, computed once)."""
        self._advance(actions)
        return dict(zip(SIGNAL_NAMES, sense(*self._sense_args()), strict=True))

    def step_scored(
        self, actions: np.ndarray
    ) -> tuple[dict, np.ndarray, np.ndarray, dict, np.ndarray]:
        """:meth:`step`, then :meth:`reward` and :meth:`observe` of its signals, the sensing in
        one compiled call (:func:`capsule_env.engine.declared_sensing.sense_scored`, the same
        numbers): ``(signals, reward, bump stop hit, cost terms, observations)``."""
        self._advance(actions)
        sig, terms, obs = sense_scored(*self._sense_args(), self._reward_parameters(),
                                       OBSERVATION_CODES[self.config.observation], self._width)  # fmt: skip
        reward, hit, *costs = terms
        return (dict(zip(SIGNAL_NAMES, sig, strict=True)), reward, hit,
                dict(zip(COST_NAMES, costs, strict=True)), self._with_preview(obs))  # fmt: skip

    def _advance(self, actions: np.ndarray) -> None:
        """Commands, the control delay, the plant (the compiled lanes kernel)."""
        self.requested[:] = self.commands(actions)
        delay = self.delay_steps
        if delay:  # the command from ``delay`` steps ago is applied
            self.command[:] = self.delay[:, 0]
            self.delay[:, :-1] = self.delay[:, 1:]
            self.delay[:, -1] = self.requested
        else:
            self.command[:] = self.requested
        code, form = self.damper.code, plant_form(self.plant)  # the same bits as declared_step
        if self.num_envs >= PARALLEL_THRESHOLD:
            lanes_step_parallel(code, form)(self.num_envs, self.plant, self.state, self.command,
                                            self.route, self.dt, self.out)  # fmt: skip
        else:
            lanes_step(code, form, 0, self.num_envs, self.plant, self.state, self.command,
                       self.route, self.dt, self.out)  # fmt: skip
        self.step_count += 1

    def _sense_args(self) -> tuple:
        """The arguments of :func:`~capsule_env.engine.declared_sensing.sense`: the signals'
        sources and rows, the noise, the measurements and the estimator."""
        noise = (self.noise_key, self.step_count, self._noise_std, self.noise_level > 0.0)
        return (self.state, self.out, self.requested, self._rows(), noise, self.measured,
                np.asarray(self._estimator, dtype=float), self._estimator_state, self.estimates)  # fmt: skip

    # ------------------------------------------------------------------ signals
    def positions_rates(self) -> tuple[np.ndarray, np.ndarray]:
        nc = self.n_coords
        return self.state[:, :nc], self.state[:, nc : 2 * nc]

    def signals(self) -> dict[str, np.ndarray]:
        """The physical signals now, by name (:data:`SIGNAL_NAMES`): (N, slots), (N, points) or
        (N, contacts), each a new array."""
        sig = signal_arrays(self.state, self.out, self.requested, self._rows(), self.n_slots,
                            self.n_coords)  # fmt: skip
        return dict(zip(SIGNAL_NAMES, sig, strict=True))

    def _rows(self) -> tuple[np.ndarray, ...]:
        return (self.stroke_rows, self.comfort_rows, self.end_rows, self.gap_rows,
                self.gap_contacts)  # fmt: skip

    def reward(self, sig: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, dict]:
        """``(reward (N,), bump stop hit (N,), cost terms by name)`` (module doc)."""
        reward, hit, *costs = reward_terms(sig["comfort_acceleration_m_s2"], sig["stroke_m"],
                                           sig["coil_current_a"], self._reward_parameters())  # fmt: skip
        return reward, hit, dict(zip(COST_NAMES, costs, strict=True))

    def _reward_parameters(self) -> tuple[float, ...]:
        cfg = self.config
        return tuple(float(x) for x in (
            cfg.acceleration_scale_m_s2, cfg.stroke_scale_m, self.i_max,
            cfg.reward_acceleration_weight, cfg.reward_stroke_weight, cfg.reward_energy_weight,
            cfg.stroke_limit_m, cfg.bump_stop_penalty))  # fmt: skip

    def observation_names(self) -> tuple[str, ...]:
        """The observation's columns: the set's, then the preview's (if any)."""
        preview = self.preview.names if self.preview is not None else ()
        return (*self._set_names(), *preview)

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` of each column, where the sensors saturate (observations are clipped
        to them): the quarter-car's column of the same quantity's bounds
        (:func:`capsule_env.engine.observations.declared_bounds`), the preview's +-1 m."""
        low, high = declared_bounds(self._set_names(), self.config.stroke_limit_m, self.i_max)
        if self.preview is not None:
            low, high = [*low, *self.preview.low], [*high, *self.preview.high]
        return np.array(low, dtype=float), np.array(high, dtype=float)

    def _set_names(self) -> tuple[str, ...]:
        m = self.model
        slots = [d.name for d in m.dampers]
        if self.config.observation == "sensors":
            return tuple(f"{s}_{part}" for s in slots for part in (*SLOT_CHANNELS[:4],
                         "last_current_command_a"))  # fmt: skip
        if self.config.observation == "measured":
            return tuple(f"{s}_{part}" for s in slots for part in (*SLOT_CHANNELS,
                         *ESTIMATE_CHANNELS, "last_current_command_a"))  # fmt: skip
        return (*m.state_names, *(f"{s}_stroke_m" for s in slots),
                *(f"{s}_stroke_rate_m_s" for s in slots),
                *(f"{p}_acceleration_m_s2" for p in m.comfort_points),
                *(f"{c.name}_elevation_m" for c in m.contacts))  # fmt: skip

    def observe(self, sig: dict[str, np.ndarray]) -> np.ndarray:
        """The observations (N, d), float32 (``sensors``: the measurements, noisy where the
        options say; ``full_state``: the true values), the preview's columns after them."""
        arrays = tuple(sig[name] for name in SIGNAL_NAMES)
        obs = observe_set(OBSERVATION_CODES[self.config.observation], self._width, self.state,
                          arrays, self.measured, self.estimates, self.requested)  # fmt: skip
        return self._with_preview(obs)

    def _with_preview(self, obs: np.ndarray) -> np.ndarray:
        """``obs`` with the preview's columns (if any) in its last ones, clipped to the
        observation bounds (:meth:`observation_bounds`: the sensors saturate)."""
        if self.preview is not None:
            cols = self.preview.columns(self.profiles, self.route, self.state[:, -1],
                                        self.plant.contact_offsets_m)  # fmt: skip
            obs[:, obs.shape[1] - cols.shape[1] :] = cols
        return np.clip(obs, self._obs_low, self._obs_high, out=obs)


def _gap_rows(model: VehicleModel, values: dict, n_slots: int, n_coords: int):
    """Each slot's gap: the deflection ``J q - g z_g`` of a spring from its lower point to a
    contact (zero rows where there is none)."""
    contacts = {c.name for c in model.contacts}
    rows, ground = np.zeros((n_slots, n_coords)), np.zeros((n_slots, len(contacts)))
    for s, slot in enumerate(model.dampers):
        for e in model.elements:
            if e.kind == SPRING and e.upper == slot.lower and e.lower in contacts:
                rows[s], ground[s] = model.element_rows(e, values)
                break
    return rows, ground


@specialised("code")
def _invert(code, p, force_n, meas, i_max, out):
    """The inverse model's current for each requested force (closed form, semi-active), on each
    slot's measured stroke and stroke rate (``meas[:, s, _STROKE]``, ``meas[:, s, _RATE]``),
    slot by slot through columns of their own (the vehicles innermost and contiguous: a loop
    that vectorises, each vehicle's numbers as alone)."""
    c = code

    def impl(code, p, force_n, meas, i_max, out):
        n_envs = out.shape[0]
        f, x, v, col = np.empty(n_envs), np.empty(n_envs), np.empty(n_envs), np.empty(n_envs)
        for s in range(out.shape[1]):
            for n in range(n_envs):
                f[n], x[n], v[n] = force_n[n, s], meas[n, s, _STROKE], meas[n, s, _RATE]
            for n in range(n_envs):
                f0, slope = affine_in_current(c, p, x[n], v[n], 0.0)
                col[n] = invert_affine(f[n], f0, slope, v[n], i_max)
            for n in range(n_envs):
                out[n, s] = col[n]

    return impl


def _bank(cfg: EnvConfig, span_m: float = 0.0) -> np.ndarray:
    """The guideway bank: ``CapsuleBatch``'s (the same seeds, lengths and spectra); a
    deterministic profile continued ``span_m`` further (the stretch between the rearmost and
    the foremost contact, which the foremost meets beyond the reference point's window)."""
    gw = cfg.guideway_spec
    if gw.kind == "random":
        seeds = np.random.SeedSequence(cfg.guideway_seed).generate_state(cfg.guideway_bank_size)
        bank = [random_profile(4.0 * cfg.window_m, gw.spacing_m, int(s), peak_m=None,
                               min_wavelength_m=gw.min_wavelength_m,
                               max_wavelength_m=gw.max_wavelength_m, psd=gw.psd)
                for s in seeds]  # fmt: skip
        return np.ascontiguousarray(np.stack(bank))
    profile = make_profile(gw, cfg.window_m / cfg.speed_m_s, extend_m=span_m)
    return np.ascontiguousarray(profile[None, :])


def inverse_is_algebraic(name: str) -> bool:
    """Whether the inverse model ``name`` inverts in closed form (force mode needs it here)."""
    return model_of_code(INVERSE_CODES[name]).affine is not None
