"""The 1/4-car plant with its secondary damper: integration, batched and compiled (no Gym).

- :mod:`~capsule_env.plant.rk4`: the RK4 substep (shared by both kernels).
- :mod:`~capsule_env.plant.block`: the vectorised block kernel.
- :mod:`~capsule_env.plant.scalar`: the scalar reference kernel (every model and shape).
- :mod:`~capsule_env.plant.substeps`: how many substeps each vehicle needs.
- :mod:`~capsule_env.plant.build`: the structures of ``N`` vehicles (:func:`make_plant_params`,
  :func:`initial_state`); :mod:`capsule_env.engine.simulate` steps them from Python
  (:func:`~capsule_env.engine.simulate.step_batch`, open-loop runs:
  :func:`~capsule_env.engine.simulate.simulate`).
- :mod:`~capsule_env.plant.params`: the named structures the kernels take.

The plant state's columns are ``capsule_env.engine.layout.STATE_NAMES``.
"""

from capsule_env.plant.block import block_constants, block_kernel_mode
from capsule_env.plant.build import initial_state, make_plant_params
from capsule_env.plant.params import PlantParams, Route
from capsule_env.plant.substeps import (
    DEFAULT_INPUT_RATE,
    MAX_AUTO_SUBSTEPS,
    SUBSTEP_BINS,
    default_substeps,
    stiffness_rates,
    substep_table,
    substep_tables,
)

__all__ = [
    "DEFAULT_INPUT_RATE",
    "MAX_AUTO_SUBSTEPS",
    "SUBSTEP_BINS",
    "PlantParams",
    "Route",
    "block_constants",
    "block_kernel_mode",
    "default_substeps",
    "initial_state",
    "make_plant_params",
    "stiffness_rates",
    "substep_table",
    "substep_tables",
]
