"""Elementary functions written in plain arithmetic, so that loops calling them vectorise.

LLVM vectorises a numba loop over vehicles (SIMD: 4 or 8 vehicles per instruction) only when
its body makes no library calls; ``math.exp``, ``math.log`` and ``math.cos`` are library calls.
These replacements use only ``+ - * /``, ``floor`` and bit casts between float64 and int64, so
the same code runs in the vectorised loop body and in its scalar remainder: a vehicle gets the
same bits whichever lane it lands in (the env's single-vs-vector equivalence relies on that).

Accuracy against libm over the ranges the kernels use (``tests/test_fastmath.py``): a few ulp
(relative error below 1e-15 for exp and cos, absolute below 1e-15 for log and tanh).

All functions are compiled with ``error_model="numpy"``: numba's default Python error model
checks every float division for zero and raises, a branch that stops vectorisation.
"""

from __future__ import annotations

import math

from numba import njit, types
from numba.extending import intrinsic

__all__ = [
    "fast_exp",
    "fast_log",
    "fast_cos_2pi",
    "fast_tanh_nonneg",
    "FAST",
    "INTERNAL",
    "BORROWED",
]

#: Decorator options of every function that must vectorise.
FAST = {"cache": True, "error_model": "numpy"}
#: Decorator options of a function only ever called from other numba functions: no CPython
#: wrapper (Python cannot call it) and no C-callable wrapper. Numba generates, optimises and
#: emits both for every compiled function otherwise; the CPython wrapper of a function taking
#: the env's named structures unboxes each of their fields: a large share of its compile time.
INTERNAL = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}
#: ... and of one that allocates no array: it borrows every array from its caller, so numba
#: emits no reference counting in it (``_nrt=False``). Numba otherwise increments and
#: decrements, atomically, the count of every array it reads from a named structure and of
#: every view it makes: about 240 atomic operations in a single ``hils`` env step, 18 % of
#: its time (measured with perf). Such a function fails to compile if it allocates.
BORROWED = {**INTERNAL, "_nrt": False}

_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e00
_LN2 = 0.6931471805599453
_SQRT2 = 1.4142135623730951


@intrinsic
def _bits_to_float(typingctx, bits):
    """Reinterpret an int64 as a float64 (no conversion)."""
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.float64))

    return sig, codegen


@intrinsic
def _float_to_bits(typingctx, value):
    """Reinterpret a float64 as an int64 (no conversion)."""
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.int64))

    return sig, codegen


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's ``llvm.fma.f64``: a fused multiply-add, which the
    vectoriser widens; :mod:`capsule_env.plant.glibc_tanh`'s)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(**FAST)
def fast_exp(x: float) -> float:
    """``exp(x)`` for ``x`` in [-708, 709] (clamped outside): ``2^k * exp(r)``, ``|r| <= ln2/2``,
    with a degree-13 Taylor polynomial (truncation below 2e-17) in Estrin's form."""
    x = min(max(x, -708.0), 709.0)
    k = math.floor(x * _INV_LN2 + 0.5)
    r = (x - k * _LN2_HI) - k * _LN2_LO
    # Estrin's scheme: the same polynomial with a short dependency chain (the kernels are
    # latency bound, and Horner's 13 dependent multiply-adds dominated a substep).
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    q0 = (1.0 + r) + (0.5 + r * (1.0 / 6.0)) * r2
    q1 = (1.0 / 24.0 + r * (1.0 / 120.0)) + (1.0 / 720.0 + r * (1.0 / 5040.0)) * r2
    q2 = (1.0 / 40320.0 + r * (1.0 / 362880.0)) + (1.0 / 3628800.0 + r * (1.0 / 39916800.0)) * r2
    q3 = 1.0 / 479001600.0 + r * (1.0 / 6227020800.0)
    p = (q0 + q1 * r4) + (q2 + q3 * r4) * r8
    scale = _bits_to_float((int(k) + 1023) << 52)
    return p * scale


@njit(**FAST)
def fast_log(x: float) -> float:
    """Natural log of a normal positive ``x``: ``x = 2^e m``, ``m`` in [sqrt(1/2), sqrt(2)),
    ``log m = 2 atanh(s)`` with ``s = (m-1)/(m+1)``, ``|s| <= 0.172`` (series to s^23)."""
    bits = _float_to_bits(x)
    e = ((bits >> 52) & 0x7FF) - 1023
    m = _bits_to_float((bits & 0xFFFFFFFFFFFFF) | 0x3FF0000000000000)
    big = m > _SQRT2
    m = m * 0.5 if big else m
    e = e + 1 if big else e
    s = (m - 1.0) / (m + 1.0)
    s2 = s * s
    p = 1.0 / 23.0
    p = 1.0 / 21.0 + s2 * p
    p = 1.0 / 19.0 + s2 * p
    p = 1.0 / 17.0 + s2 * p
    p = 1.0 / 15.0 + s2 * p
    p = 1.0 / 13.0 + s2 * p
    p = 1.0 / 11.0 + s2 * p
    p = 1.0 / 9.0 + s2 * p
    p = 1.0 / 7.0 + s2 * p
    p = 1.0 / 5.0 + s2 * p
    p = 1.0 / 3.0 + s2 * p
    p = 1.0 + s2 * p
    return 2.0 * s * p + e * _LN2


@njit(**FAST)
def fast_cos_2pi(u: float) -> float:
    """``cos(2 pi u)`` for any finite ``u``: reduced to ``w = |u - round(u)|`` in [0, 1/2], then
    to [0, 1/4] by ``cos(2 pi w) = -cos(2 pi (1/2 - w))``; Taylor to degree 20 on [0, pi/2]."""
    w = abs(u - math.floor(u + 0.5))
    flip = w > 0.25
    w = 0.5 - w if flip else w
    a = 2.0 * math.pi * w
    a2 = a * a
    p = 1.0 / 2432902008176640000.0
    p = -1.0 / 6402373705728000.0 + a2 * p
    p = 1.0 / 20922789888000.0 + a2 * p
    p = -1.0 / 87178291200.0 + a2 * p
    p = 1.0 / 479001600.0 + a2 * p
    p = -1.0 / 3628800.0 + a2 * p
    p = 1.0 / 40320.0 + a2 * p
    p = -1.0 / 720.0 + a2 * p
    p = 1.0 / 24.0 + a2 * p
    p = -0.5 + a2 * p
    p = 1.0 + a2 * p
    return -p if flip else p


@njit(**FAST)
def fast_tanh_nonneg(x: float) -> float:
    """``tanh(x)`` for ``x >= 0`` as ``(1 - e) / (1 + e)``, ``e = exp(-2x)`` (absolute error
    a few 1e-16; exactly 1 beyond x = 354)."""
    e = fast_exp(-2.0 * x)
    return (1.0 - e) / (1.0 + e)
