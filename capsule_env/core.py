"""The batched simulation behind every environment flavour (no Gym import).

:class:`EnvConfig` holds and validates every environment option; :class:`CapsuleBatch` runs
``N`` vehicles with one compiled step kernel that maps actions to coil currents (through an
inverse model in force mode), applies the control delay, advances the plant
(:func:`capsule_env.dynamics._step_chunk`: the vectorised block kernel), measures the sensors with noise and computes the reward.
The single Gymnasium env is a batch of one; the native vector env and the SB3 ``VecEnv`` are
batches of ``N``: same kernel, same numbers.

Randomness is per vehicle: vehicle ``n`` owns a ``numpy.random.Generator`` (stream ``n`` of
``numpy.random.SeedSequence(seed)``, :func:`vehicle_streams`) used only at reset (guideway window, domain randomisation, the noise key), and sensor noise is a
counter-based hash of ``(noise key, step, channel)``. So a trajectory depends only on the seed
and the actions, never on the batch size, the batch position or threading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from numba import njit

from capsule_env._fastmath import FAST, fast_cos_2pi, fast_log
from capsule_env._threads import parallel_kernel, run_batched
from capsule_env._validation import (
    available_memory_bytes,
    check_choice,
    check_in_range,
    check_integer,
    check_nonnegative,
    check_positive,
    format_bytes,
)
from capsule_env.dampers import (
    BOUC_WEN,
    BiExponentialDamper,
    BoucWenDamper,
    DamperParams,
    TanhDamper,
    make_damper,
)
from capsule_env.dynamics import (
    BLOCK,
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    MAX_AUTO_SUBSTEPS,
    STATE_SIZE,
    SUBSTEP_BINS,
    _step_chunk,
    block_constants,
    block_kernel_mode,
    substep_tables,
)
from capsule_env.guideway import (
    GUIDEWAY_KINDS,
    GuidewayParams,
    fft_length,
    make_profile,
    random_profile,
)
from capsule_env.hysteresis import hysteresis_update
from capsule_env.inverse import (
    INVERSE_NAMES,
    affine_in_current,
    affine_in_current_fast,
    invert_affine,
    invert_affine_fast,
)
from capsule_env.vehicle import VehicleParams

__all__ = [
    "ACTION_MODES",
    "SETTINGS",
    "OBSERVATION_SETS",
    "PLANT_DAMPERS",
    "SENSOR_NAMES",
    "FULL_STATE_NAMES",
    "SIGNAL_NAMES",
    "SENSOR_NOISE_STD",
    "observation_bounds",
    "EnvConfig",
    "CapsuleBatch",
]

ACTION_MODES = ("force", "current")
SETTINGS = ("sim", "hils")
OBSERVATION_SETS = ("sensors", "full_state")
PLANT_DAMPERS = ("reference", "bouc_wen", "bi_exponential", "tanh", "passive")
#: The plant damper of the ``sim`` setting: the model the controller inverts (MODEL.md 9).
SIM_PLANT_FOR_INVERSE = {"bi_exponential": "bi_exponential", "csdc": "bouc_wen", "tanh": "tanh"}

SENSOR_NAMES = (
    "car_body_acceleration_m_s2",
    "bogie_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "last_current_command_a",
)
FULL_STATE_NAMES = (
    "car_body_displacement_m",
    "car_body_velocity_m_s",
    "bogie_displacement_m",
    "bogie_velocity_m_s",
    "guideway_elevation_m",
    "car_body_acceleration_m_s2",
    "bogie_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "coil_current_a",
)
#: Per-step physical signals and reward terms (``info`` keys), in kernel column order.
SIGNAL_NAMES = (
    "car_body_displacement_m",
    "bogie_displacement_m",
    "car_body_velocity_m_s",
    "bogie_velocity_m_s",
    "car_body_acceleration_m_s2",
    "bogie_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "damper_force_n",
    "desired_force_n",
    "current_command_a",
    "coil_current_a",
    "guideway_elevation_m",
    "cost_acceleration",
    "cost_stroke",
    "cost_energy",
    "cost_velocity",
)
N_SIGNALS = len(SIGNAL_NAMES)
#: Standard deviation of the measurement noise at ``sensor_noise=1`` [reconstructed: a few per
#: cent of each channel's typical level on the default guideway; the HILS default]. Entries:
#: car body and bogie acceleration (m/s^2), stroke (m), stroke rate (m/s), then for the
#: ``full_state`` set: car body displacement (m), car body velocity (m/s), bogie displacement
#: (m), bogie velocity (m/s), guideway elevation (m).
SENSOR_NOISE_STD = np.array([0.02, 0.1, 1e-4, 2e-3, 1e-4, 2e-3, 1e-4, 2e-3, 1e-4])
N_NOISE_CHANNELS = len(SENSOR_NOISE_STD)
_INVERSE_CODE = {"bi_exponential": 4, "tanh": 3, "csdc": BOUC_WEN}


@dataclass(frozen=True)
class EnvConfig:
    """Every option of ``CapsuleSuspension-v0`` (see the env docstring for the full story).

    Options left as ``None`` take the value of the chosen ``setting``: ``sim`` (the plant's
    damper is the model the controller inverts, ideal coil, no noise, no delay: the paper's
    simulation) or ``hils`` (the reference Spencer damper with its coil lag, sensor noise and a
    one-step control delay: the paper's HILS test emulated).
    """

    action_mode: str = "force"
    inverse_model: str = "bi_exponential"
    setting: str = "sim"
    damper: str | None = None
    coil_time_constant_s: float | None = None
    sensor_noise: float | None = None
    control_delay_steps: int | None = None
    guideway: str = "random"
    guideway_params: dict = field(default_factory=dict)
    speed_kmh: float = 810.0
    guideway_seed: int = 0
    guideway_bank_size: int = 16
    control_rate_hz: float = 200.0
    episode_length_s: float = 10.0
    substeps: int | None = None
    observation: str = "sensors"
    max_force_n: float = 8000.0
    reward_acceleration_weight: float = 1.0
    reward_stroke_weight: float = 0.1
    reward_energy_weight: float = 0.01
    reward_velocity_weight: float = 0.0
    acceleration_scale_m_s2: float = 0.5
    stroke_scale_m: float = 0.02
    velocity_scale_m_s: float = 0.05
    stroke_limit_m: float = 0.06
    bump_stop_penalty: float = 100.0
    vehicle_params: dict = field(default_factory=dict)
    damper_params: dict = field(default_factory=dict)
    inverse_params: dict = field(default_factory=dict)
    vehicle_randomization: float = 0.0
    speed_range_kmh: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        check_choice("action_mode", self.action_mode, ACTION_MODES)
        check_choice("inverse_model", self.inverse_model, INVERSE_NAMES)
        check_choice("setting", self.setting, SETTINGS)
        if self.damper is not None:
            check_choice("damper", self.damper, PLANT_DAMPERS)
        if self.coil_time_constant_s is not None:
            check_in_range("coil_time_constant_s", self.coil_time_constant_s, 0.0, 10.0)
        if self.sensor_noise is not None:
            check_in_range("sensor_noise", self.sensor_noise, 0.0, 1e3)
        if self.control_delay_steps is not None:
            check_integer("control_delay_steps", self.control_delay_steps, 0, 100)
        check_choice("guideway", self.guideway, GUIDEWAY_KINDS)
        check_in_range("speed_kmh", self.speed_kmh, 1e-3, 1e4)
        check_seed("guideway_seed", self.guideway_seed)
        check_integer("guideway_bank_size", self.guideway_bank_size, 1, 4096)
        check_in_range("control_rate_hz", self.control_rate_hz, 1.0, 10_000.0)
        check_positive("episode_length_s", self.episode_length_s)
        if self.episode_length_s * self.control_rate_hz < 0.5:
            raise ValueError(
                f"episode_length_s must be at least one control step (1 / control_rate_hz = "
                f"{1.0 / self.control_rate_hz:g} s), got {self.episode_length_s!r}"
            )
        if self.substeps is not None:
            check_integer("substeps", self.substeps, 1, 10_000)
        check_choice("observation", self.observation, OBSERVATION_SETS)
        check_positive("max_force_n", self.max_force_n)
        for name in (
            "reward_acceleration_weight",
            "reward_stroke_weight",
            "reward_energy_weight",
            "reward_velocity_weight",
            "bump_stop_penalty",
        ):
            check_nonnegative(name, getattr(self, name))
        check_positive("acceleration_scale_m_s2", self.acceleration_scale_m_s2)
        check_positive("stroke_scale_m", self.stroke_scale_m)
        check_positive("velocity_scale_m_s", self.velocity_scale_m_s)
        check_positive("stroke_limit_m", self.stroke_limit_m)
        check_in_range("vehicle_randomization", self.vehicle_randomization, 0.0, 0.9)
        if self.speed_range_kmh is not None:
            _check_speed_range(self.speed_range_kmh)
        for name in ("guideway_params", "vehicle_params", "damper_params", "inverse_params"):
            if not isinstance(getattr(self, name), dict):
                raise TypeError(f"{name} must be a dict of parameter overrides")
        for key, arg in (("speed_kmh", "speed_kmh"), ("kind", "guideway")):
            if key in self.guideway_params:
                raise ValueError(
                    f"guideway_params[{key!r}] is not accepted: the env argument {arg!r} sets it "
                    "(one source of truth for the guideway and the vehicle)"
                )
        # Build everything once so that bad overrides fail here, with the parameter named.
        _ = self.vehicle, self.plant_damper, self.inverse_damper, self.guideway_spec
        self._check_substeps()
        self.check_memory(1)

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvConfig:
        """Build from keyword arguments, rejecting unknown names with the accepted list."""
        known = {f.name for f in fields(cls)}
        for key in kwargs:
            if key not in known:
                raise ValueError(
                    f"unknown environment argument {key!r}; accepted: {', '.join(sorted(known))}"
                )
        if isinstance(kwargs.get("speed_range_kmh"), list):  # e.g. from JSON
            kwargs["speed_range_kmh"] = tuple(kwargs["speed_range_kmh"])
        return cls(**kwargs)

    # ---- derived values (properties, not stored copies) ----
    @property
    def hils(self) -> bool:
        return self.setting == "hils"

    @property
    def plant_damper_name(self) -> str:
        if self.damper is not None:
            return self.damper
        return "reference" if self.hils else SIM_PLANT_FOR_INVERSE[self.inverse_model]

    @property
    def vehicle(self) -> VehicleParams:
        return _build("vehicle_params", VehicleParams, self.vehicle_params)

    @property
    def plant_damper(self) -> DamperParams:
        name = self.plant_damper_name
        damper = make_damper(name, **self.damper_params)  # names a bad key or value itself
        tau = self.effective_coil_time_constant_s
        if name != "passive":
            damper = replace(damper, coil_time_constant_s=tau)
        return damper

    @property
    def effective_coil_time_constant_s(self) -> float:
        if self.coil_time_constant_s is not None:
            return float(self.coil_time_constant_s)
        return 1.0 / 190.0 if self.hils else 0.0

    @property
    def effective_sensor_noise(self) -> float:
        if self.sensor_noise is not None:
            return float(self.sensor_noise)
        return 1.0 if self.hils else 0.0

    @property
    def effective_control_delay_steps(self) -> int:
        if self.control_delay_steps is not None:
            return int(self.control_delay_steps)
        return 1 if self.hils else 0

    @property
    def inverse_damper(self) -> BiExponentialDamper | BoucWenDamper | TanhDamper:
        name = {"bi_exponential": "bi_exponential", "csdc": "bouc_wen", "tanh": "tanh"}[
            self.inverse_model
        ]
        return make_damper(name, **self.inverse_params)

    @property
    def guideway_spec(self) -> GuidewayParams:
        params = {"kind": self.guideway, "speed_kmh": self.speed_kmh, **self.guideway_params}
        return _build("guideway_params", GuidewayParams, params)

    @property
    def dt_s(self) -> float:
        return 1.0 / self.control_rate_hz

    @property
    def max_episode_steps(self) -> int:
        return int(round(self.episode_length_s * self.control_rate_hz))

    @property
    def max_current_a(self) -> float:
        damper = self.plant_damper
        return float(getattr(damper, "max_current_a", self.inverse_damper.max_current_a))

    def substep_tables(self, vehicle_params: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
        """Substeps per control step, per vehicle (rows of packed ``vehicle_params``, each at its
        own ``speed_mps``) and coil-current bin (:func:`capsule_env.dynamics.substep_tables`),
        or the fixed ``substeps``."""
        n = np.atleast_2d(vehicle_params).shape[0]
        if self.substeps is not None:
            return np.full((n, SUBSTEP_BINS), int(self.substeps), dtype=np.int64)
        rate = self.input_rate_rad_s(np.asarray(speed_mps, dtype=float))
        return substep_tables(self.plant_damper, self.dt_s, vehicle_params, rate)

    def input_rate_rad_s(self, speed_mps: np.ndarray | float) -> np.ndarray:
        """Highest angular frequency of the guideway input at ``speed_mps`` (rad/s)."""
        gw = self.guideway_spec
        speed = np.asarray(speed_mps, dtype=float)
        if gw.kind == "sine":
            return np.full_like(speed, 2.0 * math.pi * gw.frequency_hz)
        if gw.kind == "swept_sine":
            return np.full_like(speed, 2.0 * math.pi * max(gw.start_hz, gw.stop_hz))
        shortest = {
            "random": gw.min_wavelength_m,
            "bump": gw.bump_length_m,
            "step": max(2.0 * gw.ramp_length_m, 4.0 * gw.spacing_m),
        }[gw.kind]
        return 2.0 * math.pi * speed / shortest

    @property
    def speed_range_mps(self) -> tuple[float, float]:
        """Lowest and highest vehicle speed (m/s)."""
        lo, hi = self.speed_range_kmh or (self.speed_kmh, self.speed_kmh)
        return float(lo) / 3.6, float(hi) / 3.6

    @property
    def window_m(self) -> float:
        """Guideway one episode covers at the highest speed, plus a margin (m)."""
        return self.speed_range_mps[1] * self.episode_length_s + 4 * self.guideway_spec.spacing_m

    @property
    def bank_samples(self) -> int:
        """Samples per guideway profile of the bank (four windows for a random guideway, so
        that episodes start at random places; one window otherwise)."""
        gw = self.guideway_spec
        length = (4.0 if gw.kind == "random" else 1.0) * self.window_m
        return int(round(length / gw.spacing_m)) + 1 + 8

    def memory_bytes(self, num_envs: int = 1) -> int:
        """Memory a batch of ``num_envs`` vehicles needs at its peak (bytes): the guideway
        bank (its profiles, twice while they are stacked, and the FFT that makes one), and
        about 2 KiB per vehicle."""
        gw = self.guideway_spec
        profiles = self.guideway_bank_size if gw.kind == "random" else 1
        bank = 2 * profiles * self.bank_samples * 8
        if gw.kind == "random":
            n_fft = fft_length(4.0 * self.window_m, gw.spacing_m, gw.max_wavelength_m)
            bank += 40 * n_fft
        delay = (self.effective_control_delay_steps + 1) * 8
        return bank + num_envs * (2048 + delay)

    def check_memory(self, num_envs: int = 1) -> None:
        """Refuse (``ValueError`` naming the arguments to change) a batch that would need more
        than 80 % of the memory available now."""
        need, free = self.memory_bytes(num_envs), available_memory_bytes()
        if need > 0.8 * free:
            gw = self.guideway_spec
            raise ValueError(
                f"this configuration needs about {format_bytes(need)} of memory "
                f"(num_envs={num_envs}; a guideway bank of {self.guideway_bank_size} profiles "
                f"of {self.bank_samples} samples), more than 80 % of the {format_bytes(free)} "
                f"available: lower episode_length_s ({self.episode_length_s:g} s), "
                f"guideway_bank_size ({self.guideway_bank_size}) or num_envs, or raise "
                f"guideway_params['spacing_m'] ({gw.spacing_m:g} m)"
            )

    @property
    def randomizes_substeps(self) -> bool:
        """Whether vehicles differ in what sets their substeps (randomised parameters or
        speed): then each vehicle's table is computed at its reset."""
        lo, hi = self.speed_range_mps
        return self.substeps is None and (self.vehicle_randomization > 0.0 or hi > lo)

    def _check_substeps(self) -> None:
        """Refuse a configuration whose stiffest vehicle (the randomisation corner with the
        lightest masses, stiffest springs and highest speed) needs more than
        ``MAX_AUTO_SUBSTEPS`` substeps per control step."""
        if self.substeps is not None:
            return
        r = self.vehicle_randomization
        corner = self.vehicle.as_array() * np.array([1.0 - r, 1.0 - r, 1.0 + r, 1.0 + r])
        speed = max(self.speed_range_kmh or (self.speed_kmh,)) / 3.6
        need = int(self.substep_tables(corner, np.array([speed])).max())
        if need > MAX_AUTO_SUBSTEPS:
            raise ValueError(
                f"this configuration needs {need} RK4 substeps per control step (more than "
                f"{MAX_AUTO_SUBSTEPS}): the damper or the vehicle is too stiff for "
                f"control_rate_hz={self.control_rate_hz:g} (check vehicle_params masses and "
                "stiffnesses, damper_params, vehicle_randomization, speed_kmh); raise "
                "control_rate_hz, or set substeps explicitly"
            )

    @property
    def observation_names(self) -> tuple[str, ...]:
        return SENSOR_NAMES if self.observation == "sensors" else FULL_STATE_NAMES


def observation_bounds(config: EnvConfig, i_max: float) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)`` of the observation space: generous physical limits at which the sensors
    saturate (accelerations 100 m/s^2, stroke 2 x the bump stop, rates 10 m/s, displacements
    1 m, current [0, i_max])."""
    x_lim = 2.0 * config.stroke_limit_m
    if config.observation == "sensors":
        high = [100.0, 100.0, x_lim, 10.0, i_max]
        low = [-100.0, -100.0, -x_lim, -10.0, 0.0]
    else:
        high = [1.0, 10.0, 1.0, 10.0, 1.0, 100.0, 100.0, x_lim, 10.0, i_max]
        low = [-1.0, -10.0, -1.0, -10.0, -1.0, -100.0, -100.0, -x_lim, -10.0, 0.0]
    return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)


def _check_speed_range(value: Any) -> None:
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise TypeError(f"speed_range_kmh must be None or (low, high) in km/h, got {value!r}")
    lo = check_in_range("speed_range_kmh[0]", value[0], 1e-3, 1e4)
    hi = check_in_range("speed_range_kmh[1]", value[1], 1e-3, 1e4)
    if hi < lo:
        raise ValueError(f"speed_range_kmh must be (low, high) with high >= low, got {value!r}")


def check_seed(name: str, seed: Any) -> int:
    """``seed`` as an int, or a ``TypeError``/``ValueError`` naming ``name``: seeds are integers
    in ``[0, 2**63)`` (not bools, not floats)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"{name} must be an integer in [0, 2**63), got {seed!r}")
    if not 0 <= int(seed) < 2**63:
        raise ValueError(f"{name} must be an integer in [0, 2**63), got {seed!r}")
    return int(seed)


def check_num_envs(num_envs: Any) -> int:
    """``num_envs`` as an int >= 1, or a ``TypeError``/``ValueError`` saying so."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)):
        raise TypeError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    if num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    return int(num_envs)


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


def _build(name: str, cls: type, overrides: dict) -> Any:
    known = {f.name for f in fields(cls)}
    for key in overrides:
        if key not in known:
            raise ValueError(f"unknown key {key!r} in {name}; accepted: {', '.join(sorted(known))}")
    return cls(**overrides)


# ----------------------------------------------------------------------------- kernel

_MASK64 = np.uint64(0xFFFFFFFFFFFFFFFF)


@njit(**FAST, inline="always")
def _mix(x):
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


# Packed kernel arguments (fewer arguments = less dispatch overhead per call).
# cfg_f: scalars (float64)
(F_MAX_FORCE, F_I_MAX, F_DT, F_W_ACC, F_ACC_REF, F_W_STROKE, F_STROKE_REF, F_W_ENERGY,
 F_STROKE_LIMIT, F_PENALTY, F_SPACING, F_W_VEL, F_VEL_REF) = range(13)  # fmt: skip
# cfg_i: scalars (int64)
(I_ACTION_MODE, I_INV_CODE, I_PLANT_CODE, I_FULL_OBS, I_DELAY_WRITE, I_DELAY_READ, I_NOISE) = range(7)  # fmt: skip
# env_f: per-vehicle floats; env_i: per-vehicle ints
E_CSDC_Z, E_CSDC_X, E_START, E_SPEED, E_GAIN = range(5)
E_PROFILE, E_STEP = range(2)


@njit(**FAST, inline="always")
def _gaussian_pair(key, step, pair):
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


@njit(**FAST)
def _noise_lanes(keys, steps, pair, nb, out_a, out_b):
    """Sensor noise of channels ``2 pair`` and ``2 pair + 1`` for ``nb`` vehicles (a SIMD loop:
    the views start at the block's first vehicle)."""
    for j in range(nb):
        out_a[j], out_b[j] = _gaussian_pair(keys[j], steps[j], pair)


@njit(cache=True)
def _clip_actions(actions, out):
    """Clip ``actions`` to [-1, 1] into ``out``; True if any is NaN or infinite."""
    bad = False
    for k in range(actions.shape[0]):
        x = float(actions[k])
        bad |= not math.isfinite(x)
        out[k] = min(max(x, -1.0), 1.0)
    return bad


@njit(cache=True, error_model="numpy")
def _current_lanes(actions, i_max, i_command, f_desired):
    """Current mode: action in [-1, 1] -> command in [0, i_max] (no force request)."""
    for j in range(actions.shape[0]):
        i_command[j] = 0.5 * (actions[j] + 1.0) * i_max
        f_desired[j] = 0.0


@njit(cache=True, error_model="numpy")
def _inverse_lanes(inv_code, inv_p, actions, stroke, rate, max_force, i_max, i_command, f_desired):
    """Force mode through an algebraic inverse model, one block of vehicles (a SIMD loop).

    The parameters are read into a tuple first: ``p[6] if up else p[13]`` on an array is a
    conditional load, which LLVM does not vectorise (the loop ran 3x slower); on a tuple it is
    a select between two values."""
    p = (
        inv_p[0], inv_p[1], inv_p[2], inv_p[3], inv_p[4], inv_p[5], inv_p[6], inv_p[7],
        inv_p[8], inv_p[9], inv_p[10], inv_p[11], inv_p[12], inv_p[13], inv_p[14], inv_p[15],
        inv_p[16],
    )  # fmt: skip
    for j in range(actions.shape[0]):
        f_d = actions[j] * max_force
        f0, slope = affine_in_current_fast(inv_code, p, stroke[j], rate[j])
        i_command[j] = invert_affine_fast(f_d, f0, slope, rate[j], i_max)
        f_desired[j] = f_d


@njit(cache=True, error_model="numpy")
def _env_step_block(
    model, mode, lo, hi, actions, cfg_f, cfg_i, inv_p, noise_std, obs_bounds, env_f, env_i, noise_key,
    meas, delay_buf, dp, vp, state, profiles, sub_table, derived, obs, reward, terminated, sig, applied,
    plant_out,
):  # fmt: skip
    """Step vehicles ``lo .. hi - 1`` (at most BLOCK): commands, plant, sensors, reward."""
    i_max = cfg_f[F_I_MAX]
    inv_code = cfg_i[I_INV_CODE]
    # 1. action -> current command (through the inverse model in force mode), control delay.
    # Algebraic inverses run in a vectorised loop; CSDC (a hysteresis estimate) in a scalar one.
    delay_write, delay_read = cfg_i[I_DELAY_WRITE], cfg_i[I_DELAY_READ]
    f_desired, i_command = sig[9, lo:hi], sig[10, lo:hi]
    if cfg_i[I_ACTION_MODE] == 1:
        _current_lanes(actions[lo:hi], i_max, i_command, f_desired)
    elif inv_code == BOUC_WEN:
        for n in range(lo, hi):
            f_d = actions[n] * cfg_f[F_MAX_FORCE]
            x_m, v_m = meas[2, n], meas[3, n]
            z_est = hysteresis_update(
                env_f[E_CSDC_Z, n], x_m - env_f[E_CSDC_X, n], inv_p[8], inv_p[6], inv_p[7]
            )
            env_f[E_CSDC_Z, n] = z_est
            env_f[E_CSDC_X, n] = x_m
            f0, slope = affine_in_current(inv_code, inv_p, x_m, v_m, z_est)
            sig[9, n] = f_d
            sig[10, n] = invert_affine(f_d, f0, slope, v_m, i_max)
    else:
        _inverse_lanes(inv_code, inv_p, actions[lo:hi], meas[2, lo:hi], meas[3, lo:hi],
                       cfg_f[F_MAX_FORCE], i_max,
                       i_command, f_desired)  # fmt: skip
    for n in range(lo, hi):
        delay_buf[n, delay_write] = sig[10, n]  # ring buffer of delay + 1 commands
        applied[n] = delay_buf[n, delay_read]
        env_i[E_STEP, n] += 1
    # 2. plant (the vectorised block kernel, or the scalar one; see dynamics.block_kernel_mode)
    _step_chunk(
        mode, lo, hi, model, dp, vp, state, applied, profiles, env_i[E_PROFILE],
        cfg_f[F_SPACING], env_f[E_START], env_f[E_SPEED], env_f[E_GAIN], cfg_f[F_DT], sub_table,
        derived, plant_out,
    )  # fmt: skip
    # 3. sensor noise, one channel at a time across the block
    nb = hi - lo
    noise = np.empty((N_NOISE_CHANNELS + 1, hi - lo))  # rows that are read get written
    if not cfg_i[I_NOISE]:
        noise[:] = 0.0
    else:
        n_pairs = (N_NOISE_CHANNELS + 1) // 2 if cfg_i[I_FULL_OBS] else 2
        keys = noise_key[lo:hi]
        steps = env_i[E_STEP, lo:hi]
        for j in range(n_pairs):
            _noise_lanes(keys, steps, j, nb, noise[2 * j], noise[2 * j + 1])
    # 4. sensors, reward, signals: one loop over the block (one contiguous row of meas and sig
    # per channel; every parameter is read into a local first, so no load is conditional)
    s_acc_c, s_acc_b, s_stroke, s_rate = noise_std[0], noise_std[1], noise_std[2], noise_std[3]
    acc_ref, stroke_ref, vel_ref = cfg_f[F_ACC_REF], cfg_f[F_STROKE_REF], cfg_f[F_VEL_REF]
    w_acc, w_stroke, w_energy = cfg_f[F_W_ACC], cfg_f[F_W_STROKE], cfg_f[F_W_ENERGY]
    w_vel, stroke_limit, penalty = cfg_f[F_W_VEL], cfg_f[F_STROKE_LIMIT], cfg_f[F_PENALTY]
    has_current = i_max > 0.0
    for n in range(lo, hi):
        m = n - lo
        zc, vc = state[n, BODY_DISP], state[n, BODY_VEL]
        zb, vb = state[n, BOGIE_DISP], state[n, BOGIE_VEL]
        stroke = zc - zb
        rate = vc - vb
        force, acc_c, acc_b, zg = plant_out[n, 0], plant_out[n, 1], plant_out[n, 2], plant_out[n, 3]
        meas[0, n] = acc_c + s_acc_c * noise[0, m]
        meas[1, n] = acc_b + s_acc_b * noise[1, m]
        meas[2, n] = stroke + s_stroke * noise[2, m]
        meas[3, n] = rate + s_rate * noise[3, m]
        meas[4, n] = sig[10, n]
        # reward (x * x, not x ** 2: numba lowers the power to a slow libm call)
        acc_rel = acc_c / acc_ref
        stroke_rel = stroke / stroke_ref
        current_rel = applied[n] / i_max if has_current else 0.0
        c_acc = w_acc * acc_rel * acc_rel
        c_stroke = w_stroke * stroke_rel * stroke_rel
        c_energy = w_energy * current_rel * current_rel
        vel_rel = vc / vel_ref
        c_vel = w_vel * vel_rel * vel_rel
        hit = abs(stroke) > stroke_limit
        terminated[n] = hit
        reward[n] = -(c_acc + c_stroke + c_energy + c_vel) - (penalty if hit else 0.0)
        sig[0, n] = zc
        sig[1, n] = zb
        sig[2, n] = vc
        sig[3, n] = vb
        sig[4, n] = acc_c
        sig[5, n] = acc_b
        sig[6, n] = stroke
        sig[7, n] = rate
        sig[8, n] = force
        sig[11, n] = state[n, COIL_CURRENT]
        sig[12, n] = zg
        sig[13, n] = c_acc
        sig[14, n] = c_stroke
        sig[15, n] = c_energy
        sig[16, n] = c_vel
    # 5. observations (float32 rows; sensors saturate at the observation-space bounds)
    if cfg_i[I_FULL_OBS]:
        for n in range(lo, hi):
            m = n - lo
            obs[n, 0] = state[n, BODY_DISP] + noise_std[4] * noise[4, m]
            obs[n, 1] = state[n, BODY_VEL] + noise_std[5] * noise[5, m]
            obs[n, 2] = state[n, BOGIE_DISP] + noise_std[6] * noise[6, m]
            obs[n, 3] = state[n, BOGIE_VEL] + noise_std[7] * noise[7, m]
            obs[n, 4] = sig[12, n] + noise_std[8] * noise[8, m]
            for j in range(4):  # the same (noisy) measurements the inverse model uses
                obs[n, 5 + j] = meas[j, n]
            obs[n, 9] = state[n, COIL_CURRENT]
    else:
        for n in range(lo, hi):
            for j in range(5):
                obs[n, j] = meas[j, n]
    for n in range(lo, hi):
        for j in range(obs.shape[1]):
            obs[n, j] = min(max(obs[n, j], obs_bounds[0, j]), obs_bounds[1, j])


def _make_env_kernels(model: int, mode: int) -> tuple[Any, Any]:
    """``(serial, parallel)`` env kernels for one plant model and kernel mode (closure
    constants, so each compiles separately and only when used). ``serial(lo, hi, ...)`` steps
    vehicles ``lo .. hi-1``; ``parallel(n, ...)`` runs it on chunks of ``[0, n)`` on all cores
    (:mod:`capsule_env._threads`)."""

    @njit(cache=True)
    def serial(
        lo, hi, actions, cfg_f, cfg_i, inv_p, noise_std, obs_bounds, env_f, env_i, noise_key,
        meas, delay_buf, dp, vp, state, profiles, sub_table, derived, obs, reward, terminated,
        sig, applied, plant_out,
    ):  # fmt: skip
        for b in range(lo, hi, BLOCK):
            _env_step_block(
                model, mode, b, min(hi, b + BLOCK), actions, cfg_f, cfg_i, inv_p, noise_std,
                obs_bounds, env_f, env_i, noise_key, meas, delay_buf, dp, vp, state, profiles,
                sub_table, derived, obs, reward, terminated, sig, applied, plant_out,
            )  # fmt: skip

    return serial, parallel_kernel(serial)


_ENV_KERNELS: dict[tuple[int, int], tuple[Any, Any]] = {}


def env_kernels(model: int, mode: int) -> tuple[Any, Any]:
    """``(serial, parallel)`` env kernels for a plant model and kernel mode (memoised)."""
    key = (int(model), int(mode))
    if key not in _ENV_KERNELS:
        _ENV_KERNELS[key] = _make_env_kernels(*key)
    return _ENV_KERNELS[key]


class CapsuleBatch:
    """``N`` capsule vehicles stepped together by one compiled kernel.

    Parameters
    ----------
    config : the environment options.
    num_envs : batch size N.
    fresh_signals : give ``signals`` a new buffer every step, so that rows handed out as
        ``info`` arrays keep their values (the vector envs); the single env copies them.
    """

    def __init__(self, config: EnvConfig, num_envs: int = 1, fresh_signals: bool = True) -> None:
        self.config = config
        self.num_envs = n = check_num_envs(num_envs)
        self.vehicle = config.vehicle
        self.plant = config.plant_damper
        self.inverse = config.inverse_damper
        self.i_max = config.max_current_a
        self.dt = config.dt_s
        self.max_steps = config.max_episode_steps
        self.full_obs = config.observation == "full_state"
        self.obs_dim = len(config.observation_names)
        gw = config.guideway_spec
        self.guideway = gw
        config.check_memory(n)  # before anything large is allocated
        self._window_m = config.window_m
        self.profiles = self._build_bank()
        self.spacing = gw.spacing_m
        self.max_steps = config.max_episode_steps
        # per-vehicle state (packed arrays; the named attributes are views into them)
        self.state = np.zeros((n, STATE_SIZE))
        self.damper_params = np.ascontiguousarray(np.tile(self.plant.as_array(), (n, 1)))
        self.vehicle_params = np.ascontiguousarray(np.tile(self.vehicle.as_array(), (n, 1)))
        # one row per quantity, so that each is contiguous for the vectorised kernel
        self.env_f = np.zeros((5, n))
        self.env_i = np.zeros((2, n), dtype=np.int64)
        self.csdc_z = self.env_f[E_CSDC_Z]
        self.csdc_x = self.env_f[E_CSDC_X]
        self.start_position = self.env_f[E_START]
        self.speed = self.env_f[E_SPEED]
        self.gain = self.env_f[E_GAIN]
        self.profile_index = self.env_i[E_PROFILE]
        self.step_count = self.env_i[E_STEP]
        self.speed[:] = config.speed_kmh / 3.6
        self.gain[:] = 1.0
        self.noise_key = np.zeros(n, dtype=np.uint64)
        self.measured = np.zeros((5, n))  # one row per channel
        self.delay_buf = np.zeros((n, config.effective_control_delay_steps + 1))
        self.obs = np.zeros((n, self.obs_dim), dtype=np.float32)
        self.reward = np.zeros(n)
        self.terminated = np.zeros(n, dtype=bool)
        # One row per signal (the info arrays are rows). The rows are padded by 8 values: rows
        # a multiple of 4 KiB apart would all map to the same L1 cache set.
        self._signals_buf = np.zeros((N_SIGNALS, n + 8))
        self.signals = self._signals_buf[:, :n]
        self.applied_current = np.zeros(n)
        self.plant_out = np.zeros((n, 4))
        self.noise_std = SENSOR_NOISE_STD * config.effective_sensor_noise
        self.obs_bounds = np.array(observation_bounds(config, self.i_max))
        self.rngs = vehicle_streams(None, n)
        self._inv_params = self.inverse.as_array()
        self.cfg_f = np.array(
            [
                config.max_force_n, self.i_max, self.dt, config.reward_acceleration_weight,
                config.acceleration_scale_m_s2, config.reward_stroke_weight,
                config.stroke_scale_m, config.reward_energy_weight, config.stroke_limit_m,
                config.bump_stop_penalty, gw.spacing_m, config.reward_velocity_weight,
                config.velocity_scale_m_s,
            ]
        )  # fmt: skip
        self.cfg_i = np.array(
            [
                0 if config.action_mode == "force" else 1,
                _INVERSE_CODE[config.inverse_model],
                self.plant.code,
                int(self.full_obs),
                0,
                0,
                int(np.any(self.noise_std > 0.0)),
            ],
            dtype=np.int64,
        )
        self.kernel_mode = block_kernel_mode(self.plant.code, self.damper_params)
        # substeps per vehicle and current bin, and the block kernel's per-vehicle constants;
        # recomputed at each vehicle's reset when vehicles differ (config.randomizes_substeps)
        self.sub_table = np.ascontiguousarray(
            np.tile(config.substep_tables(self.vehicle_params[:1], self.speed[:1]), (n, 1))
        )
        self.block_constants = block_constants(
            self.plant.code, self.damper_params, self.dt, self.sub_table
        )
        self._kernels = env_kernels(self.plant.code, self.kernel_mode)
        self._fresh_signals = bool(fresh_signals)
        self._nominal_vehicle = self.vehicle.as_array()
        self._action_buf = np.zeros(n)
        self._delay_pos = 0

    # ---------------------------------------------------------------- guideway bank
    def _build_bank(self) -> np.ndarray:
        cfg, gw = self.config, self.guideway
        if gw.kind == "random":
            length = 4.0 * self._window_m
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
        duration = self._window_m / (cfg.speed_kmh / 3.6)
        return np.ascontiguousarray(make_profile(gw, duration)[None, :])

    # ---------------------------------------------------------------- seeding / reset
    def seed(self, seed: int | list[int] | None) -> None:
        """Re-seed every vehicle's generator (:func:`vehicle_streams`)."""
        self.rngs = vehicle_streams(seed, self.num_envs)

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Start new episodes for the vehicles in ``mask`` (all if None)."""
        ids = range(self.num_envs) if mask is None else np.flatnonzero(mask)
        if mask is None:  # see _run: info arrays handed out stay intact
            self._signals_buf = np.zeros((N_SIGNALS, self.num_envs + 8))
            self.signals = self._signals_buf[:, : self.num_envs]
        cfg, gw = self.config, self.guideway
        n_samples = self.profiles.shape[1]
        window_samples = int(math.ceil(self._window_m / self.spacing)) + 1
        for n in ids:
            rng = self.rngs[n]
            k = int(rng.integers(self.profiles.shape[0]))
            u_offset, u_speed = rng.random(2)
            factors = 1.0 + cfg.vehicle_randomization * rng.uniform(-1.0, 1.0, 4)
            self.noise_key[n] = np.uint64(rng.integers(0, 2**63 - 1))
            lo, hi = cfg.speed_range_mps
            self.speed[n] = lo + (hi - lo) * u_speed
            self.vehicle_params[n] = self._nominal_vehicle * factors
            self.profile_index[n] = k
            if gw.kind == "random":
                j0 = int(u_offset * (n_samples - window_samples))
                self.start_position[n] = j0 * self.spacing
                window = self.profiles[k, j0 : j0 + window_samples]
                self.gain[n] = 1.0 if gw.peak_m is None else gw.peak_m / np.max(np.abs(window))
                zg0 = self.gain[n] * self.profiles[k, j0]
            else:
                self.start_position[n] = 0.0
                self.gain[n] = 1.0
                zg0 = self.profiles[k, 0]
            self.state[n] = 0.0
            self.state[n, BODY_DISP] = zg0  # static equilibrium over the start elevation
            self.state[n, BOGIE_DISP] = zg0
            self.step_count[n] = 0
            self.csdc_z[n] = 0.0
            self.csdc_x[n] = 0.0
            self.measured[:, n] = 0.0
            self.delay_buf[n] = 0.0
            self.terminated[n] = False
            self.signals[:, n] = 0.0
            self.signals[0, n] = self.signals[1, n] = self.signals[12, n] = zg0
            if self.full_obs:
                self.obs[n] = 0.0
                self.obs[n, 0] = self.obs[n, 2] = self.obs[n, 4] = zg0
            else:
                self.obs[n] = 0.0
        if cfg.randomizes_substeps:
            rows = np.fromiter(ids, dtype=np.int64)
            self.sub_table[rows] = cfg.substep_tables(self.vehicle_params[rows], self.speed[rows])
            self.block_constants[rows] = block_constants(
                self.plant.code, self.damper_params[rows], self.dt, self.sub_table[rows]
            )

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
            self._signals_buf = np.empty((N_SIGNALS, self.num_envs + 8))
            self.signals = self._signals_buf[:, : self.num_envs]
        # ring buffer of delay + 1 commands: write this step's, apply the oldest
        self._delay_pos += 1
        n_buf = self.delay_buf.shape[1]
        self.cfg_i[I_DELAY_WRITE] = self._delay_pos % n_buf
        self.cfg_i[I_DELAY_READ] = (self._delay_pos + 1) % n_buf
        run_batched(
            *self._kernels, self.num_envs, self._action_buf, self.cfg_f, self.cfg_i, self._inv_params, self.noise_std,
            self.obs_bounds, self.env_f, self.env_i, self.noise_key, self.measured,
            self.delay_buf, self.damper_params, self.vehicle_params, self.state, self.profiles,
            self.sub_table, self.block_constants, self.obs, self.reward, self.terminated,
            self._signals_buf,
            self.applied_current, self.plant_out,
        )  # fmt: skip

    @property
    def truncated(self) -> np.ndarray:
        """Vehicles whose episode reached its time limit (``max_episode_steps``)."""
        return self.step_count >= self.max_steps
