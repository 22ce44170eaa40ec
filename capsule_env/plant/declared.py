"""The compiled RK4 plant of any declared vehicle (layout and arrays:
:mod:`capsule_env.plant.declared_build`).

One control step of each vehicle, with the quarter-car kernels' scheme
(:mod:`capsule_env.plant.rk4`) over the declaration's sums instead of unrolled tuples::

    M q'' = - sum_e J_e^T f_e - sum_s J_s^T F_s,   f_e = k_e (J_e q - g_e z_g)  or
                                                   c_e (J_e q' - g_e z_g')

- classical RK4 over ``[q, q', y_s]`` with the substep count of the vehicle's table at the bin of
  its highest current (command or actual, over its slots);
- each slot's hysteretic variable ``z_s`` from the exact closed-form Bouc-Wen update over the
  stage's deformation increment (:func:`capsule_env.dampers.hysteresis.hysteresis_update`),
  each slot's coil current through its first-order lag, solved exactly;
- each contact's guideway at the start, middle and end of the substep, its rate the substep's
  mean (exact for the piecewise-linear profile between samples).

It loops over vehicles one at a time (no SIMD lanes): the quarter-car's vectorised kernel stays
its own. Compiled once per damper model. The declared envs step the same arithmetic with the
vehicles side by side (:mod:`capsule_env.plant.declared_lanes`, 2.6 x faster on one thread at
1024 half-cars, the same bits); this kernel is its reference, and the oracle's plant.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from capsule_env._fastmath import FAST
from capsule_env._jit import specialised
from capsule_env.dampers.base import COIL_TAU, I_MAX
from capsule_env.dampers.dispatch import hysteresis_params, model_force, model_prepare
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.dampers.registry import model_of_code
from capsule_env.plant.block import route_elevation, row_params

__all__ = ["declared_step", "declared_step_parallel", "CHUNK"]


@njit(cache=True)
def _elevations(plant, route, n, t, zg):
    """Each contact's guideway elevation at time ``t`` (into ``zg``)."""
    last = plant.profiles.shape[1] - 1.0
    base = route.start_m[n] + route.speed_mps[n] * t
    for c in range(zg.shape[0]):
        zg[c] = route_elevation(plant.profiles, plant.offsets, route.profile[n], route.gain[n],
                                plant.spacing_m, last, base + plant.contact_offsets_m[n, c])  # fmt: skip


@njit(cache=True)
def _dot(row, x):
    s = 0.0
    for r in range(row.shape[0]):
        s += row[r] * x[r]
    return s


@specialised("model")
def _rates(model, plant, n, xs, z, ic, pre, zg, zg_rate, k, forces):
    """``k = d/dt [q, q', y]`` at the stage state ``xs`` (and ``z``, ``ic``, ``pre`` per slot;
    ``zg``, ``zg_rate`` per contact); each slot's force into ``forces``."""
    m = model

    def impl(model, plant, n, xs, z, ic, pre, zg, zg_rate, k, forces):
        nc, ns = plant.inv_inertia.shape[1], plant.slot_rows.shape[1]
        q, v = xs[:nc], xs[nc : 2 * nc]
        acc = k[nc : 2 * nc]
        acc[:] = 0.0
        for e in range(plant.element_coef.shape[1]):
            rows, ground = plant.element_rows[n, e], plant.element_contacts[n, e]
            if plant.element_dashpot[e]:
                d = _dot(rows, v) - _dot(ground, zg_rate)
            else:
                d = _dot(rows, q) - _dot(ground, zg)
            f = plant.element_coef[n, e] * d
            for r in range(nc):
                acc[r] -= rows[r] * f
        for s in range(ns):
            rows = plant.slot_rows[n, s]
            p = row_params(plant.damper, n * ns + s)
            f, y_dot = model_force(m, p, _dot(rows, q), _dot(rows, v), xs[2 * nc + s], z[s],
                                   ic[s], pre[s])  # fmt: skip
            forces[s] = f
            k[2 * nc + s] = y_dot
            for r in range(nc):
                acc[r] -= rows[r] * f
        for r in range(nc):
            k[r] = v[r]
            acc[r] *= plant.inv_inertia[n, r]

    return impl


@specialised("model")
def _advance_z(model, plant, n, z, xs, u0, out):
    """Each slot's hysteretic variable after the deformation from ``u0`` to the stage ``xs``'s
    ``stroke - y`` (unchanged for a model without hysteresis)."""
    hysteretic, m = model_of_code(model).hysteresis is not None, model

    def impl(model, plant, n, z, xs, u0, out):
        nc, ns = plant.inv_inertia.shape[1], plant.slot_rows.shape[1]
        for s in range(ns):
            if hysteretic:
                a, g, b = hysteresis_params(m, row_params(plant.damper, n * ns + s))
                du = _dot(plant.slot_rows[n, s], xs[:nc]) - xs[2 * nc + s] - u0[s]
                out[s] = hysteresis_update(z[s], du, a, g, b)
            else:
                out[s] = z[s]

    return impl


@specialised("model")
def _substep(model, plant, route, n, h, w):
    """One RK4 substep of vehicle ``n`` on the work arrays ``w`` (:func:`_work`)."""
    m = model

    def impl(model, plant, route, n, h, w):
        x0, xs, k, z, zs, ic, cmd, e_half, pre, u0, zg, forces, t = w
        nc, ns = plant.inv_inertia.shape[1], plant.slot_rows.shape[1]
        _elevations(plant, route, n, t[0] + 0.5 * h, zg[1])
        _elevations(plant, route, n, t[0] + h, zg[2])
        for c in range(zg.shape[1]):
            zg[3, c] = (zg[2, c] - zg[0, c]) / h
        for s in range(ns):
            u0[s] = _dot(plant.slot_rows[n, s], x0[:nc]) - x0[2 * nc + s]
            ic[1, s] = cmd[s] + (ic[0, s] - cmd[s]) * e_half[s]
            ic[2, s] = cmd[s] + (ic[1, s] - cmd[s]) * e_half[s]
            p = row_params(plant.damper, n * ns + s)
            for j in range(3):
                pre[j, s] = model_prepare(m, p, ic[j, s])
        _rates(m, plant, n, x0, z, ic[0], pre[0], zg[0], zg[3], k[0], forces)
        for stage, frac in ((1, 0.5), (2, 0.5), (3, 1.0)):
            for j in range(x0.shape[0]):
                xs[j] = x0[j] + (frac * h) * k[stage - 1, j]
            _advance_z(m, plant, n, z, xs, u0, zs)
            at = 1 if stage < 3 else 2
            _rates(m, plant, n, xs, zs, ic[at], pre[at], zg[at], zg[3], k[stage], forces)
        wt = h / 6.0
        for j in range(x0.shape[0]):
            x0[j] = x0[j] + wt * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
        _advance_z(m, plant, n, z, x0, u0, zs)
        for s in range(ns):
            z[s], ic[0, s] = zs[s], ic[2, s]
        for c in range(zg.shape[1]):
            zg[0, c] = zg[2, c]
        t[0] += h

    return impl


@njit(cache=True)
def _work(nc, ns, nk):
    """The per-call work arrays of one vehicle's step."""
    nm = 2 * nc + ns
    return (np.empty(nm), np.empty(nm), np.empty((4, nm)), np.empty(ns), np.empty(ns),
            np.empty((3, ns)), np.empty(ns), np.empty(ns), np.empty((3, ns)), np.empty(ns),
            np.empty((4, nk)), np.empty(ns), np.empty(1))  # fmt: skip


# With reference counting (numba's runtime): it allocates its work arrays, once per call.
@specialised("model", **FAST)
def declared_step(model, lo, hi, plant, x, i_cmd, route, dt, out):
    """Advance vehicles ``lo .. hi-1`` by ``dt`` (state ``x`` (N, S) in place, current commands
    ``i_cmd`` (N, slots), outputs ``out`` (N, slots + coordinates + contacts) written at the
    end: :func:`capsule_env.plant.declared_build.declared_output_names`)."""
    uses_current, m = model_of_code(model).uses_current, model

    def impl(model, lo, hi, plant, x, i_cmd, route, dt, out):
        nc, ns = plant.inv_inertia.shape[1], plant.slot_rows.shape[1]
        nk = plant.contact_offsets_m.shape[1]
        w = _work(nc, ns, nk)
        x0, _, k, z, _, ic, cmd, e_half, _, _, zg, forces, t = w
        n_bins = plant.substeps.shape[1]
        base = 2 * nc  # each slot's (z, y, i) from here, then the time
        for n in range(lo, hi):
            frac = 0.0
            for s in range(ns):
                row = n * ns + s
                i_max, tau = plant.damper[row, I_MAX], plant.damper[row, COIL_TAU]
                cmd[s] = min(max(i_cmd[n, s], 0.0), i_max) if uses_current else 0.0
                cur = x[n, base + 3 * s + 2]
                i_high = max(cmd[s], cur) if tau > 0.0 else cmd[s]
                frac = max(frac, i_high / i_max if i_max > 0.0 else 0.0)
            n_sub = plant.substeps[n, min(max(int(frac * n_bins), 0), n_bins - 1)]
            h = dt / n_sub
            for s in range(ns):
                tau = plant.damper[n * ns + s, COIL_TAU]
                e_half[s] = math.exp(-0.5 * h / tau) if tau > 0.0 else 0.0
                z[s], x0[2 * nc + s] = x[n, base + 3 * s], x[n, base + 3 * s + 1]
                ic[0, s] = x[n, base + 3 * s + 2] if tau > 0.0 else cmd[s]
            x0[: 2 * nc] = x[n, : 2 * nc]
            t[0] = x[n, base + 3 * ns]
            _elevations(plant, route, n, t[0], zg[0])
            for _ in range(n_sub):
                _substep(m, plant, route, n, h, w)
            _store(x, n, nc, ns, x0, z, ic[0], t[0])
            for c in range(nk):  # the guideway's rate over the last half substep
                zg[3, c] = (zg[2, c] - zg[1, c]) * 2.0 / h
            pre = ic[1]  # reused as scratch: the prepare at the final current
            for s in range(ns):
                pre[s] = model_prepare(m, row_params(plant.damper, n * ns + s), ic[0, s])
            _rates(m, plant, n, x0, z, ic[0], pre, zg[0], zg[3], k[0], forces)
            out[n, :ns] = forces
            out[n, ns : ns + nc] = k[0, nc : 2 * nc]
            out[n, ns + nc : ns + nc + nk] = zg[0]

    return impl


@njit(cache=True)
def _store(x, n, nc, ns, x0, z, ic, t):
    base = 2 * nc
    x[n, :base] = x0[:base]
    for s in range(ns):
        x[n, base + 3 * s] = z[s]
        x[n, base + 3 * s + 1] = x0[base + s]
        x[n, base + 3 * s + 2] = ic[s]
    x[n, base + 3 * ns] = t


_PARALLEL: dict[int, Any] = {}
#: Vehicles per work item of :func:`declared_step_parallel`.
CHUNK = 32


def declared_step_parallel(code: int) -> Any:
    """``step(n, plant, x, i_cmd, route, dt, out)``: :func:`declared_step` of damper model
    ``code`` over vehicles ``0 .. n-1`` in chunks of :data:`CHUNK` on all cores (numba
    ``prange``). A vehicle's numbers do not depend on its chunk or thread."""
    if code not in _PARALLEL:
        model = code

        @njit(parallel=True, cache=False)
        def step(n, plant, x, i_cmd, route, dt, out):  # pragma: no cover - numba
            for c in prange((n + CHUNK - 1) // CHUNK):
                lo = c * CHUNK
                declared_step(model, lo, min(lo + CHUNK, n), plant, x, i_cmd, route, dt, out)

        _PARALLEL[code] = step
    return _PARALLEL[code]
