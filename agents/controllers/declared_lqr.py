"""Clipped-optimal LQR for any declared vehicle: one force per damper slot.

The gain is :func:`capsule_env.agents.controllers.lqr.lqr_gain` on the vehicle's relative form
(:func:`capsule_env.vehicles.relative_model`): ``F = -K x`` with ``x`` each
``relative_positions`` spring's deflection and each coordinate's rate, minimising the comfort
points' accelerations plus ``q_stroke`` on each slot's stroke, ``q_levitation`` on each spring
to the guideway and ``r_force`` on each force. The env's inverse model produces each request as
far as the damper can (the clipping).

Signals read: the ``full_state`` observation of
:class:`capsule_env.envs.declared_vehicle.DeclaredVehicleEnv` (every coordinate and rate, each
contact's guideway elevation): ideal sensors, as the quarter-car's ``lqr-clipped-*``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.controllers.lqr import FALLBACK_WEIGHTS, lqr_gain

from capsule_env.vehicles import model_named
from capsule_env.vehicles.declaration import SPRING

__all__ = ["DeclaredClippedLQR"]


class DeclaredClippedLQR(Controller):
    """Clipped LQR of vehicle ``vehicle`` (a registered name) with ``vehicle_params`` (a dict of
    overrides), weights ``q_stroke``, ``q_levitation`` (1/s^4), ``r_force`` (1/kg^2; default
    the quarter-car's fallback weights [reconstructed]), through ``inverse_model``, forces
    scaled by ``max_force_n`` (the env's)."""

    def __init__(
        self,
        vehicle: str,
        vehicle_params: dict[str, float] | None = None,
        q_stroke: float = FALLBACK_WEIGHTS["q_stroke"],
        q_levitation: float = FALLBACK_WEIGHTS["q_levitation"],
        r_force: float = FALLBACK_WEIGHTS["r_force"],
        inverse_model: str = "bi_exponential",
        max_force_n: float = 8000.0,
    ) -> None:
        self.model = model = model_named(vehicle)
        self.params = model.params(**(vehicle_params or {}))
        if not (q_stroke >= 0 and q_levitation >= 0 and r_force > 0):
            raise ValueError("q_stroke and q_levitation must be >= 0 and r_force > 0")
        if not max_force_n > 0:
            raise ValueError(f"max_force_n must be > 0 N, got {max_force_n!r}")
        self.name = f"lqr-clipped-{vehicle}"
        self.max_force_n = float(max_force_n)
        self.gain = np.atleast_2d(lqr_gain(self.params, q_stroke, q_levitation, r_force))
        self.env_kwargs = {"vehicle": vehicle, "vehicle_params": dict(vehicle_params or {}),
                           "action_mode": "force", "observation": "full_state",
                           "inverse_model": inverse_model, "max_force_n": self.max_force_n}  # fmt: skip
        self._deflection_rows()

    def _deflection_rows(self) -> None:
        """``x = T [q, zg] + [v]``: the rows mapping the observation's coordinates and contact
        elevations to the relative state (deflections ``J q - g z_g``)."""
        model, values = self.model, self.model.values(self.params)
        springs = {e.name: e for e in model.elements if e.kind == SPRING}
        rows = [model.element_rows(springs[s], values) for s in model.relative_positions]
        self._d_q = np.array([j for j, _ in rows])
        self._d_g = np.array([g for _, g in rows])
        n, n_slots = len(model.coordinates), len(model.dampers)
        self._q_cols = np.arange(0, 2 * n, 2)
        self._v_cols = np.arange(1, 2 * n, 2)
        first_zg = 2 * n + 2 * n_slots + len(model.comfort_points)
        self._zg_cols = first_zg + np.arange(len(model.contacts))

    def gains(self) -> dict[str, Any]:
        return {"gain": self.gain.tolist()}

    def relative_state(self, obs: np.ndarray) -> np.ndarray:
        """The relative state ``(N, 2 n)`` from ``full_state`` observations ``(N, d)``."""
        q, v, zg = obs[:, self._q_cols], obs[:, self._v_cols], obs[:, self._zg_cols]
        d = q @ self._d_q.T - zg @ self._d_g.T
        x = np.empty((obs.shape[0], 2 * q.shape[1]))
        x[:, 0::2], x[:, 1::2] = d, v
        return x

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        """``-K x`` per slot (N), ``(N, slots)``."""
        return -self.relative_state(np.atleast_2d(obs)) @ self.gain.T

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.clip(self.desired_force(obs) / self.max_force_n, -1.0, 1.0)
