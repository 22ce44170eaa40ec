"""Named layouts of every packed array the compiled kernels read.

The kernels see numbers in arrays, not dataclasses; this module gives each slot a name, once,
and every kernel reads ``state[n, BODY_VEL]`` or ``signals[SIG_STROKE, n]``, never
``state[n, 1]``. Module-level integers are compile-time constants for numba: naming costs no
speed.

Every index is derived from its tuple of names (``name.index(...)``, or an unpacking of
``range(...)`` that fails if a name is added without its constant), so a layout and its
constants cannot disagree: the shared damper slots (:data:`I_MAX`, :data:`COIL_TAU`,
:data:`BRANCH_BLEND`) come from :data:`capsule_env.dampers.base.SHARED_DAMPER_SLOTS` after the
longest model's parameters, each model's parameter slots from its own module's names
(:mod:`capsule_env.dampers`), and the per-vehicle floats' ``VF_*`` from
:data:`VEHICLE_FLOAT_NAMES`.

| array | shape | layout |
| --- | --- | --- |
| plant state | (N, STATE_SIZE) | :data:`STATE_NAMES` |
| vehicle parameters | (N, 5) | :data:`VEHICLE_PARAM_NAMES` |
| damper parameters | (N, N_DAMPER_PARAMS) | :data:`DAMPER_PARAM_NAMES` per model, then the shared slots |
| plant outputs | (N, N_PLANT_OUTPUTS) | :data:`PLANT_OUTPUT_NAMES` |
| env signals (``info``) | (N_SIGNALS, N) | :data:`SIGNAL_NAMES` |
| measurements | (N_MEASUREMENTS, N) | :data:`MEASUREMENT_NAMES` |
| per-vehicle floats of the env | (N_VEHICLE_FLOATS, N) | :data:`VEHICLE_FLOAT_NAMES` |
| sensor-noise channels | (N_NOISE_CHANNELS, block) | :data:`NOISE_CHANNEL_NAMES` |
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

from capsule_env.dampers.base import (  # noqa: F401  (the shared damper slots, named here too)
    BRANCH_BLEND,
    COIL_TAU,
    I_MAX,
    N_DAMPER_PARAMS,
    SHARED_DAMPER_SLOTS,
)
from capsule_env.dampers.registry import MODELS as _DAMPER_MODELS
from capsule_env.engine import observations as _observations

__all__ = [
    "STATE_NAMES",
    "VEHICLE_PARAM_NAMES",
    "DAMPER_PARAM_NAMES",
    "PLANT_OUTPUT_NAMES",
    "SIGNAL_NAMES",
    "MEASUREMENT_NAMES",
    "VEHICLE_FLOAT_NAMES",
    "NOISE_CHANNEL_NAMES",
]

# --------------------------------------------------------------------------- plant state
#: Columns of the plant state of one vehicle (SI units).
STATE_NAMES = (
    "car_body_displacement_m",
    "car_body_velocity_m_s",
    "bogie_displacement_m",
    "bogie_velocity_m_s",
    "hysteretic_z_m",  # Bouc-Wen / Spencer hysteretic variable
    "damper_internal_displacement_m",  # Spencer's y
    "coil_current_a",  # actual current, after the coil lag
    "time_s",
)
BODY_DISP, BODY_VEL, BOGIE_DISP, BOGIE_VEL, HYST_Z, DAMPER_Y, COIL_CURRENT, TIME = (
    STATE_NAMES.index(n) for n in STATE_NAMES
)
STATE_SIZE = len(STATE_NAMES)

# --------------------------------------------------------------------------- vehicle
#: Packed vehicle parameters (``VehicleParams.as_array``).
VEHICLE_PARAM_NAMES = (
    "car_body_mass_kg",
    "bogie_mass_kg",
    "secondary_stiffness_n_per_m",
    "levitation_stiffness_n_per_m",
    "levitation_damping_n_s_per_m",
)
MASS_BODY, MASS_BOGIE, STIFF_SECONDARY, STIFF_LEVITATION, DAMP_LEVITATION = range(
    len(VEHICLE_PARAM_NAMES)
)
N_VEHICLE_PARAMS = len(VEHICLE_PARAM_NAMES)

# --------------------------------------------------------------------------- dampers
# Each damper model declares its own parameter names, in packed order, in its module
# (capsule_env/dampers/<model>.py); the slots after them are shared by every model.


class _DamperParamNames(Mapping):
    """``{model name: its packed parameter names}``: a view of the damper registry (a
    registered model appears in it)."""

    def __getitem__(self, name: str) -> tuple[str, ...]:
        return _DAMPER_MODELS[name].param_names

    def __iter__(self) -> Iterator[str]:
        return iter(_DAMPER_MODELS)

    def __len__(self) -> int:
        return len(_DAMPER_MODELS)


#: Model parameters of each damper model, in packed order (``DamperParams.as_array``); the
#: slots after them (from :data:`I_MAX` on) are shared by every model (:data:`SHARED_DAMPER_SLOTS`).
DAMPER_PARAM_NAMES: Mapping[str, tuple[str, ...]] = _DamperParamNames()

# --------------------------------------------------------------------------- plant outputs
#: Columns of the plant kernel's per-step outputs, at the end of the control interval.
PLANT_OUTPUT_NAMES = ("damper_force_n", "body_acc_m_s2", "bogie_acc_m_s2", "guideway_m")
OUT_FORCE, OUT_BODY_ACC, OUT_BOGIE_ACC, OUT_GUIDEWAY = range(len(PLANT_OUTPUT_NAMES))
N_PLANT_OUTPUTS = len(PLANT_OUTPUT_NAMES)

# --------------------------------------------------------------------------- env signals
#: Per-step physical signals and reward terms (the env's ``info`` keys), one row each.
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
    "car_body_velocity_estimate_m_s",  # the on-board estimator's, from the accelerometers
    "bogie_velocity_estimate_m_s",
    "reward_acceleration_m_s2",  # the car-body acceleration the reward reads (Wk-weighted or not)
)
(SIG_BODY_DISP, SIG_BOGIE_DISP, SIG_BODY_VEL, SIG_BOGIE_VEL, SIG_BODY_ACC, SIG_BOGIE_ACC,
 SIG_STROKE, SIG_STROKE_RATE, SIG_FORCE, SIG_DESIRED_FORCE, SIG_CURRENT_COMMAND, SIG_COIL_CURRENT,
 SIG_GUIDEWAY, SIG_COST_ACC, SIG_COST_STROKE, SIG_COST_ENERGY, SIG_COST_VEL, SIG_BODY_VEL_EST,
 SIG_BOGIE_VEL_EST, SIG_REWARD_ACC) = (SIGNAL_NAMES.index(n) for n in SIGNAL_NAMES)  # fmt: skip
N_SIGNALS = len(SIGNAL_NAMES)

# --------------------------------------------------------------------------- measurements
#: What the vehicle's sensors read this step (with noise), one row each: what the inverse
#: model and the observations use (the rows of the observation table flagged ``measured``).
MEASUREMENT_NAMES = _observations.MEASUREMENT_NAMES
MEAS_BODY_ACC, MEAS_BOGIE_ACC, MEAS_STROKE, MEAS_STROKE_RATE, MEAS_COMMAND = (
    MEASUREMENT_NAMES.index(n)
    for n in ("car_body_acceleration_m_s2", "bogie_acceleration_m_s2", "stroke_m",
              "stroke_rate_m_s", "last_current_command_a")
)  # fmt: skip
N_MEASUREMENTS = len(MEASUREMENT_NAMES)

# --------------------------------------------------------------------------- env per vehicle
#: Per-vehicle floats of the env (one row each): the CSDC inverse's hysteresis estimate and the
#: stroke it was last advanced to, the current applied to the plant this step (the command
#: after the control delay), the two states of each velocity estimator's filter, and the error
#: of the vehicle's own estimate of its position along the guideway (for the preview), and the
#: states of the reward's acceleration filter (two per second-order section, at most
#: :data:`MAX_REWARD_FILTER_SECTIONS`), then the envelope's (:mod:`capsule_env.envelope.kernel`):
#: the trip time at the episode's start, the route's start and speed then, and the levitation's
#: stiffness limit ``K_inf``.
VEHICLE_FLOAT_NAMES = (
    "csdc_z_estimate",
    "csdc_last_stroke_m",
    "applied_current_a",
    "body_estimator_state_1",
    "body_estimator_state_2",
    "bogie_estimator_state_1",
    "bogie_estimator_state_2",
    "position_error_m",
    *(f"reward_filter_state_{k}" for k in range(1, 2 * 4 + 1)),
    "trip_time_at_start_s",
    "route_start_m",
    "route_speed_m_s",
    "levitation_stiffness_limit_n_per_m",
)
(VF_CSDC_Z, VF_CSDC_STROKE, VF_APPLIED, VF_EST_BODY_1, VF_EST_BODY_2, VF_EST_BOGIE_1,
 VF_EST_BOGIE_2, VF_POSITION_ERROR) = range(VEHICLE_FLOAT_NAMES.index("reward_filter_state_1"))  # fmt: skip
#: The first of the reward filter's slots (two per second-order section).
VF_REWARD_FILTER = VEHICLE_FLOAT_NAMES.index("reward_filter_state_1")
#: Second-order sections the reward's acceleration filter may have.
MAX_REWARD_FILTER_SECTIONS = 4
N_VEHICLE_FLOATS = len(VEHICLE_FLOAT_NAMES)

# --------------------------------------------------------------------------- sensor noise
#: Sensor-noise channels, in the order their standard normals are drawn (channel ``c`` is
#: member ``c % 2`` of Box-Muller pair ``c // 2``): a channel keeps its noise whatever other
#: channels an observation set reads; new channels are appended
#: (:data:`capsule_env.engine.observations.NOISE_CHANNELS`).
NOISE_CHANNEL_NAMES = _observations.NOISE_CHANNEL_NAMES
(NOISE_BODY_ACC, NOISE_BOGIE_ACC, NOISE_STROKE, NOISE_STROKE_RATE, NOISE_BODY_DISP,
 NOISE_BODY_VEL, NOISE_BOGIE_DISP, NOISE_BOGIE_VEL, NOISE_GUIDEWAY, NOISE_GAP,
 NOISE_CURRENT) = (
    NOISE_CHANNEL_NAMES.index(n)
    for n in ("car_body_acceleration_m_s2", "bogie_acceleration_m_s2", "stroke_m",
              "stroke_rate_m_s", "car_body_displacement_m", "car_body_velocity_m_s",
              "bogie_displacement_m", "bogie_velocity_m_s", "guideway_elevation_m",
              "levitation_gap_m", "coil_current_a")
)  # fmt: skip
N_NOISE_CHANNELS = len(NOISE_CHANNEL_NAMES)
