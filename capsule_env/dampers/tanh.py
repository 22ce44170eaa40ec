"""The hyperbolic-tangent hysteresis model (paper eq. 3, Kwok et al. 2006, docs/model.md 4.4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from capsule_env._fastmath import fast_tanh_nonneg
from capsule_env._jit import inlined, kernel_function
from capsule_env.common.validation import check_positive
from capsule_env.dampers.base import (
    BRANCH_BLEND,
    DamperModel,
    DamperParamsBase,
    branch_weight,
    check_blend,
    slots,
)

__all__ = ["TanhDamper", "MODEL"]

PARAM_NAMES = ("c_a", "c_b", "k_a", "k_b", "alpha_a", "alpha_b", "f0_a", "f0_b", "beta", "delta")
C_A, C_B, K_A, K_B, ALPHA_A, ALPHA_B, F0_A, F0_B, BETA, DELTA = slots(PARAM_NAMES, *PARAM_NAMES)


@dataclass(frozen=True)
class TanhDamper(DamperParamsBase):
    """Hyperbolic-tangent hysteresis model (paper eq. 3, Kwok et al. 2006, docs/model.md 4.4)::

        F = c v + k x + alpha tanh(beta v + delta sgn_w(x)) + f0
        c, k, alpha, f0 linear in current (p = p_a + p_b i); beta, delta constant

    ``sgn_w`` is ``sign(x)`` made continuous over ``|x| < branch_blend_m`` (see
    :func:`~capsule_env.dampers.base.branch_weight`): the literal sign makes the force jump at
    x = 0, where a vehicle at rest starts, and no fixed-step integrator converges there.

    Default values: identified from the reference damper's loops (variable projection over
    beta, delta; ``python -m capsule_env.identification.cli --emit-defaults``).
    """

    c_a: float = 7712.4
    c_b: float = 3348.4
    k_a: float = 22663.0
    k_b: float = -4151.8
    alpha_a: float = 715.17
    alpha_b: float = 2902.5
    f0_a: float = -8.1468
    f0_b: float = 2.7051
    beta: float = 40.729
    delta: float = -0.072137
    max_current_a: float = 1.5
    coil_time_constant_s: float = 0.0
    branch_blend_m: float = 1e-4
    code: ClassVar[int] = 3
    name: ClassVar[str] = "tanh"
    param_names: ClassVar[tuple[str, ...]] = PARAM_NAMES

    def __post_init__(self) -> None:
        self._validate_common()
        check_positive("beta", self.beta)
        check_blend(self.branch_blend_m)


@inlined
def hysteresis_term(p, x: float, v: float) -> float:
    """``tanh(beta v + delta sgn_w(x))`` (the sign of the stroke blended)."""
    arg = p[BETA] * v + p[DELTA] * (2.0 * branch_weight(x, p[BRANCH_BLEND]) - 1.0)
    th = fast_tanh_nonneg(abs(arg))
    return th if arg >= 0.0 else -th


@kernel_function
def force(p, x: float, v: float, y: float, z: float, i: float, pre: float):
    """``(F, 0)`` of paper eq. 3 with the sign of the stroke blended."""
    th = hysteresis_term(p, x, v)
    f = (p[C_A] + p[C_B] * i) * v + (p[K_A] + p[K_B] * i) * x + (p[ALPHA_A] + p[ALPHA_B] * i) * th
    return f + p[F0_A] + p[F0_B] * i, 0.0


@inlined
def affine(p, x: float, v: float, z: float):
    """``(F0, slope)``: c, k, alpha and f0 are linear in the current (the tanh inverse)."""
    th = hysteresis_term(p, x, v)
    f0 = p[C_A] * v + p[K_A] * x + p[ALPHA_A] * th + p[F0_A]
    return f0, p[C_B] * v + p[K_B] * x + p[ALPHA_B] * th + p[F0_B]


def linearise(p: np.ndarray, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """``c = |c| + |alpha| beta``; ``k = |k| + |alpha| |delta| 1.5 / width``: the branch blend,
    d/dx of ``alpha tanh(beta v + delta sgn_w(x))`` with ``sgn_w' <= 1.5 / width``."""
    zero = 0.0 * i
    alpha = np.abs(p[ALPHA_A] + p[ALPHA_B] * i)
    c = np.abs(p[C_A] + p[C_B] * i) + alpha * p[BETA]
    k = np.abs(p[K_A] + p[K_B] * i) + alpha * abs(p[DELTA]) * 1.5 / p[BRANCH_BLEND]
    return [(c, k, zero, zero)]


MODEL = DamperModel(
    name=TanhDamper.name,
    code=TanhDamper.code,
    params=TanhDamper,
    param_names=PARAM_NAMES,
    force=force,
    affine=affine,
    linearise=linearise,
)
