"""The declared plant (:mod:`capsule_env.plant.declared`) with the vehicles side by side: the
same arithmetic, laid out for speed, the same bits.

:func:`capsule_env.plant.declared.declared_step` advances one vehicle at a time over the
declaration's rows, cutting an array view per row, slot and stage: numba counts the references
of each view atomically, and with all cores on the batch those counts are shared between them.
This kernel copies a chunk of up to :data:`LANES` vehicles into work arrays with one row per
quantity and one column (lane) per vehicle, sorts the lanes by their number of substeps (so
substep ``s`` loops over a prefix: the vehicles that still need it), and runs each stage as
loops over the declaration's rows with the lanes innermost, indexing scalars only (no views,
no reference counting below the entry point).

Each vehicle gets the operations of :func:`declared_step`, in its order (each sum over a row
from ``0.0``, coordinate by coordinate; the exact Bouc-Wen update with the C library's
``tanh``/``tan``/``atan``/``atanh``; ``exp`` of the coil lag; no fast-math flags), so its numbers
are those of :func:`declared_step` bit for bit, whatever its chunk, lane or thread
(``tests/test_declared_lanes.py`` compares them with ``==``). The lane loops calling the C
library do not vectorise (numba has no vector library here that returns the same bits); the
loops of plain arithmetic do.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from capsule_env._fastmath import BORROWED, FAST
from capsule_env._jit import specialised, unique_symbol
from capsule_env.dampers.base import COIL_TAU, I_MAX, N_DAMPER_PARAMS
from capsule_env.dampers.dispatch import hysteresis_params, model_force, model_prepare
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.dampers.registry import model_of_code
from capsule_env.plant.block import route_elevation
from capsule_env.plant.glibc_tanh import glibc_tanh, matches_libm

__all__ = ["LANES", "VECTOR_TANH", "form_dims", "lanes_step", "lanes_step_parallel", "plant_form"]

#: Vehicles side by side in one chunk (and per work item of :func:`lanes_step_parallel`).
LANES = 64
_FORM_BASE = 64  # each count of a form below this
#: The flag of a form whose kernel calls :func:`capsule_env.plant.glibc_tanh.glibc_tanh` (in
#: vectorised loops) in place of the C library's ``tanh`` (lane by lane).
VECTOR_TANH = _FORM_BASE**4


def plant_form(plant: Any) -> int:
    """The form of a :class:`capsule_env.plant.declared_build.DeclaredPlant` as one integer:
    its counts of coordinates, springs and dashpots, damper slots and contacts, which the
    kernel is compiled for (its loops then have known lengths), and :data:`VECTOR_TANH` where
    :func:`capsule_env.plant.glibc_tanh.matches_libm` (the hysteretic update's ``tanh`` then
    vectorises, the same bits)."""
    dims = (plant.inv_inertia.shape[1], plant.element_coef.shape[1], plant.slot_rows.shape[1],
            plant.contact_offsets_m.shape[1])  # fmt: skip
    if max(dims) >= _FORM_BASE:
        raise ValueError(f"the lanes kernel takes fewer than {_FORM_BASE} coordinates, elements, "
                         f"slots and contacts each, got {dims}")  # fmt: skip
    form = sum(d * _FORM_BASE**j for j, d in enumerate(dims))
    return form + (VECTOR_TANH if matches_libm() else 0)


def form_dims(form: int) -> tuple[int, int, int, int]:
    """``(coordinates, springs and dashpots, slots, contacts)`` of :func:`plant_form`'s code."""
    nc, ne, ns, nk = (form // _FORM_BASE**j % _FORM_BASE for j in range(4))
    return nc, ne, ns, nk


@njit(**FAST, inline="always")
def _lane_row(dp, i):
    """Lane ``i``'s damper parameters (``dp``: (parameters, lanes)) as a tuple, as
    :func:`capsule_env.plant.block.row_params` reads a row."""
    return (
        dp[0, i], dp[1, i], dp[2, i], dp[3, i], dp[4, i], dp[5, i], dp[6, i], dp[7, i],
        dp[8, i], dp[9, i], dp[10, i], dp[11, i], dp[12, i], dp[13, i], dp[14, i], dp[15, i],
        dp[16, i],
    )  # fmt: skip


assert N_DAMPER_PARAMS == 17  # noqa: S101 - _lane_row's length


@njit(**FAST, **BORROWED)
def _elevations(plant, route, na, veh, t, frac, h, zg):
    """Each contact's guideway elevation at ``t + frac h`` for lanes ``0 .. na-1`` (into
    ``zg`` (contacts, lanes))."""
    last = plant.profiles.shape[1] - 1.0
    for c in range(zg.shape[0]):
        for i in range(na):
            n = veh[i]
            base = route.start_m[n] + route.speed_mps[n] * (t[i] + frac * h[i])
            zg[c, i] = route_elevation(plant.profiles, plant.offsets, route.profile[n],
                                       route.gain[n], plant.spacing_m, last,
                                       base + plant.contact_offsets_m[n, c])  # fmt: skip


@specialised("form")
def _springs(form, plant, g, na, xs, zgv, zgr, k):
    """The springs' and dashpots' forces over the inertias, accumulated into ``k``'s rate rows
    (from 0.0), for lanes ``0 .. na-1``."""
    nc, ne, _, nk = form_dims(form)

    def impl(form, plant, g, na, xs, zgv, zgr, k):
        erow, econ, ecoef = g[0], g[1], g[2]
        for r in range(nc):
            for i in range(na):
                k[nc + r, i] = 0.0
        for e in range(ne):
            dash = plant.element_dashpot[e] != 0
            off = nc if dash else 0
            for i in range(na):
                s1 = 0.0
                for r in range(nc):
                    s1 += erow[e, r, i] * xs[off + r, i]
                s2 = 0.0
                for c in range(nk):
                    s2 += econ[e, c, i] * (zgr[c, i] if dash else zgv[c, i])
                f = ecoef[e, i] * (s1 - s2)
                for r in range(nc):
                    k[nc + r, i] -= erow[e, r, i] * f

    return impl


@specialised("model", "form")
def _rates(model, form, plant, g, na, xs, z, ic, pre, zgv, zgr, k, forces):
    """``k = d/dt [q, q', y]`` (rows, lanes) at the stage state ``xs`` for lanes ``0 ..
    na-1``, each slot's force into ``forces`` (``declared._rates``, lane by lane)."""
    m, (nc, _, ns, _) = model, form_dims(form)

    def impl(model, form, plant, g, na, xs, z, ic, pre, zgv, zgr, k, forces):
        srow, inv, dpar = g[3], g[4], g[5]
        _springs(form, plant, g, na, xs, zgv, zgr, k)
        for s in range(ns):
            for i in range(na):
                x, v = 0.0, 0.0
                for r in range(nc):
                    x += srow[s, r, i] * xs[r, i]
                for r in range(nc):
                    v += srow[s, r, i] * xs[nc + r, i]
                p = _lane_row(dpar[s], i)
                f, y_dot = model_force(m, p, x, v, xs[2 * nc + s, i], z[s, i], ic[s, i],
                                       pre[s, i])  # fmt: skip
                forces[s, i] = f
                k[2 * nc + s, i] = y_dot
                for r in range(nc):
                    k[nc + r, i] -= srow[s, r, i] * f
        for r in range(nc):
            for i in range(na):
                k[r, i] = xs[nc + r, i]
                k[nc + r, i] *= inv[r, i]

    return impl


@specialised("model", "form")
def _advance_z(model, form, g, na, z, xs, u0, out):
    """Each slot's hysteretic variable after the deformation from ``u0`` to the stage's
    ``stroke - y`` (``declared._advance_z``, lane by lane; :func:`_advance_z_split` where the
    chunk's hysteresis has a linear unloading branch)."""
    hysteretic, m = model_of_code(model).hysteresis is not None, model
    nc, _, ns, _ = form_dims(form)
    f = form

    def impl(model, form, g, na, z, xs, u0, out):
        srow, dpar = g[3], g[5]
        if hysteretic and g[8][0] == 1:
            _advance_z_split(f, g, na, z, xs, u0, out)
            return
        for s in range(ns):
            for i in range(na):
                if hysteretic:
                    a, gamma, beta = hysteresis_params(m, _lane_row(dpar[s], i))
                    d = 0.0
                    for r in range(nc):
                        d += srow[s, r, i] * xs[r, i]
                    du = d - xs[2 * nc + s, i] - u0[s, i]
                    out[s, i] = hysteresis_update(z[s, i], du, a, gamma, beta)
                else:
                    out[s, i] = z[s, i]

    return impl


@specialised("form")
def _advance_z_split(form, g, na, z, xs, u0, out):
    """:func:`hysteresis_update`'s operations, in its order, for a chunk whose every lane has a
    linear unloading branch (``beta - gamma == 0``) and a loading one with ``gamma + beta > 0``
    (:func:`_hysteresis_constants`), in three loops over the lanes: the plain arithmetic before
    ``tanh`` (vectorised), the C library's ``tanh`` lane by lane, the arithmetic after it
    (vectorised), or :func:`glibc_tanh` in a vectorised loop where the form says
    (:data:`VECTOR_TANH`). The same bits as the branchy call per lane: the same operations on the same
    values (``sqrt(A / p)`` and ``sqrt(A p)`` computed once a step, not at every call), each
    lane's result chosen among the branches' rather than branched to."""
    nc, _, ns, _ = form_dims(form)
    vector_tanh = form // VECTOR_TANH % 2 == 1

    def impl(form, g, na, z, xs, u0, out):
        srow, hc, tmp = g[3], g[6], g[7]
        for s in range(ns):
            for i in range(na):
                d = 0.0
                for r in range(nc):
                    d += srow[s, r, i] * xs[r, i]
                du = d - xs[2 * nc + s, i] - u0[s, i]
                sign = 1.0 if du > 0.0 else -1.0
                q = sign * z[s, i]
                path = abs(du)
                m_zero = -q / hc[s, 0, i]  # _path_to_zero with p = 0
                tmp[0, i] = hc[s, 2, i] * (path - m_zero if q < 0.0 else path)
                tmp[1, i] = du
            if vector_tanh:
                for i in range(na):
                    tmp[2, i] = glibc_tanh(tmp[0, i])
            else:
                for i in range(na):
                    tmp[2, i] = math.tanh(tmp[0, i])
            for i in range(na):
                du, big_t, a, r = tmp[1, i], tmp[2, i], hc[s, 0, i], hc[s, 1, i]
                sign = 1.0 if du > 0.0 else -1.0
                q = sign * z[s, i]
                path = abs(du)
                m_zero = -q / a
                unloading = q < 0.0
                t0 = (0.0 if unloading else q) / r
                loaded = sign * (r * (t0 + big_t) / (1.0 + t0 * big_t))
                stays = sign * (q + a * path)  # _riccati with p = 0
                res = stays if (unloading and path <= m_zero) else loaded
                out[s, i] = z[s, i] if du == 0.0 else res

    return impl


@specialised("model", "form")
def _hysteresis_constants(model, form, na, g):
    """Each lane's and slot's ``A``, ``sqrt(A / p)`` and ``sqrt(A p)`` (``p = gamma + beta``,
    :func:`capsule_env.dampers.hysteresis._riccati`'s) into ``g[6]``, and into ``g[8][0]``
    whether every lane has ``beta - gamma == 0`` and ``gamma + beta > 0`` (then
    :func:`_advance_z_split` applies)."""
    hysteretic, m = model_of_code(model).hysteresis is not None, model
    _, _, ns, _ = form_dims(form)

    def impl(model, form, na, g):
        hc, flag = g[6], g[8]
        flag[0] = 1 if hysteretic else 0
        if not hysteretic:
            return
        for s in range(ns):
            for i in range(na):
                a, gamma, beta = hysteresis_params(m, _lane_row(g[5][s], i))
                p = gamma + beta
                hc[s, 0, i], hc[s, 1, i], hc[s, 2, i] = a, math.sqrt(a / p), math.sqrt(a * p)
                if not (beta - gamma == 0.0 and p > 0.0):
                    flag[0] = 0

    return impl


@specialised("model", "form")
def _begin(model, form, plant, route, g, na, veh, h, w):
    """A substep's guideway (its middle, its end, its mean rate), each slot's deformation at
    its start and coil current at its middle and end, and the model's ``prepare`` at each."""
    m, (nc, _, ns, nk) = model, form_dims(form)

    def impl(model, form, plant, route, g, na, veh, h, w):
        x0, _, _, _, _, ic, cmd, e_half, pre, u0, zg, _, t = w
        srow, dpar = g[3], g[5]
        _elevations(plant, route, na, veh, t, 0.5, h, zg[1])
        _elevations(plant, route, na, veh, t, 1.0, h, zg[2])
        for c in range(nk):
            for i in range(na):
                zg[3, c, i] = (zg[2, c, i] - zg[0, c, i]) / h[i]
        for s in range(ns):
            for i in range(na):
                d = 0.0
                for r in range(nc):
                    d += srow[s, r, i] * x0[r, i]
                u0[s, i] = d - x0[2 * nc + s, i]
                ic[1, s, i] = cmd[s, i] + (ic[0, s, i] - cmd[s, i]) * e_half[s, i]
                ic[2, s, i] = cmd[s, i] + (ic[1, s, i] - cmd[s, i]) * e_half[s, i]
                p = _lane_row(dpar[s], i)
                for j in range(3):
                    pre[j, s, i] = model_prepare(m, p, ic[j, s, i])

    return impl


@specialised("model", "form")
def _substep(model, form, plant, route, g, na, veh, h, w):
    """One RK4 substep of lanes ``0 .. na-1`` on the work arrays ``w`` (:func:`_work`)."""
    m, f, (nc, _, ns, _) = model, form, form_dims(form)
    nm = 2 * nc + ns

    def impl(model, form, plant, route, g, na, veh, h, w):
        x0, xs, k, z, zs, ic, _, _, pre, u0, zg, forces, t = w
        _begin(m, f, plant, route, g, na, veh, h, w)
        _rates(m, f, plant, g, na, x0, z, ic[0], pre[0], zg[0], zg[3], k[0], forces)
        for stage in range(1, 4):
            frac = 0.5 if stage < 3 else 1.0
            for j in range(nm):
                for i in range(na):
                    xs[j, i] = x0[j, i] + (frac * h[i]) * k[stage - 1, j, i]
            _advance_z(m, f, g, na, z, xs, u0, zs)
            at = 1 if stage < 3 else 2
            _rates(m, f, plant, g, na, xs, zs, ic[at], pre[at], zg[at], zg[3], k[stage], forces)
        for j in range(nm):
            for i in range(na):
                wt = h[i] / 6.0
                x0[j, i] = x0[j, i] + wt * (k[0, j, i] + 2.0 * k[1, j, i] + 2.0 * k[2, j, i]
                                            + k[3, j, i])  # fmt: skip
        _advance_z(m, f, g, na, z, x0, u0, zs)
        _carry(f, na, h, w)

    return impl


@specialised("form")
def _carry(form, na, h, w):
    """The substep's end becomes the next one's start: hysteretic variables, coil currents,
    guideway, time."""
    _, _, ns, nk = form_dims(form)

    def impl(form, na, h, w):
        _, _, _, z, zs, ic, _, _, _, _, zg, _, t = w
        for s in range(ns):
            for i in range(na):
                z[s, i], ic[0, s, i] = zs[s, i], ic[2, s, i]
        for c in range(nk):
            for i in range(na):
                zg[0, c, i] = zg[2, c, i]
        for i in range(na):
            t[i] += h[i]

    return impl


@njit(cache=True)
def _work(nc, ns, nk):
    """The work arrays of one chunk (rows, lanes), and the lanes' vehicles, substep counts and
    substep lengths."""
    nm, lanes = 2 * nc + ns, LANES
    w = (np.empty((nm, lanes)), np.empty((nm, lanes)), np.empty((4, nm, lanes)),
         np.empty((ns, lanes)), np.empty((ns, lanes)), np.empty((3, ns, lanes)),
         np.empty((ns, lanes)), np.empty((ns, lanes)), np.empty((3, ns, lanes)),
         np.empty((ns, lanes)), np.empty((4, nk, lanes)), np.empty((ns, lanes)),
         np.empty(lanes))  # fmt: skip
    return w, np.empty(lanes, np.int64), np.empty(lanes, np.int64), np.empty(lanes)


@njit(cache=True)
def _lane_params(nc, ne, ns, nk, n_params):
    """The lanes' copies of their vehicles' rows: each spring's and dashpot's deflection row,
    its contacts' shares and coefficient, each slot's stroke row, the inverse inertias and
    each slot's damper parameters (:func:`_gather`)."""
    lanes = LANES
    return (
        np.empty((ne, nc, lanes)),
        np.empty((ne, nk, lanes)),
        np.empty((ne, lanes)),
        np.empty((ns, nc, lanes)),
        np.empty((nc, lanes)),
        np.empty((ns, n_params, lanes)),
        np.empty((ns, 3, lanes)),
        np.empty((3, lanes)),
        np.zeros(1, np.int64),
    )


@njit(**FAST, **BORROWED)
def _gather(plant, na, veh, g):
    """The rows of the lanes' vehicles ``veh`` into ``g`` (:func:`_lane_params`)."""
    erow, econ, ecoef, srow, inv, dpar = g[0], g[1], g[2], g[3], g[4], g[5]
    ns = srow.shape[0]
    for i in range(na):
        n = veh[i]
        for e in range(erow.shape[0]):
            ecoef[e, i] = plant.element_coef[n, e]
            for r in range(erow.shape[1]):
                erow[e, r, i] = plant.element_rows[n, e, r]
            for c in range(econ.shape[1]):
                econ[e, c, i] = plant.element_contacts[n, e, c]
        for r in range(inv.shape[0]):
            inv[r, i] = plant.inv_inertia[n, r]
        for s in range(ns):
            for r in range(srow.shape[1]):
                srow[s, r, i] = plant.slot_rows[n, s, r]
            for j in range(dpar.shape[1]):
                dpar[s, j, i] = plant.damper[n * ns + s, j]


@specialised("model", "form")
def _load(model, form, lo, hi, plant, x, i_cmd, route, dt, w, g, veh, n_sub, h):
    """Vehicles ``lo .. hi-1`` into the lanes, sorted by their substep count (most first, in
    vehicle order within a count); returns the largest count."""
    uses_current, m, f = model_of_code(model).uses_current, model, form
    nc, _, ns, _ = form_dims(form)

    def impl(model, form, lo, hi, plant, x, i_cmd, route, dt, w, g, veh, n_sub, h):
        x0, _, _, z, _, ic, cmd, e_half, _, _, zg, _, t = w
        n_bins, base = plant.substeps.shape[1], 2 * nc
        most = 0
        for n in range(lo, hi):  # the count of each vehicle: declared_step's rule
            frac = 0.0
            for s in range(ns):
                row = n * ns + s
                i_max, tau = plant.damper[row, I_MAX], plant.damper[row, COIL_TAU]
                c = min(max(i_cmd[n, s], 0.0), i_max) if uses_current else 0.0
                i_high = max(c, x[n, base + 3 * s + 2]) if tau > 0.0 else c
                frac = max(frac, i_high / i_max if i_max > 0.0 else 0.0)
            n_sub[n - lo] = plant.substeps[n, min(max(int(frac * n_bins), 0), n_bins - 1)]
            most = max(most, n_sub[n - lo])
        lane = 0
        for count in range(most, -1, -1):  # a counting sort, stable
            for n in range(lo, hi):
                if n_sub[n - lo] == count:
                    veh[lane] = n
                    lane += 1
        for i in range(hi - lo):
            n = veh[i]
            frac = 0.0
            for s in range(ns):
                row = n * ns + s
                i_max, tau = plant.damper[row, I_MAX], plant.damper[row, COIL_TAU]
                cmd[s, i] = min(max(i_cmd[n, s], 0.0), i_max) if uses_current else 0.0
                i_high = max(cmd[s, i], x[n, base + 3 * s + 2]) if tau > 0.0 else cmd[s, i]
                frac = max(frac, i_high / i_max if i_max > 0.0 else 0.0)
            n_sub[i] = plant.substeps[n, min(max(int(frac * n_bins), 0), n_bins - 1)]
            h[i] = dt / n_sub[i]
            for s in range(ns):
                tau = plant.damper[n * ns + s, COIL_TAU]
                e_half[s, i] = math.exp(-0.5 * h[i] / tau) if tau > 0.0 else 0.0
                z[s, i], x0[2 * nc + s, i] = x[n, base + 3 * s], x[n, base + 3 * s + 1]
                ic[0, s, i] = x[n, base + 3 * s + 2] if tau > 0.0 else cmd[s, i]
            for j in range(2 * nc):
                x0[j, i] = x[n, j]
            t[i] = x[n, base + 3 * ns]
        _gather(plant, hi - lo, veh, g)
        _hysteresis_constants(m, f, hi - lo, g)
        _elevations(plant, route, hi - lo, veh, t, 0.0, h, zg[0])  # t + 0.0 h: t
        return most

    return impl


@specialised("model", "form")
def _finish(model, form, na, plant, g, x, veh, h, w, out):
    """The lanes' state back into ``x`` and their outputs into ``out`` (``declared_step``'s
    end: the rates at the final state, the guideway's rate over the last half substep)."""
    m, f, (nc, _, ns, nk) = model, form, form_dims(form)

    def impl(model, form, na, plant, g, x, veh, h, w, out):
        x0, _, k, z, _, ic, _, _, pre, _, zg, forces, t = w
        base = 2 * nc
        for i in range(na):
            n = veh[i]
            for j in range(base):
                x[n, j] = x0[j, i]
            for s in range(ns):
                x[n, base + 3 * s] = z[s, i]
                x[n, base + 3 * s + 1] = x0[base + s, i]
                x[n, base + 3 * s + 2] = ic[0, s, i]
            x[n, base + 3 * ns] = t[i]
            for c in range(nk):
                zg[3, c, i] = (zg[2, c, i] - zg[1, c, i]) * 2.0 / h[i]
            for s in range(ns):
                pre[0, s, i] = model_prepare(m, _lane_row(g[5][s], i), ic[0, s, i])
        _rates(m, f, plant, g, na, x0, z, ic[0], pre[0], zg[0], zg[3], k[0], forces)
        for i in range(na):
            n = veh[i]
            for s in range(ns):
                out[n, s] = forces[s, i]
            for r in range(nc):
                out[n, ns + r] = k[0, nc + r, i]
            for c in range(nk):
                out[n, ns + nc + c] = zg[0, c, i]

    return impl


@specialised("model", "form", **FAST)
def lanes_step(model, form, lo, hi, plant, x, i_cmd, route, dt, out):
    """:func:`capsule_env.plant.declared.declared_step`'s call (the same arguments, the same
    results bit for bit), chunk by chunk of :data:`LANES` vehicles, for plants of the form
    ``form`` (:func:`plant_form`)."""
    m, f, (nc, ne, ns, nk) = model, form, form_dims(form)

    def impl(model, form, lo, hi, plant, x, i_cmd, route, dt, out):
        w, veh, n_sub, h = _work(nc, ns, nk)
        g = _lane_params(nc, ne, ns, nk, plant.damper.shape[1])
        for start in range(lo, hi, LANES):
            stop = min(start + LANES, hi)
            most = _load(m, f, start, stop, plant, x, i_cmd, route, dt, w, g, veh, n_sub, h)
            na = stop - start
            for sub in range(most):
                while na > 0 and n_sub[na - 1] <= sub:
                    na -= 1
                _substep(m, f, plant, route, g, na, veh, h, w)
            _finish(m, f, stop - start, plant, g, x, veh, h, w, out)

    return impl


_PARALLEL: dict[tuple[int, int], Any] = {}


def lanes_step_parallel(code: int, form: int) -> Any:
    """``step(n, plant, x, i_cmd, route, dt, out)``: :func:`lanes_step` of damper model ``code``
    and plant form ``form`` (:func:`plant_form`) over vehicles ``0 .. n-1`` in chunks of
    :data:`LANES` on all cores (numba ``prange``)."""
    if (code, form) not in _PARALLEL:
        model, shape = code, form

        # Cached on disk (a symbol of its own per variant: :func:`unique_symbol`); the
        # one-at-a-time kernel's threaded entry compiles again in every process.
        @njit(parallel=True, cache=True, no_cfunc_wrapper=True)
        @unique_symbol(f"lanes_{code}_{form}")
        def step(n, plant, x, i_cmd, route, dt, out):  # pragma: no cover - numba
            for c in prange((n + LANES - 1) // LANES):
                lo = c * LANES
                lanes_step(model, shape, lo, min(lo + LANES, n), plant, x, i_cmd, route, dt, out)

        _PARALLEL[code, form] = step
    return _PARALLEL[code, form]
