"""The one RK4 substep of the plant, shared by the scalar and the vectorised kernels.

One substep ``h`` of classical RK4 on ``[z_c, z_c', z_b, z_b', y]`` (masses and Spencer's
internal displacement), with

- the stiff hysteretic variable ``z`` taken at every stage from the exact closed-form
  Bouc-Wen update over the stage's deformation increment (:mod:`capsule_env.hysteresis`);
- the coil current following its command through the first-order lag, solved exactly
  (``e_half = exp(-h / (2 tau))`` per half substep; 0 without lag);
- the guideway elevation at the start, middle and end of the substep given by the caller.

Everything is written without branches or library calls in the vectorised variants (the
damper laws of :mod:`capsule_env.dampers`, :func:`~capsule_env.hysteresis.hysteresis_update_fast`),
so that a loop over vehicles vectorises; the scalar kernel uses the general hysteresis update
(Bouc-Wen's unloading branch needs tan/atan).

Each function is compiled once per model and hysteresis form (literal arguments; the model's
code is chosen at typing, :func:`capsule_env._jit.specialised`) and inlined by LLVM: :func:`rk4_substep`
into the kernels' loops with ``forceinline`` (LLVM's ``alwaysinline``), the functions it calls
because they are small. Numba's own inlining (``inline="always"``) copies the callee's IR at
every call site before typing: the block kernel's loop, which calls :func:`rk4_substep` twice,
took twice as long to compile that way, and nested inlines made compiling a kernel 10 times
slower.
"""

from __future__ import annotations

from numba import njit

from capsule_env._fastmath import BORROWED, FAST
from capsule_env._jit import specialised
from capsule_env.dampers.dispatch import model_force, model_prepare
from capsule_env.dampers.registry import model_of_code
from capsule_env.hysteresis import hysteresis_update, hysteresis_update_fast

__all__ = [
    "HYST_NONE",
    "HYST_GENERAL",
    "HYST_FAST_LINEAR_UNLOAD",
    "HYST_FAST_TANH_UNLOAD",
    "LANE_INPUT_NAMES",
    "damper_force_and_rate",
    "inv_dashpots",
    "rk4_substep",
]

#: How the hysteretic variable is advanced: not at all (algebraic models), by the general
#: closed form (any shape; scalar kernel), or by the branch-free form whose unloading branch
#: is linear (``beta == gamma``) or of tanh form (``beta > gamma``).
HYST_NONE, HYST_GENERAL, HYST_FAST_LINEAR_UNLOAD, HYST_FAST_TANH_UNLOAD = range(4)

#: The values one substep reads, in order: the plant state (8), the substep ``h``, the current
#: command and the coil-lag factor, the vehicle's inverse masses and stiffnesses, and the
#: guideway elevation at the start, middle and end of the substep.
LANE_INPUT_NAMES = ("z_c", "v_c", "z_b", "v_b", "z", "y", "i", "t", "h", "i_cmd", "e_half",
                    "inv_m_c", "inv_m_b", "k_s", "k_p", "zg_start", "zg_mid", "zg_end")  # fmt: skip

#: The damper model's ``prepare`` and ``force`` (:mod:`capsule_env.dampers.dispatch`), under
#: the names the plant used before the registry.
inv_dashpots = model_prepare
damper_force_and_rate = model_force


@specialised("model", "hysteresis")
def _advance_z(model, hysteresis, z, du, p, hc):
    """The hysteretic variable after a deformation increment ``du`` (``hc``: the Riccati
    constants of the fast forms)."""
    if hysteresis == HYST_GENERAL:
        hyst = model_of_code(model).hysteresis
        a_k, g_k, b_k = hyst.a_coef, hyst.gamma, hyst.beta

        def impl(model, hysteresis, z, du, p, hc):
            return hysteresis_update(z, du, p[a_k], p[g_k], p[b_k])

    elif hysteresis == HYST_NONE:

        def impl(model, hysteresis, z, du, p, hc):
            return z

    else:

        def impl(model, hysteresis, z, du, p, hc):
            a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u, k_u, inv_k_u = hc
            tanh_unload = hysteresis == HYST_FAST_TANH_UNLOAD
            return hysteresis_update_fast(z, du, a, inv_a, r_l, inv_r_l, k_l, r_u, inv_r_u, k_u,
                                          inv_k_u, tanh_unload)  # fmt: skip

    return impl


@njit(**FAST, **BORROWED, forceinline=True)
def rk4_substep(model, hysteresis, v, p, hc):
    """One RK4 substep of one vehicle: ``v`` the :data:`LANE_INPUT_NAMES` values, ``p`` the
    damper parameters and ``hc`` the Riccati constants (tuples). Returns the new
    ``(z_c, z_c', z_b, z_b', z, y, i, t, zg_end)``."""
    zc, vc, zb, vb, z, y, ic, t, h, i_cmd, e_half = v[0:11]
    inv_mc, inv_mb, ks, kp, zg0, zgh, zg1 = v[11:18]
    ic_half = i_cmd + (ic - i_cmd) * e_half
    ic1 = i_cmd + (ic_half - i_cmd) * e_half
    inv_c0 = inv_dashpots(model, p, ic)
    inv_ch = inv_dashpots(model, p, ic_half)
    inv_c1 = inv_dashpots(model, p, ic1)
    u0 = zc - zb - y
    # stage 1
    f1, y1 = damper_force_and_rate(model, p, zc - zb, vc - vb, y, z, ic, inv_c0)
    sec = ks * (zc - zb) + f1
    k10, k11, k12, k13 = vc, -sec * inv_mc, vb, (sec - kp * (zb - zg0)) * inv_mb
    # stage 2
    a0, a1 = zc + 0.5 * h * k10, vc + 0.5 * h * k11
    a2, a3, a4 = zb + 0.5 * h * k12, vb + 0.5 * h * k13, y + 0.5 * h * y1
    zs = _advance_z(model, hysteresis, z, a0 - a2 - a4 - u0, p, hc)
    f2, y2 = damper_force_and_rate(model, p, a0 - a2, a1 - a3, a4, zs, ic_half, inv_ch)
    sec = ks * (a0 - a2) + f2
    k20, k21, k22, k23 = a1, -sec * inv_mc, a3, (sec - kp * (a2 - zgh)) * inv_mb
    # stage 3
    a0, a1 = zc + 0.5 * h * k20, vc + 0.5 * h * k21
    a2, a3, a4 = zb + 0.5 * h * k22, vb + 0.5 * h * k23, y + 0.5 * h * y2
    zs = _advance_z(model, hysteresis, z, a0 - a2 - a4 - u0, p, hc)
    f3, y3 = damper_force_and_rate(model, p, a0 - a2, a1 - a3, a4, zs, ic_half, inv_ch)
    sec = ks * (a0 - a2) + f3
    k30, k31, k32, k33 = a1, -sec * inv_mc, a3, (sec - kp * (a2 - zgh)) * inv_mb
    # stage 4
    a0, a1 = zc + h * k30, vc + h * k31
    a2, a3, a4 = zb + h * k32, vb + h * k33, y + h * y3
    zs = _advance_z(model, hysteresis, z, a0 - a2 - a4 - u0, p, hc)
    f4, y4 = damper_force_and_rate(model, p, a0 - a2, a1 - a3, a4, zs, ic1, inv_c1)
    sec = ks * (a0 - a2) + f4
    k40, k41, k42, k43 = a1, -sec * inv_mc, a3, (sec - kp * (a2 - zg1)) * inv_mb
    wt = h / 6.0
    zc = zc + wt * (k10 + 2.0 * k20 + 2.0 * k30 + k40)
    vc = vc + wt * (k11 + 2.0 * k21 + 2.0 * k31 + k41)
    zb = zb + wt * (k12 + 2.0 * k22 + 2.0 * k32 + k42)
    vb = vb + wt * (k13 + 2.0 * k23 + 2.0 * k33 + k43)
    y_new = y + wt * (y1 + 2.0 * y2 + 2.0 * y3 + y4)
    z = _advance_z(model, hysteresis, z, zc - zb - y_new - u0, p, hc)
    return zc, vc, zb, vb, z, y_new, ic1, t + h, zg1


@njit(**FAST, **BORROWED)
def plant_outputs(model, p, zc, vc, zb, vb, z, y, ic, inv_mc, inv_mb, ks, kp, zg):
    """``(damper force, body acceleration, bogie acceleration)`` at a state."""
    force, _ = damper_force_and_rate(model, p, zc - zb, vc - vb, y, z, ic,
                                     inv_dashpots(model, p, ic))  # fmt: skip
    sec = ks * (zc - zb) + force
    return force, -sec * inv_mc, (sec - kp * (zb - zg)) * inv_mb
