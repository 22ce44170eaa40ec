"""Building a damper by name and evaluating its force from numpy (the public entry points)."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
from numba import literally, njit

from capsule_env.common.validation import check_array_in_range
from capsule_env.dampers.base import N_DAMPER_PARAMS, DamperParamsBase
from capsule_env.dampers.dispatch import damper_eval, hysteresis_params
from capsule_env.dampers.hysteresis import hysteresis_rate
from capsule_env.dampers.registry import model_named

__all__ = ["make_damper", "damper_force"]


def make_damper(name: str, **overrides: float) -> DamperParamsBase:
    """Build a damper model by name (one of ``registry.MODELS``, the built-in ones
    :data:`~capsule_env.dampers.DAMPER_NAMES`) with parameter overrides.

    Raises ``ValueError`` naming the parameter for an unknown model or an unknown/bad parameter.
    """
    cls = model_named(name).params
    known = {f.name for f in fields(cls)}
    for key in overrides:
        if key not in known:
            raise ValueError(
                f"unknown parameter {key!r} for damper model {name!r}; accepted: "
                f"{', '.join(sorted(known))}"
            )
    return cls(**overrides)


@njit(cache=True)
def _damper_force_batch(model, params, x, v, i, z, y, force, z_dot, y_dot):
    literally(model)  # compiled per model (the dispatch is on its code)
    for k in range(x.shape[0]):
        p = params[k]
        f, yd, w = damper_eval(model, p, x[k], v[k], y[k], z[k], i[k])
        a_coef, gamma, beta = hysteresis_params(model, p)
        force[k] = f
        y_dot[k] = yd
        z_dot[k] = hysteresis_rate(z[k], w, a_coef, gamma, beta) if a_coef > 0.0 else 0.0


def damper_force(
    damper: DamperParamsBase,
    stroke_m: np.ndarray | float,
    stroke_rate_m_s: np.ndarray | float,
    current_a: np.ndarray | float,
    state: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Force and internal-state derivative of a damper model, batched (numpy in, numpy out).

    Parameters
    ----------
    damper : a damper parameter dataclass.
    stroke_m, stroke_rate_m_s, current_a : broadcastable arrays; current in
        ``[0, damper.max_current_a]`` (A).
    state : ``(..., 2)`` internal state ``[z, y]`` (m); zeros if None.

    Returns
    -------
    force : (N) array, positive when resisting a positive stroke rate.
    state_derivative : ``(..., 2)`` array ``[z', y']``.
    """
    x, v, i = np.broadcast_arrays(
        np.asarray(stroke_m, float),
        np.asarray(stroke_rate_m_s, float),
        np.asarray(current_a, float),
    )
    shape = x.shape
    i_max = getattr(damper, "max_current_a", np.inf)
    check_array_in_range("current_a", i, 0.0, i_max)
    if state is None:
        state = np.zeros((*shape, 2))
    state = np.broadcast_to(np.asarray(state, float), (*shape, 2)).reshape(-1, 2)
    n = x.size
    params = np.broadcast_to(damper.as_array(), (n, N_DAMPER_PARAMS))
    force, z_dot, y_dot = np.empty(n), np.empty(n), np.empty(n)
    _damper_force_batch(
        damper.code,
        np.ascontiguousarray(params),
        x.ravel().copy(),
        v.ravel().copy(),
        i.ravel().copy(),
        np.ascontiguousarray(state[:, 0]),
        np.ascontiguousarray(state[:, 1]),
        force,
        z_dot,
        y_dot,
    )
    return force.reshape(shape), np.stack([z_dot, y_dot], axis=-1).reshape(*shape, 2)
