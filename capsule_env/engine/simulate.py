"""Stepping the plant from Python: a batch by one control interval, or one vehicle over a run.

:func:`step_batch` advances ``N`` vehicles by one control interval with the compiled kernels
(the vectorised block kernel where the damper model allows, else the scalar one; on all cores
for large batches); :func:`simulate` runs one vehicle open loop over a guideway profile and
returns its time series. The env uses the same kernels (:mod:`capsule_env.engine.kernels`):
this module sits beside them, above the plant.
"""

from __future__ import annotations

import numpy as np

from capsule_env.dampers import DamperParams
from capsule_env.engine.kernels import PLANT, BatchedKernel
from capsule_env.engine.layout import (
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    HYST_Z,
    N_PLANT_OUTPUTS,
    PLANT_OUTPUT_NAMES,
    STATE_SIZE,
    TIME,
)
from capsule_env.plant.block import block_kernel_mode, levitation_damped
from capsule_env.plant.build import initial_state, make_plant_params
from capsule_env.plant.params import PlantParams, Route
from capsule_env.plant.substeps import substep_table
from capsule_env.vehicles import VehicleParams

__all__ = ["step_batch", "simulate"]


def step_batch(
    damper_code: int,
    plant: PlantParams,
    state: np.ndarray,
    current_command_a: np.ndarray,
    route: Route,
    dt_s: float,
    out: np.ndarray,
) -> None:
    """Advance ``N`` vehicles in place by one control interval ``dt_s``.

    Parameters
    ----------
    damper_code : the damper model code (``damper.code``), shared by the batch.
    plant : the vehicles' :class:`PlantParams` (:func:`make_plant_params`), made for ``dt_s``.
    state : (N, STATE_SIZE) float64 plant state (``layout.STATE_NAMES``), updated in place.
    current_command_a : (N,) commanded coil current (A), held over the interval and clipped to
        ``[0, i_max]``; the actual current follows it through the coil lag.
    route : the :class:`Route` of each vehicle over the profiles.
    dt_s : control interval (s).
    out : (N, N_PLANT_OUTPUTS) written with ``layout.PLANT_OUTPUT_NAMES`` at the end.

    Notes
    -----
    All arrays must be C-contiguous float64 (int64 for ``route.profile``).
    """
    mode = block_kernel_mode(damper_code, plant.damper, levitation_damped(plant.vehicle))
    BatchedKernel(PLANT, damper_code, mode, state.shape[0])(
        plant, state, current_command_a, route, float(dt_s), out
    )


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

    ``substeps``: None (the default :func:`~capsule_env.plant.substeps.substep_table`, adaptive
    to the current), a fixed number per control interval, or a table.

    ``current_command_a`` is a scalar or one value per control interval. The returned dict has
    ``time_s`` (samples at the end of each interval, plus t = 0 first) and the columns
    ``car_body_displacement_m``, ``car_body_velocity_m_s``, ``bogie_displacement_m``,
    ``bogie_velocity_m_s``, ``stroke_m``, ``stroke_rate_m_s``, ``coil_current_a``,
    ``hysteretic_z_m`` and the ``layout.PLANT_OUTPUT_NAMES`` (NaN at t = 0).
    """
    vehicle = vehicle or VehicleParams()
    n_steps = int(round(duration_s / dt_s))
    commands = np.broadcast_to(np.asarray(current_command_a, float), (n_steps,))
    table = substep_table(damper, dt_s, vehicle) if substeps is None else substeps
    plant = make_plant_params(damper.code, damper.as_array(), vehicle.as_array(), table,
                              np.asarray(profile_m, float), spacing_m, dt_s)  # fmt: skip
    state = initial_state(1) if state0 is None else np.array(state0, float).reshape(1, STATE_SIZE)
    route = Route(np.zeros(1, dtype=np.int64), np.zeros(1), np.array([float(speed_mps)]),
                  np.ones(1))  # fmt: skip
    states = np.empty((n_steps + 1, STATE_SIZE))
    outputs = np.full((n_steps + 1, N_PLANT_OUTPUTS), np.nan)
    states[0] = state[0]
    out = np.empty((1, N_PLANT_OUTPUTS))
    cmd = np.empty(1)
    mode = block_kernel_mode(damper.code, plant.damper, levitation_damped(plant.vehicle))
    kernel = BatchedKernel(PLANT, damper.code, mode, 1)
    for step in range(n_steps):
        cmd[0] = commands[step]
        kernel(plant, state, cmd, route, float(dt_s), out)
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
    for j, name in enumerate(PLANT_OUTPUT_NAMES):
        result[name] = outputs[:, j]
    return result
