"""capsule-env: semi-active MR-damper suspension of a Hyperloop capsule vehicle.

Physics (pure functions and frozen parameter dataclasses, no Gym import):

- :mod:`capsule_env.vehicles.modes`: the 2-DOF vertical 1/4-car, modes, state-space form.
- :mod:`capsule_env.guideway`: FRA-shaped random guideway, sine, swept sine, bump, step.
- :mod:`capsule_env.dampers`: MR damper forward models (reference Spencer, Bouc-Wen, tanh,
  Bi-exponential) and the linear passive damper, one interface.
- :mod:`capsule_env.dampers.hysteresis`: closed-form Bouc-Wen (n = 2) update.
- :mod:`capsule_env.plant`: the batched plant + damper integration kernels.
- :mod:`capsule_env.dampers.rig`: a damper alone under a prescribed stroke (test-rig loops).
"""

# First: a writable place for numba's cache before any kernel is defined (capsule_env._jit).
from capsule_env import _jit  # noqa: F401  (isort: keep first)
from capsule_env.dampers import (
    DAMPER_NAMES,
    BiExponentialDamper,
    BoucWenDamper,
    LinearDamper,
    ReferenceDamper,
    TanhDamper,
    damper_force,
    make_damper,
)
from capsule_env.guideway import GuidewayParams, make_profile, random_profile
from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.modes import (
    modal_properties,
    natural_frequencies_hz,
    state_space,
)

__version__ = "0.1.0"

__all__ = [
    "DAMPER_NAMES",
    "BiExponentialDamper",
    "BoucWenDamper",
    "GuidewayParams",
    "LinearDamper",
    "ReferenceDamper",
    "TanhDamper",
    "VehicleParams",
    "damper_force",
    "make_damper",
    "make_profile",
    "modal_properties",
    "natural_frequencies_hz",
    "random_profile",
    "state_space",
]


def _register() -> None:
    """Register ``CapsuleSuspension-v0`` with Gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    if "CapsuleSuspension-v0" not in registry:
        register(
            id="CapsuleSuspension-v0",
            entry_point="capsule_env.envs.declared_vehicle:make_suspension_env",
            vector_entry_point="capsule_env.envs.declared_vector:make_suspension_vector_env",
            # no max_episode_steps: the env ends its episodes itself after episode_length_s *
            # control_rate_hz steps, an argument (a fixed number here would override it)
        )
    from capsule_env.tasks import register_tasks

    register_tasks()


_register()
