"""The reference damper: Spencer et al. (1997) modified Bouc-Wen model, the "hardware" in
simulation (docs/model.md 4.2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from capsule_env._jit import kernel_function
from capsule_env.common.validation import check_nonnegative, check_positive
from capsule_env.dampers.base import (
    DamperModel,
    DamperParamsBase,
    Hysteresis,
    check_bouc_wen_shape,
    slots,
)

__all__ = ["ReferenceDamper", "MODEL", "spencer_force", "spencer_inv_dashpots"]

PARAM_NAMES = ("c0a", "c0b", "c1a", "c1b", "alpha_a", "alpha_b", "k0", "k1", "x0", "gamma",
               "beta", "a_coef")  # fmt: skip
C0A, C0B, C1A, C1B, ALPHA_A, ALPHA_B, K0, K1, X0, GAMMA, BETA, A = slots(PARAM_NAMES, *PARAM_NAMES)


@dataclass(frozen=True)
class ReferenceDamper(DamperParamsBase):
    """Spencer et al. (1997) modified Bouc-Wen model: the "hardware" in simulation (docs/model.md 4.2).

    ::

        F  = c1 y' + k1 (x - x0)
        y' = (alpha z + c0 x' + k0 (x - y)) / (c0 + c1)
        z' = -gamma |x' - y'| z |z| - beta (x' - y') z^2 + A (x' - y')      (n = 2)
        p(i) = p_a + p_b i   for alpha, c0, c1;   i' = (i_cmd - i) / tau

    Provenance: [standard form, scaled]. Spencer's published values in SI with every force
    coefficient x 5 (capsule size) and command voltage replaced by current through
    ``u = 1.5 V/A * i`` (b-coefficients = Spencer's per-volt values x 5 x 1.5). Spencer's
    eta = 190 1/s becomes ``coil_time_constant_s = 1/190``. ``n`` is fixed at Spencer's 2, which
    gives the closed-form hysteresis update used by the integrator.
    """

    c0a: float = 1.05e4
    c0b: float = 2.625e3
    c1a: float = 1.415e5
    c1b: float = 2.2125e3
    alpha_a: float = 7.0e4
    alpha_b: float = 5.2125e5
    k0: float = 2.345e4
    k1: float = 2.5e3
    x0: float = 0.0
    gamma: float = 3.63e6
    beta: float = 3.63e6
    a_coef: float = 301.0
    max_current_a: float = 1.5
    coil_time_constant_s: float = 1.0 / 190.0
    code: ClassVar[int] = 1
    name: ClassVar[str] = "reference"
    param_names: ClassVar[tuple[str, ...]] = PARAM_NAMES

    def __post_init__(self) -> None:
        self._validate_common()
        for n in ("c0a", "c1a", "a_coef"):
            check_positive(n, getattr(self, n))
        for n in ("c0b", "c1b", "alpha_a", "alpha_b", "k0", "k1"):
            check_nonnegative(n, getattr(self, n))
        check_bouc_wen_shape(self.gamma, self.beta)


@kernel_function
def spencer_inv_dashpots(p, i: float) -> float:
    """``1 / (c0 + c1)`` at current ``i`` (the model's ``prepare``)."""
    return 1.0 / ((p[C0A] + p[C0B] * i) + (p[C1A] + p[C1B] * i))


@kernel_function
def spencer_force(p, x: float, v: float, y: float, z: float, i: float, inv_c: float):
    """``(F, y')`` with ``inv_c = 1 / (c0 + c1)`` at ``i`` (:func:`spencer_inv_dashpots`,
    computed ahead, off the integrator's dependency chain)."""
    c0 = p[C0A] + p[C0B] * i
    c1 = p[C1A] + p[C1B] * i
    alpha = p[ALPHA_A] + p[ALPHA_B] * i
    y_dot = (alpha * z + c0 * v + p[K0] * (x - y)) * inv_c
    return c1 * y_dot + p[K1] * (x - p[X0]), y_dot


def linearise(p: np.ndarray, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """Pre-yield (``z = A u`` follows the deformation: the stiffest) and yielded (``z``
    saturated): ``(c0, k1, alpha A + k0, c0 + c1)`` and ``(c0, k1, k0, c0 + c1)``."""
    zero = 0.0 * i
    c0, c1 = p[C0A] + p[C0B] * i, p[C1A] + p[C1B] * i
    alpha = p[ALPHA_A] + p[ALPHA_B] * i
    pre_yield = (c0, p[K1] + zero, alpha * p[A] + p[K0], c0 + c1)
    return [pre_yield, (c0, p[K1] + zero, p[K0] + zero, c0 + c1)]


MODEL = DamperModel(
    name=ReferenceDamper.name,
    code=ReferenceDamper.code,
    params=ReferenceDamper,
    param_names=PARAM_NAMES,
    force=spencer_force,
    prepare=spencer_inv_dashpots,
    hysteresis=Hysteresis(a_coef=A, gamma=GAMMA, beta=BETA, fast=True),
    internal_displacement=True,
    linearise=linearise,
)
