"""The one RK4 substep of the plant, shared by the scalar and the vectorised kernels.

One substep ``h`` of classical RK4 on ``[z_c, z_c', z_b, z_b', y]`` (masses and Spencer's
internal displacement), with

- the stiff hysteretic variable ``z`` taken at every stage from the exact closed-form
  Bouc-Wen update over the stage's deformation increment (:mod:`capsule_env.dampers.hysteresis`);
- the coil current following its command through the first-order lag, solved exactly
  (``e_half = exp(-h / (2 tau))`` per half substep; 0 without lag);
- the guideway elevation at the start, middle and end of the substep given by the caller;
  where the levitation is damped (``damped``, a compile-time flag), its rate taken as the
  substep's mean, ``(z_g(t + h) - z_g(t)) / h`` (exact for the guideway's piecewise-linear
  profile when the substep lies between two samples).

Everything is written without branches or library calls in the vectorised variants (the
damper laws of :mod:`capsule_env.dampers`, :func:`~capsule_env.dampers.hysteresis.hysteresis_update_fast`),
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

from capsule_env._jit import kernel_function, specialised
from capsule_env.dampers.dispatch import model_force, model_prepare
from capsule_env.dampers.hysteresis import hysteresis_update, hysteresis_update_fast
from capsule_env.dampers.registry import model_of_code
from capsule_env.plant.equations import VEHICLE_LANE_NAMES, accelerations, levitation_force

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
                    *VEHICLE_LANE_NAMES, "zg_start", "zg_mid", "zg_end")  # fmt: skip

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


@kernel_function(inline=True)
def _rates(model, damped, p, x, pre, zg, zg_rate, vehicle):
    """The time derivatives of the state ``x = (z_c, z_c', z_b, z_b', z, y, i)`` (the first
    7 of ``layout.STATE_NAMES``) but ``z`` and ``i`` (advanced in closed form):
    ``(z_c', z_c'', z_b', z_b'', y')`` at guideway elevation ``zg`` (rising at ``zg_rate``,
    read where ``damped``); ``pre``: the damper model's ``prepare`` at current ``i``."""
    zc, vc, zb, vb, z, y, i = x
    force, y_dot = damper_force_and_rate(model, p, zc - zb, vc - vb, y, z, i, pre)
    lev = levitation_force(damped, zb - zg, vb - zg_rate, vehicle)
    acc_c, acc_b = accelerations(zc, zb, force, lev, vehicle)
    return vc, acc_c, vb, acc_b, y_dot


@kernel_function(inline=True)
def _stage(x, k, step):
    """``x + step k`` over ``(z_c, z_c', z_b, z_b', y)``: the state an RK4 stage reads."""
    return (x[0] + step * k[0], x[1] + step * k[1], x[2] + step * k[2], x[3] + step * k[3],
            x[4] + step * k[4])  # fmt: skip


@kernel_function(inline=True)
def _combine(x, k1, k2, k3, k4, wt):
    """``x + wt (k1 + 2 k2 + 2 k3 + k4)`` over ``(z_c, z_c', z_b, z_b', y)``: the RK4 step."""
    return (
        x[0] + wt * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
        x[1] + wt * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        x[2] + wt * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
        x[3] + wt * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
        x[4] + wt * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4]),
    )


@kernel_function(inline=True)
def rk4_substep(model, hysteresis, damped, v, p, hc):
    """One RK4 substep of one vehicle: ``v`` the :data:`LANE_INPUT_NAMES` values, ``p`` the
    damper parameters and ``hc`` the Riccati constants (tuples); ``damped``: whether the
    levitation has damping (compile-time). Returns the new
    ``(z_c, z_c', z_b, z_b', z, y, i, t, zg_end)``."""
    zc, vc, zb, vb, z, y, ic, t, h, i_cmd, e_half = v[0:11]
    vehicle, (zg0, zgh, zg1) = v[11:16], v[16:19]
    zg_rate = (zg1 - zg0) / h if damped else 0.0
    ic_half = i_cmd + (ic - i_cmd) * e_half
    ic1 = i_cmd + (ic_half - i_cmd) * e_half
    pre_0 = inv_dashpots(model, p, ic)
    pre_h = inv_dashpots(model, p, ic_half)
    pre_1 = inv_dashpots(model, p, ic1)
    x0 = (zc, vc, zb, vb, y)
    u0 = zc - zb - y  # the deformation that drives z, at the start
    k1 = _rates(model, damped, p, (zc, vc, zb, vb, z, y, ic), pre_0, zg0, zg_rate, vehicle)
    a = _stage(x0, k1, 0.5 * h)
    zs = _advance_z(model, hysteresis, z, a[0] - a[2] - a[4] - u0, p, hc)
    k2 = _rates(model, damped, p, (a[0], a[1], a[2], a[3], zs, a[4], ic_half), pre_h, zgh,
                zg_rate, vehicle)  # fmt: skip
    a = _stage(x0, k2, 0.5 * h)
    zs = _advance_z(model, hysteresis, z, a[0] - a[2] - a[4] - u0, p, hc)
    k3 = _rates(model, damped, p, (a[0], a[1], a[2], a[3], zs, a[4], ic_half), pre_h, zgh,
                zg_rate, vehicle)  # fmt: skip
    a = _stage(x0, k3, h)
    zs = _advance_z(model, hysteresis, z, a[0] - a[2] - a[4] - u0, p, hc)
    k4 = _rates(model, damped, p, (a[0], a[1], a[2], a[3], zs, a[4], ic1), pre_1, zg1, zg_rate,
                vehicle)  # fmt: skip
    zc, vc, zb, vb, y_new = _combine(x0, k1, k2, k3, k4, h / 6.0)
    z = _advance_z(model, hysteresis, z, zc - zb - y_new - u0, p, hc)
    return zc, vc, zb, vb, z, y_new, ic1, t + h, zg1


@kernel_function
def plant_outputs(model, damped, p, x, zg, zg_rate, vehicle):
    """``(damper force, body acceleration, bogie acceleration)`` at a state ``x = (z_c, z_c',
    z_b, z_b', z, y, i)``, guideway elevation ``zg`` and its rate ``zg_rate`` (read where
    ``damped``)."""
    zc, vc, zb, vb, z, y, ic = x
    force, _ = damper_force_and_rate(model, p, zc - zb, vc - vb, y, z, ic,
                                     inv_dashpots(model, p, ic))  # fmt: skip
    lev = levitation_force(damped, zb - zg, vb - zg_rate, vehicle)
    acc_c, acc_b = accelerations(zc, zb, force, lev, vehicle)
    return force, acc_c, acc_b
