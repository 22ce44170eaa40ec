"""The force laws under their former names and signatures (``capsule_env.dampers`` before the
models became one module each): deprecated, reached through ``capsule_env.dampers.<name>``
with a ``DeprecationWarning``; each model's ``force`` is the law now."""

from __future__ import annotations

from numba import njit

from capsule_env._fastmath import FAST
from capsule_env.dampers import bi_exponential, bouc_wen, tanh

__all__ = ["bouc_wen_force", "tanh_force", "bi_exponential_force"]


@njit(**FAST)
def bouc_wen_force(p, x: float, v: float, z: float, i: float) -> float:
    """Bouc-Wen force (``bouc_wen.force`` without its internal rate)."""
    return bouc_wen.force(p, x, v, 0.0, z, i, 1.0)[0]


@njit(**FAST)
def tanh_force(p, x: float, v: float, i: float) -> float:
    """tanh-model force (``tanh.force`` without its internal rate)."""
    return tanh.force(p, x, v, 0.0, 0.0, i, 1.0)[0]


@njit(**FAST)
def bi_exponential_force(p, x: float, v: float, i: float) -> float:
    """Bi-exponential force (``bi_exponential.force`` without its internal rate)."""
    return bi_exponential.force(p, x, v, 0.0, 0.0, i, 1.0)[0]
