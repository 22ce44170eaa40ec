"""The scalar reference kernel: one vehicle at a time, any damper model and shape.

It advances each vehicle with the same RK4 substep as the vectorised kernel
(:func:`capsule_env.plant.rk4.rk4_substep`) but with the general closed-form hysteresis update,
so it serves every case the block kernel does not (the Bouc-Wen model, whose unloading branch
needs tan/atan; Spencer parameters with ``gamma > beta``), and it is the reference the block
kernel is tested against (``tests/test_plant.py``). Compiled once per damper model.
"""

from __future__ import annotations

import math

from capsule_env._jit import specialised
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.layout import (
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    COIL_TAU,
    DAMP_LEVITATION,
    DAMPER_Y,
    HYST_Z,
    I_MAX,
    MASS_BODY,
    MASS_BOGIE,
    OUT_BODY_ACC,
    OUT_BOGIE_ACC,
    OUT_FORCE,
    OUT_GUIDEWAY,
    STIFF_LEVITATION,
    STIFF_SECONDARY,
    TIME,
)
from capsule_env.plant.block import route_elevation, row_params
from capsule_env.plant.rk4 import HYST_GENERAL, HYST_NONE, plant_outputs, rk4_substep

__all__ = ["scalar_step"]

_NO_CONSTANTS = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)


@specialised("model", "damped")
def scalar_step(model, damped, lo, hi, plant, x, i_cmd, route, dt, out):
    """Advance vehicles ``lo .. hi-1`` by ``dt``, one at a time (any number of them).

    The number of substeps is ``plant.substeps[n, bin]`` for the bin of the highest current in
    the interval (the damper's stiffness grows with current). ``damped``: the levitation has
    damping (its rate term compiled in). Compiled once per (model, damped)."""
    m, dmp = model, damped
    damper = model_of_code(m)
    uses_current = damper.uses_current
    hyst = HYST_NONE if damper.hysteresis is None else HYST_GENERAL

    def impl(model, damped, lo, hi, plant, x, i_cmd, route, dt, out):
        dp, vp, table = plant.damper, plant.vehicle, plant.substeps
        profiles, spacing, offsets = plant.profiles, plant.spacing_m, plant.offsets
        last = profiles.shape[1] - 1.0
        n_bins = table.shape[1]
        for n in range(lo, hi):
            p = row_params(dp, n)
            i_max, tau = dp[n, I_MAX], dp[n, COIL_TAU]
            cmd = min(max(i_cmd[n], 0.0), i_max) if uses_current else 0.0
            ic = x[n, COIL_CURRENT]
            i_high = max(cmd, ic) if tau > 0.0 else cmd
            b = int(i_high / i_max * n_bins) if i_max > 0.0 else 0
            n_sub = table[n, min(max(b, 0), n_bins - 1)]
            h = dt / n_sub
            e_half = math.exp(-0.5 * h / tau) if tau > 0.0 else 0.0
            if tau <= 0.0:
                ic = cmd
            inv_mc, inv_mb = 1.0 / vp[n, MASS_BODY], 1.0 / vp[n, MASS_BOGIE]
            ks, kp, cp = vp[n, STIFF_SECONDARY], vp[n, STIFF_LEVITATION], vp[n, DAMP_LEVITATION]
            k, g = route.profile[n], route.gain[n]
            start, speed = route.start_m[n], route.speed_mps[n]
            zc, vc, zb, vb = x[n, BODY_DISP], x[n, BODY_VEL], x[n, BOGIE_DISP], x[n, BOGIE_VEL]
            z, y, t = x[n, HYST_Z], x[n, DAMPER_Y], x[n, TIME]
            zg0 = route_elevation(profiles, offsets, k, g, spacing, last, start + speed * t)
            zgh = zg1 = zg0
            for _ in range(n_sub):
                zgh = route_elevation(
                    profiles, offsets, k, g, spacing, last, start + speed * (t + 0.5 * h)
                )
                zg1 = route_elevation(
                    profiles, offsets, k, g, spacing, last, start + speed * (t + h)
                )
                v = (zc, vc, zb, vb, z, y, ic, t, h, cmd, e_half, inv_mc, inv_mb, ks, kp, cp,
                     zg0, zgh, zg1)  # fmt: skip
                zc, vc, zb, vb, z, y, ic, t, zg0 = rk4_substep(m, hyst, dmp, v, p, _NO_CONSTANTS)
            x[n, BODY_DISP], x[n, BODY_VEL], x[n, BOGIE_DISP], x[n, BOGIE_VEL] = zc, vc, zb, vb
            x[n, HYST_Z], x[n, DAMPER_Y], x[n, COIL_CURRENT], x[n, TIME] = z, y, ic, t
            zg_rate = (zg1 - zgh) * 2.0 / h if dmp else 0.0
            force, acc_c, acc_b = plant_outputs(m, dmp, p, (zc, vc, zb, vb, z, y, ic), zg0,
                                                zg_rate, (inv_mc, inv_mb, ks, kp, cp))  # fmt: skip
            out[n, OUT_FORCE], out[n, OUT_BODY_ACC] = force, acc_c
            out[n, OUT_BOGIE_ACC], out[n, OUT_GUIDEWAY] = acc_b, zg0

    return impl
