"""The force of a fitted (or any) damper model on a loop's samples, in the loop's steady state.

:func:`predict_force` is how every identified model is scored (the RMSE of
:mod:`capsule_env.identification.results`) and drawn (:func:`capsule_env.plots.plot_fits`). It
sits above the fitters because it simulates Bouc-Wen with their loop simulation
(:class:`~capsule_env.identification.bouc_wen.BoucWenSequences`).
"""

from __future__ import annotations

import numpy as np

from capsule_env.dampers import BOUC_WEN, REFERENCE, DamperParams, damper_force
from capsule_env.dampers.rig import simulate_damper
from capsule_env.identification.bouc_wen import BoucWenSequences
from capsule_env.identification.loops import Loop, warm_sequence

__all__ = ["predict_force"]


def predict_force(damper: DamperParams, loop: Loop, substeps: int = 4) -> np.ndarray:
    """Force (N) of a forward model on a loop's samples, at the loop's current.

    Algebraic models (Bi-exponential, tanh, linear) are evaluated sample by sample with
    :func:`capsule_env.dampers.damper_force`. Models with internal states are simulated from
    zero state over one preceding period of the stroke (the loop itself when periodic), so
    the prediction is the steady response: Bouc-Wen with the exact hysteresis update on the
    stroke samples, the reference damper with :func:`capsule_env.dampers.rig.simulate_damper`.
    """
    x, v, i = loop.stroke_m, loop.stroke_rate_m_s, np.full(loop.n_samples, loop.current_a)
    if damper.code == BOUC_WEN:
        seq = BoucWenSequences([loop])
        z = seq.z(damper.a_coef, damper.gamma, damper.beta)
        state = np.stack([z, np.zeros_like(z)], axis=-1)
        return damper_force(damper, x, v, i, state=state)[0]
    if damper.code == REFERENCE:
        t2, x2, v2, n_warm = warm_sequence(loop)
        out = simulate_damper(damper, t2, x2, v2, loop.current_a, substeps=substeps)
        return out["force_n"][n_warm:]
    return damper_force(damper, x, v, i)[0]
