"""The env kernel's named structures: what stays fixed, what evolves, what a step writes.

:class:`EnvParams` holds a batch's options as the kernel reads them, and
:meth:`EnvParams.from_config` makes them from an :class:`capsule_env.config.EnvConfig`.
:class:`EnvState` holds what evolves per vehicle, each group of per-vehicle floats under a
name of its own (the applied current, the CSDC inverse's state, the velocity estimators', the
position error, the reward filter's) as views of one block, so that a vehicle's reset zeroes
them in one assignment (:meth:`EnvState.allocate`). :class:`EnvOutputs` holds what a step
writes. Their arrays have the layouts of :mod:`capsule_env.layout`; the kernel is
:mod:`capsule_env.env_kernel`. The kernel owns the step count and the control-delay ring: it
advances both (Python only zeroes them at a reset).
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from capsule_env.layout import (
    N_MEASUREMENTS,
    N_VEHICLE_FLOATS,
    STATE_SIZE,
    VEHICLE_FLOAT_NAMES,
)
from capsule_env.observations import OBSERVATION_SETS, SENSOR_NOISE_STD, noise_channels_read
from capsule_env.plant.params import Route

if TYPE_CHECKING:
    from capsule_env.config import EnvConfig

__all__ = [
    "EnvParams",
    "EnvState",
    "EnvOutputs",
    "OBS_SENSORS",
    "OBS_FULL_STATE",
    "OBS_MEASURED",
    "OBSERVATION_CODES",
    "noise_pairs",
    "float_groups",
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
}


def float_groups(block: np.ndarray) -> dict[str, np.ndarray]:
    """The named groups of :class:`EnvState`'s per-vehicle floats as views of ``block``
    ((N_VEHICLE_FLOATS, N), rows ``layout.VEHICLE_FLOAT_NAMES``), by field name
    (``EnvState(..., **float_groups(block))``, ``state._replace(**float_groups(block))``)."""
    groups = {}
    for name, rows in _GROUPS.items():
        first = VEHICLE_FLOAT_NAMES.index(rows[0])
        assert VEHICLE_FLOAT_NAMES[first : first + len(rows)] == rows
        view = block[first : first + len(rows)]
        groups[name] = view[0] if len(rows) == 1 else view
    return groups


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

    @classmethod
    def from_config(cls, config: EnvConfig, survey_error: np.ndarray | None = None) -> EnvParams:
        """The options of ``config`` as the kernel reads them. ``survey_error`` is the survey
        map's error on the guideway bank's grid (``CapsuleBatch`` draws it with the bank;
        None: a (1, 1) zero array, no preview error)."""
        from capsule_env.config import INVERSE_CODES, observation_bounds

        i_max = config.max_current_a
        code = OBSERVATION_CODES[config.observation]
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
        )


class EnvState(NamedTuple):
    """What evolves, per vehicle (one contiguous row per quantity for the SIMD loops)."""

    plant: np.ndarray  # (N, STATE_SIZE)
    route: Route
    step_count: np.ndarray  # (N,) int64 steps since the reset (the kernel advances it)
    noise_key: np.ndarray  # (N,) uint64 drawn at the reset
    measured: np.ndarray  # (N_MEASUREMENTS, N), rows layout.MEASUREMENT_NAMES
    delay: np.ndarray  # (N, control_delay_steps + 1) ring buffer of commands (the kernel's)
    applied_current: np.ndarray  # (N,) the command applied this step, after the delay (A)
    csdc: np.ndarray  # (2, N) rows CSDC_Z, CSDC_STROKE
    estimator: np.ndarray  # (4, N) the velocity estimators' states, rows from EST_BODY, EST_BOGIE
    position_error: np.ndarray  # (N,) the error of the vehicle's own position estimate (m)
    reward_filter: np.ndarray  # (2 MAX_REWARD_FILTER_SECTIONS, N) two per filter section

    @classmethod
    def allocate(cls, num_envs: int, delay_steps: int, route: Route) -> EnvState:
        """A zero state of ``num_envs`` vehicles with a ring of ``delay_steps + 1`` commands;
        the per-vehicle floats are views of one block (:func:`float_groups`)."""
        return cls(
            plant=np.zeros((num_envs, STATE_SIZE)),
            route=route,
            step_count=np.zeros(num_envs, dtype=np.int64),
            noise_key=np.zeros(num_envs, dtype=np.uint64),
            measured=np.zeros((N_MEASUREMENTS, num_envs)),
            delay=np.zeros((num_envs, delay_steps + 1)),
            **float_groups(np.zeros((N_VEHICLE_FLOATS, num_envs))),
        )

    @property
    def vehicle_floats(self) -> np.ndarray:
        """(N_VEHICLE_FLOATS, N) every per-vehicle float, rows ``layout.VEHICLE_FLOAT_NAMES``:
        the block the named groups are views of."""
        return self.csdc.base

    @property
    def floats(self) -> np.ndarray:
        """Deprecated: :attr:`vehicle_floats`, or better the named groups."""
        warnings.warn(
            "EnvState.floats is deprecated: use the named groups (applied_current, csdc, "
            "estimator, position_error, reward_filter) or vehicle_floats",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.vehicle_floats


class EnvOutputs(NamedTuple):
    """What one step writes."""

    obs: np.ndarray  # (N, obs_dim) float32
    reward: np.ndarray  # (N,)
    terminated: np.ndarray  # (N,) bool
    signals: np.ndarray  # (N_SIGNALS, N + padding), rows layout.SIGNAL_NAMES
    plant: np.ndarray  # (N, N_PLANT_OUTPUTS) the plant kernel's outputs
