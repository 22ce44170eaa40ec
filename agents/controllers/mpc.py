"""Semi-active model predictive control (MPC) of the capsule's MR damper, with and without
guideway preview (issue 29).

At each control interval the law plans the damper forces of the next ``horizon_steps``
intervals by a quadratic programme (:mod:`capsule_env.agents.controllers.mpc_qp`,
:mod:`capsule_env.agents.controllers.mpc_solver`) and requests the first:

- **model**: the linear 2-DOF plant sampled at the control interval, with the known control
  delay (``delay_steps`` requests in flight, the ``hils`` setting's one) and the coil lag as a
  first-order lag of the force (``coil_time_constant_s``, the ``hils`` 1/190 s);
- **cost**: the clipped LQR's and preview LQ's, ``a_c^2 + q_stroke s^2 + q_gap g^2 +
  r_force F^2`` per interval, with the infinite-horizon LQ cost-to-go (and the preview beyond
  the horizon) as the terminal cost: unconstrained, the MPC is exactly the (preview) LQ law;
- **constraint**: each planned force dissipative and inside the band the damper can make,
  ``F(v, 0) .. F(v, i_max)`` of the inverted model at the predicted stroke rate ``v`` (the
  measured rate for the force requested now). The set is non-convex (the band flips with the
  rate's sign and curves with it); the sign pattern is fixed from the previous plan (shifted
  by one interval), the band edges linearised there, and the QP re-solved when the new plan's
  predicted signs differ (``max_passes``). A slack with an exact penalty keeps the QP feasible
  where the linearised band is empty;
- **state**: as the clipped LQR's: the four measured states (LVDT stroke, on-board velocity
  estimates, gap sensor) or the true ones (``full_state``), the acting force from the measured
  coil current through the inverted model, and the law's own requests in flight;
- **solver**: DAQP (a dual active-set solver for the small dense QPs of embedded MPC: the
  exact optimum in about 20 us here, warm-started from the previous plan), or OSQP (ADMM,
  updated in place and warm-started; approximate to its tolerances, about 10 x slower here;
  ``solver={"backend": "osqp"}``), both from the ``mpc`` extra
  (:mod:`capsule_env.agents.controllers.mpc_solver`). A failed or time-limited solve falls back to the
  unconstrained LQ law (clipped by the env's inverse like the clipped LQR), counted in
  :attr:`MPCController.counters`, with a ``RuntimeWarning`` once such steps are at least 10
  and more than 1 % of the planned ones (naming the option to raise);
- **bad samples**: a vehicle whose observation holds a NaN or inf in a column the law reads
  requests 0 N that step (the env's inverse makes it 0 A, the passive damper); the sample
  enters none of the law's state (not the Wk filter nor the solver's warm start; the previous
  plan is dropped, as after a fallback; the request in flight is the 0 A force), the vehicle's
  next finite observation is planned as usual, and the other vehicles are untouched. Counted
  (``nonfinite_steps``), warned about once.

What it gives up: the global optimum of the non-convex problem (a hybrid MIQP would find it):
the sign pattern is a local choice, and the linearised edges are exact only at the reference
rates. The prediction ignores the damper's own nonlinearity between the request and the force
produced (the request is assumed produced when inside the band).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from capsule_env.agents.controllers.base import restarted_vehicles
from capsule_env.agents.controllers.mpc_qp import (
    CondensedQP,
    band_edges,
    condense,
    prediction_model,
)
from capsule_env.agents.controllers.mpc_solver import (
    BandQP,
    PlanResult,
    SolverOptions,
    check_blocks,
    check_integer,
    check_real,
)
from capsule_env.agents.controllers.preview_lq import (
    DEFAULT_PREVIEW_HORIZON_S,
    DEFAULT_PREVIEW_POINTS,
    preview_rises,
)
from capsule_env.agents.controllers.skyhook import DEFAULT_MAX_FORCE_N, ForceLaw
from capsule_env.agents.controllers.tuned import tuned_gains

from capsule_env.engine.config import EnvConfig
from capsule_env.vehicles import VehicleParams

__all__ = ["MPCController", "LINEAR_TWIN", "DEFAULT_HORIZON_STEPS"]

#: The linear law whose tuned weights an untuned MPC starts from (same signals and preview).
LINEAR_TWIN = {
    "mpc-biexp-meas": "lqr-clipped-biexp-meas",
    "mpc-biexp": "lqr-clipped-biexp",
    "preview-mpc-biexp-meas": "preview-lq-biexp-meas",
    "preview-mpc-biexp": "preview-lq-biexp",
}
#: Horizon (control intervals) [reconstructed: 50 ms, a quarter period of the bogie's mode
#: at 5.4 Hz; beyond it the terminal LQ cost-to-go stands for the rest].
DEFAULT_HORIZON_STEPS = 10
#: The ``hils`` setting's coil time constant (s), the lag the prediction model plans for.
HILS_COIL_TIME_CONSTANT_S = EnvConfig(setting="hils").effective_coil_time_constant_s
_WEIGHTS = ("q_stroke", "q_levitation", "r_force")
#: The solver-failure warning: raised once, when at least this many planned vehicle-steps
#: fell back to the LQ law and they are more than this fraction of the planned ones.
FAILING_MIN_STEPS = 10
FAILING_FRACTION = 0.01


def _check_weight(name: str, value: Any) -> None:
    """``ValueError`` naming ``name`` unless ``value`` is a real number or a 1-D array of
    them (not bools), one per vehicle."""
    try:
        array = np.asarray(value)
    except ValueError:  # a ragged sequence
        array = np.asarray(None)
    if array.dtype.kind not in "iuf" or array.ndim > 1 or array.size == 0:
        raise ValueError(f"{name} must be a real number or a 1-D array of one per vehicle, got "
                         f"{value!r}")  # fmt: skip


class MPCController(ForceLaw):
    """Semi-active MPC through an inverse model (see the module docstring). Force mode.

    Parameters
    ----------
    inverse_model : ``"bi_exponential"`` (the band's model and the env's inverse) or ``"tanh"``.
    q_stroke, q_levitation (1/s^4), r_force (1/kg^2) : cost weights, scalars or 1-D arrays of
        one per vehicle (checked against the batch at the first step); None: the tuned values of this law, else those of its linear twin
        (:data:`LINEAR_TWIN`), else 1e3, 1e3, 1e-9 [reconstructed].
    observation : ``"measured"`` (default) or ``"full_state"``.
    preview : read the surveyed guideway ahead (``preview_points`` over ``preview_horizon_s``).
    horizon_steps : planned intervals, 1 to 200.
    move_blocks : lengths of the blocks over which a move is held (summing to the horizon);
        None: a move per interval.
    delay_steps : control delay planned for (the ``hils`` 1), 0 to 10.
    coil_time_constant_s : coil lag planned for (default the ``hils`` 1/190 s; 0: none).
    dt_s : the control interval (the env's default 5 ms).
    wk_cost : weight the cost's car-body acceleration by ISO 2631-1 Wk (the metric the tables
        report), the filter's state run on the measured acceleration; False: the plain
        acceleration of the clipped LQR's and preview LQ's cost.
    solver : solver options, keys of :class:`~capsule_env.agents.controllers.mpc_solver.SolverOptions`:
        ``backend`` (``"daqp"``, default, or ``"osqp"``), ``max_iter``, ``time_limit_s`` (0:
        none, the default, so that a result does not depend on the machine's load),
        ``max_passes`` (solves per step while the sign pattern changes, default 2),
        ``constrained_steps`` (the intervals under the band, default the first 3; 0: all),
        ``secant_m_s`` (the band edges' slope: the secant over this rate; default 1e-4 m/s,
        the tangent); OSQP's ``eps_abs``, ``eps_rel`` (1e-3), ``polish`` (a bool). Integers
        and numbers are checked by type (a bool is neither): ``ValueError`` naming the option.
    """

    q_stroke: np.ndarray  # the weights, set by _set_gains
    q_levitation: np.ndarray
    r_force: np.ndarray
    _in_flight: np.ndarray  # the memories (n, ...), set by _build (see _memories)
    _wk_state: np.ndarray
    _ref_rate: np.ndarray
    _ref_stroke: np.ndarray
    SIGNALS: tuple[str, ...] = ("stroke", "body_velocity", "gap", "bogie_velocity",
                                "relative_velocity")  # fmt: skip

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        q_stroke: float | np.ndarray | None = None,
        q_levitation: float | np.ndarray | None = None,
        r_force: float | np.ndarray | None = None,
        vehicle: VehicleParams | None = None,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
        observation: str = "measured",
        preview: bool = False,
        preview_points: int = DEFAULT_PREVIEW_POINTS,
        preview_horizon_s: float = DEFAULT_PREVIEW_HORIZON_S,
        horizon_steps: int = DEFAULT_HORIZON_STEPS,
        move_blocks: tuple[int, ...] | None = None,
        delay_steps: int = 1,
        coil_time_constant_s: float = HILS_COIL_TIME_CONSTANT_S,
        dt_s: float = 0.005,
        solver: dict[str, Any] | None = None,
        wk_cost: bool = False,
    ) -> None:
        if inverse_model not in ("bi_exponential", "tanh"):
            raise ValueError(f"inverse_model must be 'bi_exponential' or 'tanh' (a stateless "
                             f"band), got {inverse_model!r}")  # fmt: skip
        max_force_n = check_real("max_force_n", max_force_n, 0.0, 1e6, open_low=True, unit=" N")
        super().__init__("preview-mpc" if preview else "mpc", inverse_model, max_force_n,
                         observation)  # fmt: skip
        self.horizon_steps = check_integer("horizon_steps", horizon_steps, 1, 200)
        self.delay_steps = check_integer("delay_steps", delay_steps, 0, 10)
        self.move_blocks = check_blocks(move_blocks, self.horizon_steps)
        self.dt_s = check_real("dt_s", dt_s, 1e-4, 0.1, unit=" s")
        self.coil_time_constant_s = check_real("coil_time_constant_s", coil_time_constant_s,
                                               0.0, 1.0, unit=" s")  # fmt: skip
        self.solver_options = self._check_solver(solver)
        self.preview_points = self.n_rises = 0
        if preview:
            self._set_preview(preview_points, preview_horizon_s)
        self._set_weights(q_stroke, q_levitation, r_force)
        if not isinstance(wk_cost, bool):
            raise ValueError(f"wk_cost must be True or False, got {wk_cost!r}")
        self.wk_cost = wk_cost
        if wk_cost:  # the filter runs on the measured car-body acceleration
            self.SIGNALS = (*type(self).SIGNALS, "body_acceleration")
        self.prediction = prediction_model(vehicle or VehicleParams(), self.dt_s, self.delay_steps,
                                      self.coil_time_constant_s, wk_cost)  # fmt: skip
        self.damper: Any = EnvConfig(inverse_model=inverse_model).inverse_damper
        self._qps: list[BandQP] = []
        self._warned = {"nonfinite": False, "failing": False}  # each warning once
        self.reset_counters()

    @staticmethod
    def _check_solver(solver: Any) -> SolverOptions:
        if solver is None:
            return SolverOptions()
        if not isinstance(solver, Mapping):
            raise ValueError(f"solver must be a dict of solver options or None, got {solver!r}")
        unknown = sorted(set(solver) - set(SolverOptions.__dataclass_fields__))
        if unknown:
            raise ValueError(f"unknown solver option(s) {unknown}; accepted: "
                             f"{', '.join(SolverOptions.__dataclass_fields__)}")  # fmt: skip
        return SolverOptions(**solver).check()

    def _set_preview(self, points: int, horizon_s: float) -> None:
        self.preview_points = check_integer("preview_points", points, 1, 64)
        self.preview_horizon_s = check_real("preview_horizon_s", horizon_s, 1e-3, 10.0,
                                            unit=" s")  # fmt: skip
        self.n_rises = max(self.horizon_steps, int(round(horizon_s / self.dt_s)))
        self.env_kwargs = {**self.env_kwargs, "preview_points": self.preview_points,
                           "preview_horizon_s": self.preview_horizon_s}  # fmt: skip

    def _set_weights(self, q_stroke: Any, q_levitation: Any, r_force: Any) -> None:
        twin = tuned_gains(LINEAR_TWIN.get(self.name, "")) or {}
        fallback = {"q_stroke": 1.0e3, "q_levitation": 1.0e3, "r_force": 1.0e-9}
        units = {"r_force": "1_kg2", "q_stroke": "1_s4", "q_levitation": "1_s4"}  # searched first
        fallback = {g: float(twin.get(f"{g}_{units[g]}", v)) for g, v in fallback.items()}
        given = {"q_stroke": q_stroke, "q_levitation": q_levitation, "r_force": r_force}
        for name, value in given.items():
            if value is not None:
                _check_weight(name, value)
        self._set_gains(units, given, fallback)
        lengths = {g: getattr(self, g).size for g in _WEIGHTS if getattr(self, g).size > 1}
        if len(set(lengths.values())) > 1:
            raise ValueError("q_stroke, q_levitation and r_force given per vehicle must have "
                             f"the same length, got {lengths}")  # fmt: skip
        #: The batch size the per-vehicle weights are for (None: scalars, any batch).
        self.weight_vehicles = max(lengths.values()) if lengths else None
        w = np.broadcast_arrays(self.q_stroke, self.q_levitation, self.r_force)
        if (
            not all(np.all(np.isfinite(a)) for a in w)
            or np.any(w[0] < 0)
            or np.any(w[1] < 0)
            or np.any(w[2] <= 0)
        ):
            raise ValueError("q_stroke and q_levitation must be finite and >= 0, r_force "
                             "finite and > 0")  # fmt: skip

    @property
    def signals_read(self) -> tuple[str, ...]:
        ahead = tuple(f"preview_ahead_{k}" for k in range(1, self.preview_points + 1))
        lag = ("coil_current_a",) if self.prediction.lag else ()
        return (*super().signals_read, *lag, *ahead)

    def reset_counters(self) -> None:
        """Zero :attr:`counters`: ``vehicle_steps`` (every vehicle's step, the non-finite
        ones included), ``solves`` (QP solves), ``failed_solves`` and ``time_limited_solves``
        (steps whose solve failed or ran over ``time_limit_s``), ``fallback_steps`` (steps on
        the unconstrained LQ law for that reason; a RuntimeWarning once they are at least
        :data:`FAILING_MIN_STEPS` and more than :data:`FAILING_FRACTION` of the planned
        steps) and ``nonfinite_steps`` (steps with a non-finite observation: 0 N requested).
        The warnings are not re-armed: once per controller."""
        self.counters = {"vehicle_steps": 0, "solves": 0, "failed_solves": 0,
                         "time_limited_solves": 0, "fallback_steps": 0,
                         "nonfinite_steps": 0}  # fmt: skip

    def reset(self) -> None:
        self._qps = []

    def predict(  # type: ignore[no-untyped-def]  # Controller.predict's signature
        self, observation, state=None, episode_start=None, deterministic=True
    ):
        """As :meth:`Controller.predict`; a vehicle whose ``episode_start`` is set starts as
        under a fresh law, the others untouched: its requests in flight, the Wk filter's
        state, the previous plan's predicted rates and strokes (the next plan's sign pattern
        and linearisation points) and its solver's warm start go (its QP is set up afresh)."""
        if episode_start is not None:
            vehicles = restarted_vehicles(episode_start, observation)
            if vehicles and len(self._qps) == len(np.atleast_2d(np.asarray(observation))):
                self._restart(vehicles)  # (another batch: the next step sets all up afresh)
        return super().predict(observation, state, episode_start, deterministic)

    def _memories(self, n: int) -> dict[str, np.ndarray]:
        """What a fresh law remembers of ``n`` vehicles: nothing (zeros; no previous plan)."""
        wk_size = self.prediction.wk_states.stop - self.prediction.wk_states.start
        return {"_in_flight": np.zeros((n, self.delay_steps)), "_wk_state": np.zeros((n, wk_size)),
                "_ref_rate": np.full((n, self.horizon_steps), np.nan),
                "_ref_stroke": np.zeros((n, self.horizon_steps))}  # fmt: skip

    def _restart(self, vehicles: list[int]) -> None:
        """``vehicles`` as under a fresh law: their memories and their QPs' warm starts."""
        for name, fresh in self._memories(1).items():
            getattr(self, name)[vehicles] = fresh
        for k in vehicles:
            self._qps[k] = BandQP(self._qps[k].qp, self.damper, self.max_force_n,
                                  self.solver_options)  # fmt: skip

    def _build(self, n: int) -> None:
        """One QP per vehicle (one condensed problem per distinct weight set)."""
        if self.weight_vehicles not in (None, n):
            raise ValueError(f"q_stroke, q_levitation, r_force: {self.weight_vehicles} values "
                             f"(one per vehicle) for a batch of {n} vehicles; give scalars or "
                             f"{n} values")  # fmt: skip
        weights = [np.broadcast_to(getattr(self, g), (n,)) for g in _WEIGHTS]
        cache: dict[tuple[float, float, float], CondensedQP] = {}
        self._qps = []
        for triple in zip(*(w.tolist() for w in weights)):
            if triple not in cache:
                cache[triple] = condense(self.prediction, triple, self.horizon_steps, self.n_rises,
                                         self.move_blocks)  # fmt: skip
            self._qps.append(BandQP(cache[triple], self.damper, self.max_force_n,
                                    self.solver_options))  # fmt: skip
        for name, fresh in self._memories(n).items():
            setattr(self, name, fresh)

    def state_and_rises(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The prediction model's state ``z`` (n, size) and the guideway rises read (n, R)."""
        x = np.stack([self.signal(obs, s) for s in self.SIGNALS[:4]], axis=1)
        parts = [x]
        if self.prediction.lag:  # the acting force: the measured current through the model
            current = obs[:, self._columns["coil_current_a"]]
            edges = band_edges(self.damper, x[:, 0], self.signal(obs, "relative_velocity"))
            frac = np.clip(current / self.damper.max_current_a, 0.0, 1.0)
            parts.append((edges[0] + frac * (edges[1] - edges[0]))[:, None])
        if self.wk_cost:  # the Wk filter's state, then advanced by this step's measurement
            parts.append(self._wk_state)
            assert self.prediction.wk_discrete is not None  # built with wk_cost
            a_w, b_w = self.prediction.wk_discrete
            acc = self.signal(obs, "body_acceleration")
            self._wk_state = self._wk_state @ a_w.T + acc[:, None] * b_w[:, 0]
        parts.append(self._in_flight)
        n = obs.shape[0]
        if self.preview_points:
            step = self.preview_horizon_s / self.preview_points
            rises = preview_rises(obs[:, -self.preview_points :], step, self.dt_s, self.n_rises)
        else:
            rises = np.zeros((n, self.horizon_steps))
        return np.concatenate(parts, axis=1), rises

    def plan(self, k: int, z0: np.ndarray, rises: np.ndarray, rate: float,
             stroke: float) -> PlanResult:  # fmt: skip
        """Vehicle ``k``'s plan (counted in :attr:`counters`)."""
        ref = self._ref_rate[k]
        ref_rate = np.zeros_like(ref) if np.isnan(ref[0]) else ref
        result = self._qps[k].plan(z0, rises, rate, stroke, ref_rate, self._ref_stroke[k])
        self.counters["solves"] += result.solves
        if result.status == "failed":
            self.counters["failed_solves"] += 1
        elif result.status == "time_limit":
            self.counters["time_limited_solves"] += 1
        return result

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        """The first planned force of each vehicle (N); 0 N (the damper's 0 A) for a vehicle
        whose observation is not finite (:meth:`nonfinite`): that sample does not enter the Wk
        filter and the next plan starts afresh; with a delay, the record of requests in flight
        holds what the damper makes of 0 N at the sample with its non-finite entries read as 0."""
        n = obs.shape[0]
        if len(self._qps) != n:
            self._build(n)
        bad = self.nonfinite(obs)
        clean = np.where(np.isfinite(obs), obs, 0.0) if bad.any() else obs
        wk_before = self._wk_state[bad]
        z0, rises = self.state_and_rises(clean)
        self._wk_state[bad] = wk_before  # the bad sample does not enter the Wk filter
        rate = self.signal(clean, "relative_velocity")
        stroke = self.signal(clean, "stroke")
        force = np.zeros(n)
        for k in np.flatnonzero(~bad).tolist():
            force[k] = self._first_move(k, z0[k], rises[k], float(rate[k]), float(stroke[k]))
        self._ref_rate[bad] = np.nan  # the next plan starts afresh
        self.counters["vehicle_steps"] += n
        self._warn_if_failing()
        force = np.clip(force, -self.max_force_n, self.max_force_n)
        if self.delay_steps:  # what the damper will make of it: the band at the measured rate
            made = self.achievable(force, stroke, rate)
            self._in_flight = np.concatenate([made[:, None], self._in_flight[:, :-1]], axis=1)
        return force

    def _first_move(self, k: int, z0: np.ndarray, rises: np.ndarray, rate: float,
                    stroke: float) -> float:  # fmt: skip
        """Vehicle ``k``'s planned force now, or the fallback's (the unconstrained LQ law,
        clipped by the env) when the solve fails."""
        result = self.plan(k, z0, rises, rate, stroke)
        if result.u is None:
            qp = self._qps[k].qp
            self.counters["fallback_steps"] += 1
            self._ref_rate[k] = np.nan
            return float(-(qp.lq_gain @ z0 + qp.lq_rise_gain[: rises.shape[0]] @ rises))
        assert result.rate_m_s is not None and result.stroke_m is not None  # a solved plan
        self._ref_rate[k] = np.append(result.rate_m_s[1:], result.rate_m_s[-1])
        self._ref_stroke[k] = np.append(result.stroke_m[1:], result.stroke_m[-1])
        return float(result.u[0])

    def nonfinite(self, obs: np.ndarray) -> np.ndarray:
        """Which vehicles' observations hold a NaN or inf in a column the law reads (bool,
        (n,)); counted in ``counters["nonfinite_steps"]``, warned about once per controller."""
        columns = [self._columns[c] for c in self.signals_read if c in self._columns]
        columns += range(obs.shape[1] - self.preview_points, obs.shape[1])
        bad = ~np.all(np.isfinite(obs[:, columns]), axis=1)
        if bad.any():
            self.counters["nonfinite_steps"] += int(bad.sum())
            if not self._warned["nonfinite"]:
                self._warned["nonfinite"] = True
                warnings.warn(
                    f"{self.name}: a non-finite observation (vehicle {int(np.argmax(bad))} of "
                    f"{bad.size}): requested 0 N (the damper's 0 A) for it and kept it out of "
                    "the plan's state; counted in counters['nonfinite_steps'] (warned once)",
                    RuntimeWarning,
                    stacklevel=2,
                )
        return bad

    def _warn_if_failing(self) -> None:
        """Warn once when the solver failed on at least :data:`FAILING_MIN_STEPS` planned
        vehicle-steps, more than :data:`FAILING_FRACTION` of them."""
        c, o = self.counters, self.solver_options
        fell_back, planned = c["fallback_steps"], c["vehicle_steps"] - c["nonfinite_steps"]
        if (
            self._warned["failing"]
            or fell_back < FAILING_MIN_STEPS
            or fell_back <= FAILING_FRACTION * planned
        ):
            return
        self._warned["failing"] = True
        option = "time_limit_s" if c["time_limited_solves"] > c["failed_solves"] else "max_iter"
        extra = " (or loosen 'eps_abs'/'eps_rel')" if o.backend == "osqp" else ""
        warnings.warn(
            f"{self.name}: the {o.backend} solver failed on {fell_back} of {planned} planned "
            f"vehicle-steps ({c['failed_solves']} failed, {c['time_limited_solves']} over the "
            f"time limit), which fell back to the unconstrained LQ law; raise the solver option "
            f"{option!r} (now {getattr(o, option)}){extra}; see counters (warned once)",
            RuntimeWarning,
            stacklevel=2,
        )

    def achievable(self, force_n: np.ndarray, stroke_m: np.ndarray,
                   rate_m_s: np.ndarray) -> np.ndarray:  # fmt: skip
        """The force the inverted model makes of a request (the env's inverse: 0 A when the
        request does not push the way the stroke moves, else the request clipped to the
        band)."""
        edges = band_edges(self.damper, stroke_m, rate_m_s)
        low, high = np.minimum(edges[0], edges[1]), np.maximum(edges[0], edges[1])
        return np.where(force_n * rate_m_s <= 0.0, edges[0], np.clip(force_n, low, high))

    def gains(self) -> dict:
        out = super().gains()
        out.update({"horizon_s": self.horizon_steps * self.dt_s,
                    "planned_delay_s": self.delay_steps * self.dt_s,
                    "planned_coil_time_constant_s": self.coil_time_constant_s})  # fmt: skip
        if self.preview_points:
            out["preview_horizon_s"] = self.preview_horizon_s
        return out
