"""Inverse MR damper models: desired damper force -> coil current (docs/model.md, section 5).

Every inverse here rests on one fact: at fixed kinematics (and fixed hysteretic state) the
Bi-exponential, tanh and Bouc-Wen forces are *affine in the current*,
``F(i) = F0 + slope * i``. Inverting that line, clipped to ``[0, i_max]``, is the paper's
closed-form Bi-exponential inverse (eqs. 5-11), the tanh-model inverse and the algebraic core of
the CSDC algorithm (Wang & Liao 2005) for Bouc-Wen. Shared rules:

- semi-active rule: a request whose sign is opposite to the stroke rate (``F_d v < 0``) cannot
  be produced by a passive device, so the current is 0; so is a request for 0 N (or at
  ``v = 0``): near ``v = 0`` the hysteresis offset alone can make ``i_max`` the "nearest"
  force to 0 N, and the lowest current is what a zero request means;
- a request outside the achievable band ``[F(0), F(i_max)]`` is clipped to the nearest
  achievable force (0 A or ``i_max``);
- where the slope vanishes (e.g. ``v = 0`` with no hysteresis offset) nothing is divided: the
  current that brings the force nearest the request is chosen.

The CSDC inverse has state: its estimate of the Bouc-Wen ``z``, run online from the measured
stroke with the exact hysteresis update; :class:`CSDCInverse` keeps it per vehicle and is reset
per episode. Pure numba/numpy, no Gym import.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np
from numba import literally, njit

from capsule_env.common.validation import check_choice
from capsule_env.dampers import BiExponentialDamper, BoucWenDamper, TanhDamper
from capsule_env.dampers.base import I_MAX, DamperParamsBase
from capsule_env.dampers.dispatch import model_affine
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.dampers.registry import MODELS, model_named

__all__ = [
    "INVERSE_NAMES",
    "INVERSE_MODELS",
    "INVERSE_CODES",
    "affine_in_current",
    "invert_affine",
    "csdc_z_update",
    "bi_exponential_inverse",
    "tanh_inverse",
    "CSDCInverse",
    "inverse_current",
]


def inverse_models() -> dict[str, str]:
    """``{inverse name: the damper model it inverts}``: every registered model with an affine
    form (``DamperModel.affine``), under its ``inverse_name``."""
    return {m.inverse_name: m.name for m in MODELS.values() if m.affine is not None}


class _InverseCodes(Mapping):
    """``{inverse name: the damper code of the model it inverts}``, a view of the registry."""

    def __getitem__(self, name: str) -> int:
        return model_named(inverse_models()[name]).code

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(inverse_models()))

    def __len__(self) -> int:
        return len(inverse_models())


#: Damper code of the model each inverse (``EnvConfig.inverse_model``) inverts, registered
#: models included.
INVERSE_CODES: Mapping[str, int] = _InverseCodes()
#: The inverses of the built-in models and the model each inverts (``csdc``: Bouc-Wen's, with
#: its hysteresis estimate; the others are named after their model).
INVERSE_MODELS = dict(sorted(inverse_models().items()))
INVERSE_NAMES = tuple(INVERSE_MODELS)
#: The CSDC inverse's model and the packed slots of its hysteresis.
_CSDC = model_named(INVERSE_MODELS["csdc"])
_CSDC_CODE = _CSDC.code
_A, _GAMMA, _BETA = _CSDC.hysteresis.a_coef, _CSDC.hysteresis.gamma, _CSDC.hysteresis.beta

#: ``affine_in_current(model, p, x, v, z) -> (F0, slope)`` with ``F(i) = F0 + slope * i``: the
#: model's affine form (:func:`capsule_env.dampers.dispatch.model_affine`), the model's code a
#: compile-time constant. Written without branches or library calls for the algebraic models,
#: so that a loop over vehicles vectorises; ``p`` is the packed parameters (array or tuple).
affine_in_current = model_affine


@njit(cache=True, error_model="numpy", inline="always")
def invert_affine(f_desired, f0, slope, v, i_max):
    """Current for ``F0 + slope * i = F_d`` with the semi-active rule and clipping, as selects
    (no branches, so that a loop over vehicles vectorises).

    A request that does not push the way the stroke moves (``F_d v <= 0``: opposite signs, a
    zero request, or no stroke rate) gets 0 A: a semi-active damper cannot help there, and a
    request for no force is a request for the lowest current. Where the force barely depends on
    the current, the end of the band nearer the request is chosen (nothing is divided by ~0)."""
    f_max = f0 + slope * i_max
    flat = abs(slope) * i_max <= 1e-9 * (abs(f0) + abs(f_desired) + 1.0)
    nearer = 0.0 if abs(f0 - f_desired) <= abs(f_max - f_desired) else i_max
    i = min(max((f_desired - f0) / slope, 0.0), i_max)
    i = nearer if flat else i
    return 0.0 if f_desired * v <= 0.0 else i


@njit(cache=True, error_model="numpy")
def _inverse_batch(model, params, f_d, x, v, z, out):
    literally(model)  # compiled per model (the dispatch is on its code)
    for k in range(f_d.shape[0]):
        p = params[k]
        f0, slope = affine_in_current(model, p, x[k], v[k], z[k])
        out[k] = invert_affine(f_d[k], f0, slope, v[k], p[I_MAX])


def _batch(damper, desired_force_n, stroke_m, stroke_rate_m_s, z=None) -> np.ndarray:
    f_d, x, v = np.broadcast_arrays(
        np.asarray(desired_force_n, float),
        np.asarray(stroke_m, float),
        np.asarray(stroke_rate_m_s, float),
    )
    shape = f_d.shape
    for name, arr in (("desired_force_n", f_d), ("stroke_m", x), ("stroke_rate_m_s", v)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite (got NaN or inf)")
    n = f_d.size
    zz = np.zeros(n) if z is None else np.broadcast_to(np.asarray(z, float), shape).ravel().copy()
    params = np.ascontiguousarray(np.broadcast_to(damper.as_array(), (n, damper.as_array().size)))
    out = np.empty(n)
    _inverse_batch(
        damper.code, params, f_d.ravel().copy(), x.ravel().copy(), v.ravel().copy(), zz, out
    )
    return out.reshape(shape)


def bi_exponential_inverse(
    damper: BiExponentialDamper,
    desired_force_n: np.ndarray | float,
    stroke_m: np.ndarray | float,
    stroke_rate_m_s: np.ndarray | float,
) -> np.ndarray:
    """Closed-form Bi-exponential inverse (paper eqs. 5-11, docs/model.md 5), batched.

    ``i* = (F_d - a0 S_d(v) - b0 v - c0) / (a1 S_d(v) + b1 v + c1)`` with the upper set where
    ``x >= 0`` and the lower set where ``x < 0``; valid where ``F(v, 0) <= F_d <= F(v, i_max)``,
    clipped to ``[0, i_max]`` outside; 0 A when ``F_d`` and ``v`` have opposite signs.
    Returns the current (A) with the broadcast shape of the inputs.
    """
    if not isinstance(damper, BiExponentialDamper):
        raise ValueError("damper must be a BiExponentialDamper for the Bi-exponential inverse")
    return _batch(damper, desired_force_n, stroke_m, stroke_rate_m_s)


def tanh_inverse(
    damper: TanhDamper,
    desired_force_n: np.ndarray | float,
    stroke_m: np.ndarray | float,
    stroke_rate_m_s: np.ndarray | float,
) -> np.ndarray:
    """Inverse of the tanh model (its c, k, alpha, f0 are linear in current), batched."""
    if not isinstance(damper, TanhDamper):
        raise ValueError("damper must be a TanhDamper for the tanh inverse")
    return _batch(damper, desired_force_n, stroke_m, stroke_rate_m_s)


@njit(cache=True, inline="always")
def csdc_z_update(p, z_estimate: float, stroke_increment_m: float) -> float:
    """The CSDC inverse's Bouc-Wen ``z`` estimate advanced over a measured stroke increment
    (the exact n = 2 update of :mod:`capsule_env.dampers.hysteresis`)."""
    return hysteresis_update(z_estimate, stroke_increment_m, p[_A], p[_GAMMA], p[_BETA])


@njit(cache=True, error_model="numpy")
def _csdc_batch(p, f_d, x, v, z, x_prev, out):
    for k in range(f_d.shape[0]):
        z[k] = csdc_z_update(p, z[k], x[k] - x_prev[k])
        x_prev[k] = x[k]
        f0, slope = affine_in_current(_CSDC_CODE, p, x[k], v[k], z[k])
        out[k] = invert_affine(f_d[k], f0, slope, v[k], p[I_MAX])


class CSDCInverse:
    """Continuous state damper controller (CSDC) inverse of the Bouc-Wen model, with state.

    ``i = clip((F_d - c0a x' - k0 (x - x0) - alpha_a z) / (c0b x' + alpha_b z), 0, i_max)``
    when ``F_d x' > 0``, else 0 (paper eq. 2, docs/model.md 5). ``z`` is estimated online by
    running the Bouc-Wen z-equation on the measured stroke: each call advances the estimate over
    the stroke increment since the previous call with the exact n = 2 update (exact for
    monotone stroke between calls), then inverts.

    Parameters
    ----------
    damper : the identified Bouc-Wen model the controller believes in.
    num_vehicles : batch size; each vehicle has its own estimate.
    """

    def __init__(self, damper: BoucWenDamper, num_vehicles: int = 1) -> None:
        if not isinstance(damper, BoucWenDamper):
            raise ValueError("damper must be a BoucWenDamper for the CSDC inverse")
        self.damper = damper
        self._params = damper.as_array()
        self.z_estimate = np.zeros(num_vehicles)
        self._previous_stroke = np.zeros(num_vehicles)

    def reset(self, stroke_m: np.ndarray | float = 0.0, mask: np.ndarray | None = None) -> None:
        """Start a new episode: estimate z = 0 at the given stroke (all vehicles or ``mask``)."""
        if mask is None:
            self.z_estimate[:] = 0.0
            self._previous_stroke[:] = stroke_m
        else:
            self.z_estimate[mask] = 0.0
            self._previous_stroke[mask] = np.broadcast_to(stroke_m, self.z_estimate.shape)[mask]

    def __call__(
        self,
        desired_force_n: np.ndarray | float,
        stroke_m: np.ndarray | float,
        stroke_rate_m_s: np.ndarray | float,
    ) -> np.ndarray:
        """Advance the z estimate to the measured stroke and return the current (A)."""
        n = self.z_estimate.shape[0]
        f_d, x, v = (
            np.ascontiguousarray(np.broadcast_to(np.asarray(a, float), (n,)))
            for a in (desired_force_n, stroke_m, stroke_rate_m_s)
        )
        for name, arr in (("desired_force_n", f_d), ("stroke_m", x), ("stroke_rate_m_s", v)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} must be finite (got NaN or inf)")
        out = np.empty(n)
        _csdc_batch(self._params, f_d, x, v, self.z_estimate, self._previous_stroke, out)
        return out


def inverse_current(
    name: str,
    damper: DamperParamsBase,
    desired_force_n: np.ndarray | float,
    stroke_m: np.ndarray | float,
    stroke_rate_m_s: np.ndarray | float,
) -> np.ndarray:
    """Stateless inverse by name (``"bi_exponential"``, ``"tanh"`` or a registered model's);
    CSDC, whose model has a hysteretic state, needs its object."""
    inverses = inverse_models()
    check_choice("inverse model", name, tuple(sorted(inverses)))
    model = model_named(inverses[name])
    if model.hysteresis is not None:
        raise ValueError(f"the {name!r} inverse has state: use CSDCInverse(damper, num_vehicles)")
    if not isinstance(damper, model.params):
        raise ValueError(f"damper must be a {model.params.__name__} for the {name} inverse")
    return _batch(damper, desired_force_n, stroke_m, stroke_rate_m_s)
