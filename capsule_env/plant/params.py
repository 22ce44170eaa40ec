"""The named structures the plant kernels take (as gymnax and Brax pass ``EnvParams``):
each field an array with a documented layout (:mod:`capsule_env.engine.layout`), one row per vehicle.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["PlantParams", "Route"]


class PlantParams(NamedTuple):
    """What the plant of each vehicle is made of (changes only at a reset).

    Attributes
    ----------
    damper : (N, N_DAMPER_PARAMS) packed damper parameters (``layout.DAMPER_PARAM_NAMES``).
    vehicle : (N, N_VEHICLE_PARAMS) packed vehicle parameters (``layout.VEHICLE_PARAM_NAMES``).
    substeps : (N, bins) int64 RK4 substeps per control step by coil-current bin
        (:func:`capsule_env.plant.substeps.substep_tables`).
    constants : (N, N_BLOCK_CONSTANTS) per-vehicle constants of the vectorised kernel
        (:func:`capsule_env.plant.block.block_constants`).
    profiles : (K, L) guideway elevation profiles (m), sampled every ``spacing_m``.
    spacing_m : profile sample spacing (m).
    offsets : (K, L) elevation added to each profile after its route's gain (m; the tube's
        spans, :mod:`capsule_env.guideway.spans`), or an empty (0, 0) array: none.
    """

    damper: np.ndarray
    vehicle: np.ndarray
    substeps: np.ndarray
    constants: np.ndarray
    profiles: np.ndarray
    spacing_m: float
    offsets: np.ndarray


class Route(NamedTuple):
    """Where each vehicle runs: profile ``profile[n]`` read at ``start_m[n] + speed_mps[n] t``,
    scaled by ``gain[n]`` (plus the plant's ``offsets[profile[n]]`` there, unscaled)."""

    profile: np.ndarray  # (N,) int64
    start_m: np.ndarray  # (N,)
    speed_mps: np.ndarray  # (N,)
    gain: np.ndarray  # (N,)
