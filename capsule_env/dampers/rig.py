"""A damper on a test rig: the damper alone under a prescribed stroke (the loops of a rig).

Identification fits models to such loops (:mod:`capsule_env.identification`): the reference
damper's response to a sinusoidal stroke at constant currents plays the part of the paper's
measured loops. The internal states (Spencer's ``y``, the hysteretic ``z``) are advanced with
RK4 substeps between samples, ``z`` by the exact closed-form update over each stage's
deformation increment (the plant's integrator, :mod:`capsule_env.plant.rk4`, with the stroke
prescribed instead of computed).
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, njit

from capsule_env.dampers import DamperParams
from capsule_env.dampers.base import COIL_TAU
from capsule_env.dampers.dispatch import damper_eval, hysteresis_params
from capsule_env.dampers.hysteresis import hysteresis_update

__all__ = [
    "simulate_damper",
    "sinusoidal_stroke",
    "dissipation_ratio",
    "check_dissipative",
    "DISSIPATION_TESTS",
    "MIN_DISSIPATION_RATIO",
]

#: The strokes a damper must dissipate on (amplitude m, frequency Hz): the capsule's strokes
#: (a few mm to 2.5 cm) at its body and bogie modes' rates.
DISSIPATION_TESTS = ((0.001, 1.0), (0.005, 1.0), (0.025, 1.0), (0.005, 8.0))
#: The least share of a loop's force that must act against the stroke rate (the work per cycle
#: over ``rms(F) rms(v) T``: 1 for a pure viscous damper, 0 for a spring, negative for a
#: force that feeds energy in). Measured: the Labcontrol loops 0.85-0.96, the reference
#: damper's 0.96; pure noise within +-0.06, a sign-flipped loop -0.96 (docs/howto-identify.md).
MIN_DISSIPATION_RATIO = 0.3


@njit(cache=True)
def _damper_response(model, dp, t, x, v, i_cmd, n_sub, force, z_out, y_out, i_out):
    literally(model)  # compiled per model (the dispatch is on its code)
    a_coef, gamma, beta = hysteresis_params(model, dp)
    hysteretic = a_coef > 0.0
    tau = dp[COIL_TAU]
    z = 0.0
    y = 0.0
    ic = i_cmd[0]
    for k in range(t.shape[0]):
        if k > 0:
            dt = t[k] - t[k - 1]
            h = dt / n_sub
            e_half = math.exp(-0.5 * h / tau) if tau > 0.0 else 0.0
            cmd = i_cmd[k - 1]
            for j in range(n_sub):
                f0 = j / n_sub
                fm = (j + 0.5) / n_sub
                f1 = (j + 1.0) / n_sub
                xa = x[k - 1] + f0 * (x[k] - x[k - 1])
                xm = x[k - 1] + fm * (x[k] - x[k - 1])
                xb = x[k - 1] + f1 * (x[k] - x[k - 1])
                va = v[k - 1] + f0 * (v[k] - v[k - 1])
                vm = v[k - 1] + fm * (v[k] - v[k - 1])
                vb = v[k - 1] + f1 * (v[k] - v[k - 1])
                ic_half = cmd + (ic - cmd) * e_half
                ic1 = cmd + (ic_half - cmd) * e_half
                u0 = xa - y
                _, d1, _ = damper_eval(model, dp, xa, va, y, z, ic)
                ys = y + 0.5 * h * d1
                zs = hysteresis_update(z, xm - ys - u0, a_coef, gamma, beta) if hysteretic else z
                _, d2, _ = damper_eval(model, dp, xm, vm, ys, zs, ic_half)
                ys = y + 0.5 * h * d2
                zs = hysteresis_update(z, xm - ys - u0, a_coef, gamma, beta) if hysteretic else z
                _, d3, _ = damper_eval(model, dp, xm, vm, ys, zs, ic_half)
                ys = y + h * d3
                zs = hysteresis_update(z, xb - ys - u0, a_coef, gamma, beta) if hysteretic else z
                _, d4, _ = damper_eval(model, dp, xb, vb, ys, zs, ic1)
                y_new = y + h / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
                if hysteretic:
                    z = hysteresis_update(z, xb - y_new - u0, a_coef, gamma, beta)
                y = y_new
                ic = ic1 if tau > 0.0 else cmd
        force[k], _, _ = damper_eval(model, dp, x[k], v[k], y, z, ic)
        z_out[k] = z
        y_out[k] = y
        i_out[k] = ic


def simulate_damper(
    damper: DamperParams,
    time_s: np.ndarray,
    stroke_m: np.ndarray,
    stroke_rate_m_s: np.ndarray,
    current_a: np.ndarray | float,
    substeps: int = 4,
) -> dict[str, np.ndarray]:
    """Damper alone under a prescribed stroke (the loops of a damper test rig).

    The stroke and its rate are sampled at ``time_s`` and interpolated linearly between
    samples; ``current_a`` (scalar or per sample) is the commanded current, followed through the
    model's coil lag. Internal states start at zero. Returns ``force_n``, ``hysteretic_z_m``,
    ``internal_displacement_m`` and ``coil_current_a`` per sample.
    """
    t = np.ascontiguousarray(time_s, dtype=float)
    x = np.ascontiguousarray(np.broadcast_to(np.asarray(stroke_m, float), t.shape))
    v = np.ascontiguousarray(np.broadcast_to(np.asarray(stroke_rate_m_s, float), t.shape))
    i = np.ascontiguousarray(np.broadcast_to(np.asarray(current_a, float), t.shape))
    i_max = getattr(damper, "max_current_a", np.inf)
    if not np.all(np.isfinite(i)) or i.min() < 0.0 or i.max() > i_max:
        raise ValueError(f"current_a must be finite and in [0, {i_max}] A")
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0.0):
        raise ValueError("time_s must be a 1-D strictly increasing array of at least 2 samples")
    force, z, y, ic = (np.empty_like(t) for _ in range(4))
    _damper_response(damper.code, damper.as_array(), t, x, v, i, int(substeps), force, z, y, ic)
    return {
        "force_n": force,
        "hysteretic_z_m": z,
        "internal_displacement_m": y,
        "coil_current_a": ic,
    }


def sinusoidal_stroke(
    frequency_hz: float, amplitude_m: float, cycles: float, samples_per_cycle: int = 2000
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time_s, stroke_m, stroke_rate_m_s)`` of ``x = amplitude sin(2 pi f t)``."""
    n = int(round(cycles * samples_per_cycle)) + 1
    t = np.linspace(0.0, cycles / frequency_hz, n)
    w = 2.0 * np.pi * frequency_hz
    return t, amplitude_m * np.sin(w * t), amplitude_m * w * np.cos(w * t)


def dissipation_ratio(
    time_s: np.ndarray, force_n: np.ndarray, stroke_rate_m_s: np.ndarray
) -> float:
    """The work the force takes from the stroke over the record, ``integral F v dt``, over
    ``rms(F) rms(v) T``: 1 for a viscous damper, about 0.9 to 0.96 for an MR damper's loop, 0
    for a spring or noise, below 0 for a force that feeds energy into the motion."""
    t = np.asarray(time_s, float)
    power_w = np.asarray(force_n, float) * np.asarray(stroke_rate_m_s, float)
    work_j = float(np.sum(0.5 * (power_w[1:] + power_w[:-1]) * np.diff(t)))
    scale = float(
        np.sqrt(np.mean(np.square(force_n))) * np.sqrt(np.mean(np.square(stroke_rate_m_s)))
    )
    duration_s = float(t[-1] - t[0])
    return work_j / (scale * duration_s) if scale > 0.0 and duration_s > 0.0 else 0.0


def check_dissipative(damper: DamperParams, name: str = "damper") -> None:
    """``ValueError`` unless ``damper`` dissipates on every stroke of :data:`DISSIPATION_TESTS`
    at 0 A and at its largest current: each steady cycle's :func:`dissipation_ratio` at least
    :data:`MIN_DISSIPATION_RATIO`. A damper that feeds energy in (negative damping, a
    sign-flipped fit) is no damper: as a plant it drives the capsule into its bump stops."""
    currents = (0.0, float(getattr(damper, "max_current_a", 0.0)))
    for amplitude_m, frequency_hz in DISSIPATION_TESTS:
        t, x, v = sinusoidal_stroke(frequency_hz, amplitude_m, cycles=2.0, samples_per_cycle=400)
        last = t >= 1.0 / frequency_hz  # the second cycle: internal states settled
        for current_a in sorted(set(currents)):
            force = simulate_damper(damper, t, x, v, current_a)["force_n"]
            ratio = dissipation_ratio(t[last], force[last], v[last])
            if not ratio >= MIN_DISSIPATION_RATIO:
                raise ValueError(
                    f"{name} does not dissipate: on a {1000 * amplitude_m:g} mm, "
                    f"{frequency_hz:g} Hz stroke at {current_a:g} A its work per cycle is "
                    f"{ratio:.2f} of rms(F) rms(v) T (a damper's is >= {MIN_DISSIPATION_RATIO}; "
                    "below 0 it feeds energy in): are signs flipped or a damping coefficient "
                    "negative?"
                )
