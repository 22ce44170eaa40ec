"""Every option of ``CapsuleSuspension-v0``, checked once, and what follows from them.

:class:`EnvConfig` is a frozen dataclass of the env's arguments; it validates each (a
``TypeError`` or ``ValueError`` naming the argument and the accepted range), refuses a
configuration too stiff to integrate or too large for the machine's memory before anything is
allocated, and derives the rest as properties (the plant's damper, the inverted model, the
guideway, the substep tables, the episode length). No Gym import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from capsule_env.common.units import kmh_to_m_s
from capsule_env.common.validation import (
    UnexpectedArgumentError,
    available_memory_bytes,
    check_choice,
    check_in_range,
    check_integer,
    check_nonnegative,
    check_positive,
    format_bytes,
    unexpected_argument,
)
from capsule_env.dampers import DAMPER_NAMES, make_damper
from capsule_env.dampers.base import DamperParamsBase
from capsule_env.dampers.inverse import INVERSE_CODES as _INVERSE_CODES
from capsule_env.dampers.inverse import INVERSE_MODELS, inverse_models
from capsule_env.dampers.registry import MODELS
from capsule_env.engine import observations as _observations
from capsule_env.engine.layout import MAX_REWARD_FILTER_SECTIONS, STIFF_LEVITATION
from capsule_env.envelope.options import Envelope, build_envelope
from capsule_env.guideway import GUIDEWAY_KINDS, GuidewayParams, fft_length
from capsule_env.metrics import wk_filter_sos
from capsule_env.plant.substeps import MAX_AUTO_SUBSTEPS, SUBSTEP_BINS, substep_tables
from capsule_env.vehicles import VehicleModel, VehicleParams, model_named
from capsule_env.vehicles.compiled import check_compiled

__all__ = [
    "ACTION_MODES",
    "SETTINGS",
    "OBSERVATION_SETS",
    "PLANT_DAMPERS",
    "SENSOR_NAMES",
    "FULL_STATE_NAMES",
    "MEASURED_NAMES",
    "OBSERVATION_NAMES",
    "SENSOR_NOISE_STD",
    "INVERSE_CODES",
    "EnvConfig",
    "UnexpectedArgumentError",
    "observation_bounds",
    "check_seed",
    "check_num_envs",
]

ACTION_MODES = ("force", "current")
SETTINGS = ("sim", "hils")
OBSERVATION_SETS = _observations.OBSERVATION_SETS
#: The built-in plant dampers (``capsule_env.dampers.DAMPER_NAMES``; a registered model is
#: accepted too: ``capsule_env.dampers.registry.MODELS``).
PLANT_DAMPERS = DAMPER_NAMES
#: The plant damper of the ``sim`` setting: the model the controller inverts
#: (docs/model.md, section 8; ``capsule_env.dampers.inverse.INVERSE_MODELS``).
SIM_PLANT_FOR_INVERSE = INVERSE_MODELS

#: The column names of each observation set, from the one table
#: (:data:`capsule_env.engine.observations.OBSERVABLES`).
OBSERVATION_NAMES = _observations.OBSERVATION_NAMES
#: The ``sensors`` set: what a real vehicle measures (with noise in ``hils``).
SENSOR_NAMES = OBSERVATION_NAMES["sensors"]
#: The ``full_state`` set: every state (with noise where ``sensor_noise`` > 0).
FULL_STATE_NAMES = OBSERVATION_NAMES["full_state"]
#: The ``measured`` set: what a capsule's own sensors read (with noise in ``hils``) and the
#: on-board estimates of the absolute velocities (:meth:`EnvConfig.velocity_estimator_coefficients`).
MEASURED_NAMES = OBSERVATION_NAMES["measured"]
#: Standard deviation of the measurement noise at ``sensor_noise=1`` [reconstructed: a few per
#: cent of each channel's typical level on the default guideway; the HILS default], one per
#: ``layout.NOISE_CHANNEL_NAMES``, read by name from
#: :data:`capsule_env.engine.observations.NOISE_CHANNELS`.
SENSOR_NOISE_STD = _observations.SENSOR_NOISE_STD
#: Damper code of the model each ``inverse_model`` inverts (registered models included).
INVERSE_CODES = _INVERSE_CODES
#: Filters of the car-body acceleration in the reward (``reward_acceleration_filter``).
REWARD_ACCELERATION_FILTERS = ("none", "wk")
#: Most guideway preview points an observation may carry.
MAX_PREVIEW_POINTS = 64
#: Wavelength bands (m) of the survey map's errors [reconstructed]: a long-wavelength offset
#: of the map (datum drift between survey points) and a short-wavelength error (the survey's
#: own resolution and noise).
SURVEY_OFFSET_BAND_M = (50.0, 500.0)
SURVEY_NOISE_BAND_M = (2.0, 50.0)


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
    reward_acceleration_filter: str = "none"
    acceleration_scale_m_s2: float = 0.5
    stroke_scale_m: float = 0.02
    velocity_scale_m_s: float = 0.05
    stroke_limit_m: float = 0.06
    bump_stop_penalty: float = 100.0
    vehicle: str = "quarter_car"
    vehicle_params: dict = field(default_factory=dict)
    damper_params: dict = field(default_factory=dict)
    inverse_params: dict = field(default_factory=dict)
    vehicle_randomization: float = 0.0
    speed_range_kmh: tuple[float, float] | None = None
    velocity_estimator_corner_hz: float = 0.1
    velocity_estimator_damping: float = 0.7071067811865476
    preview_points: int = 0
    preview_horizon_s: float = 0.5
    survey_offset_m: float = 5e-4
    survey_noise_m: float = 1e-4
    position_error_m: float = 0.05
    levitation: str = "fixed"
    levitation_params: dict = field(default_factory=dict)
    speed_profile: str = "constant"
    trip_params: dict = field(default_factory=dict)
    spans: str = "none"
    span_params: dict = field(default_factory=dict)
    payload_range: tuple[float, float] | None = None
    magnet_length_m: float | None = None

    def __post_init__(self) -> None:
        self._check_plant_options()
        self._check_episode_options()
        self._check_observation_and_reward()
        self._check_vehicles_preview_and_overrides()

    def _check_plant_options(self) -> None:
        check_choice("action_mode", self.action_mode, ACTION_MODES)
        check_choice("inverse_model", self.inverse_model, tuple(sorted(inverse_models())))
        check_choice("setting", self.setting, SETTINGS)
        if self.damper is not None:
            check_choice("damper", self.damper, tuple(MODELS))
        if self.coil_time_constant_s is not None:
            check_in_range("coil_time_constant_s", self.coil_time_constant_s, 0.0, 10.0)
        if self.sensor_noise is not None:
            check_in_range("sensor_noise", self.sensor_noise, 0.0, 1e3)
        if self.control_delay_steps is not None:
            check_integer("control_delay_steps", self.control_delay_steps, 0, 100)

    def _check_episode_options(self) -> None:
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

    def _check_observation_and_reward(self) -> None:
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
        check_choice("reward_acceleration_filter", self.reward_acceleration_filter,
                     REWARD_ACCELERATION_FILTERS)  # fmt: skip
        check_positive("acceleration_scale_m_s2", self.acceleration_scale_m_s2)
        check_positive("stroke_scale_m", self.stroke_scale_m)
        check_positive("velocity_scale_m_s", self.velocity_scale_m_s)
        check_positive("stroke_limit_m", self.stroke_limit_m)

    def _check_vehicles_preview_and_overrides(self) -> None:
        check_in_range("vehicle_randomization", self.vehicle_randomization, 0.0, 0.9)
        if self.speed_range_kmh is not None:
            _check_speed_range(self.speed_range_kmh)
        check_in_range("velocity_estimator_corner_hz", self.velocity_estimator_corner_hz, 1e-3,
                       0.1 * self.control_rate_hz)  # fmt: skip
        check_in_range("velocity_estimator_damping", self.velocity_estimator_damping, 0.1, 10.0)
        check_integer("preview_points", self.preview_points, 0, MAX_PREVIEW_POINTS)
        check_in_range("preview_horizon_s", self.preview_horizon_s, 1e-3, 10.0)
        if self.preview_points and self.preview_horizon_s < self.preview_points * 1e-4:
            raise ValueError("preview_horizon_s must leave at least 0.1 ms between preview points")
        check_in_range("survey_offset_m", self.survey_offset_m, 0.0, 0.1)
        check_in_range("survey_noise_m", self.survey_noise_m, 0.0, 0.1)
        check_in_range("position_error_m", self.position_error_m, 0.0, 100.0)
        for name in ("guideway_params", "vehicle_params", "damper_params", "inverse_params"):
            if not isinstance(getattr(self, name), dict):
                raise TypeError(f"{name} must be a dict of parameter overrides")
        for key, arg in (("speed_kmh", "speed_kmh"), ("kind", "guideway")):
            if key in self.guideway_params:
                raise ValueError(
                    f"guideway_params[{key!r}] is not accepted: the env argument {arg!r} sets it "
                    "(one source of truth for the guideway and the vehicle)"
                )
        if self.payload_range is not None:
            _check_payload_range(self.payload_range)
        if self.speed_profile == "trip" and self.speed_range_kmh is not None:
            raise ValueError("speed_range_kmh must be None with speed_profile='trip' (the trip "
                             "sets the speed)")  # fmt: skip
        # Build everything once so that bad overrides fail here, with the parameter named.
        _ = self.vehicle_parameters, self.plant_damper, self.inverse_damper, self.guideway_spec
        if self.damper_params:  # a plant damper of the user's: it must dissipate (issue 40)
            _check_dissipative_plant(self.plant_damper, self.plant_damper_name)
        _ = self.envelope
        self._check_substeps()
        self.check_memory(1)

    @classmethod
    def from_kwargs(
        cls,
        _owner: str = "EnvConfig.from_kwargs",
        _also_accepted: tuple[str, ...] = (),
        /,
        **kwargs: Any,
    ) -> EnvConfig:
        """Build from keyword arguments (the env's options).

        An unknown name raises :class:`UnexpectedArgumentError` (a ``TypeError`` and a
        ``ValueError``) worded as Python's own, ``<_owner>() got an unexpected keyword argument
        'name'``, with the accepted names. The positional-only ``_owner`` names the callable the
        arguments were given to (e.g. ``"CapsuleSuspensionEnv.__init__"``) and
        ``_also_accepted`` lists its own arguments (e.g. ``render_mode``) for the message.
        """
        known = {f.name for f in fields(cls)}
        for key in kwargs:
            if key not in known:
                raise unexpected_argument(_owner, key, known | set(_also_accepted))
        for name in ("speed_range_kmh", "payload_range"):
            if isinstance(kwargs.get(name), list):  # e.g. from JSON
                kwargs[name] = tuple(kwargs[name])
        return cls(**kwargs)

    # ---- derived values (properties, not stored copies) ----
    @property
    def hils(self) -> bool:
        return self.setting == "hils"

    @property
    def plant_damper_name(self) -> str:
        if self.damper is not None:
            return self.damper
        return "reference" if self.hils else inverse_models()[self.inverse_model]

    @property
    def vehicle_model(self) -> VehicleModel:
        """The declared vehicle (:mod:`capsule_env.vehicles`) named by ``vehicle``."""
        return check_compiled(model_named(self.vehicle))

    @property
    def vehicle_parameters(self) -> VehicleParams:
        """The vehicle's parameters: its model's defaults with ``vehicle_params`` applied."""
        model = self.vehicle_model
        params = _build("vehicle_params", model.params, self.vehicle_params)
        check_compiled(model, params)
        return params

    @property
    def packed_vehicle(self) -> np.ndarray:
        """The parameters as the compiled plant reads them (the model's packed order)."""
        return self.vehicle_model.as_array(self.vehicle_parameters)

    @property
    def plant_damper(self) -> DamperParamsBase:
        name = self.plant_damper_name
        damper: Any = make_damper(name, **self.damper_params)  # names a bad key or value itself
        tau = self.effective_coil_time_constant_s
        if hasattr(damper, "coil_time_constant_s"):  # a damper with a coil (a dataclass)
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
    def inverse_damper(self) -> DamperParamsBase:
        return make_damper(inverse_models()[self.inverse_model], **self.inverse_params)

    @property
    def guideway_spec(self) -> GuidewayParams:
        params = {"kind": self.guideway, "speed_kmh": self.speed_kmh, **self.guideway_params}
        return _build("guideway_params", GuidewayParams, params)

    @property
    def envelope(self) -> Envelope:
        """The envelope options (EDS levitation, trips, spans), validated
        (:mod:`capsule_env.envelope.options`)."""
        return build_envelope(self)

    @property
    def dt_s(self) -> float:
        return 1.0 / self.control_rate_hz

    @property
    def max_episode_steps(self) -> int:
        return int(round(self.episode_length_s * self.control_rate_hz))

    @property
    def max_current_a(self) -> float:
        damper = self.plant_damper
        inverse: Any = self.inverse_damper  # every inverted model has a coil
        return float(getattr(damper, "max_current_a", inverse.max_current_a))

    def substep_tables(self, vehicle_params: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
        """Substeps per control step, per vehicle (rows of packed ``vehicle_params``, each at its
        own ``speed_mps``) and coil-current bin (:func:`capsule_env.plant.substeps.substep_tables`),
        or the fixed ``substeps``."""
        n = np.atleast_2d(vehicle_params).shape[0]
        if self.substeps is not None:
            return np.full((n, SUBSTEP_BINS), int(self.substeps), dtype=np.int64)
        envelope = self.envelope
        if envelope.trip is not None:  # the trip's highest speed, whatever the vehicle's now
            speed_mps = np.full(n, envelope.highest_speed_m_s(0.0))
        rate = self.input_rate_rad_s(np.asarray(speed_mps, dtype=float))
        return substep_tables(self.plant_damper, self.dt_s, vehicle_params, rate)

    def input_rate_rad_s(self, speed_mps: np.ndarray | float) -> np.ndarray:
        """Highest angular frequency of the guideway input at ``speed_mps`` (rad/s); with the
        tube's spans, at least their fourth harmonic (``8 pi v / span_m``)."""
        gw = self.guideway_spec
        speed = np.asarray(speed_mps, dtype=float)
        span = 4.0 * math.pi * speed * 2.0 / self.span_params.get("span_m", 30.0)
        spans = self.spans != "none"
        if gw.kind == "sine":
            rate = np.full_like(speed, 2.0 * math.pi * gw.frequency_hz)
            return np.maximum(rate, span) if spans else rate
        if gw.kind == "swept_sine":
            rate = np.full_like(speed, 2.0 * math.pi * max(gw.start_hz, gw.stop_hz))
            return np.maximum(rate, span) if spans else rate
        shortest = {
            "random": gw.min_wavelength_m,
            "bump": gw.bump_length_m,
            "step": max(2.0 * gw.ramp_length_m, 4.0 * gw.spacing_m),
        }[gw.kind]
        rate = 2.0 * math.pi * speed / shortest
        return np.maximum(rate, span) if spans else rate

    @property
    def speed_m_s(self) -> float:
        """The vehicle's speed (m/s) at ``speed_kmh``."""
        return kmh_to_m_s(float(self.speed_kmh))

    @property
    def speed_range_mps(self) -> tuple[float, float]:
        """Lowest and highest vehicle speed (m/s)."""
        lo, hi = self.speed_range_kmh or (self.speed_kmh, self.speed_kmh)
        return kmh_to_m_s(float(lo)), kmh_to_m_s(float(hi))

    @property
    def window_m(self) -> float:
        """Guideway one episode covers at the highest speed, plus a margin (m)."""
        top = self.envelope.highest_speed_m_s(self.speed_range_mps[1])
        return top * self.episode_length_s + 4 * self.guideway_spec.spacing_m

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
        if self.preview_points:  # the survey map's error profiles
            bank += 2 * profiles * self.bank_samples * 8
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
        varies = self.vehicle_randomization > 0.0 or hi > lo or self.speed_profile == "trip"
        varies = varies or self.payload_range is not None
        return self.substeps is None and varies

    def _check_substeps(self) -> None:
        """Refuse a configuration whose stiffest vehicle (the randomisation corner with the
        lightest masses, stiffest springs and highest speed) needs more than
        ``MAX_AUTO_SUBSTEPS`` substeps per control step."""
        if self.substeps is not None:
            return
        r = self.vehicle_randomization
        corner = self.packed_vehicle * np.array([1.0 - r, 1.0 - r, 1.0 + r, 1.0 + r, 1.0])
        if self.payload_range is not None:  # the lightest car body
            corner[0] *= 1.0 + min(self.payload_range)
        if self.levitation == "eds":  # the stiffness at any speed is below K_inf
            corner[STIFF_LEVITATION] /= self.envelope.reference_shape
        speed = kmh_to_m_s(max(self.speed_range_kmh or (self.speed_kmh,)))
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
        """The observation's columns (:func:`capsule_env.engine.observations.columns`): the chosen set,
        then the trip's (speed and longitudinal acceleration, with ``speed_profile="trip"``),
        then the preview points (if any)."""
        return _observations.columns(self.observation, self.has_trip, self.preview_points)

    @property
    def has_trip(self) -> bool:
        """Whether the speed follows a trip (and the observation has the trip's columns)."""
        return self.speed_profile == "trip"

    @property
    def preview_names(self) -> tuple[str, ...]:
        """Columns of the guideway preview (:func:`capsule_env.engine.observations.preview_columns`)."""
        return tuple(c.name for c in _observations.preview_columns(self.preview_points))

    def reward_filter_sos(self) -> np.ndarray:
        """Second-order sections ``(b0, b1, b2, 1, a1, a2)`` the reward's car-body acceleration
        passes through, (0, 6) for none: ``reward_acceleration_filter="wk"`` is the ISO 2631-1
        Wk weighting as a causal filter at the control rate (:func:`capsule_env.metrics.
        wk_filter_sos`), so that the reward's acceleration term is the per-step square of the
        quantity the tables report (``wk_rms_body_acc_m_s2``)."""
        if self.reward_acceleration_filter == "wk":
            sos = wk_filter_sos(self.dt_s)
            assert sos.shape[0] <= MAX_REWARD_FILTER_SECTIONS
            return sos
        return np.zeros((0, 6))

    def velocity_estimator_coefficients(self) -> np.ndarray:
        """``(b0, b1, b2, a1, a2)`` of the on-board velocity estimator at the control rate.

        Each absolute velocity is the accelerometer's band-limited integral, ``H(s) = s / (s^2
        + 2 zeta w_c s + w_c^2)`` (an integrator times a second-order high-pass: the velocity
        above the corner ``w_c``, no drift below it), discretised by the bilinear transform
        prewarped at the corner. Defaults [reconstructed]: ``velocity_estimator_corner_hz`` 0.1
        Hz, a thirteenth of the 1.3 Hz body mode (there: phase lead 6.2 deg, gain 1.0000), and
        ``velocity_estimator_damping`` 1/sqrt(2) (Butterworth). Chosen by measurement in
        ``hils`` (random guideway, sensor noise): RMS error of the body velocity 8 % (0.05 Hz),
        12 % (0.1), 24 % (0.2), 36 % (0.3), mostly the guideway's long waves the body follows
        below the corner; of the bogie velocity 20, 16, 17, 21 % (accelerometer noise at low
        corners); continuous Skyhook on the estimate reached the Wk of Skyhook on the (noisy)
        true velocities for corners up to 0.2 Hz."""
        w = 2.0 * math.pi * self.velocity_estimator_corner_hz
        zeta, dt = self.velocity_estimator_damping, self.dt_s
        k = w / math.tan(0.5 * w * dt)
        a0 = k * k + 2.0 * zeta * w * k + w * w
        a1 = (2.0 * w * w - 2.0 * k * k) / a0
        a2 = (k * k - 2.0 * zeta * w * k + w * w) / a0
        return np.array([k / a0, 0.0, -k / a0, a1, a2])


def observation_bounds(config: EnvConfig, i_max: float) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)`` of the observation space: generous physical limits at which the sensors
    saturate (accelerations 100 m/s^2, stroke 2 x the bump stop, rates and velocities 10 m/s,
    displacements, the gap and the preview 1 m, commanded current [0, i_max], measured current
    [-0.5, i_max + 0.5] A so that its noise is not clipped on one side): each column's
    ``low`` and ``high`` in :data:`capsule_env.engine.observations.OBSERVABLES`, then the preview's."""
    low, high = _observations.column_bounds(config.observation, config.stroke_limit_m, i_max,
                                            config.has_trip, config.preview_points)  # fmt: skip
    return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)


_DISSIPATIVE: set[tuple[int, tuple[float, ...]]] = set()  # plant dampers checked already


def _check_dissipative_plant(damper: Any, model: str) -> None:
    """``ValueError`` naming ``damper_params`` when the plant damper they give feeds energy in
    (:func:`capsule_env.dampers.rig.check_dissipative`: a sign-flipped or negative-damping
    identification would drive the capsule into its bump stops); each damper checked once."""
    from capsule_env.dampers.rig import check_dissipative

    key = (int(damper.code), tuple(float(p) for p in damper.as_array()))
    if key in _DISSIPATIVE:
        return
    check_dissipative(damper, f"damper_params: the {model} plant damper")
    _DISSIPATIVE.add(key)


def _check_payload_range(value: Any) -> None:
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise TypeError(f"payload_range must be None or (low, high), fractions of the car body "
                        f"mass, got {value!r}")  # fmt: skip
    lo = check_in_range("payload_range[0]", value[0], -0.9, 10.0)
    hi = check_in_range("payload_range[1]", value[1], -0.9, 10.0)
    if hi < lo:
        raise ValueError(f"payload_range must be (low, high) with high >= low, got {value!r}")


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


def _build(name: str, cls: type, overrides: dict) -> Any:
    known = {f.name for f in fields(cls)}
    for key in overrides:
        if key not in known:
            raise ValueError(f"unknown key {key!r} in {name}; accepted: {', '.join(sorted(known))}")
    return cls(**overrides)
