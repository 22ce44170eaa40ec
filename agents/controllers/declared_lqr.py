"""Clipped-optimal LQR for any declared vehicle: one force per damper slot.

The gain is :func:`capsule_env.agents.controllers.lqr.lqr_gain` on the vehicle's relative form
(:func:`capsule_env.vehicles.relative_model`): ``F = -K x`` with ``x`` each
``relative_positions`` spring's deflection and each coordinate's rate, minimising the comfort
points' accelerations plus ``q_stroke`` on each slot's stroke, ``q_levitation`` on each spring
to the guideway and ``r_force`` on each force. The env's inverse model produces each request as
far as the damper can (the clipping).

Signals read: the ``full_state`` observation of
:class:`capsule_env.envs.declared_vehicle.DeclaredVehicleEnv` (every coordinate and rate, each
contact's guideway elevation): ideal sensors, as the quarter-car's ``lqr-clipped-*``. A vehicle
of the quarter-car's form is refused (``gym.make`` runs it on the compiled env, whose
observations are laid out otherwise): its law is the quarter-car's ``lqr-clipped-*``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.controllers.lqr import FALLBACK_WEIGHTS, lqr_gain

from capsule_env.vehicles import model_named
from capsule_env.vehicles.compiled import runs_compiled
from capsule_env.vehicles.declaration import SPRING

__all__ = ["DeclaredClippedLQR", "IndependentClippedLQR"]


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
        observation: str = "full_state",
    ) -> None:
        if observation not in ("full_state", "measured"):
            raise ValueError(f"observation must be 'full_state' or 'measured', got {observation!r}")
        self.model = model = model_named(vehicle)
        self.params = model.params(**(vehicle_params or {}))
        if runs_compiled(model, self.params):  # gym.make gives it the compiled env's layout
            raise ValueError(f"vehicle {vehicle!r} has the quarter-car's form: gym.make runs it "
                             "on the compiled env, whose observations this law does not read; "
                             "use the quarter-car's clipped LQR (make_controller("
                             "'lqr-clipped-biexp' or 'lqr-clipped-biexp-meas'))")  # fmt: skip
        if not (q_stroke >= 0 and q_levitation >= 0 and r_force > 0):
            raise ValueError("q_stroke and q_levitation must be >= 0 and r_force > 0")
        if not max_force_n > 0:
            raise ValueError(f"max_force_n must be > 0 N, got {max_force_n!r}")
        self.name = f"lqr-coupled-{vehicle}" + ("-meas" if observation == "measured" else "")
        self.max_force_n = float(max_force_n)
        self.gain = np.atleast_2d(lqr_gain(self.params, q_stroke, q_levitation, r_force))
        self.env_kwargs = {"vehicle": vehicle, "vehicle_params": dict(vehicle_params or {}),
                           "action_mode": "force", "observation": observation,
                           "inverse_model": inverse_model, "max_force_n": self.max_force_n}  # fmt: skip
        self._deflection_rows()
        if observation == "measured":
            self._measured_rows()

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

    def _measured_rows(self) -> None:
        """On ``measured``: each ``relative_positions`` spring's deflection is a slot's stroke
        (a spring beside the slot) or a slot's gap (the spring from its lower end to the
        guideway); the coordinates' rates solve ``E v = estimates`` over the slots' ends."""
        model, values = self.model, self.model.values(self.params)
        n_slots, per = len(model.dampers), 8  # measured columns per slot (declared_batch)
        strokes = [model.element_rows(d, values) for d in model.dampers]
        contacts = {c.name for c in model.contacts}
        gaps = []
        for d in model.dampers:
            lev = [e for e in model.elements if e.kind == SPRING and e.upper == d.lower
                   and e.lower in contacts]  # fmt: skip
            gaps.append(model.element_rows(lev[0], values) if lev else None)
        self._d_cols = []
        for j, g in zip(self._d_q, self._d_g, strict=True):
            col = _matching(j, g, strokes, 0, per) if not g.any() else _matching(j, g, gaps, 4, per)
            if col is None:
                raise ValueError(f"vehicle {model.name!r}: a relative_positions deflection is "
                                 "neither a slot's stroke nor its gap: not measured")  # fmt: skip
            self._d_cols.append(col)
        ends = np.array([model.point_row(p, values) for d in model.dampers
                         for p in (d.upper, d.lower)])  # fmt: skip
        if np.linalg.matrix_rank(ends) < len(model.coordinates):
            raise ValueError(f"vehicle {model.name!r}: the slots' ends do not determine every "
                             "coordinate's rate: no measured clipped LQR")  # fmt: skip
        self._rates_from_ends = np.linalg.pinv(ends)
        self._est_cols = np.array([s * per + c for s in range(n_slots) for c in (5, 6)])

    def gains(self) -> dict[str, Any]:
        return {"gain": self.gain.tolist()}

    def relative_state(self, obs: np.ndarray) -> np.ndarray:
        """The relative state ``(N, 2 n)`` from observations ``(N, d)``."""
        if self.env_kwargs["observation"] == "measured":
            d = obs[:, self._d_cols]
            v = obs[:, self._est_cols] @ self._rates_from_ends.T
        else:
            q, v, zg = obs[:, self._q_cols], obs[:, self._v_cols], obs[:, self._zg_cols]
            d = q @ self._d_q.T - zg @ self._d_g.T
        x = np.empty((obs.shape[0], 2 * d.shape[1]))
        x[:, 0::2], x[:, 1::2] = d, v
        return x

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        """``-K x`` per slot (N), ``(N, slots)``."""
        return -self.relative_state(np.atleast_2d(obs)) @ self.gain.T

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.clip(self.desired_force(obs) / self.max_force_n, -1.0, 1.0)


def _matching(j: np.ndarray, g: np.ndarray, rows: list, channel: int, per: int) -> int | None:
    """The measured column of the slot whose rows equal ``(j, g)`` (``channel`` of it)."""
    for s, pair in enumerate(rows):
        if pair is not None and np.array_equal(pair[0], j) and np.array_equal(pair[1], g):
            return s * per + channel
    return None


class IndependentClippedLQR(Controller):
    """One quarter-car clipped LQR per damper slot, each on its own slot's measured signals:
    ``F_s = -K x_s``, ``x_s = [stroke, upper velocity estimate, gap, lower velocity estimate]``,
    ``K`` the tuned ``lqr-clipped-biexp-meas`` of the 1/4-car (tuned on its training bank, for
    the 1/4-car whose values are the half-car's corners). It ignores the coupling through the
    body's pitch: the baseline a coupled law is measured against."""

    #: The measured columns per slot, and the offsets within them of ``x_s``'s entries: the
    #: stroke, the upper velocity estimate, the gap, the lower velocity estimate.
    slot_columns, state_offsets = 8, (0, 5, 4, 6)

    def __init__(self, vehicle: str = "half_car", max_force_n: float = 8000.0) -> None:
        from capsule_env.agents.controllers.classical import make_controller
        from capsule_env.agents.controllers.mpc_solver import check_real

        quarter: Any = make_controller("lqr-clipped-biexp-meas")
        self.gain = np.asarray(quarter.gain, dtype=float)
        self.model = model_named(vehicle)
        self.name = "lqr-clipped-biexp-meas"
        self.max_force_n = check_real("max_force_n", max_force_n, 0.0, 1e6, open_low=True,
                                      unit=" N")  # fmt: skip
        #: The constructor's arguments as plain JSON values (the export's contract carries them).
        self.arguments: dict[str, Any] = {"vehicle": vehicle, "max_force_n": self.max_force_n}
        self.env_kwargs = {"vehicle": vehicle, "action_mode": "force", "observation": "measured",
                           "inverse_model": "bi_exponential", "max_force_n": self.max_force_n}  # fmt: skip

    def gains(self) -> dict[str, Any]:
        return {"gain_per_slot": self.gain.tolist()}

    def act(self, obs: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(obs).reshape(np.atleast_2d(obs).shape[0], -1, self.slot_columns)
        state = x[..., list(self.state_offsets)]
        return np.clip(-(state @ self.gain) / self.max_force_n, -1.0, 1.0)
