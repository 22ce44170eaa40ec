"""Clipped-optimal control (Dyke et al. 1996): an LQR force law for the linear plant, produced
as far as the damper can (the env's inverse model clips the request to the achievable,
dissipative band).

State ``x = [z_c - z_b, z_c', z_b - z_g, z_b']``. On ``full_state`` (ideal sensors) each
component is read from the true states; on ``measured`` (``-meas``) all four are measured:
the LVDT stroke, the on-board body velocity estimate, the levitation gap sensor and the bogie
velocity estimate (:mod:`capsule_env.agents.controllers.law`). Force mode: the law asks for a continuum of forces.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from capsule_env.agents.controllers.skyhook import DEFAULT_MAX_FORCE_N, ForceLaw
from scipy.linalg import solve_continuous_are

from capsule_env.vehicles import (
    SPRING,
    LinearModel,
    VehicleModel,
    VehicleParams,
    model_of_params,
    relative_model,
)

#: The parameters a gain-scheduled law overrides (the EDS levitation at each speed).
LEVITATION_STIFFNESS, LEVITATION_DAMPING = (
    "levitation_stiffness_n_per_m",
    "levitation_damping_n_s_per_m",
)

#: Names (with units) of the components of the feedback gain ``K``, in state order.
GAIN_NAMES = ("k_stroke_n_m", "k_body_velocity_n_s_m", "k_gap_n_m", "k_bogie_velocity_n_s_m")
STATE_SIGNALS = ("stroke", "body_velocity", "gap", "bogie_velocity")


def lqr_gain(
    vehicle: VehicleParams,
    q_stroke: float,
    q_levitation: float,
    r_force: float,
    levitation_stiffness_n_per_m: float | None = None,
    levitation_damping_n_s_per_m: float | None = None,
) -> np.ndarray:
    """The LQR gain ``K`` (4,) with ``F = -K x`` minimising
    ``J = integral(a_c^2 + q_stroke (z_c - z_b)^2 + q_lev (z_b - z_g)^2 + r F^2)``, with
    ``a_c = (-k_s (z_c - z_b) - F) / m_c`` the car-body acceleration (the cross term kept).

    The levitation is a spring ``k_p`` (default: the vehicle's, the paper's 810 km/h value)
    and a damper ``c_p`` (N s/m, default: the vehicle's, 0 for the paper's undamped
    levitation) between the bogie and the guideway: ``m_b z_b'' = k_s (z_c - z_b) + F - k_p (z_b - z_g) - c_p (z_b' - z_g')``,
    the guideway's velocity a disturbance. The gain-scheduled law
    (:mod:`capsule_env.agents.controllers.scheduled_lqr`) gives the EDS values at each speed."""
    _check_weights(q_stroke=q_stroke, q_levitation=q_levitation, r_force=r_force)
    model = model_of_params(vehicle)
    scheduled = {LEVITATION_STIFFNESS: levitation_stiffness_n_per_m,
                 LEVITATION_DAMPING: levitation_damping_n_s_per_m}  # fmt: skip
    overrides = {k: float(v) for k, v in scheduled.items() if v is not None}
    plant = relative_model(model, vehicle, 0.0, **overrides)
    a, b, c_acc, d_acc = plant.a, plant.b, plant.c_acc, plant.d_acc
    q = c_acc.T @ c_acc + state_weights(model, plant, q_stroke, q_levitation)
    r = d_acc.T @ d_acc + r_force * np.eye(b.shape[1])
    n = c_acc.T @ d_acc
    p = solve_continuous_are(a, b, q, r, s=n)
    gain = np.linalg.solve(r, b.T @ p + n.T)
    return gain[0] if gain.shape[0] == 1 else gain


def _check_weights(**weights: object) -> None:
    """``TypeError``/``ValueError`` naming a weight that is not a finite number, ``>= 0`` (the
    state weights) or ``> 0`` (``r_force``)."""
    for name, value in weights.items():
        if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
            raise TypeError(f"{name} must be a number, got {type(value).__name__}")
        low_ok = value > 0 if name == "r_force" else value >= 0
        if not (np.isfinite(value) and low_ok):
            bound = "> 0" if name == "r_force" else ">= 0"
            raise ValueError(f"{name} must be finite and {bound}, got {value!r}")


def state_weights(
    model: VehicleModel, plant: LinearModel, q_stroke: float, q_gap: float
) -> np.ndarray:
    """The state cost's diagonal part: ``q_stroke`` on each damper slot's stroke, ``q_gap`` on
    each spring to the guideway's deflection (the levitation gaps), in the relative form."""
    n = plant.a.shape[0]
    positions = plant.stroke[:, 0::2]
    weights = np.zeros((n, n))
    weights[0::2, 0::2] = q_stroke * (positions.T @ positions)
    contacts = {c.name for c in model.contacts}
    springs = {e.name: e for e in model.elements if e.kind == SPRING}
    gaps = [2 * p for p, s in enumerate(model.relative_positions) if springs[s].lower in contacts]
    weights[gaps, gaps] += q_gap
    return weights


#: The weights' units (the suffixes of their keys in :meth:`~ClippedOptimalController.gains`)
#: and their values when no tuned ones exist [reconstructed].
WEIGHT_UNITS = {"q_stroke": "1_s4", "q_levitation": "1_s4", "r_force": "1_kg2"}
FALLBACK_WEIGHTS = {"q_stroke": 1.0e3, "q_levitation": 1.0e3, "r_force": 1.0e-9}


def set_weights(
    law: ForceLaw, given: dict[str, float | np.ndarray | None], fallback: dict[str, float]
) -> list[np.ndarray]:
    """Store an LQR law's weights (``law._set_gains``: ``given`` where not None, else the
    tuned values, else ``fallback``), check them and return them broadcast together
    (``[q_stroke, q_levitation, r_force]``). Raises ``ValueError`` for negative state weights
    or a force weight that is not positive."""
    law._set_gains(WEIGHT_UNITS, given, fallback)
    weights = list(np.broadcast_arrays(*(getattr(law, name) for name in WEIGHT_UNITS)))
    if np.any(weights[0] < 0) or np.any(weights[1] < 0) or np.any(weights[2] <= 0):
        raise ValueError("q_stroke and q_levitation must be >= 0 and r_force > 0")
    return weights


def design_per_vehicle(
    weights: list[np.ndarray], design: Callable[[float, float, float], np.ndarray]
) -> np.ndarray:
    """``design(q_stroke, q_levitation, r_force)`` for each vehicle's weights (each distinct
    triple designed once), shaped ``(*weights' shape, *design's shape)``."""
    cache: dict[tuple[float, float, float], np.ndarray] = {}
    rows = []
    for triple in zip(*(w.ravel().tolist() for w in weights)):
        if triple not in cache:
            cache[triple] = design(*triple)
        rows.append(cache[triple])
    return np.array(rows).reshape(*weights[0].shape, *rows[0].shape)


class ClippedOptimalController(ForceLaw):
    """Clipped-optimal LQR through an inverse model (see the module docstring).

    Its :attr:`gain` is ``K``: ``(4,)``, or ``(N, 4)`` for per-vehicle weights.

    Parameters
    ----------
    inverse_model : ``"bi_exponential"``, ``"csdc"`` or ``"tanh"``.
    q_stroke, q_levitation (1/s^4), r_force (1/kg^2) : the cost weights, scalars or one per
        vehicle; None: the tuned values, else 1e3, 1e3, 1e-9 [reconstructed].
    vehicle : the plant's parameters (default :class:`VehicleParams`).
    max_force_n : the env's force scale.
    observation : ``"full_state"`` (ideal sensors, default) or ``"measured"``.
    """

    SIGNALS = STATE_SIGNALS
    # Weights, scalar or one per vehicle, set by _set_gains: q_stroke and q_levitation
    # (1/s^4), r_force (1/kg^2).
    q_stroke: np.ndarray
    q_levitation: np.ndarray
    r_force: np.ndarray

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        q_stroke: float | np.ndarray | None = None,
        q_levitation: float | np.ndarray | None = None,
        r_force: float | np.ndarray | None = None,
        vehicle: VehicleParams | None = None,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
        observation: str = "full_state",
    ) -> None:
        super().__init__("lqr-clipped", inverse_model, max_force_n, observation)
        given = {"q_stroke": q_stroke, "q_levitation": q_levitation, "r_force": r_force}
        weights = set_weights(self, given, FALLBACK_WEIGHTS)
        vehicle = vehicle or VehicleParams()
        self.gain = design_per_vehicle(weights, lambda *triple: lqr_gain(vehicle, *triple))

    def gains(self) -> dict:
        out = super().gains()
        for k, name in enumerate(GAIN_NAMES):
            value = self.gain[..., k]
            out[name] = float(value) if value.ndim == 0 else value.tolist()
        return out

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        x = np.stack([self.signal(obs, s) for s in STATE_SIGNALS], axis=1)
        return -np.sum(x * self.gain, axis=1)
