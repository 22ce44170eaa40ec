"""``tanh`` as glibc 2.36 computes it on x86-64 with FMA (``__tanh`` over ``__expm1_fma``),
written without branches or library calls, so that a loop over vehicles calling it vectorises.

The exact Bouc-Wen update (:func:`capsule_env.dampers.hysteresis.hysteresis_update`) calls the C
library's ``tanh`` once per slot and stage: a call per lane that stops LLVM vectorising the
loop, a fifth of the lanes kernel's time on the half-car. This is the same arithmetic as that
library's code (fdlibm's ``s_tanh.c`` and ``s_expm1.c``, with the fused multiply-adds that GCC
formed in ``__expm1_fma``, read from its disassembly), each branch computed and the lane's chosen,
so it returns the library's bits wherever the library is that one (a signalling NaN aside: the
library quiets it, this returns it as it is; arithmetic never makes one, so the kernel never
meets it; ``tests/test_review_tanh_branch_14.py``). Elsewhere (another C library,
a CPU without FMA, where glibc picks its plain ``__expm1``) it need not:
:func:`matches_libm` compares it with the library on :func:`probe_values` (every branch of both
functions), and the lanes kernel uses it only where they agree (``tests/test_glibc_tanh.py``).

The algorithm and its constants are fdlibm's; the polynomial's evaluation order in ``_expm1``
(``R1 + h2 R2 + h4 R3``, needed for the library's bits) is glibc's own change to fdlibm's
``s_expm1.c`` (marked there "Modified by Naohiko Shimizu/Tokai University, Japan 1997/08/25,
for performance improvement on pipelined processors"), which glibc distributes under its
LGPL-2.1-or-later; whether Sun's notice alone covers this copy under the package's MIT licence
is for the maintainers to settle (not settled here). fdlibm's notice, preserved as it asks:

    Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
    Developed at SunPro, a Sun Microsystems, Inc. business.
    Permission to use, copy, modify, and distribute this software is freely granted,
    provided that this notice is preserved.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

from capsule_env._fastmath import BORROWED, FAST, _bits_to_float, _float_to_bits, _fma

__all__ = ["glibc_tanh", "matches_libm", "probe_values"]


def _f(bits: int) -> float:
    """The double with the bit pattern ``bits`` (the library's constants, as it stores them)."""
    return float(np.array(bits, dtype=np.uint64).view(np.float64))


_LN2_HI, _LN2_LO = _f(0x3FE62E42FEE00000), _f(0x3DEA39EF35793C76)
_INV_LN2 = _f(0x3FF71547652B82FE)
_Q1, _Q2, _Q3 = _f(0xBFA11111111110F4), _f(0x3F5A01A019FE5585), _f(0xBF14CE199EAADBB7)
_Q4, _Q5 = _f(0x3ED0CFCA86E65239), _f(0xBE8AFDB76E09C32D)
_TINY_X = _f(0x3C80000000000000)  # 2^-55: tanh(x) = x (1 + x) below


@njit(**FAST, **BORROWED, forceinline=True)
def _expm1(y):
    """``__expm1_fma`` for ``2^-54 <= |y| < 709`` (the arguments ``tanh`` gives it)."""
    hx = (_float_to_bits(y) >> 32) & 0x7FFFFFFF
    neg = y < 0.0
    # argument reduction: k = 0, +-1 (hi, lo from constants) or round(y / ln2)
    kf = min(max(y * _INV_LN2 + (-0.5 if neg else 0.5), -1100.0), 1100.0)
    kg = int(kf)
    one_k = -1 if neg else 1
    k = 0 if hx <= 0x3FD62E42 else (one_k if hx <= 0x3FF0A2B1 else kg)
    t = float(kg)
    hi = (y + _LN2_HI if neg else y - _LN2_HI) if hx <= 0x3FF0A2B1 else y - t * _LN2_HI
    lo = (-_LN2_LO if neg else _LN2_LO) if hx <= 0x3FF0A2B1 else t * _LN2_LO
    xr = hi - lo
    c = (hi - xr) - lo
    xr = y if k == 0 else xr
    # the polynomial, with __expm1_fma's fused multiply-adds
    hfx = xr * 0.5
    hxs = xr * hfx
    h2 = hxs * hxs
    r1 = _fma(h2 * h2, _fma(hxs, _Q5, _Q4), _fma(h2, _fma(hxs, _Q3, _Q2), _fma(hxs, _Q1, 1.0)))
    tt = _fma(-r1, hfx, 3.0)
    e = ((r1 - tt) / _fma(-xr, tt, 6.0)) * hxs
    if_zero = xr - _fma(e, xr, -hxs)
    e = _fma(e - c, xr, -c) - hxs
    if_minus_one = _fma(0.5, xr - e, -0.5)
    if_one = -2.0 * (e - (xr + 0.5)) if xr < -0.25 else _fma(xr - e, 2.0, 1.0)
    kc = min(max(k, -1000), 1000)
    y_far = 1.0 - (e - xr)
    y_small = _bits_to_float((0x3FF00000 - (0x200000 >> min(max(kc, 0), 21))) << 32) - (e - xr)
    y_large = (xr - (e + _bits_to_float((0x3FF - kc) << 52))) + 1.0
    y = y_far if (kc <= -2 or kc > 56) else (y_small if kc < 20 else y_large)
    scaled = _bits_to_float(_float_to_bits(y) + (kc << 52))
    if_far = scaled - 1.0
    res = if_far if (kc <= -2 or kc > 56) else scaled
    res = if_one if k == 1 else res
    res = if_minus_one if k == -1 else res
    return if_zero if k == 0 else res


@njit(**FAST, **BORROWED, forceinline=True)
def glibc_tanh(x):
    """glibc 2.36's ``tanh(x)`` (x86-64, FMA), branch-free (module doc)."""
    ax = abs(x)
    t = _expm1(ax + ax if ax >= 1.0 else ax * -2.0)
    z = 1.0 - 2.0 / (t + 2.0) if ax >= 1.0 else -t / (t + 2.0)
    z = z if ax < 22.0 else 1.0
    z = -z if x < 0.0 else z
    z = x * (1.0 + x) if ax < _TINY_X else z
    return x if (ax == 0.0 or x != x) else z


@njit(**FAST)
def _tanh_both(xs, out_port, out_libm):  # pragma: no cover - numba
    for i in range(xs.shape[0]):
        out_port[i] = glibc_tanh(xs[i])
    for i in range(xs.shape[0]):
        out_libm[i] = math.tanh(xs[i])


def probe_values(n_random: int = 200_000, seed: int = 0) -> np.ndarray:
    """Arguments over every branch of ``tanh`` and ``expm1``: log-uniform magnitudes from 1e-20
    to 30 of both signs, the branch limits and their neighbours, zeros, infinities."""
    rng = np.random.default_rng(seed)
    mags = 10.0 ** rng.uniform(-20.0, math.log10(30.0), n_random)
    limits = np.array([_TINY_X, 0.25 * math.log(2.0), 0.75 * math.log(2.0), 0.5, 1.0, 22.0,
                       0.5 * 56 * math.log(2.0), 0.5 * 20 * math.log(2.0)]
                      + [0.5 * k * math.log(2.0) for k in range(-3, 64)])  # fmt: skip
    near = np.concatenate([np.nextafter(limits, 0.0), limits, np.nextafter(limits, np.inf)])
    values = np.concatenate([mags, np.abs(near), [0.0, np.inf]])
    return np.concatenate([values, -values])


@functools.cache
def matches_libm() -> bool:
    """Whether :func:`glibc_tanh` returns this machine's C library's ``tanh`` bit for bit on
    :func:`probe_values` (then the lanes kernel vectorises the hysteretic update with it)."""
    xs = probe_values()
    port, libm = np.empty_like(xs), np.empty_like(xs)
    _tanh_both(xs, port, libm)
    return bool((port.view(np.int64) == libm.view(np.int64)).all())
