"""A plant damper identified from measured loops, at the capsule's scale (issue 43).

The ``hils`` comparison's plant is the reference (Spencer) damper. This module makes a second
plant from a folder of measured Labcontrol MR-damper loops (a small damper, peak forces about
0.1 to 0.9 kN, coil voltage not recorded):

1. :func:`select_pair`: the *high* loop is the one of the largest peak force (the most
   current); the *low* loop the one of the smallest peak force among those at the same stroke
   (half peak-to-peak within 25 %) and frequency (within 10 %) (the least current).
2. :func:`capsule_scales`: one mapping for both loops, from the high loop to the reference
   damper's 1.5 A identification loop (+-25 mm, 1 Hz sine): stroke times
   ``25 mm / half its peak-to-peak``; time scaled so its peak stroke rate (99th percentile of
   ``|v|``) becomes the reference loop's ``2 pi 1 Hz 25 mm`` = 0.157 m/s; force times
   ``reference peak / its peak`` (99th percentiles of ``|F|``, robust to the rig's spikes).
3. :func:`identify_measured_plant`: the high loop is taken as 1.5 A and the low one as 0 A
   (the linear current laws all three models assume pass through the two measured ends); the
   plant is the tanh hysteresis model fitted to both scaled loops, a model form neither pair
   inverts (as the Spencer plant is neither's), and the Bouc-Wen and Bi-exponential models are
   fitted to the same scaled loops, as the paper identified both on its damper's loops.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.dampers import ReferenceDamper
from capsule_env.dampers.rig import check_dissipative
from capsule_env.identification.bi_exponential import fit_bi_exponential
from capsule_env.identification.bouc_wen import fit_bouc_wen
from capsule_env.identification.constrained import rmse_at_current
from capsule_env.identification.loops import Loop, reference_loops
from capsule_env.identification.measured import load_measured_loop, measured_files, scale_loop
from capsule_env.identification.tanh import fit_tanh

__all__ = ["capsule_scales", "identify_measured_plant", "loop_shape", "select_pair"]

#: The reference identification loop the high loop is mapped onto: +-25 mm at 1 Hz.
REFERENCE_AMPLITUDE_M = 0.025
REFERENCE_FREQUENCY_HZ = 1.0
#: The current the high loop is taken to be at (the reference damper's largest, A).
HIGH_CURRENT_A = 1.5
_ROBUST_PEAK_PCT = 99.0


def loop_shape(loop: Loop) -> dict[str, float]:
    """A loop's stroke amplitude (half its peak-to-peak, m), dominant frequency (Hz, the
    peak of the stroke's spectrum, zero-padded 16 times), robust peak stroke rate and force
    (99th percentiles of ``|v|`` (m/s) and ``|F|`` (N))."""
    x = loop.stroke_m - np.mean(loop.stroke_m)
    dt = float(np.mean(np.diff(loop.time_s)))
    n = 16 * x.size
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), n))
    freqs = np.fft.rfftfreq(n, dt)
    return {
        "amplitude_m": float(np.ptp(x) / 2.0),
        "frequency_hz": float(freqs[1 + int(np.argmax(spectrum[1:]))]),
        "peak_rate_m_s": float(np.percentile(np.abs(loop.stroke_rate_m_s), _ROBUST_PEAK_PCT)),
        "peak_force_n": float(np.percentile(np.abs(loop.force_n), _ROBUST_PEAK_PCT)),
    }


def select_pair(loops: Sequence[Loop]) -> tuple[int, int]:
    """Indices ``(low, high)``: ``high`` the loop of the largest robust peak force, ``low``
    the smallest among the loops within 25 % of its amplitude and 10 % of its frequency
    (``ValueError`` when no other loop is)."""
    shapes = [loop_shape(lp) for lp in loops]
    high = int(np.argmax([s["peak_force_n"] for s in shapes]))
    h = shapes[high]
    alike = [k for k, s in enumerate(shapes) if k != high
             and abs(s["amplitude_m"] / h["amplitude_m"] - 1.0) <= 0.25
             and abs(s["frequency_hz"] / h["frequency_hz"] - 1.0) <= 0.10]  # fmt: skip
    if not alike:
        raise ValueError(
            f"no loop has the stroke (+-25 %) and frequency (+-10 %) of the largest-force loop "
            f"({h['amplitude_m'] * 1e3:.1f} mm, {h['frequency_hz']:.2f} Hz): no low-current pair"
        )
    return min(alike, key=lambda k: shapes[k]["peak_force_n"]), high


def capsule_scales(high: Loop) -> dict[str, float]:
    """The stroke, time and force scales that map ``high`` onto the reference damper's 1.5 A
    loop (+-25 mm, 1 Hz; see the module docstring)."""
    s = loop_shape(high)
    ref = reference_loops(currents=(HIGH_CURRENT_A,), frequency_hz=REFERENCE_FREQUENCY_HZ,
                          amplitude_m=REFERENCE_AMPLITUDE_M)[0]  # fmt: skip
    r = loop_shape(ref)
    stroke = REFERENCE_AMPLITUDE_M / s["amplitude_m"]
    # the scaled rate is rate * stroke / time: make its robust peak the reference's
    time = stroke * s["peak_rate_m_s"] / r["peak_rate_m_s"]
    return {"stroke_scale": stroke, "time_scale": time,
            "force_scale": r["peak_force_n"] / s["peak_force_n"],
            "reference_peak_force_n": r["peak_force_n"]}  # fmt: skip


def _params(model: Any) -> dict[str, float]:
    return {f.name: float(getattr(model, f.name)) for f in fields(model)}


def identify_measured_plant(source: str | Path | Sequence[Loop]) -> dict[str, Any]:
    """The measured plant and both pairs' models from a folder of Labcontrol ``.mat`` files
    (or a list of loops): ``{"plant": tanh params, "bouc_wen": ..., "bi_exponential": ...,
    "rmse_1p5A_n": {model: RMSE on the scaled high loop}, "scales": ..., "files": (low, high),
    "shapes": ...}``. ``ValueError`` for a bad folder or a plant that does not dissipate."""
    if isinstance(source, (str, Path)):
        loops = [load_measured_loop(f) for f in measured_files(source)]
    else:
        loops = list(source)
    low, high = select_pair(loops)
    scales = capsule_scales(loops[high])
    kw = {k: scales[k] for k in ("stroke_scale", "time_scale", "force_scale")}
    scaled = [scale_loop(loops[low], current_a=0.0, **kw),
              scale_loop(loops[high], current_a=HIGH_CURRENT_A, **kw)]  # fmt: skip
    models = {"plant": fit_tanh(scaled), "bouc_wen": fit_bouc_wen(scaled),
              "bi_exponential": fit_bi_exponential(scaled)[0]}  # fmt: skip
    check_dissipative(models["plant"], "the measured plant (tanh fit)")
    ref_rmse = rmse_at_current(ReferenceDamper(), scaled, HIGH_CURRENT_A)
    return {
        **{k: _params(m) for k, m in models.items()},
        "rmse_1p5A_n": {
            **{k: rmse_at_current(m, scaled, HIGH_CURRENT_A) for k, m in models.items()},
            "reference": ref_rmse,
        },  # fmt: skip
        "scales": scales,
        "files": (loops[low].source, loops[high].source),
        "shapes": {"low": loop_shape(loops[low]), "high": loop_shape(loops[high])},
    }
