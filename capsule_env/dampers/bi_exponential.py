"""The Bi-exponential MR damper model (paper eq. 4, docs/model.md 4.5) [reconstructed form]."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from capsule_env._fastmath import fast_exp
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

__all__ = ["BiExponentialDamper", "MODEL", "bi_exponential_branch"]

#: The parameters of one branch; the upper (x >= 0) set, then the lower (x < 0) one.
BRANCH_PARAMS = ("a0", "a1", "b0", "b1", "c0", "c1", "d")
PARAM_NAMES = tuple(f"{branch}_{p}" for branch in ("upper", "lower") for p in BRANCH_PARAMS)
#: Offsets of the upper and lower branches, and of each parameter within a branch.
UPPER, LOWER = slots(PARAM_NAMES, "upper_a0", "lower_a0")
A0, A1, B0, B1, C0, C1, D = slots(BRANCH_PARAMS, *BRANCH_PARAMS)


@dataclass(frozen=True)
class BiExponentialDamper(DamperParamsBase):
    """Bi-exponential MR damper model (paper eq. 4, docs/model.md 4.5) [reconstructed form]::

        S_d(v) = sign(v) (1 - exp(-d |v|))
        F(v, i) = a(i) S_d(v) + b(i) v + c(i)    (upper set when x >= 0, lower set when x < 0)
        a(i) = a0 + a1 i,  b(i) = b0 + b1 i,  c(i) = c0 + c1 i,  d constant per branch (s/m)

    a: yield force (N), b: post-yield viscous slope (N s/m), c: hysteresis offset (N).
    Within ``|x| < branch_blend_m`` the seven parameters pass smoothly from the lower set to
    the upper one (:func:`~capsule_env.dampers.base.branch_weight`) [reconstructed
    regularisation, default 0.1 mm]: the literal switch makes the force jump by
    ``c_upper - c_lower`` (about 700 N) at x = 0, where a vehicle at rest starts, and no
    fixed-step integrator converges there.
    Default values: identified from the reference damper's loops by the paper's procedure
    (per branch and current fits; d = mean over currents; a, b, c refitted and made linear in
    current; ``python -m capsule_env.identification.cli --emit-defaults``), with the literal branch split
    ``x >= 0`` / ``x < 0`` (``fit_bi_exponential(loops, branch_gap_m=0.0)``). Today's
    ``--emit-defaults`` leaves out the samples within ``branch_blend_m`` of ``x = 0`` (two of
    1000 per loop) and differs by up to 0.58 %; the defaults were kept (docs/model.md 6).
    """

    upper_a0: float = 683.33
    upper_a1: float = 2355.0
    upper_b0: float = 7934.0
    upper_b1: float = 7596.9
    upper_c0: float = 346.01
    upper_c1: float = -82.488
    upper_d: float = 118.68
    lower_a0: float = 683.01
    lower_a1: float = 2353.3
    lower_b0: float = 7939.7
    lower_b1: float = 7608.8
    lower_c0: float = -362.3
    lower_c1: float = 87.897
    lower_d: float = 119.0
    max_current_a: float = 1.5
    coil_time_constant_s: float = 0.0
    branch_blend_m: float = 1e-4
    code: ClassVar[int] = 4
    name: ClassVar[str] = "bi_exponential"
    param_names: ClassVar[tuple[str, ...]] = PARAM_NAMES

    def __post_init__(self) -> None:
        self._validate_common()
        check_positive("upper_d", self.upper_d)
        check_positive("lower_d", self.lower_d)
        check_blend(self.branch_blend_m)


@inlined
def bi_exponential_branch(p, x: float):
    """The parameters ``(a0, a1, b0, b1, c0, c1, d)`` at stroke ``x``: the lower set plus
    :func:`~capsule_env.dampers.base.branch_weight` times (upper - lower)."""
    w = branch_weight(x, p[BRANCH_BLEND])
    up, lo = UPPER, LOWER
    return (
        p[lo + A0] + w * (p[up + A0] - p[lo + A0]),
        p[lo + A1] + w * (p[up + A1] - p[lo + A1]),
        p[lo + B0] + w * (p[up + B0] - p[lo + B0]),
        p[lo + B1] + w * (p[up + B1] - p[lo + B1]),
        p[lo + C0] + w * (p[up + C0] - p[lo + C0]),
        p[lo + C1] + w * (p[up + C1] - p[lo + C1]),
        p[lo + D] + w * (p[up + D] - p[lo + D]),
    )


@inlined
def saturation(d: float, v: float) -> float:
    """``S_d(v) = sign(v) (1 - exp(-d |v|))``."""
    mag = 1.0 - fast_exp(-d * abs(v))
    return mag if v >= 0.0 else -mag


@kernel_function
def force(p, x: float, v: float, y: float, z: float, i: float, pre: float):
    """``(F, 0)`` of paper eq. 4 with the branches blended."""
    a0, a1, b0, b1, c0, c1, d = bi_exponential_branch(p, x)
    s_d = saturation(d, v)
    return (a0 + a1 * i) * s_d + (b0 + b1 * i) * v + c0 + c1 * i, 0.0


@inlined
def affine(p, x: float, v: float, z: float):
    """``(F0, slope)`` of paper eqs. 5-11: ``F0 = a0 S_d + b0 v + c0``,
    ``slope = a1 S_d + b1 v + c1``."""
    a0, a1, b0, b1, c0, c1, d = bi_exponential_branch(p, x)
    s_d = saturation(d, v)
    return a0 * s_d + b0 * v + c0, a1 * s_d + b1 * v + c1


def linearise(p: np.ndarray, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """``c``: the steeper branch's slope at ``v = 0`` (``|a| d + |b|``); ``k``: the force step
    between the branches (at ``|v| <= 1`` m/s) over the blend, whose weight rises with slope
    at most ``0.75 / width``."""
    zero = 0.0 * i
    up, lo = UPPER, LOWER
    slopes = [np.abs(p[o + A0] + p[o + A1] * i) * p[o + D] + np.abs(p[o + B0] + p[o + B1] * i)
              for o in (up, lo)]  # fmt: skip

    def jump(k0: int, k1: int) -> np.ndarray:  # |upper - lower| of a current-linear law
        return np.abs((p[up + k0] - p[lo + k0]) + (p[up + k1] - p[lo + k1]) * i)

    step = jump(C0, C1) + jump(A0, A1) + jump(B0, B1)
    return [(np.maximum(*slopes), step * 0.75 / p[BRANCH_BLEND], zero, zero)]


MODEL = DamperModel(
    name=BiExponentialDamper.name,
    code=BiExponentialDamper.code,
    params=BiExponentialDamper,
    param_names=PARAM_NAMES,
    force=force,
    affine=affine,
    linearise=linearise,
)
