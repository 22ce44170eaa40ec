"""The plant's structures for ``N`` vehicles: their state at rest and their :class:`PlantParams`
(packed damper and vehicle parameters, substep tables, the block kernel's constants, the
guideway profiles). The compiled kernels that step them are driven from
:mod:`capsule_env.engine.simulate` and the env."""

from __future__ import annotations

import numpy as np

from capsule_env.engine.layout import STATE_SIZE
from capsule_env.plant.block import block_constants
from capsule_env.plant.params import PlantParams
from capsule_env.plant.substeps import as_substep_table

__all__ = ["initial_state", "make_plant_params"]


def initial_state(n: int = 1) -> np.ndarray:
    """Plant at rest on a level guideway: an (n, STATE_SIZE) array of zeros."""
    return np.zeros((n, STATE_SIZE))


def make_plant_params(
    damper_code: int,
    damper_params: np.ndarray,
    vehicle_params: np.ndarray,
    substeps: int | np.ndarray,
    profiles: np.ndarray,
    spacing_m: float,
    dt_s: float,
    offsets: np.ndarray | None = None,
) -> PlantParams:
    """The :class:`PlantParams` of ``N`` vehicles (``N`` rows of packed damper and vehicle
    parameters; ``substeps`` an int, one (bins,) table or (N, bins) tables), with the block
    kernel's per-vehicle constants computed for the control interval ``dt_s``; ``offsets``:
    (K, L) elevation added to the profiles after the routes' gains (None: none)."""
    dp = np.ascontiguousarray(np.atleast_2d(damper_params), dtype=np.float64)
    vp = np.ascontiguousarray(np.atleast_2d(vehicle_params), dtype=np.float64)
    table = as_substep_table(substeps, dp.shape[0])
    constants = block_constants(damper_code, dp, dt_s, table)
    profiles = np.ascontiguousarray(np.atleast_2d(profiles), dtype=np.float64)
    off = np.zeros((0, 0)) if offsets is None else np.ascontiguousarray(offsets, dtype=np.float64)
    if off.size and off.shape != profiles.shape:
        raise ValueError(f"offsets must have the profiles' shape {profiles.shape}, got {off.shape}")
    return PlantParams(dp, vp, table, constants, profiles, float(spacing_m), off)
