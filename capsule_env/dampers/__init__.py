"""MR damper forward models and the linear passive damper (docs/model.md, section 4): one
module per model, found by :mod:`~capsule_env.dampers.registry`.

Every model shares one interface: ``(stroke x, stroke rate v, current i, internal state) ->
(force F, state derivative)``. Sign convention (docs/model.md 1): ``x = z_c - z_b``, ``F > 0``
resists ``v > 0``; the force acts as ``-F`` on the car body and ``+F`` on the bogie.

Each model is a frozen dataclass of parameters that packs into a fixed-length float vector
(``as_array``) read by the compiled kernels, so a batch of parameter sets (one row per
vehicle) gives domain randomisation for free. The internal state is ``[z, y]``: the Bouc-Wen
hysteretic variable ``z`` (m) and Spencer's internal displacement ``y`` (m); models without them
ignore them. The coil current the model sees is the *actual* current; the coil/driver lag
``i' = (i_cmd - i) / tau`` is integrated by the plant (``coil_time_constant_s``, 0 = none).

| model | name | module | provenance of the default values |
| --- | --- | --- | --- |
| :class:`LinearDamper` | ``"passive"`` | ``passive.py`` | c_s of docs/model.md 2 [reconstructed] |
| :class:`ReferenceDamper` | ``"reference"`` | ``reference.py`` | Spencer et al. 1997 x 5 in force [standard, scaled] |
| :class:`BoucWenDamper` | ``"bouc_wen"`` | ``bouc_wen.py`` | identified from reference loops (docs/model.md 6) |
| :class:`TanhDamper` | ``"tanh"`` | ``tanh.py`` | identified from reference loops (docs/model.md 6) |
| :class:`BiExponentialDamper` | ``"bi_exponential"`` | ``bi_exponential.py`` | identified from reference loops (docs/model.md 6) |

Adding a model: docs/howto-damper-model.md.
"""

from __future__ import annotations

from capsule_env._jit import inlined, kernel_function
from capsule_env.dampers.api import damper_force, make_damper
from capsule_env.dampers.base import (
    N_DAMPER_PARAMS,
    DamperModel,
    DamperParamsBase,
    Hysteresis,
    branch_weight,
    branch_weights,
)
from capsule_env.dampers.bi_exponential import BiExponentialDamper, bi_exponential_branch
from capsule_env.dampers.bouc_wen import BoucWenDamper
from capsule_env.dampers.passive import LinearDamper
from capsule_env.dampers.reference import ReferenceDamper
from capsule_env.dampers.registry import DAMPER_NAMES, MODELS, model_named, register
from capsule_env.dampers.tanh import TanhDamper

__all__ = [
    "PASSIVE",
    "REFERENCE",
    "BOUC_WEN",
    "TANH",
    "BI_EXPONENTIAL",
    "DAMPER_NAMES",
    "MODELS",
    "N_DAMPER_PARAMS",
    "DamperModel",
    "DamperParamsBase",
    "Hysteresis",
    "LinearDamper",
    "ReferenceDamper",
    "BoucWenDamper",
    "TanhDamper",
    "BiExponentialDamper",
    "DamperParams",
    "make_damper",
    "damper_force",
    "model_named",
    "register",
    "branch_weight",
    "branch_weights",
    "bi_exponential_branch",
    "kernel_function",
    "inlined",
]

#: Integer codes of the built-in models (each model's ``code``; the kernels read the registry).
PASSIVE, REFERENCE, BOUC_WEN, TANH, BI_EXPONENTIAL = (
    c.code for c in (LinearDamper, ReferenceDamper, BoucWenDamper, TanhDamper, BiExponentialDamper)
)
#: The built-in parameter dataclasses (a model of one's own derives from DamperParamsBase).
DamperParams = LinearDamper | ReferenceDamper | BoucWenDamper | TanhDamper | BiExponentialDamper

#: Names of the former single module that moved: where they live now.
