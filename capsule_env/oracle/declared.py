"""The clairvoyant oracle on any declared vehicle: the applied current of every damper slot at
every control step, searched with the whole guideway known (the quarter-car's method,
:mod:`capsule_env.oracle`, over the declared plant :mod:`capsule_env.plant.declared`).

- The episodes are :class:`~capsule_env.envs.declared_vehicle.DeclaredVehicleEnv`'s (the same
  seeds give the same routes and start states), stepped by the same compiled plant.
- Gradients by the adjoint: every control step of a trajectory linearised at once by forward
  differences of single steps (``T (n_x + slots)`` of them in one kernel call), then one
  backward recursion gives ``dF/du_t`` for every step and slot.
- L-BFGS-B with bounds ``[0, i_max]`` from each start (zero current, 10 % of ``i_max``, and any
  sequence given: a controller's own, so the oracle is never worse than it); the search with
  each episode's finest substep count, every figure re-measured with the env's adaptive
  substeps.

The objective is the mean over the vehicle's comfort points of the ISO 2631-1 Wk-weighted RMS
acceleration (:func:`capsule_env.metrics.wk_weighted_rms`), plus the quarter-car oracle's
quadratic penalty on each slot's stroke beyond ``stroke_limit_m``. A local search: an upper
bound on the clairvoyant optimum, a lower bound on nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize

from capsule_env.engine.declared_batch import DeclaredBatch
from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv
from capsule_env.oracle.plant import FD_RELATIVE_STEP, RideObjective
from capsule_env.plant.declared import declared_step, declared_step_parallel
from capsule_env.plant.declared_build import DeclaredPlant
from capsule_env.plant.params import Route

__all__ = ["DeclaredEpisodes", "DeclaredOracleResult", "declared_oracle", "adjoint_gradient_multi"]

_SCALE_FLOOR = 1e-6
#: The stroke penalty's weight, as the quarter-car oracle's default.
STROKE_PENALTY = 100.0


def _tile_plant(plant: DeclaredPlant, rows: np.ndarray, search: bool) -> DeclaredPlant:
    """The plant arrays of vehicles ``rows`` (with repeats); ``search``: every bin at the
    vehicle's finest substep count (no switching under the finite differences)."""
    ns = plant.slot_rows.shape[1]
    damper = plant.damper.reshape(-1, ns, plant.damper.shape[1])[rows].reshape(
        -1, plant.damper.shape[1]
    )
    table = plant.substeps[rows]
    if search:
        table = np.repeat(table.max(axis=1, keepdims=True), table.shape[1], axis=1)
    return plant._replace(
        inv_inertia=np.ascontiguousarray(plant.inv_inertia[rows]),
        element_rows=np.ascontiguousarray(plant.element_rows[rows]),
        element_contacts=np.ascontiguousarray(plant.element_contacts[rows]),
        element_coef=np.ascontiguousarray(plant.element_coef[rows]),
        slot_rows=np.ascontiguousarray(plant.slot_rows[rows]),
        damper=np.ascontiguousarray(damper), substeps=np.ascontiguousarray(table),
        contact_offsets_m=np.ascontiguousarray(plant.contact_offsets_m[rows]),
    )  # fmt: skip


def _tile_route(route: Route, rows: np.ndarray) -> Route:
    return Route(*(np.ascontiguousarray(a[rows]) for a in route))


class DeclaredEpisodes:
    """The episodes of ``DeclaredVehicleEnv(**env_kwargs)`` for ``seeds``: their routes and
    start states, replayed open loop with given applied currents."""

    def __init__(self, env_kwargs: dict[str, Any], seeds: list[int]) -> None:
        env = DeclaredVehicleEnv(**{k: v for k, v in env_kwargs.items() if k != "action_mode"})
        self.env_kwargs = dict(env_kwargs)
        cfg = env.config
        batch = DeclaredBatch(cfg, env.vehicle_model, env.vehicle_parameters, len(seeds))
        batch.seed([int(s) for s in seeds])
        for n in range(len(seeds)):
            batch.reset(n)
        self.batch, self.seeds = batch, list(seeds)
        self.model, self.dt_s, self.i_max = env.vehicle_model, cfg.dt_s, batch.i_max
        self.n_steps, self.n_slots = cfg.max_episode_steps, batch.n_slots
        self.n_coords = batch.n_coords
        self.n_state = len(batch.state_names)
        self.columns = np.arange(self.n_state - 1)  # all but the time
        self.objective = RideObjective(self.n_steps, self.dt_s, cfg.stroke_limit_m, STROKE_PENALTY)

    def run(
        self, lanes: np.ndarray, currents: np.ndarray, search: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """Episodes ``lanes`` with applied currents (lanes, T, slots): ``(states (lanes, T+1,
        S), outputs (lanes, T, O))``."""
        lanes = np.asarray(lanes, dtype=np.int64)
        plant = _tile_plant(self.batch.plant, lanes, search)
        route = _tile_route(self.batch.route, lanes)
        x = np.ascontiguousarray(self.batch.state[lanes])
        out = np.zeros((len(lanes), self.batch.out.shape[1]))
        states, outs = [x.copy()], []
        for t in range(self.n_steps):
            cmd = np.ascontiguousarray(currents[:, t, :])
            declared_step(self.batch.damper.code, 0, len(lanes), plant, x, cmd, route, self.dt_s,
                          out)  # fmt: skip
            states.append(x.copy())
            outs.append(out.copy())
        return np.stack(states, axis=1), np.stack(outs, axis=1)

    def comfort_acc(self, outs: np.ndarray) -> np.ndarray:
        """Comfort points' accelerations (..., points, T) from outputs (..., T, O)."""
        ns, nc = self.n_slots, self.n_coords
        return np.moveaxis(outs[..., ns : ns + nc] @ self.batch.comfort_rows.T, -1, -2)

    def strokes(self, states: np.ndarray) -> np.ndarray:
        """Each slot's stroke (..., slots, T) after each step."""
        q = states[..., 1:, : self.n_coords]
        return np.moveaxis(q @ self.batch.stroke_rows.T, -1, -2)

    def value(self, states: np.ndarray, outs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(objective, Wk)`` per lane: the mean Wk over the comfort points, plus the stroke
        penalty."""
        wk = self.objective.wk(self.comfort_acc(outs)).mean(axis=-1)
        penalty = self.objective.penalty(self.strokes(states)).sum(axis=-1)
        return wk + penalty, wk

    def linearise(self, k: int, states: np.ndarray, outs: np.ndarray, currents: np.ndarray):
        """Forward differences of every step of one trajectory: ``(jac_x (T, n, n), jac_u
        (T, n, m), acc_x (T, n_c, n), acc_u (T, n_c, m))`` over the coordinates'
        accelerations ``n_c`` and the active columns ``n``."""
        cols, m, T = self.columns, self.n_slots, self.n_steps
        n = len(cols)
        copies = n + m
        x0 = states[:-1]
        deviation = x0[:, cols] - x0[:, cols].mean(axis=0)
        dx = FD_RELATIVE_STEP * np.maximum(np.sqrt(np.mean(deviation**2, axis=0)), _SCALE_FLOOR)
        x = np.repeat(x0[:, None, :], copies, axis=1)
        x[:, np.arange(n), cols] += dx
        cmd = np.repeat(currents[:, None, :], copies, axis=1)
        step = FD_RELATIVE_STEP * self.i_max
        du = np.empty((T, m))
        for s in range(m):
            u = currents[:, s]
            cmd[:, n + s, s] = np.where(u + step <= self.i_max, u + step, u - step)
            du[:, s] = cmd[:, n + s, s] - u
        rows = np.full(T * copies, k, dtype=np.int64)
        plant = _tile_plant(self.batch.plant, rows, search=True)
        route = _tile_route(self.batch.route, rows)
        x = np.ascontiguousarray(x.reshape(T * copies, -1))
        out = np.zeros((T * copies, outs.shape[1]))
        declared_step_parallel(self.batch.damper.code)(
            T * copies, plant, x, np.ascontiguousarray(cmd.reshape(T * copies, m)), route,
            self.dt_s, out)  # fmt: skip
        ns, nc = self.n_slots, self.n_coords
        d_next = x.reshape(T, copies, -1)[:, :, cols] - states[1:, None, cols]
        acc = out[:, ns : ns + nc].reshape(T, copies, nc) - outs[:, None, ns : ns + nc]
        return (d_next[:, :n, :] / dx[None, :, None],
                np.swapaxes(d_next[:, n:, :] / du[:, :, None], 1, 2),
                np.swapaxes(acc[:, :n, :] / dx[None, :, None], 1, 2),
                np.swapaxes(acc[:, n:, :] / du[:, :, None], 1, 2))  # fmt: skip

    def value_and_gradient(self, k: int, currents: np.ndarray) -> tuple[float, np.ndarray]:
        """The objective of episode ``k`` at currents (T, slots) and its gradient, by the
        adjoint (search substeps)."""
        states, outs = self.run(np.array([k]), currents[None], search=True)
        states, outs = states[0], outs[0]
        acc = self.comfort_acc(outs)  # (points, T)
        value, d_acc_coords, d_state = self._derivatives(states, acc)
        jac_x, jac_u, acc_x, acc_u = self.linearise(k, states, outs, currents)
        grad = adjoint_gradient_multi(jac_x, jac_u, acc_x, acc_u, d_acc_coords, d_state)
        return value, grad

    def _derivatives(self, states: np.ndarray, acc: np.ndarray):
        """``(F, dF/da over the coordinates (T, n_c), dF/dx_{t+1} (T, n))``."""
        obj, rows = self.objective, self.batch.comfort_rows
        d_acc = np.zeros((self.n_steps, self.n_coords))
        wk_sum = 0.0
        for p in range(acc.shape[0]):
            weighted = obj._weigh(acc[p])
            wk = float(np.sqrt(np.mean(weighted * weighted)))
            wk_sum += wk
            if wk > 0.0:
                d = obj._weigh(weighted) / (self.n_steps * wk) / acc.shape[0]
                d_acc += d[:, None] * rows[p][None, :]
        value = wk_sum / acc.shape[0]
        d_state = np.zeros((self.n_steps, len(self.columns)))
        stroke = self.strokes(states)  # (slots, T)
        limit = obj.max_stroke_m
        for s in range(stroke.shape[0]):
            excess = np.maximum(np.abs(stroke[s]) - limit, 0.0) / limit
            value += obj.stroke_penalty * float(np.mean(excess * excess))
            d = 2.0 * obj.stroke_penalty * excess * np.sign(stroke[s]) / (self.n_steps * limit)
            d_state[:, : self.n_coords] += d[:, None] * self.batch.stroke_rows[s][None, :]
        return value, d_acc, d_state


def adjoint_gradient_multi(jac_x, jac_u, acc_x, acc_u, d_acc, d_state) -> np.ndarray:
    """``dF/du_t`` (T, m) by the adjoint recursion: ``lambda_T = 0``; at each step ``lambda
    += d_state[t]``, ``grad_t = jac_u[t]^T lambda + acc_u[t]^T d_acc[t]``, ``lambda =
    jac_x[t] lambda + acc_x[t]^T d_acc[t]`` (``jac_x[t, j, i] = d x_{t+1}[i] / d x_t[j]``)."""
    n_steps, n = jac_x.shape[0], jac_x.shape[1]
    lam = np.zeros(n)
    grad = np.empty((n_steps, jac_u.shape[2]))
    for t in range(n_steps - 1, -1, -1):
        lam = lam + d_state[t]
        grad[t] = jac_u[t].T @ lam + acc_u[t].T @ d_acc[t]
        lam = jac_x[t] @ lam + acc_x[t].T @ d_acc[t]
    return grad


@dataclass
class DeclaredOracleResult:
    """Per episode: the best applied currents (E, T, slots) and their mean comfort-point Wk
    (m/s^2) re-measured with the adaptive substeps, every start's figure (E, starts), and the
    best sequence's largest stroke (m). A sequence that passes the bump stop
    (``stroke_limit_m``, where the env would end the episode) is chosen only when no
    candidate of that episode stays within it."""

    currents: np.ndarray
    wk_m_s2: np.ndarray
    start_wk_m_s2: np.ndarray
    max_stroke_m: np.ndarray


def declared_oracle(
    env_kwargs: dict[str, Any],
    seeds: list[int],
    starts: list[np.ndarray] | None = None,
    max_iterations: int = 50,
) -> DeclaredOracleResult:
    """The oracle on episodes ``seeds`` of ``DeclaredVehicleEnv(**env_kwargs)``; ``starts``:
    extra start sequences, one (E, T, slots) array each (e.g. a controller's applied
    currents), besides zero and 10 % of ``i_max``."""
    ep = DeclaredEpisodes(env_kwargs, seeds)
    shape = (len(seeds), ep.n_steps, ep.n_slots)
    candidates = [np.zeros(shape), np.full(shape, 0.1 * ep.i_max), *(starts or [])]
    if int(max_iterations) < 0:
        raise ValueError(f"max_iterations must be >= 0, got {max_iterations!r}")
    best = np.zeros(shape)
    best_wk, best_stroke = np.full(len(seeds), np.inf), np.full(len(seeds), np.inf)
    start_wk = np.zeros((len(seeds), len(candidates)))
    lanes = np.arange(len(seeds))
    limit = ep.objective.max_stroke_m
    for j, start in enumerate(candidates):
        if np.shape(start) != shape:
            raise ValueError(f"starts[{j}] must have shape {shape}, got {np.shape(start)}")
        start = np.clip(np.asarray(start, dtype=float), 0.0, ep.i_max)
        found = np.array([_search(ep, k, start[k], max_iterations) for k in lanes])
        for cand, is_start in ((start, True), (found, False)):  # the start counts too
            states, outs = ep.run(lanes, cand)
            _, wk = ep.value(states, outs)
            stroke = np.abs(ep.strokes(states)).max(axis=(1, 2))
            # within the bump stop first, then the lowest Wk
            better = (stroke <= limit) & ((best_stroke > limit) | (wk < best_wk))
            better |= (stroke > limit) & (best_stroke > limit) & (wk < best_wk)
            best[better], best_wk[better], best_stroke[better] = (
                cand[better],
                wk[better],
                stroke[better],
            )
            if is_start:
                start_wk[:, j] = wk
    return DeclaredOracleResult(best, best_wk, start_wk, best_stroke)


def _search(ep: DeclaredEpisodes, k: int, start: np.ndarray, max_iterations: int) -> np.ndarray:
    shape = start.shape

    def fun(u: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad = ep.value_and_gradient(k, u.reshape(shape))
        return value, grad.reshape(-1)

    res = minimize(fun, start.reshape(-1), jac=True, method="L-BFGS-B",
                   bounds=[(0.0, ep.i_max)] * start.size,
                   options={"maxiter": max_iterations})  # fmt: skip
    return res.x.reshape(shape)
