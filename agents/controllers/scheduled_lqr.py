"""Gain-scheduled clipped-optimal control: the clipped LQR of :mod:`capsule_env.agents.controllers.lqr`
with its gain designed at a grid of speeds and interpolated at the vehicle's current speed.

Why: with ``levitation="eds"`` the plant's levitation stiffness ``k_p(v)`` and damping
``c_p(v)`` follow the speed (:mod:`capsule_env.envelope.levitation`: ``k_p`` rises from about a tenth
of its 810 km/h value at lift-off; ``c_p`` is positive below the coil's characteristic speed
and slightly negative above). A fixed-gain LQR is optimal at the one speed it was designed for
(810 km/h); on a trip (``speed_profile="trip"``, :mod:`capsule_env.envelope.trips`) the plant moves
away from it. The classical answer is gain scheduling (Rugh & Shamma, "Research on gain
scheduling", Automatica 36(10), 2000): design at frozen operating points, interpolate.

**Design.** At each speed ``v_j`` of the grid (the lift-off speed of the EDS model, 150 km/h
by default, to ``top_speed_kmh`` = 1200 km/h in steps of ``grid_step_kmh`` = 25 km/h: 43
points) the plant is the fixed law's 2-DOF model with ``k_p = k_p(v_j)`` and a levitation
damper ``c_p = c_p(v_j)`` (:func:`capsule_env.agents.controllers.lqr.lqr_gain`); ``K_j`` is its LQR gain
for the same cost as the fixed law (``a_c^2 + q_stroke x^2 + q_levitation gap^2 + r_force
F^2``; the weights are the law's, shared by every speed). With ``levitation="fixed"`` every
``K_j`` is the fixed law's gain.

**Interpolation.** ``K(v) = K_j + (v - v_j) / (v_{j+1} - v_j) (K_{j+1} - K_j)`` for ``v_j <= v
<= v_{j+1}``: piecewise linear in the speed, each gain component apart; outside the grid the
nearest end's gain is held (the env refuses speeds below lift-off with ``levitation="eds"``).

**Signals.** The fixed LQR's four, ``x = [z_c - z_b, z_c', z_b - z_g, z_b']`` (on
``measured``, suffix ``-meas``: the LVDT stroke, the on-board body velocity estimate, the gap
sensor and the bogie velocity estimate; on ``full_state`` the true states), plus the speed,
the observation column ``speed_m_s`` that the env adds after each set's own columns when
``speed_profile="trip"`` (the capsule knows its speed). The law asks for that option in its
:attr:`env_kwargs`; on an observation without the column it raises ``ValueError`` naming it.

**Weights.** ``q_stroke``, ``q_levitation`` (1/s^4) and ``r_force`` (1/kg^2): None takes the
law's own tuned values (``agents/controllers/tuned_gains.json``: searched on the trip task's training
bank), else the fixed clipped LQR's tuned weights (searched at 810 km/h), else 1e3, 1e3, 1e-9.
Force mode: the env's inverse model clips the request to the dissipative band.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from capsule_env.agents.controllers.law import law_name
from capsule_env.agents.controllers.lqr import (
    FALLBACK_WEIGHTS,
    STATE_SIGNALS,
    WEIGHT_UNITS,
    design_per_vehicle,
    lqr_gain,
    set_weights,
)
from capsule_env.agents.controllers.skyhook import DEFAULT_MAX_FORCE_N, ForceLaw
from capsule_env.agents.controllers.tuned import tuned_gains

from capsule_env.common.units import kmh_to_m_s
from capsule_env.common.validation import check_choice, check_in_range
from capsule_env.engine.config import OBSERVATION_NAMES
from capsule_env.engine.observations import TRIP_COLUMN_NAMES
from capsule_env.envelope.levitation import (
    EdsParams,
    check_levitating,
    eds_coil,
    levitation_damping_n_s_per_m,
    levitation_stiffness_n_per_m,
)
from capsule_env.envelope.options import LEVITATION_MODELS
from capsule_env.vehicles import VehicleParams

__all__ = [
    "SPEED_COLUMN",
    "LEVITATION_MODELS",
    "ScheduledLQRController",
    "design_speeds_m_s",
    "gain_schedule",
    "interpolate_gains",
    "levitation_schedule",
]

#: The observation column the law reads the speed from (m/s): the first a trip adds.
SPEED_COLUMN = TRIP_COLUMN_NAMES[0]
#: Defaults of the speed grid: its top (km/h) and its step (km/h).
TOP_SPEED_KMH = 1200.0
GRID_STEP_KMH = 25.0


def design_speeds_m_s(low_kmh: float, high_kmh: float, step_kmh: float) -> np.ndarray:
    """The grid: ``low_kmh`` to ``high_kmh`` in equal steps of at most ``step_kmh`` (m/s)."""
    check_in_range("grid_step_kmh", step_kmh, 1e-3, 1e4)
    if not high_kmh > low_kmh:
        raise ValueError(f"top_speed_kmh must exceed the lift-off speed {low_kmh:g} km/h, "
                         f"got {high_kmh:g}")  # fmt: skip
    points = math.ceil((high_kmh - low_kmh) / step_kmh - 1e-9) + 1
    return kmh_to_m_s(np.linspace(low_kmh, high_kmh, points))


def levitation_schedule(
    speeds_m_s: np.ndarray, vehicle: VehicleParams, levitation: str, eds: EdsParams
) -> tuple[np.ndarray, np.ndarray]:
    """``(k_p (N/m), c_p (N s/m))`` at each speed: the EDS coil model calibrated to
    ``vehicle`` (:mod:`capsule_env.envelope.levitation`, the env's formula), or with ``"fixed"`` the
    vehicle's stiffness and damping at every speed (the paper's levitation: no damping)."""
    check_choice("levitation", levitation, LEVITATION_MODELS)
    speeds = np.asarray(speeds_m_s, dtype=float)
    if levitation == "fixed":
        stiffness = np.full(speeds.shape, vehicle.levitation_stiffness_n_per_m)
        return stiffness, np.full(speeds.shape, vehicle.levitation_damping_n_s_per_m)
    coil = eds_coil(vehicle, eds)
    check_levitating("the design speeds", speeds, coil)
    stiffness = levitation_stiffness_n_per_m(speeds, coil)
    return stiffness, levitation_damping_n_s_per_m(speeds, coil)


def gain_schedule(
    vehicle: VehicleParams,
    stiffness_n_per_m: np.ndarray,
    damping_n_s_per_m: np.ndarray,
    weights: tuple[float, float, float],
) -> np.ndarray:
    """The LQR gain ``(G, 4)`` at each grid point's ``k_p``, ``c_p``; ``weights`` is
    ``(q_stroke, q_levitation, r_force)``."""
    rows = [lqr_gain(vehicle, *weights, float(k), float(c))
            for k, c in zip(stiffness_n_per_m, damping_n_s_per_m)]  # fmt: skip
    return np.array(rows)


def interpolate_gains(
    speeds_m_s: np.ndarray, table: np.ndarray, speed_m_s: np.ndarray
) -> np.ndarray:
    """The gain ``(N, 4)`` at each vehicle's ``speed_m_s`` (N,), linear in the speed between
    the grid points ``speeds_m_s`` (G,), held at the ends. ``table``: ``(G, 4)``, or ``(N, G,
    4)`` (one schedule per vehicle)."""
    speed = np.asarray(speed_m_s, dtype=float)
    last = len(speeds_m_s) - 2
    j = np.clip(np.searchsorted(speeds_m_s, speed, side="right") - 1, 0, last)
    lo, hi = speeds_m_s[j], speeds_m_s[j + 1]
    frac = np.clip((speed - lo) / (hi - lo), 0.0, 1.0)[:, None]
    if table.ndim == 2:
        below, above = table[j], table[j + 1]
    else:
        rows = np.arange(table.shape[0])
        below, above = table[rows, j], table[rows, j + 1]
    return below + frac * (above - below)


def _default_weights(observation: str) -> dict[str, float]:
    """The fixed clipped LQR's tuned weights on the same observation set (constructor
    names), else the fixed law's fallback."""
    fixed = tuned_gains(law_name("lqr-clipped-biexp", observation)) or {}
    return {g: float(fixed.get(f"{g}_{u}", FALLBACK_WEIGHTS[g])) for g, u in WEIGHT_UNITS.items()}


class ScheduledLQRController(ForceLaw):
    """Gain-scheduled clipped LQR through an inverse model (see the module docstring).

    Its :attr:`speeds_m_s` (G,) is the design grid and :attr:`gain_table` the gain at each
    grid point: ``(G, 4)``, or ``(N, G, 4)`` for per-vehicle weights.

    Parameters
    ----------
    inverse_model : ``"bi_exponential"``, ``"csdc"`` or ``"tanh"``.
    levitation : the model the schedule is designed on, ``"eds"`` (default) or ``"fixed"``;
        also the env option the law asks for.
    levitation_params : :class:`capsule_env.envelope.levitation.EdsParams` fields (the env's option of
        the same name); None: the defaults.
    q_stroke, q_levitation (1/s^4), r_force (1/kg^2) : the cost weights, scalars or one per
        vehicle; None: the tuned values (see the module docstring).
    vehicle : the plant's nominal parameters (default :class:`VehicleParams`).
    top_speed_kmh : the grid's top (km/h), default 1200; its bottom is the lift-off speed.
    grid_step_kmh : the grid's largest step (km/h), default 25.
    max_force_n : the env's force scale.
    observation : ``"full_state"`` (ideal sensors, default) or ``"measured"``.
    """

    SIGNALS = STATE_SIGNALS
    q_stroke: np.ndarray  # the weights, one per vehicle or shared, set by set_weights
    q_levitation: np.ndarray
    r_force: np.ndarray

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        levitation: str = "eds",
        levitation_params: dict[str, Any] | None = None,
        q_stroke: float | np.ndarray | None = None,
        q_levitation: float | np.ndarray | None = None,
        r_force: float | np.ndarray | None = None,
        vehicle: VehicleParams | None = None,
        top_speed_kmh: float = TOP_SPEED_KMH,
        grid_step_kmh: float = GRID_STEP_KMH,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
        observation: str = "full_state",
    ) -> None:
        super().__init__("lqr-sched", inverse_model, max_force_n, observation)
        check_choice("levitation", levitation, LEVITATION_MODELS)
        given = {"q_stroke": q_stroke, "q_levitation": q_levitation, "r_force": r_force}
        weights = set_weights(self, given, _default_weights(observation))
        vehicle = vehicle or VehicleParams()
        eds = EdsParams(**(levitation_params or {}))
        self.speeds_m_s = design_speeds_m_s(eds.lift_off_speed_kmh, top_speed_kmh, grid_step_kmh)
        stiffness, damping = levitation_schedule(self.speeds_m_s, vehicle, levitation, eds)
        self.gain_table = design_per_vehicle(
            weights, lambda *triple: gain_schedule(vehicle, stiffness, damping, triple)
        )
        self.env_kwargs = {**self.env_kwargs, "speed_profile": "trip", "levitation": levitation}
        if levitation_params:
            self.env_kwargs["levitation_params"] = dict(levitation_params)
        self._speed_column = len(OBSERVATION_NAMES[observation])

    @property
    def signals_read(self) -> tuple[str, ...]:
        """The fixed LQR's four signals' columns and the speed column."""
        return (*super().signals_read, SPEED_COLUMN)

    def speed(self, obs: np.ndarray) -> np.ndarray:
        """Each vehicle's speed (m/s), from the observation column ``speed_m_s``."""
        if obs.shape[1] <= self._speed_column:
            raise ValueError(
                f"{self.name} reads the observation column {SPEED_COLUMN!r}, which this env "
                f"does not give (observations of {obs.shape[1]} columns): make the env with "
                "speed_profile='trip' (the law's env_kwargs)"
            )
        return obs[:, self._speed_column]

    def gain_at(self, speed_m_s: np.ndarray) -> np.ndarray:
        """The interpolated gain ``(N, 4)`` at each vehicle's speed (m/s)."""
        return interpolate_gains(self.speeds_m_s, self.gain_table, np.atleast_1d(speed_m_s))

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        x = np.stack([self.signal(obs, s) for s in STATE_SIGNALS], axis=1)
        return -np.sum(x * self.gain_at(self.speed(obs)), axis=1)
