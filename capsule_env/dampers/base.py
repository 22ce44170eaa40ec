"""What a damper model is: the description every model module declares (:class:`DamperModel`),
the packed parameter vector the kernels read, and what the models share.

A model module (``capsule_env/dampers/<model>.py``) exports ``MODEL``, a :class:`DamperModel`
that names the model, its integer code, its parameter dataclass (whose fields, in order, are
the packed slots), its force law, its hysteresis, and where it has them its force as an affine
function of the current (for the inverse controllers) and its linearisation near rest (for the
plant's substep rule). :mod:`capsule_env.dampers.registry` collects the modules; the kernels,
the substep rule, the inverse and the configuration read the registry and never name a model.

Packed parameters (``params.as_array()``, one row per vehicle in the kernels): the model's own
parameters in the order of :attr:`DamperModel.param_names` (at most :data:`MAX_MODEL_PARAMS`),
then the shared slots :data:`SHARED_DAMPER_SLOTS` at :data:`I_MAX`, :data:`COIL_TAU`,
:data:`BRANCH_BLEND` (0 where a model has no such field).

The compiled functions of a model take ``p``, the packed parameters (an array row or a tuple),
and ``i``, the actual coil current (A); they are written without branches or library calls
(``exp``/``tanh`` from :mod:`capsule_env._fastmath`) so that the plant's loop over vehicles
vectorises:

- ``prepare(p, i)``: a current-dependent value computed once per current, off the
  integrator's dependency chain (Spencer's ``1 / (c0 + c1)``; :func:`no_preparation` else);
- ``force(p, x, v, y, z, i, pre) -> (F, y')``: the force (N, ``> 0`` resisting ``v > 0``) and
  the rate of the model's internal displacement ``y`` (0 for models without one), at stroke
  ``x``, stroke rate ``v``, hysteretic variable ``z``;
- ``affine(p, x, v, z) -> (F0, slope)`` with ``F(i) = F0 + slope i`` (optional).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numba import njit

from capsule_env._jit import inlined, kernel_function
from capsule_env.common.validation import check_finite, check_nonnegative, check_positive

__all__ = [
    "MAX_MODEL_PARAMS",
    "SHARED_DAMPER_SLOTS",
    "I_MAX",
    "COIL_TAU",
    "BRANCH_BLEND",
    "N_DAMPER_PARAMS",
    "Hysteresis",
    "DamperModel",
    "DamperParamsBase",
    "slots",
    "no_preparation",
    "branch_weight",
    "branch_weights",
    "check_blend",
    "check_bouc_wen_shape",
]

#: Most parameters a model may pack before the shared slots.
MAX_MODEL_PARAMS = 14
#: Slots every model has, after its own parameters.
SHARED_DAMPER_SLOTS = ("max_current_a", "coil_time_constant_s", "branch_blend_m")
I_MAX, COIL_TAU, BRANCH_BLEND = (MAX_MODEL_PARAMS + SHARED_DAMPER_SLOTS.index(n)
                                 for n in SHARED_DAMPER_SLOTS)  # fmt: skip
#: Length of a packed damper parameter vector.
N_DAMPER_PARAMS = MAX_MODEL_PARAMS + len(SHARED_DAMPER_SLOTS)


def slots(names: tuple[str, ...], *wanted: str) -> tuple[int, ...]:
    """The packed slots of parameters ``wanted`` among a model's ``names`` (compile-time
    constants of its laws)."""
    return tuple(names.index(n) for n in wanted)


@dataclass(frozen=True)
class Hysteresis:
    """A model's Bouc-Wen hysteretic variable ``z`` (n = 2): ``z' = -gamma |w| z |z| - beta w
    z^2 + A w`` driven by the deformation rate ``w = x' - y'``.

    ``a_coef``, ``gamma``, ``beta``: the packed slots of ``A``, ``gamma``, ``beta``.
    ``fast``: whether the vectorised kernel may advance ``z`` with the branch-free Riccati
    form (Spencer: yes where ``beta >= gamma``; Bouc-Wen: no, its identified unloading
    branch needs tan/atan and it runs on the scalar kernel).
    """

    a_coef: int
    gamma: int
    beta: int
    fast: bool = False


@dataclass(frozen=True)
class DamperModel:
    """The description of one damper model, read by the registry and the kernels.

    Attributes
    ----------
    name : the model's name (``EnvConfig.damper``, ``make_damper``).
    code : its integer code, a compile-time constant of the kernels (unique).
    params : its parameter dataclass (a :class:`DamperParamsBase`), whose fields are packed.
    param_names : the packed order of the model's own parameters.
    force : compiled ``force(p, x, v, y, z, i, pre) -> (F, y')``.
    prepare : compiled ``prepare(p, i)``, the ``pre`` of ``force`` (:func:`no_preparation`).
    hysteresis : its hysteretic variable, or None (an algebraic model).
    internal_displacement : whether it has Spencer's internal displacement ``y``.
    uses_current : whether the current changes its force (False: the plant sees 0 A).
    affine : compiled ``affine(p, x, v, z) -> (F0, slope)``, or None: the force as an affine
        function of the current, which the inverse controllers invert.
    inverse_name : the name of that inverse (``EnvConfig.inverse_model``; the model's name by
        default; Bouc-Wen's is ``"csdc"``, which keeps a hysteresis estimate).
    linearise : ``linearise(p, i) -> [(c, k, K, C), ...]``: the model near ``x = v = 0`` in
        each of its regimes, arrays over the currents ``i`` (numpy; the substep rule,
        :func:`capsule_env.plant.substeps.stiffness_rates`): ``F = c x' + k x`` for an
        algebraic model (``K = C = 0``); with an internal displacement
        ``y' = (K (x - y) + c x') / C`` and ``F = (C - c) y' + k x``.
    """

    name: str
    code: int
    params: type
    param_names: tuple[str, ...]
    force: Any
    linearise: Callable[[np.ndarray, np.ndarray], list[tuple[np.ndarray, ...]]]
    prepare: Any = None
    hysteresis: Hysteresis | None = None
    internal_displacement: bool = False
    uses_current: bool = True
    affine: Any = None
    inverse_name: str = ""

    def __post_init__(self) -> None:
        if not self.inverse_name:
            object.__setattr__(self, "inverse_name", self.name)
        if self.prepare is None:
            object.__setattr__(self, "prepare", no_preparation)
        if len(self.param_names) > MAX_MODEL_PARAMS:
            raise ValueError(
                f"damper model {self.name!r} has {len(self.param_names)} parameters; at most "
                f"{MAX_MODEL_PARAMS} fit before the shared slots"
            )


class DamperParamsBase:
    """Packing and shared validation of a model's parameter dataclass (frozen dataclasses
    deriving from it set the class variables ``name`` and ``code``)."""

    code: ClassVar[int]
    name: ClassVar[str]
    param_names: ClassVar[tuple[str, ...]]

    def as_array(self) -> np.ndarray:
        """Packed float64 vector of length :data:`N_DAMPER_PARAMS` for the kernels: the
        model's parameters in the order of ``param_names``, then ``max_current_a``,
        ``coil_time_constant_s`` and ``branch_blend_m`` (0 where absent)."""
        out = np.zeros(N_DAMPER_PARAMS)
        for slot, field_name in enumerate(self.param_names):
            out[slot] = getattr(self, field_name)
        out[I_MAX] = getattr(self, "max_current_a", 0.0)
        out[COIL_TAU] = getattr(self, "coil_time_constant_s", 0.0)
        out[BRANCH_BLEND] = getattr(self, "branch_blend_m", 0.0)
        return out

    def _validate_common(self) -> None:
        for f in fields(self):  # type: ignore[arg-type]
            check_finite(f.name, getattr(self, f.name))
        if hasattr(self, "max_current_a"):
            check_positive("max_current_a", self.max_current_a)
            check_nonnegative("coil_time_constant_s", self.coil_time_constant_s)


@kernel_function
def no_preparation(p, i: float) -> float:
    """The ``prepare`` of a model that needs none."""
    return 1.0


@inlined
def branch_weight(x: float, width_m: float) -> float:
    """Weight of the upper (x >= 0) branch of a sign-of-stroke model: 0 for ``x <= -width_m``,
    1 for ``x >= width_m``, the smoothstep ``s^2 (3 - 2 s)`` of ``s = (1 + x / width_m) / 2`` in
    between (continuous force and slope; no branch, so loops over vehicles vectorise)."""
    s = min(max(0.5 + 0.5 * x / width_m, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@njit(cache=True)
def branch_weights(x: np.ndarray, width_m: float) -> np.ndarray:
    """:func:`branch_weight` of every element of a 1-D array (numpy callers: identification)."""
    out = np.empty(x.shape[0])
    for k in range(x.shape[0]):
        out[k] = branch_weight(x[k], width_m)
    return out


def check_blend(width_m: float) -> None:
    """``branch_blend_m`` within [1e-7, 1e-2] m."""
    if not 1e-7 <= width_m <= 1e-2:
        raise ValueError(
            f"branch_blend_m must be in [1e-07, 0.01] m (the stroke band over which the "
            f"sign-of-stroke branch switches), got {width_m!r}"
        )


def check_bouc_wen_shape(gamma: float, beta: float) -> None:
    """Bounded Bouc-Wen loop (n = 2): gamma >= 0 and gamma + beta > 0.

    Loading saturates at ``sqrt(A / (gamma + beta))``; unloading moves towards
    ``sqrt(A / (beta - gamma))``, which lies inside the saturation level only if gamma >= 0.
    """
    if not (gamma >= 0.0 and gamma + beta > 0.0):
        raise ValueError(
            "gamma must be >= 0 and gamma + beta > 0 for a bounded hysteresis loop, got "
            f"gamma={gamma!r}, beta={beta!r}"
        )
