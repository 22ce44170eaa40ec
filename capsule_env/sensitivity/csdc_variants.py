"""Variants of the CSDC inverse of the Bouc-Wen model, run as Python-level controllers (issue 27).

The env's CSDC (:class:`capsule_env.dampers.inverse.CSDCInverse`, force mode) advances its estimate of
the Bouc-Wen ``z`` with the exact ``n = 2`` update over each measured stroke increment and
inverts the force algebraically. The paper's Simulink version is lost; this module holds the
variants a sensitivity study needs, each a choice of two parts:

- the ``z`` observer: ``"exact"`` (today's: :func:`capsule_env.dampers.hysteresis.hysteresis_update`
  over the stroke increment) or ``"euler"`` (forward Euler of ``z' = A v - gamma |v| z |z| -
  beta v z^2`` with the measured stroke rate held over the control step, in ``substeps`` equal
  steps: a plain discrete integrator, as a Simulink model at a fixed step would have it);
- the current law: ``"continuous"``, the continuous state damper controller (Wang & Liao
  2005: the current that makes the model's force, affine in the current, equal the request,
  clipped to ``[0, i_max]``; 0 A when ``F_d v <= 0``) or ``"two_level"``, the two-level
  clipped-optimal law of Dyke et al. (1996), ``i = i_max H((F_d - F) F)``, with ``F`` the
  model's force at the present coil current and ``z`` estimate (in ``sim`` the plant is the
  model, so this is the damper force).

:class:`CSDCVariant` is the inverse (state per vehicle, reset per episode);
:class:`InverseSkyhook` the paper's on-off Skyhook (``F_d = c_max v`` when ``z_c' v > 0``, else
``c_min v``, on ideal sensors) requesting its force through any such inverse, run with the env
in ``action_mode="current"`` (it has SB3's ``predict``, so
:func:`capsule_env.evaluation.episodes.run_episodes` runs it). With ``observer="exact"`` and
``law="continuous"`` it is the env's force-mode ``skyhook-csdc`` (tests/test_csdc_variants.py).

References: D. H. Wang, W. H. Liao, JIMSS 16, 983-993, 2005; S. J. Dyke, B. F. Spencer Jr.,
M. K. Sain, J. D. Carlson, Smart Mater. Struct. 5, 565-575, 1996 (docs/model.md references).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.dampers import BoucWenDamper
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.dampers.inverse import affine_in_current, invert_affine
from capsule_env.engine.config import FULL_STATE_NAMES

__all__ = ["CSDC_LAWS", "CSDC_OBSERVERS", "CSDCVariant", "InverseSkyhook", "euler_z_step"]

CSDC_OBSERVERS = ("exact", "euler")
CSDC_LAWS = ("continuous", "two_level")
_COL = {name: k for k, name in enumerate(FULL_STATE_NAMES)}


def euler_z_step(
    z: np.ndarray, rate_m_s: np.ndarray, dt_s: float, damper: BoucWenDamper, substeps: int = 1
) -> np.ndarray:
    """``z`` advanced by ``dt_s`` with ``substeps`` forward-Euler steps of the Bouc-Wen
    equation (``n = 2``) at the constant rate ``rate_m_s`` (m/s). No limiting: a step too long
    for the model's stiffness (about ``2 gamma |v| z_max``) makes the estimate oscillate or
    diverge, as a plain discrete integrator would."""
    a, g, b = damper.a_coef, damper.gamma, damper.beta
    h = dt_s / substeps
    z = np.array(z, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(substeps):
            z = z + h * (a * rate_m_s - g * np.abs(rate_m_s) * z * np.abs(z) - b * rate_m_s * z * z)
    return z


class CSDCVariant:
    """A CSDC inverse of the Bouc-Wen model: a ``z`` observer and a current law (module doc).

    Parameters
    ----------
    damper : the Bouc-Wen model the controller believes in.
    num_vehicles : batch size (one estimate per vehicle).
    observer : ``"exact"`` or ``"euler"``.
    law : ``"continuous"`` or ``"two_level"``.
    dt_s : the control step (s), used by the Euler observer.
    substeps : Euler steps per control step (>= 1).
    """

    def __init__(self, damper: BoucWenDamper, num_vehicles: int = 1, observer: str = "exact",
                 law: str = "continuous", dt_s: float = 0.005, substeps: int = 1) -> None:  # fmt: skip
        if not isinstance(damper, BoucWenDamper):
            raise TypeError(f"damper must be a BoucWenDamper, got {type(damper).__name__}")
        if observer not in CSDC_OBSERVERS:
            raise ValueError(f"observer must be one of {CSDC_OBSERVERS}, got {observer!r}")
        if law not in CSDC_LAWS:
            raise ValueError(f"law must be one of {CSDC_LAWS}, got {law!r}")
        if isinstance(substeps, bool) or int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        if not dt_s > 0.0:
            raise ValueError(f"dt_s must be > 0 s, got {dt_s!r}")
        self.damper, self.observer, self.law = damper, observer, law
        self.dt_s, self.substeps = float(dt_s), int(substeps)
        self._p = damper.as_array()
        self.z_estimate = np.zeros(num_vehicles)
        self._previous_stroke = np.zeros(num_vehicles)

    def reset(self, stroke_m: np.ndarray | float, mask: np.ndarray | None = None) -> None:
        """Start episodes: ``z = 0`` at the given stroke (all vehicles, or those in ``mask``)."""
        mask = np.ones(self.z_estimate.shape, bool) if mask is None else np.asarray(mask, bool)
        self.z_estimate[mask] = 0.0
        self._previous_stroke[mask] = np.broadcast_to(stroke_m, self.z_estimate.shape)[mask]

    def observe(self, stroke_m: np.ndarray, rate_m_s: np.ndarray) -> np.ndarray:
        """Advance the ``z`` estimate to this step's measurements; returns it."""
        if self.observer == "exact":
            d, z = self.damper, self.z_estimate
            for k in range(z.size):
                du = stroke_m[k] - self._previous_stroke[k]
                z[k] = hysteresis_update(z[k], du, d.a_coef, d.gamma, d.beta)
        else:
            self.z_estimate[:] = euler_z_step(
                self.z_estimate, rate_m_s, self.dt_s, self.damper, self.substeps
            )
        self._previous_stroke[:] = stroke_m
        return self.z_estimate

    def __call__(self, desired_force_n: np.ndarray, stroke_m: np.ndarray, rate_m_s: np.ndarray,
                 coil_current_a: np.ndarray) -> np.ndarray:  # fmt: skip
        """The coil current (A) for each vehicle's force request, after :meth:`observe`."""
        z = self.observe(stroke_m, rate_m_s)
        i_max = self.damper.max_current_a
        out = np.zeros_like(z)
        for k in range(z.size):
            f0, slope = affine_in_current(self.damper.code, self._p, stroke_m[k], rate_m_s[k], z[k])
            if not (np.isfinite(f0) and np.isfinite(slope)):
                out[k] = 0.0  # a diverged estimate: no information, the lowest current
            elif self.law == "continuous":
                out[k] = invert_affine(desired_force_n[k], f0, slope, rate_m_s[k], i_max)
            else:
                force = f0 + slope * coil_current_a[k]
                out[k] = i_max if (desired_force_n[k] - force) * force > 0.0 else 0.0
        return out


class InverseSkyhook:
    """On-off Skyhook (paper eq. 15) on ideal sensors, its force through a :class:`CSDCVariant`.

    ``F_d = c_max v`` when ``z_c' v > 0``, else ``c_min v`` (``v = z_c' - z_b'``; the inverse
    reads the measured stroke and stroke rate, as the env's force mode does), clipped to
    ``+-max_force_n`` as the env's force mode clips its action; the inverse turns it into a
    current, sent as the current-mode action ``2 i / i_max - 1``. ``env_kwargs`` run it on the
    Bouc-Wen plant with ``damper_params`` (the ``sim`` pairing: the plant is the inverted
    model); pass ``plant_damper=None`` to keep the setting's plant (``hils``: the reference).

    Parameters
    ----------
    make_inverse : ``num_vehicles -> CSDCVariant`` (one per rollout).
    c_max, c_min : the Skyhook gains (N s/m), default 7e4 and 0 (the paper-reproduction gain).
    max_force_n : the force request's clip (N), the env's default 8000.
    damper_params : the plant's Bouc-Wen parameters (``sim``).
    plant_damper : the plant's damper name, ``"bouc_wen"`` or None (the setting's).
    """

    name = "skyhook-csdc-variant"

    def __init__(self, make_inverse: Any, c_max: float = 7.0e4, c_min: float = 0.0,
                 max_force_n: float = 8000.0, damper_params: dict | None = None,
                 plant_damper: str | None = "bouc_wen") -> None:  # fmt: skip
        self.make_inverse = make_inverse
        self.c_max, self.c_min, self.max_force_n = float(c_max), float(c_min), float(max_force_n)
        kwargs: dict[str, Any] = {"observation": "full_state", "action_mode": "current",
                                  "inverse_model": "csdc"}  # fmt: skip
        if plant_damper is not None:
            kwargs.update(damper=plant_damper, damper_params=dict(damper_params or {}))
        self.env_kwargs = kwargs
        self.inverse: CSDCVariant | None = None

    def reset(self) -> None:
        self.inverse = None

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        obs = np.atleast_2d(np.asarray(observation, dtype=float))
        n = obs.shape[0]
        stroke, rate = obs[:, _COL["stroke_m"]], obs[:, _COL["stroke_rate_m_s"]]
        if self.inverse is None:
            self.inverse = self.make_inverse(n)
            self.inverse.reset(stroke)
        elif episode_start is not None and np.any(episode_start):
            self.inverse.reset(stroke, np.asarray(episode_start, bool))
        body = obs[:, _COL["car_body_velocity_m_s"]]
        rel = body - obs[:, _COL["bogie_velocity_m_s"]]  # the Skyhook's v, as agents/ reads it
        f_d = np.where(body * rel > 0.0, self.c_max * rel, self.c_min * rel)
        f_d = np.clip(f_d, -self.max_force_n, self.max_force_n)
        current = self.inverse(f_d, stroke, rate, obs[:, _COL["coil_current_a"]])
        i_max = self.inverse.damper.max_current_a
        return (2.0 * current / i_max - 1.0).reshape(n, 1), state
