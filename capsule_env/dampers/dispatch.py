"""The compile-time dispatch on a damper model's code: what compiled code calls to use "the
model", without naming one.

Each function here takes the model's integer code as its first argument, a compile-time
constant of the caller (a closure variable or a literal), and compiles only that model's code
(:func:`capsule_env._jit.specialised`). A Python-level entry point that takes the code as a
value makes it one with ``numba.literally(model)``.
"""

from __future__ import annotations

from capsule_env._jit import KERNEL_OPTIONS, specialised
from capsule_env.dampers.registry import model_of_code

__all__ = ["model_prepare", "model_force", "model_affine", "hysteresis_params", "damper_eval"]


@specialised("model")
def model_prepare(model, p, i):
    """The model's ``prepare(p, i)`` at current ``i`` (Spencer's ``1 / (c0 + c1)``; 1 for
    models without one)."""
    prepare = model_of_code(model).prepare

    def impl(model, p, i):
        return prepare(p, i)

    return impl


@specialised("model")
def model_force(model, p, x, v, y, z, i, pre):
    """``(F, y')`` of the model at stroke ``x``, stroke rate ``v``, internal displacement
    ``y``, hysteretic variable ``z``, current ``i`` and ``pre`` = :func:`model_prepare`."""
    force = model_of_code(model).force

    def impl(model, p, x, v, y, z, i, pre):
        return force(p, x, v, y, z, i, pre)

    return impl


# Inlined by LLVM (forceinline) into the SIMD loops that invert it, not by numba: numba's
# inlining of an overload types its implementation again at every call site, besides compiling
# it for itself (a first step typed the Bi-exponential's four times).
@specialised("model", forceinline=True, **KERNEL_OPTIONS)
def model_affine(model, p, x, v, z):
    """``(F0, slope)`` with ``F(i) = F0 + slope * i`` for the model at ``(x, v, z)``: its
    ``affine`` form (a model without one has none: a typing error names it)."""
    m = model_of_code(model)
    if m.affine is None:
        raise TypeError(f"damper model {m.name!r} has no affine-in-current form to invert")
    affine = m.affine

    def impl(model, p, x, v, z):
        return affine(p, x, v, z)

    return impl


@specialised("model", inline="always", cache=True)
def hysteresis_params(model, p):
    """``(A, gamma, beta)`` of the model's hysteresis (zeros for models without one)."""
    hyst = model_of_code(model).hysteresis
    if hyst is None:

        def impl(model, p):
            return 0.0, 0.0, 0.0

    else:
        a_k, g_k, b_k = hyst.a_coef, hyst.gamma, hyst.beta

        def impl(model, p):
            return p[a_k], p[g_k], p[b_k]

    return impl


@specialised("model", inline="always", cache=True)
def damper_eval(model, p, x, v, y, z, i):
    """Force and internal rates of one damper: ``(F, y', w)``: force (N), the internal
    displacement's rate (m/s; 0 for models without one) and ``w = x' - y'``, the deformation
    rate that drives the hysteretic variable (0 for models without one)."""
    m = model_of_code(model)
    prepare, force = m.prepare, m.force
    if m.hysteresis is None:

        def impl(model, p, x, v, y, z, i):
            f, y_dot = force(p, x, v, y, z, i, prepare(p, i))
            return f, y_dot, 0.0

    else:

        def impl(model, p, x, v, y, z, i):
            f, y_dot = force(p, x, v, y, z, i, prepare(p, i))
            return f, y_dot, v - y_dot

    return impl
