"""The Bouc-Wen MR damper model (paper eq. 1, docs/model.md 4.3): the model the CSDC inverse
controller inverts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from capsule_env._jit import inlined, kernel_function
from capsule_env.common.validation import check_positive
from capsule_env.dampers.base import (
    DamperModel,
    DamperParamsBase,
    Hysteresis,
    check_bouc_wen_shape,
    slots,
)

__all__ = ["BoucWenDamper", "MODEL"]

PARAM_NAMES = ("c0a", "c0b", "alpha_a", "alpha_b", "k0", "x0", "gamma", "beta", "a_coef")
C0A, C0B, ALPHA_A, ALPHA_B, K0, X0, GAMMA, BETA, A = slots(PARAM_NAMES, *PARAM_NAMES)


@dataclass(frozen=True)
class BoucWenDamper(DamperParamsBase):
    """Bouc-Wen MR damper model (paper eq. 1, docs/model.md 4.3) [standard form]::

        F  = c0 x' + k0 (x - x0) + alpha z
        z' = -gamma |x'| z |z| - beta x' z^2 + A x'        (n = 2)
        alpha = alpha_a + alpha_b i,   c0 = c0a + c0b i

    Default values: identified from the reference damper's loops (1 Hz, +-25 mm, 0-1.5 A) by
    nonlinear least squares in the A = 1 form (z in metres, yield displacement
    ``1/sqrt(gamma + beta)``): ``python -m capsule_env.identification.cli --emit-defaults`` regenerates
    them and ``tests/test_identification.py`` checks they agree. ``n`` is fixed at 2
    (closed-form hysteresis update).
    """

    c0a: float = 8432.5
    c0b: float = 11518.0
    alpha_a: float = 8.8191e7
    alpha_b: float = 2.6567e8
    k0: float = 15768.0
    x0: float = 0.00038801
    gamma: float = 2.0282e10
    beta: float = 1.0146e7
    a_coef: float = 1.0
    max_current_a: float = 1.5
    coil_time_constant_s: float = 0.0
    code: ClassVar[int] = 2
    name: ClassVar[str] = "bouc_wen"
    param_names: ClassVar[tuple[str, ...]] = PARAM_NAMES

    def __post_init__(self) -> None:
        self._validate_common()
        check_positive("a_coef", self.a_coef)
        check_bouc_wen_shape(self.gamma, self.beta)


@kernel_function
def force(p, x: float, v: float, y: float, z: float, i: float, pre: float):
    """``(c0 v + k0 (x - x0) + alpha z, 0)`` (paper eq. 1)."""
    return (
        (p[C0A] + p[C0B] * i) * v + p[K0] * (x - p[X0]) + (p[ALPHA_A] + p[ALPHA_B] * i) * z
    ), 0.0


@inlined
def affine(p, x: float, v: float, z: float):
    """``(F0, slope)``: ``F0 = c0a v + k0 (x - x0) + alpha_a z``, ``slope = c0b v + alpha_b z``
    (the algebraic core of the CSDC inverse, Wang & Liao 2005)."""
    f0 = p[C0A] * v + p[K0] * (x - p[X0]) + p[ALPHA_A] * z
    return f0, p[C0B] * v + p[ALPHA_B] * z


def linearise(p: np.ndarray, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """Pre-yield (``z = A x``: ``k0 + |alpha| A``) and yielded (``k0``), dashpot ``c0``."""
    zero = 0.0 * i
    c0, alpha = p[C0A] + p[C0B] * i, p[ALPHA_A] + p[ALPHA_B] * i
    pre_yield = (c0, p[K0] + np.abs(alpha) * p[A], zero, zero)
    return [pre_yield, (c0, p[K0] + zero, zero, zero)]


MODEL = DamperModel(
    name=BoucWenDamper.name,
    code=BoucWenDamper.code,
    params=BoucWenDamper,
    param_names=PARAM_NAMES,
    force=force,
    hysteresis=Hysteresis(a_coef=A, gamma=GAMMA, beta=BETA, fast=False),
    affine=affine,
    inverse_name="csdc",
    linearise=linearise,
)
