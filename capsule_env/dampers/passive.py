"""The linear viscous passive damper ``F = c v`` (the passive baseline, docs/model.md 2/7)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from capsule_env._jit import kernel_function
from capsule_env.common.validation import check_nonnegative
from capsule_env.dampers.base import DamperModel, DamperParamsBase, slots

__all__ = ["LinearDamper", "MODEL"]

PARAM_NAMES = ("damping_n_s_per_m",)
(DAMPING,) = slots(PARAM_NAMES, *PARAM_NAMES)


@dataclass(frozen=True)
class LinearDamper(DamperParamsBase):
    """Linear viscous passive damper ``F = c v`` (the passive baseline, docs/model.md 2/7).

    ``damping_n_s_per_m``: c_s (N s/m), default 1.5e4 [reconstructed].
    """

    damping_n_s_per_m: float = 1.5e4
    code: ClassVar[int] = 0
    name: ClassVar[str] = "passive"
    param_names: ClassVar[tuple[str, ...]] = PARAM_NAMES

    def __post_init__(self) -> None:
        self._validate_common()
        check_nonnegative("damping_n_s_per_m", self.damping_n_s_per_m)


@kernel_function
def force(p, x: float, v: float, y: float, z: float, i: float, pre: float):
    """``(c v, 0)``: the force and no internal displacement rate."""
    return p[DAMPING] * v, 0.0


def linearise(p: np.ndarray, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """Already linear: ``c = c_s`` at every current."""
    zero = 0.0 * i
    return [(p[DAMPING] + zero, zero, zero, zero)]


MODEL = DamperModel(
    name=LinearDamper.name,
    code=LinearDamper.code,
    params=LinearDamper,
    param_names=PARAM_NAMES,
    force=force,
    linearise=linearise,
    uses_current=False,
)
