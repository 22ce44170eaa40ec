"""The env kernel's named structures: what stays fixed, what evolves, what a step writes.

:class:`EnvParams` holds a batch's options as the kernel reads them, and
:meth:`EnvParams.from_config` makes them from an :class:`capsule_env.engine.config.EnvConfig`.
:class:`EnvState` holds what evolves per vehicle, each group of per-vehicle floats under a
name of its own (the applied current, the CSDC inverse's state, the velocity estimators', the
position error, the reward filter's) as views of one block, so that a vehicle's reset zeroes
them in one assignment: properties of :class:`EnvState` in Python, functions of the same names
in compiled code. :class:`EnvOutputs` holds what a step
writes. Their arrays have the layouts of :mod:`capsule_env.engine.layout`; the kernel is
:mod:`capsule_env.engine.env_kernel`. The kernel owns the step count and the control-delay ring: it
advances both (Python only zeroes them at a reset).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit

from capsule_env._fastmath import BORROWED, FAST
from capsule_env.engine.layout import (
    N_MEASUREMENTS,
    N_VEHICLE_FLOATS,
    STATE_SIZE,
    VEHICLE_FLOAT_NAMES,
)
from capsule_env.engine.observations import (
    OBSERVATION_SETS,
    SENSOR_NOISE_STD,
    first_column,
    noise_channels_read,
)
from capsule_env.plant.params import Route

if TYPE_CHECKING:
    from capsule_env.engine.config import EnvConfig

__all__ = [
    "EnvParams",
    "EnvState",
    "EnvOutputs",
    "OBS_SENSORS",
    "OBS_FULL_STATE",
    "OBS_MEASURED",
    "OBSERVATION_CODES",
    "noise_pairs",
    "applied_current",
    "csdc",
    "estimator",
    "position_error",
    "reward_filter",
    "CSDC_Z",
    "CSDC_STROKE",
    "EST_BODY",
    "EST_BOGIE",
]

#: Observation sets (``EnvParams.observation``), by the names of ``EnvConfig.observation``.
OBSERVATION_CODES = {name: code for code, name in enumerate(OBSERVATION_SETS)}
OBS_SENSORS, OBS_FULL_STATE, OBS_MEASURED = (
    OBSERVATION_CODES[n] for n in ("sensors", "full_state", "measured")
)
#: Rows of ``EnvState.csdc``: the CSDC inverse's hysteresis estimate and the stroke it was
#: last advanced to.
CSDC_Z, CSDC_STROKE = 0, 1
#: First rows of ``EnvState.estimator``: the two states of the car body's velocity estimator,
#: then the bogie's.
EST_BODY, EST_BOGIE = 0, 2
#: The groups of ``EnvState``'s per-vehicle floats, by field: their rows of
#: ``layout.VEHICLE_FLOAT_NAMES`` (contiguous).
_GROUPS = {
    "applied_current": ("applied_current_a",),
    "csdc": ("csdc_z_estimate", "csdc_last_stroke_m"),
    "estimator": (
        "body_estimator_state_1",
        "body_estimator_state_2",
        "bogie_estimator_state_1",
        "bogie_estimator_state_2",
    ),
    "position_error": ("position_error_m",),
    "reward_filter": tuple(n for n in VEHICLE_FLOAT_NAMES if n.startswith("reward_filter_")),
    "envelope": (
        "trip_time_at_start_s",
        "route_start_m",
        "route_speed_m_s",
        "levitation_stiffness_limit_n_per_m",
    ),
}


def _rows(group: str) -> tuple[int, int]:
    """``(first, stop)`` rows of a group of ``layout.VEHICLE_FLOAT_NAMES``, checked contiguous."""
    names = _GROUPS[group]
    first = VEHICLE_FLOAT_NAMES.index(names[0])
    assert VEHICLE_FLOAT_NAMES[first : first + len(names)] == names, group
    return first, first + len(names)


_APPLIED = _rows("applied_current")[0]
_CSDC, _CSDC_STOP = _rows("csdc")
_EST, _EST_STOP = _rows("estimator")
_POSITION_ERROR = _rows("position_error")[0]
_REWARD_FILTER, _REWARD_FILTER_STOP = _rows("reward_filter")
_ENVELOPE, _ENVELOPE_STOP = _rows("envelope")
#: Rows of the observation bounds (``EnvParams.obs_bounds``).
LOW, HIGH = 0, 1


# The named groups of EnvState.vehicle_floats as the kernel reads them (views; inlined, so
# they cost nothing; EnvState's properties of the same names give the same views to Python).
# One array in EnvState rather than five keeps the per-call cost of the kernel's structures
# down (each array read from them is reference-counted at every call of the serial kernel).
@njit(**FAST, **BORROWED, inline="always")
def applied_current(state):
    """(N,) the command applied this step, after the control delay (A)."""
    return state.vehicle_floats[_APPLIED]


@njit(**FAST, **BORROWED, inline="always")
def csdc(state):
    """(2, N) the CSDC inverse's state, rows :data:`CSDC_Z`, :data:`CSDC_STROKE`."""
    return state.vehicle_floats[_CSDC:_CSDC_STOP]


@njit(**FAST, **BORROWED, inline="always")
def estimator(state):
    """(4, N) the velocity estimators' states, two each from :data:`EST_BODY`,
    :data:`EST_BOGIE`."""
    return state.vehicle_floats[_EST:_EST_STOP]


@njit(**FAST, **BORROWED, inline="always")
def position_error(state):
    """(N,) the error of each vehicle's own estimate of its position (m)."""
    return state.vehicle_floats[_POSITION_ERROR]


@njit(**FAST, **BORROWED, inline="always")
def reward_filter(state):
    """(2 MAX_REWARD_FILTER_SECTIONS, N) the reward filter's states, two per section."""
    return state.vehicle_floats[_REWARD_FILTER:_REWARD_FILTER_STOP]


@njit(**FAST, **BORROWED, inline="always")
def envelope(state):
    """(4, N) the envelope's per-vehicle values (``capsule_env.envelope.kernel.ENV_*`` rows)."""
    return state.vehicle_floats[_ENVELOPE:_ENVELOPE_STOP]


def noise_pairs(observation: int) -> np.ndarray:
    """The Box-Muller pairs an observation set needs drawn (pair ``c // 2`` for channel ``c``):
    those of its columns' noise channels and of the measurements'."""
    channels = noise_channels_read(OBSERVATION_SETS[observation])
    return np.array(sorted({c // 2 for c in channels}), dtype=np.int64)


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
    estimator: np.ndarray  # (5,) the velocity estimator's biquad (b0, b1, b2, a1, a2)
    preview_points: int  # guideway preview columns after the observation set's (0: none)
    preview_step_s: float  # time between preview points
    survey_error: np.ndarray  # (K, L) the survey map's error, on the profiles' grid (m)
    reward_filter: np.ndarray  # (S, 6) second-order sections of the reward's acceleration filter
    trip: (
        np.ndarray
    )  # (5,) the trip's (a, b, t1, t2, t3), zeros without (capsule_env.envelope.options)
    eds: np.ndarray  # (2,) the EDS coil's (v_c, tau)
    trip_column: int  # first of the trip's observation columns (-1: none)
    survey_bank: np.ndarray  # (K, L) the true guideway the survey map reads ((0, 0): the plant's)

    @classmethod
    def from_config(cls, config: EnvConfig, survey_error: np.ndarray | None = None,
                    survey_bank: np.ndarray | None = None) -> EnvParams:  # fmt: skip
        """The options of ``config`` as the kernel reads them. ``survey_error`` is the survey
        map's error on the guideway bank's grid (``CapsuleBatch`` draws it with the bank;
        None: a (1, 1) zero array, no preview error); ``survey_bank`` the true guideway bank
        when the plant reads another (``magnet_length_m``; None: the plant's)."""
        from capsule_env.engine.config import INVERSE_CODES, observation_bounds

        i_max = config.max_current_a
        code = OBSERVATION_CODES[config.observation]
        envelope = config.envelope
        noise_std = SENSOR_NOISE_STD * config.effective_sensor_noise
        return cls(
            max_force_n=float(config.max_force_n),
            i_max_a=float(i_max),
            dt_s=float(config.dt_s),
            reward_acceleration_weight=float(config.reward_acceleration_weight),
            acceleration_scale_m_s2=float(config.acceleration_scale_m_s2),
            reward_stroke_weight=float(config.reward_stroke_weight),
            stroke_scale_m=float(config.stroke_scale_m),
            reward_energy_weight=float(config.reward_energy_weight),
            reward_velocity_weight=float(config.reward_velocity_weight),
            velocity_scale_m_s=float(config.velocity_scale_m_s),
            stroke_limit_m=float(config.stroke_limit_m),
            bump_stop_penalty=float(config.bump_stop_penalty),
            current_mode=config.action_mode == "current",
            inverse_code=int(INVERSE_CODES[config.inverse_model]),
            observation=code,
            noisy=bool(np.any(noise_std > 0.0)),
            inverse_params=config.inverse_damper.as_array(),
            noise_std=noise_std,
            noise_pairs=noise_pairs(code),
            obs_bounds=np.array(observation_bounds(config, i_max), dtype=np.float64),
            estimator=config.velocity_estimator_coefficients(),
            preview_points=int(config.preview_points),
            preview_step_s=float(config.preview_horizon_s / max(config.preview_points, 1)),
            survey_error=np.zeros((1, 1)) if survey_error is None else survey_error,
            reward_filter=config.reward_filter_sos(),
            trip=envelope.trip_array(),
            eds=envelope.eds_array(),
            trip_column=first_column(
                config.observation, "trip", envelope.trip is not None, config.preview_points
            ),  # fmt: skip
            survey_bank=np.zeros((0, 0)) if survey_bank is None else survey_bank,
        )


def _group_view(group: str, doc: str | None) -> property:
    """A read-only property: the view of ``vehicle_floats`` that is ``group`` (the Python side
    of the compiled accessor of the same name, whose docstring it takes)."""
    first, stop = _rows(group)
    rows = first if stop - first == 1 else slice(first, stop)
    return property(lambda self: self.vehicle_floats[rows], doc=doc)


class EnvState(NamedTuple):
    """What evolves, per vehicle (one contiguous row per quantity for the SIMD loops). The
    per-vehicle floats are one block whose groups have names: the properties
    :attr:`applied_current`, :attr:`csdc`, :attr:`estimator`, :attr:`position_error`,
    :attr:`reward_filter` (views; in compiled code the functions of the same names)."""

    plant: np.ndarray  # (N, STATE_SIZE)
    route: Route
    step_count: np.ndarray  # (N,) int64 steps since the reset (the kernel advances it)
    noise_key: np.ndarray  # (N,) uint64 drawn at the reset
    measured: np.ndarray  # (N_MEASUREMENTS, N), rows layout.MEASUREMENT_NAMES
    delay: np.ndarray  # (N, control_delay_steps + 1) ring buffer of commands (the kernel's)
    vehicle_floats: np.ndarray  # (N_VEHICLE_FLOATS, N), rows layout.VEHICLE_FLOAT_NAMES

    @classmethod
    def allocate(cls, num_envs: int, delay_steps: int, route: Route) -> EnvState:
        """A zero state of ``num_envs`` vehicles with a ring of ``delay_steps + 1`` commands."""
        return cls(
            plant=np.zeros((num_envs, STATE_SIZE)),
            route=route,
            step_count=np.zeros(num_envs, dtype=np.int64),
            noise_key=np.zeros(num_envs, dtype=np.uint64),
            measured=np.zeros((N_MEASUREMENTS, num_envs)),
            delay=np.zeros((num_envs, delay_steps + 1)),
            vehicle_floats=np.zeros((N_VEHICLE_FLOATS, num_envs)),
        )

    applied_current = _group_view("applied_current", applied_current.__doc__)
    csdc = _group_view("csdc", csdc.__doc__)
    estimator = _group_view("estimator", estimator.__doc__)
    position_error = _group_view("position_error", position_error.__doc__)
    reward_filter = _group_view("reward_filter", reward_filter.__doc__)
    envelope = _group_view("envelope", envelope.__doc__)


class EnvOutputs(NamedTuple):
    """What one step writes."""

    obs: np.ndarray  # (N, obs_dim) float32
    reward: np.ndarray  # (N,)
    terminated: np.ndarray  # (N,) bool
    signals: np.ndarray  # (N_SIGNALS, N + padding), rows layout.SIGNAL_NAMES
    plant: np.ndarray  # (N, N_PLANT_OUTPUTS) the plant kernel's outputs
