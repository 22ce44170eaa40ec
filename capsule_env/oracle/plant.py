"""The oracle's plant: evaluation episodes replayed open loop, linearised step by step, and the
adjoint gradient of the ride objective with respect to the applied coil current.

:class:`OracleEpisodes` holds what each episode of the env is made of (vehicle, damper, route
over the guideway bank, start state, substep tables), exactly as ``CapsuleBatch`` draws it at
the reset, and steps it with the env's own compiled plant kernel (``capsule_env.engine.kernels``):

- :meth:`OracleEpisodes.run` replays applied-current sequences open loop, many trajectories in
  one kernel call per control step;
- :meth:`OracleEpisodes.linearise` differentiates every control step of one trajectory at once:
  the step map ``x_{t+1} = f(x_t, u_t)`` and the body acceleration ``a_t = g(x_t, u_t)`` by
  forward differences of *one* step each, all ``T (n_x + 1)`` single steps (one per
  perturbed state column, one for the current) in one batched kernel call;
- :func:`adjoint_gradient` runs the backward recursion ``lambda_t = A_t^T lambda_{t+1} +
  dF/da_t dg/dx_t`` and returns ``dF/du_t`` for every ``t`` in ``O(T n_x^2)``.

:class:`RideObjective` is the Wk-weighted RMS body acceleration (exactly
:func:`capsule_env.metrics.wk_weighted_rms`) plus an optional stroke penalty, with its
derivatives with respect to the accelerations and the states.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from capsule_env import metrics
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.kernels import PLANT, BatchedKernel
from capsule_env.engine.layout import (
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    COIL_TAU,
    DAMPER_Y,
    HYST_Z,
    N_PLANT_OUTPUTS,
    OUT_BODY_ACC,
    STATE_SIZE,
)
from capsule_env.plant import PlantParams, Route, make_plant_params
from capsule_env.plant.block import HALF

__all__ = [
    "FD_RELATIVE_STEP",
    "Linearisation",
    "OracleEpisodes",
    "RideObjective",
    "TripSchedule",
    "active_state_columns",
    "adjoint_gradient",
    "trip_schedule",
]

#: Forward-difference step of each state column, relative to that column's RMS deviation over
#: the trajectory (and of the current, relative to ``i_max``). Checked against central
#: differences of the whole objective (``tests/test_oracle.py``): 1e-6 keeps the truncation
#: error and the rounding error both near 1e-6 of the gradient.
FD_RELATIVE_STEP = 1e-6
#: Smallest scale of a state column (its unit: m, m/s or A) for the perturbation step, so that
#: a column that stays still (e.g. the start of an episode) is still perturbed.
_SCALE_FLOOR = 1e-6


def active_state_columns(damper_code: int, damper_params: np.ndarray) -> tuple[int, ...]:
    """The state columns the next step depends on (``layout.STATE_NAMES`` indices): the four
    mechanical ones; the hysteretic variable of the Spencer and Bouc-Wen models; Spencer's
    internal displacement; the coil current when the coil lags (without lag the current is the
    applied one, an input). Time is never one: it advances by ``dt`` whatever the state."""
    model = model_of_code(damper_code)
    cols = [BODY_DISP, BODY_VEL, BOGIE_DISP, BOGIE_VEL]
    if model.hysteresis is not None:
        cols.append(HYST_Z)
    if model.internal_displacement:
        cols.append(DAMPER_Y)
    if model.uses_current and float(np.asarray(damper_params)[COIL_TAU]) > 0.0:
        cols.append(COIL_CURRENT)
    return tuple(cols)


class Linearisation(NamedTuple):
    """One trajectory's step maps, linearised at every step ``t`` over the active state
    columns (``n`` of them, :func:`active_state_columns`).

    jac_x : (T, n, n), ``jac_x[t, j, i] = d x_{t+1}[i] / d x_t[j]``.
    jac_u : (T, n), ``d x_{t+1}[i] / d u_t``.
    acc_x : (T, n), ``d a_t / d x_t[j]`` (``a_t`` the body acceleration after step ``t``).
    acc_u : (T,), ``d a_t / d u_t``.
    """

    jac_x: np.ndarray
    jac_u: np.ndarray
    acc_x: np.ndarray
    acc_u: np.ndarray


@njit(cache=True)
def adjoint_gradient(jac_x, jac_u, acc_x, acc_u, d_acc, d_state):  # pragma: no cover - numba
    """``dF/du_t`` for every step ``t`` of a trajectory (a (T,) array), by the adjoint
    recursion over its :class:`Linearisation`: ``F`` depends on the body accelerations ``a_t``
    (``d_acc[t] = dF/da_t``) and on the states after each step (``d_state[t, i] =
    dF/dx_{t+1}[i]``, active columns). With ``lambda_{T} = d_state[T-1]``:

    ``dF/du_t = jac_u[t] . lambda_{t+1} + d_acc[t] acc_u[t]``,
    ``lambda_t = jac_x[t] lambda_{t+1} + d_acc[t] acc_x[t] + d_state[t-1]``.
    """
    n_steps, n = acc_x.shape
    lam = np.zeros(n)
    new = np.empty(n)
    grad = np.empty(n_steps)
    for t in range(n_steps - 1, -1, -1):
        for i in range(n):
            lam[i] += d_state[t, i]
        s = d_acc[t] * acc_u[t]
        for i in range(n):
            s += jac_u[t, i] * lam[i]
        grad[t] = s
        for j in range(n):
            v = d_acc[t] * acc_x[t, j]
            for i in range(n):
                v += jac_x[t, j, i] * lam[i]
            new[j] = v
        for j in range(n):
            lam[j] = new[j]
    return grad


class RideObjective:
    """``F = Wk + stroke_penalty * mean_t(max(0, |s_t| - L) / L)^2``: the ISO 2631-1
    Wk-weighted RMS body acceleration (:func:`capsule_env.metrics.wk_weighted_rms`, m/s^2) of
    the ``T`` accelerations after each step, plus a quadratic penalty on the stroke ``s_t``
    beyond ``L = max_stroke_m`` (none when ``max_stroke_m`` is infinite or the penalty 0)."""

    def __init__(
        self, n_steps: int, dt_s: float, max_stroke_m: float, stroke_penalty: float
    ) -> None:
        self.n_steps = int(n_steps)
        self.dt_s = float(dt_s)
        self.weights = np.abs(metrics.wk_weighting(np.fft.rfftfreq(self.n_steps, self.dt_s)))
        self.max_stroke_m = float(max_stroke_m)
        self.stroke_penalty = float(stroke_penalty)

    def _weigh(self, x: np.ndarray) -> np.ndarray:
        """The zero-phase Wk filter (mean removed, per FFT line): a symmetric linear map."""
        spectrum = np.fft.rfft(x - x.mean(axis=-1, keepdims=True), axis=-1)
        return np.fft.irfft(spectrum * self.weights, n=self.n_steps, axis=-1)

    def wk(self, acc: np.ndarray) -> np.ndarray:
        """Wk-weighted RMS of accelerations (..., T), as ``metrics.wk_weighted_rms``."""
        return metrics.wk_weighted_rms(acc, self.dt_s)

    def penalty(self, stroke: np.ndarray) -> np.ndarray:
        """The stroke penalty of strokes (..., T)."""
        if self.stroke_penalty == 0.0 or not math.isfinite(self.max_stroke_m):
            return np.zeros(np.shape(stroke)[:-1])
        excess = np.maximum(np.abs(stroke) - self.max_stroke_m, 0.0) / self.max_stroke_m
        return self.stroke_penalty * np.mean(excess * excess, axis=-1)

    def value_and_derivatives(
        self, acc: np.ndarray, states: np.ndarray, columns: Sequence[int]
    ) -> tuple[float, float, np.ndarray, np.ndarray]:
        """For one trajectory (accelerations (T,), states (T + 1, STATE_SIZE)): ``(F, Wk,
        dF/da (T,), dF/dx_{t+1} (T, len(columns)))`` over the state ``columns``.

        ``dWk/da = W(W a) / (T Wk)`` with ``W`` the weighting map: ``Wk^2 = |W a|^2 / T`` and
        ``W`` is symmetric (a real, even circular convolution; the mean removal a symmetric
        projection that ``W`` already implies, ``|Wk(0)| = 0``)."""
        weighted = self._weigh(acc)
        wk = math.sqrt(float(np.mean(weighted * weighted)))
        d_acc = self._weigh(weighted) / (self.n_steps * wk) if wk > 0.0 else np.zeros_like(acc)
        d_state = np.zeros((self.n_steps, len(columns)))
        stroke = states[1:, BODY_DISP] - states[1:, BOGIE_DISP]
        value = wk + float(self.penalty(stroke))
        if value > wk:
            excess = np.maximum(np.abs(stroke) - self.max_stroke_m, 0.0) / self.max_stroke_m
            d_stroke = (
                2.0 * self.stroke_penalty * excess * np.sign(stroke)
                / (self.n_steps * self.max_stroke_m)
            )  # fmt: skip
            d_state[:, list(columns).index(BODY_DISP)] = d_stroke
            d_state[:, list(columns).index(BOGIE_DISP)] = -d_stroke
        return value, wk, d_acc, d_state


class TripSchedule(NamedTuple):
    """What a trip changes at every control step ``t`` of each episode ``k``, as the env
    kernel's ``envelope_interval`` sets it before the plant's step: the route over the
    interval (``start_m[t, k] + speed_mps[t, k] time``, the chord of the trip) and the
    vehicle's packed parameters (the EDS levitation's ``k_p`` and ``c_p`` at the interval's
    mid-time speed; unchanged rows without ``levitation="eds"``).

    start_m, speed_mps : (T, E); vehicle : (T, E, N_VEHICLE_PARAMS).
    """

    start_m: np.ndarray
    speed_mps: np.ndarray
    vehicle: np.ndarray


def trip_schedule(batch: CapsuleBatch, n_steps: int) -> TripSchedule:
    """Record a trip's :class:`TripSchedule` by stepping ``batch`` (just reset) ``n_steps``
    times: what the envelope sets depends on the time alone, never on the actions or the
    motion, so these are the values every run of the same episodes meets (the batch is left
    at the episodes' end)."""
    n = batch.num_envs
    start, speed = np.empty((n_steps, n)), np.empty((n_steps, n))
    vehicle = np.empty((n_steps, *batch.vehicle_params.shape))
    zeros = np.zeros(n)
    for t in range(n_steps):
        batch.step(zeros)
        route = batch.env_state.route
        start[t], speed[t], vehicle[t] = route.start_m, route.speed_mps, batch.vehicle_params
    return TripSchedule(start, speed, vehicle)


def _tile(rows: np.ndarray, lanes: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(rows[lanes])


class OracleEpisodes:
    """The episodes an env runs for ``seeds`` (episode ``k``: the single env seeded
    ``seeds[k]``, as :func:`capsule_env.evaluation.episodes.run_episodes` runs them), replayed open loop.

    Two substep rules: ``"env"``, the env's adaptive tables (what the evaluation measures), and
    ``"search"``, each episode's largest table entry at every current (no substep-count
    switching: the step map is smooth in the current, which finite differences need; it is
    the finer integration, within the tables' 0.5 % force accuracy of the env's).

    Public attributes: ``config`` (:class:`~capsule_env.engine.config.EnvConfig`), ``seeds``,
    ``n_episodes``, ``n_steps``, ``dt_s``, ``i_max`` (A), ``code`` (plant damper), ``columns``
    (:func:`active_state_columns`), ``state0`` (E, STATE_SIZE), ``damper_params``,
    ``vehicle_params``, ``env_tables`` and ``search_tables`` (E, bins).
    """

    def __init__(
        self, env_kwargs: Mapping[str, Any], seeds: Sequence[int], episode_length_s: float
    ) -> None:
        kwargs = {"episode_length_s": episode_length_s, **env_kwargs}
        self.config = EnvConfig.from_kwargs(**kwargs)
        self.seeds = tuple(int(s) for s in seeds)
        batch = CapsuleBatch(self.config, len(self.seeds))
        batch.seed(list(self.seeds))
        batch.reset()
        self.n_episodes = len(self.seeds)
        self.n_steps = int(batch.max_steps)
        self.dt_s = float(batch.dt)
        self.i_max = float(batch.i_max)
        self.code = int(batch.plant.code)
        self.damper_params = batch.damper_params.copy()
        self.vehicle_params = batch.vehicle_params.copy()
        self.state0 = batch.state.copy()
        self.route = Route(*(np.array(r, copy=True) for r in batch.env_state.route))
        self.profiles, self.spacing_m = batch.profiles, float(batch.spacing)
        self.offsets = batch.offsets
        self.env_tables = batch.sub_table.copy()
        self.search_tables = np.ascontiguousarray(
            np.broadcast_to(self.env_tables.max(axis=1, keepdims=True), self.env_tables.shape)
        )
        self.mode = batch.kernel_mode
        self.columns = active_state_columns(self.code, self.damper_params[0])
        self.schedule = (
            trip_schedule(batch, self.n_steps) if self.config.speed_profile != "constant" else None
        )
        self._fd_cache: dict[int, tuple[PlantParams, Route, BatchedKernel]] = {}

    # ------------------------------------------------------------------ open-loop runs
    def _follow_trip(self, t: int, lanes: np.ndarray, plant: PlantParams, route: Route) -> None:
        """On a trip, set the route and the vehicles of ``lanes`` to step ``t``'s."""
        if self.schedule is not None:
            route.start_m[:] = self.schedule.start_m[t, lanes]
            route.speed_mps[:] = self.schedule.speed_mps[t, lanes]
            plant.vehicle[:] = self.schedule.vehicle[t, lanes]

    def _plant(self, lanes: np.ndarray, substeps: str, repeat: int = 1) -> PlantParams:
        tables = self.env_tables if substeps == "env" else self.search_tables
        rows = np.repeat(lanes, repeat)
        return make_plant_params(
            self.code, _tile(self.damper_params, rows), _tile(self.vehicle_params, rows),
            _tile(tables, rows), self.profiles, self.spacing_m, self.dt_s, self.offsets,
        )  # fmt: skip

    def _route(self, lanes: np.ndarray, repeat: int = 1) -> Route:
        rows = np.repeat(lanes, repeat)
        return Route(*(np.ascontiguousarray(r[rows]) for r in self.route))

    def run(
        self, episodes: np.ndarray, currents: np.ndarray, substeps: str = "search"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Replay applied currents ``currents`` (L, T) (A, clipped to ``[0, i_max]`` by the
        kernel) on episodes ``episodes`` (L,) from their start states. Returns the states
        (L, T + 1, STATE_SIZE), row 0 the start, and the plant outputs (L, T, N_PLANT_OUTPUTS)
        (``layout.PLANT_OUTPUT_NAMES``) after each step. Lanes go through the kernel
        :data:`~capsule_env.plant.block.HALF` at a time (one call per step costs the same for
        1 or HALF vehicles)."""
        episodes = np.asarray(episodes, dtype=np.int64)
        u = np.asarray(currents, dtype=np.float64)
        n_lanes = episodes.size
        states = np.empty((n_lanes, self.n_steps + 1, STATE_SIZE))
        outputs = np.empty((n_lanes, self.n_steps, N_PLANT_OUTPUTS))
        for lo in range(0, n_lanes, HALF):
            hi = min(n_lanes, lo + HALF)
            lanes = episodes[lo:hi]
            plant, route = self._plant(lanes, substeps), self._route(lanes)
            kernel = BatchedKernel(PLANT, self.code, self.mode, hi - lo)
            x = np.ascontiguousarray(self.state0[lanes])
            cmd = np.empty(hi - lo)
            out = np.empty((hi - lo, N_PLANT_OUTPUTS))
            states[lo:hi, 0] = x
            for t in range(self.n_steps):
                cmd[:] = u[lo:hi, t]
                self._follow_trip(t, lanes, plant, route)
                kernel(plant, x, cmd, route, self.dt_s, out)
                states[lo:hi, t + 1] = x
                outputs[lo:hi, t] = out
        return states, outputs

    def skyhook_currents(self) -> np.ndarray:
        """On-off Skyhook on the true state of each episode's search plant (closed loop, no
        noise, no delay): ``i_max`` while the body velocity and the stroke rate agree in sign,
        else 0. A heuristic start for the search, (E, T)."""
        lanes = np.arange(self.n_episodes)
        plant, route = self._plant(lanes, "search"), self._route(lanes)
        kernel = BatchedKernel(PLANT, self.code, self.mode, self.n_episodes)
        x = self.state0.copy()
        out = np.empty((self.n_episodes, N_PLANT_OUTPUTS))
        u = np.empty((self.n_episodes, self.n_steps))
        for t in range(self.n_steps):
            on = x[:, BODY_VEL] * (x[:, BODY_VEL] - x[:, BOGIE_VEL]) > 0.0
            u[:, t] = np.where(on, self.i_max, 0.0)
            self._follow_trip(t, lanes, plant, route)
            kernel(plant, x, np.ascontiguousarray(u[:, t]), route, self.dt_s, out)
        return u

    # ------------------------------------------------------------------ linearisation
    def _fd_batch(self, k: int) -> tuple[PlantParams, Route, BatchedKernel]:
        """The batch of ``T (n + 1)`` copies of episode ``k``'s vehicle (search substeps),
        made once per episode."""
        if k not in self._fd_cache:
            copies = self.n_steps * (len(self.columns) + 1)
            lane = np.array([k])
            plant = self._plant(lane, "search", copies)
            kernel = BatchedKernel(PLANT, self.code, self.mode, copies)
            route = self._route(lane, copies)
            if self.schedule is not None:  # copy t * (n + 1) + j: step t's route and vehicle
                per_step = copies // self.n_steps
                route.start_m[:] = np.repeat(self.schedule.start_m[:, k], per_step)
                route.speed_mps[:] = np.repeat(self.schedule.speed_mps[:, k], per_step)
                plant.vehicle[:] = np.repeat(self.schedule.vehicle[:, k], per_step, axis=0)
            self._fd_cache[k] = (plant, route, kernel)
        return self._fd_cache[k]

    def linearise(
        self,
        k: int,
        states: np.ndarray,
        acc: np.ndarray,
        currents: np.ndarray,
        rel_step: float = FD_RELATIVE_STEP,
    ) -> Linearisation:
        """Linearise every step of one trajectory of episode ``k`` by forward differences:
        ``states`` (T + 1, STATE_SIZE) and body accelerations ``acc`` (T,) from :meth:`run`
        with the search substeps, ``currents`` (T,) its applied currents. One batched kernel
        call runs all ``T (n + 1)`` perturbed single steps (one per active state column, one
        for the current; the unperturbed steps are the trajectory's own). The current's step
        goes down at ``i_max``: a one-sided derivative into the feasible range."""
        plant, route, kernel = self._fd_batch(k)
        cols = list(self.columns)
        n, n_steps = len(cols), self.n_steps
        copies = n + 1
        x0 = states[:-1]
        deviation = x0[:, cols] - x0[:, cols].mean(axis=0)
        dx = rel_step * np.maximum(np.sqrt(np.mean(deviation**2, axis=0)), _SCALE_FLOOR)
        x = np.repeat(x0[:, None, :], copies, axis=1)
        x[:, np.arange(n), cols] += dx
        u = np.asarray(currents, dtype=np.float64)
        step = rel_step * self.i_max
        cmd = np.repeat(u[:, None], copies, axis=1)
        cmd[:, n] = np.where(u + step <= self.i_max, u + step, u - step)
        du = cmd[:, n] - u  # the step actually taken
        x = np.ascontiguousarray(x.reshape(n_steps * copies, STATE_SIZE))
        out = np.empty((n_steps * copies, N_PLANT_OUTPUTS))
        kernel(plant, x, np.ascontiguousarray(cmd.reshape(-1)), route, self.dt_s, out)
        d_next = x.reshape(n_steps, copies, STATE_SIZE)[:, :, cols] - states[1:, None, cols]
        d_acc = out[:, OUT_BODY_ACC].reshape(n_steps, copies) - acc[:, None]
        return Linearisation(
            jac_x=np.ascontiguousarray(d_next[:, :n, :] / dx[None, :, None]),
            jac_u=np.ascontiguousarray(d_next[:, n, :] / du[:, None]),
            acc_x=np.ascontiguousarray(d_acc[:, :n] / dx[None, :]),
            acc_u=np.ascontiguousarray(d_acc[:, n] / du),
        )
