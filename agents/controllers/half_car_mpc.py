"""Semi-active MPC of the half-car (issue 42): both dampers planned together, with or without
the wheelbase preview.

At each control interval the law plans both dampers' forces over the next ``horizon_steps``
intervals and requests the first of each, as the quarter-car's semi-active MPC
(:mod:`capsule_env.agents.controllers.mpc`) does for its one damper:

- **model**: the half-car's relative form (:func:`capsule_env.vehicles.relative_model`), both
  dampers' forces as inputs, sampled at the control interval (zero-order hold), each coil's
  lag as a first-order lag of its force (``coil_time_constant_s``, the ``hils`` 1/190 s), the
  control delay (``delay_steps`` request pairs in flight, newest first); with ``preview``,
  the wheelbase window of :mod:`capsule_env.agents.controllers.wheelbase` (the front's past
  rises; the rear contact's input is the front's ``(a + b) / v`` earlier). State ``z = [x (8);
  F_act (2, with a lag); in flight (2 delay_steps); window]``;
- **cost**: the coupled half-car laws' (``lq-discrete-biexp-meas``, ``wheelbase-lq-biexp-meas``):
  the comfort points' accelerations squared, ``q_stroke`` on each stroke, ``q_levitation`` on
  each gap, ``r_force`` on each force, per interval; the terminal cost the infinite-horizon
  LQ cost-to-go ``z' P z`` (discrete Riccati equation): unconstrained, the plan's first move
  is the discrete LQ law ``-K z`` whatever the horizon (without a coil lag, exactly that of
  :func:`capsule_env.agents.controllers.wheelbase.wheelbase_gains`: ``tests/test_half_car_mpc.py``);
- **constraint**: each damper's planned force dissipative and inside the band of the inverted
  Bi-exponential model at that damper's own predicted stroke and stroke rate (the measured
  ones for the force requested now), the sign pattern fixed from the previous plan, the QP of
  :class:`capsule_env.agents.controllers.mpc_solver.BandQP` with one block of rows per damper;
- **state**: the relative state rebuilt from the measured strokes, gaps and velocity estimates
  (:meth:`DeclaredClippedLQR.relative_state`), each coil's acting force from the band at the
  measured stroke and rate and the coil current estimated from the task's
  ``last_current_command_a`` columns through the lag, the law's own requests in flight (what
  the damper makes of them at the measured rate), and the front's rises estimated from its gap
  sensor and velocity estimate exactly as ``wheelbase-lq-biexp-meas`` estimates them.

A failed solve falls back to the unconstrained LQ law (clipped by the env's inverse), counted
in :attr:`HalfCarMPC.counters` with the solves and their time. A vehicle whose observation is
not finite requests 0 N that step (the passive 0 A) and its next plan starts afresh; the
non-finite columns enter the law's memories (the window, the coil current) as zeros.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from capsule_env.agents.controllers.lqr import state_weights
from capsule_env.agents.controllers.mpc import HILS_COIL_TIME_CONSTANT_S, MPCController
from capsule_env.agents.controllers.mpc_qp import CondensedQP, _zoh, band_edges, blocking_matrix
from capsule_env.agents.controllers.mpc_solver import (
    BandQP,
    check_blocks,
    check_integer,
    check_real,
)
from capsule_env.agents.controllers.wheelbase import WheelbasePreviewLQ
from scipy.linalg import solve_discrete_are

from capsule_env.common.units import kmh_to_m_s, m_s_to_kmh
from capsule_env.engine.config import EnvConfig
from capsule_env.vehicles import model_named, relative_model

__all__ = ["CoupledModel", "coupled_model", "coupled_lq", "condense_coupled", "HalfCarMPC"]

#: The coupled half-car laws' weights tuned on the training bank (docs/half-car.md): the
#: MPC's defaults (``HalfCarMPC``'s rows in the evaluation pass their own tuned ones).
COUPLED_WEIGHTS = {"q_stroke": 0.001, "q_levitation": 0.1, "r_force": 3e-8}
#: The longest wheelbase window the preview law is designed with (intervals): its Riccati
#: equation grows with it (6 s to set up at 577, 24 km/h at 5 ms).
MAX_WINDOW = 600
_PER_SLOT, _STROKE, _RATE, _COMMAND = 8, 0, 1, 7  # the measured columns per slot


@dataclass(frozen=True)
class CoupledModel:
    """``z_{k+1} = A z_k + B u_k`` (``u``: the requested forces, one per damper); the comfort
    accelerations ``C z + D u``; ``stroke``, ``rate``: each damper's stroke and stroke rate as
    rows on ``z``; ``stroke_weight``, ``gap_weight``: the state cost per unit ``q_stroke`` and
    ``q_levitation``; ``plant_size``: the relative state's size; ``window``: the wheelbase
    window's length (0 without the preview)."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    stroke: np.ndarray
    rate: np.ndarray
    stroke_weight: np.ndarray
    gap_weight: np.ndarray
    plant_size: int
    lag: bool
    delay_steps: int
    window: int

    @property
    def size(self) -> int:
        return self.a.shape[0]

    @property
    def inputs(self) -> int:
        return self.b.shape[1]


def _continuous(plant: Any, tau_s: float) -> tuple[np.ndarray, ...]:
    """``(A, B, E, C, D)`` on ``[x; F_act (with a lag)]``: inputs the requests and each
    contact's guideway velocity; the comfort accelerations ``C z + D u``."""
    n, m = plant.a.shape[0], plant.b.shape[1]
    lag = tau_s > 0.0
    size = n + (m if lag else 0)
    a, b = np.zeros((size, size)), np.zeros((size, m))
    e = np.zeros((size, plant.e_rate.shape[1]))
    a[:n, :n], e[:n] = plant.a, plant.e_rate
    c = np.zeros((plant.c_acc.shape[0], size))
    c[:, :n] = plant.c_acc
    if not lag:
        b[:n] = plant.b
        return a, b, e, c, plant.d_acc.copy()
    a[:n, n:] = plant.b  # tau F_act' = u - F_act
    a[n:, n:] = -np.eye(m) / tau_s
    b[n:] = np.eye(m) / tau_s
    c[:, n:] = plant.d_acc
    return a, b, e, c, np.zeros_like(plant.d_acc)


def coupled_model(
    vehicle: str = "half_car", dt_s: float = 0.005, delay_steps: int = 1,
    coil_time_constant_s: float = HILS_COIL_TIME_CONSTANT_S, speed_m_s: float = 225.0,
    preview: bool = False,
) -> CoupledModel:  # fmt: skip
    """The augmented prediction model (module doc) of ``vehicle`` (two contacts, two slots)."""
    model = model_named(vehicle)
    params = model.params()
    plant = relative_model(model, params)
    offsets = model.contact_offsets_m(params)
    a_c, b_c, e_c, c0, d0 = _continuous(plant, coil_time_constant_s)
    nb, m = a_c.shape[0], b_c.shape[1]
    base_a, inputs = _zoh(a_c, np.concatenate([b_c, e_c], axis=1), dt_s)
    base_b, base_e = inputs[:, :m], inputs[:, m:] / dt_s  # a rise over the interval: d / dt
    delay = (offsets[0] - offsets[1]) / speed_m_s / dt_s
    frac = float(delay - np.floor(delay))
    nd, w = int(delay_steps), (int(np.floor(delay)) + 1 if preview else 0)
    size = nb + m * nd + w
    a, b = np.zeros((size, size)), np.zeros((size, m))
    c, d = np.zeros((c0.shape[0], size)), d0
    a[:nb, :nb], c[:, :nb] = base_a, c0
    if nd:  # the oldest requests in flight are applied; the new ones enter the line
        a[:nb, nb + m * (nd - 1) : nb + m * nd] = base_b
        a[nb + m : nb + m * nd, nb : nb + m * (nd - 1)] = np.eye(m * (nd - 1))
        b[nb : nb + m] = np.eye(m)
        c[:, nb + m * (nd - 1) : nb + m * nd], d = d0, np.zeros_like(d0)  # the applied force's
    else:
        b[:nb] = base_b
    if w:  # [d_f(k-D-1) .. d_f(k-1)]: the rear contact's rise now, then the shift
        start = nb + m * nd
        a[:nb, start] += base_e[:, 1] * frac
        a[:nb, start + 1] += base_e[:, 1] * (1.0 - frac)
        a[start : size - 1, start + 1 : size] = np.eye(w - 1)
    n = plant.a.shape[0]
    pad = np.zeros((m, size))
    stroke, rate = pad.copy(), pad.copy()
    stroke[:, :n], rate[:, :n] = plant.stroke, plant.stroke @ plant.a  # no input reaches it
    weights = [np.zeros((size, size)) for _ in range(2)]
    weights[0][:n, :n] = state_weights(model, plant, 1.0, 0.0)
    weights[1][:n, :n] = state_weights(model, plant, 0.0, 1.0)
    return CoupledModel(a, b, c, d, stroke, rate, weights[0], weights[1], n,
                        coil_time_constant_s > 0.0, nd, w)  # fmt: skip


def coupled_lq(
    model: CoupledModel, q_stroke: float, q_gap: float, r_force: float
) -> tuple[np.ndarray, ...]:
    """``(Q, S, R, P, K)``: the stage cost ``z'Qz + 2 z'S u + u'R u``, the Riccati solution
    and the LQ gain ``u = -K z`` (``K``: (inputs, size))."""
    q = model.c.T @ model.c + q_stroke * model.stroke_weight + q_gap * model.gap_weight
    s = model.c.T @ model.d
    r = model.d.T @ model.d + r_force * np.eye(model.inputs)
    p = solve_discrete_are(model.a, model.b, q, r, s=s)
    k = np.linalg.solve(r + model.b.T @ p @ model.b, model.b.T @ p @ model.a + s.T)
    return q, s, r, p, k


def condense_coupled(
    model: CoupledModel,
    weights: tuple[float, float, float],
    horizon: int,
    blocks: tuple[int, ...] | None = None,
) -> CondensedQP:
    """The condensed QP (``1/2 w'Hw + w' F_z z_0``) of both dampers over ``horizon``
    intervals, moves held over ``blocks``, rows input-major (:class:`CondensedQP`'s
    ``inputs``); the terminal cost the LQ cost-to-go; no rises read (the future is zero)."""
    q, s, r, p, k = coupled_lq(model, *weights)
    n, m, big_n = model.size, model.inputs, int(horizon)
    order = (np.arange(big_n)[None, :] * m + np.arange(m)[:, None]).ravel()  # input-major
    phi = np.zeros((big_n + 1, n, n))
    gam = np.zeros((big_n + 1, n, big_n * m))  # columns time-major: u_j's at j m ..
    phi[0] = np.eye(n)
    for j in range(big_n):
        phi[j + 1] = model.a @ phi[j]
        gam[j + 1] = model.a @ gam[j]
        gam[j + 1][:, j * m : (j + 1) * m] += model.b
    h = gam[big_n].T @ p @ gam[big_n]
    f_z = gam[big_n].T @ p @ phi[big_n]
    for j in range(big_n):
        pick = np.zeros((m, big_n * m))
        pick[:, j * m : (j + 1) * m] = np.eye(m)
        cross = pick.T @ s.T @ gam[j]
        h += gam[j].T @ q @ gam[j] + cross + cross.T + pick.T @ r @ pick
        f_z += gam[j].T @ q @ phi[j] + pick.T @ s.T @ phi[j]
    t = np.kron(np.eye(m), blocking_matrix(big_n, blocks))  # (m N, m W), input-major
    h, f_z = h[np.ix_(order, order)], f_z[order]
    g = gam[:big_n][:, :, order]  # (N, n, m N) on the input-major moves

    def rows(r_: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        on_z = np.einsum("in,jnk->ijk", r_, phi[:big_n]).reshape(m * big_n, n)
        on_u = np.einsum("in,jnk->ijk", r_, g).reshape(m * big_n, m * big_n)
        return on_z, on_u @ t

    (rate_z, rate_w), (stroke_z, stroke_w) = rows(model.rate), rows(model.stroke)
    none = np.zeros((m * big_n, 0))
    return CondensedQP(
        h=2.0 * t.T @ h @ t, f_z=2.0 * t.T @ f_z, f_d=np.zeros((t.shape[1], 0)), blocking=t,
        rate_z=rate_z, rate_w=rate_w, rate_d=none, stroke_z=stroke_z, stroke_w=stroke_w,
        stroke_d=none, lq_gain=k, lq_rise_gain=np.zeros(0), inputs=m,
    )  # fmt: skip


class HalfCarMPC(WheelbasePreviewLQ):
    """The half-car's semi-active MPC on its measured signals (module doc): ``preview=False``
    is ``mpc-coupled-biexp-meas``, ``preview=True`` ``wheelbase-mpc-biexp-meas``. Force mode,
    through the Bi-exponential inverse (the band's model).

    Parameters: the weights ``q_stroke``, ``q_levitation`` (1/s^4), ``r_force`` (1/kg^2;
    default :data:`COUPLED_WEIGHTS`); ``horizon_steps`` (1 to 200), ``move_blocks`` (lengths
    summing to it, None: a move per interval), ``delay_steps`` (0 to 10, the ``hils`` 1),
    ``coil_time_constant_s`` (0 to 1 s; 0: no lag), ``dt_s``, ``speed_kmh`` (the wheelbase
    delay's; with ``preview`` the window, wheelbase / speed / ``dt_s``, at most
    :data:`MAX_WINDOW` intervals: above 24 km/h at 5 ms), ``max_force_n``, ``solver`` (the keys of
    :class:`~capsule_env.agents.controllers.mpc_solver.SolverOptions`, checked as the
    quarter-car MPC checks them). A bad value raises ``ValueError`` naming the parameter.
    :attr:`arguments`: every constructor argument as checked, as plain JSON values
    (``HalfCarMPC(**law.arguments)`` rebuilds the law; the export's contract carries them)."""

    #: Whether the weights are the training bank's tuned ones (the evaluation's rows set it).
    gains_tuned: bool = False

    def __init__(
        self, q_stroke: float = COUPLED_WEIGHTS["q_stroke"],
        q_levitation: float = COUPLED_WEIGHTS["q_levitation"],
        r_force: float = COUPLED_WEIGHTS["r_force"], preview: bool = False,
        horizon_steps: int = 10, move_blocks: tuple[int, ...] | None = None,
        delay_steps: int = 1, coil_time_constant_s: float = HILS_COIL_TIME_CONSTANT_S,
        dt_s: float = 0.005, speed_kmh: float = 810.0, max_force_n: float = 8000.0,
        solver: dict[str, Any] | None = None,
    ) -> None:  # fmt: skip
        weights = (check_real("q_stroke", q_stroke, 0.0, 1e12, unit=" 1/s^4"),
                   check_real("q_levitation", q_levitation, 0.0, 1e12, unit=" 1/s^4"),
                   check_real("r_force", r_force, 0.0, 1.0, open_low=True, unit=" 1/kg^2"))  # fmt: skip
        if not isinstance(preview, (bool, np.bool_)):
            raise ValueError(f"preview must be True or False, got {preview!r}")
        preview = bool(preview)
        horizon = check_integer("horizon_steps", horizon_steps, 1, 200)
        nd = check_integer("delay_steps", delay_steps, 0, 10)
        dt = check_real("dt_s", dt_s, 1e-4, 0.1, unit=" s")
        tau = check_real("coil_time_constant_s", coil_time_constant_s, 0.0, 1.0, unit=" s")
        speed = check_real("speed_kmh", speed_kmh, 1.0, 2000.0, unit=" km/h")
        force = check_real("max_force_n", max_force_n, 0.0, 1e6, open_low=True, unit=" N")
        options = MPCController._check_solver(solver)
        blocks = check_blocks(move_blocks, horizon)
        if preview:
            _check_window(kmh_to_m_s(speed), dt)
        super().__init__(*weights, dt_s=dt, speed_kmh=speed, delay_steps=nd,
                         max_force_n=force, preview=preview)  # fmt: skip
        self.name = "wheelbase-mpc-biexp-meas" if preview else "mpc-coupled-biexp-meas"
        self.arguments: dict[str, Any] = {
            "q_stroke": weights[0], "q_levitation": weights[1], "r_force": weights[2],
            "preview": preview, "horizon_steps": horizon, "delay_steps": nd,
            "move_blocks": None if blocks is None else [int(b) for b in blocks],
            "coil_time_constant_s": tau, "dt_s": dt, "speed_kmh": speed, "max_force_n": force,
            "solver": dataclasses.asdict(options)}  # fmt: skip
        self.weights, self.horizon_steps, self.coil_time_constant_s = weights, horizon, tau
        self.model = coupled_model(dt_s=dt, delay_steps=nd, coil_time_constant_s=tau,
                                   speed_m_s=kmh_to_m_s(speed), preview=preview)  # fmt: skip
        self.qp = condense_coupled(self.model, weights, horizon, blocks)
        self.solver_options = options
        self.damper: Any = EnvConfig(inverse_model="bi_exponential").inverse_damper
        self._keep = float(np.exp(-dt / tau)) if tau > 0.0 else 0.0  # the coil's lag per step
        self._solvers: list[BandQP] = []  # one per vehicle, set up at the first step
        self.reset_counters()

    def reset_counters(self) -> None:
        """Zero :attr:`counters`: ``vehicle_steps``, ``solves`` (QP solves), ``failed_solves``,
        ``fallback_steps`` (steps on the unconstrained LQ law after a failed solve),
        ``nonfinite_steps`` (0 N requested) and ``solve_time_s`` (the plans' wall time)."""
        self.counters: dict[str, float] = {"vehicle_steps": 0, "solves": 0, "failed_solves": 0,
                                           "fallback_steps": 0, "nonfinite_steps": 0,
                                           "solve_time_s": 0.0}  # fmt: skip

    def gains(self) -> dict[str, Any]:
        return {"q_stroke_1_s4": self.weights[0], "q_levitation_1_s4": self.weights[1],
                "r_force_1_kg2": self.weights[2], "horizon_s": self.horizon_steps * self.dt_s,
                "planned_delay_s": self.delay_steps * self.dt_s,
                "planned_coil_time_constant_s": self.coil_time_constant_s}  # fmt: skip

    def _restart(self, obs: np.ndarray, vehicles: list[int]) -> None:
        """``vehicles`` as under a fresh law (:meth:`WheelbasePreviewLQ.predict`): their
        memories (the rise estimate's last sample, the window, the requests in flight, the
        coil current, the plan) and their solvers' warm starts (set up afresh)."""
        super()._restart(np.where(np.isfinite(obs), obs, 0.0), vehicles)  # as act() reads it
        self._memory["plans"][vehicles] = np.nan
        for k in vehicles:
            self._solvers[k] = BandQP(self.qp, self.damper, self.max_force_n,
                                      self.solver_options)  # fmt: skip

    def _state(self, obs: np.ndarray) -> np.ndarray:
        """The prediction model's state per vehicle (module doc), (N, size); advances the
        front's rise window and the coil currents' estimate by this step."""
        rise = self._estimate_rise(obs)
        mem, n, m = self._memory, obs.shape[0], self.model.inputs
        if "plans" not in mem or mem["plans"].shape[0] != n:
            rows = self.qp.blocking.shape[0]
            mem.update(current=np.zeros((n, m)), plans=np.full((n, rows), np.nan),
                       commands=np.zeros((n, max(self.delay_steps, 1), m)),
                       strokes=np.zeros((n, rows)))  # fmt: skip
            self._solvers = [BandQP(self.qp, self.damper, self.max_force_n, self.solver_options)
                             for _ in range(n)]  # fmt: skip
        if self.model.window:
            mem["window"][:, :-1] = mem["window"][:, 1:]
            mem["window"][:, -1] = rise
        # one vehicle at a time: a batched product's last bits depend on the batch, and the
        # band's on/off decisions amplify them (0.25 % on one episode's Wk)
        parts = [np.concatenate([self.state_law.relative_state(obs[k : k + 1]) for k in range(n)])]
        if self.model.lag:  # the current applied over the last interval, through the lag
            commands = obs[:, _COMMAND::_PER_SLOT]
            applied = commands if not self.delay_steps else mem["commands"][:, -1]
            mem["current"] = self._keep * mem["current"] + (1.0 - self._keep) * applied
            if self.delay_steps:
                mem["commands"] = np.concatenate([commands[:, None], mem["commands"][:, :-1]], 1)
            parts.append(self._acting_force(obs, mem["current"]))
        return np.concatenate([*parts, mem["in_flight"], mem["window"]], axis=1)

    def _acting_force(self, obs: np.ndarray, current_a: np.ndarray) -> np.ndarray:
        """Each damper's force at its measured stroke and rate and the estimated current."""
        edges = band_edges(self.damper, obs[:, _STROKE::_PER_SLOT].ravel(),
                           obs[:, _RATE::_PER_SLOT].ravel())  # fmt: skip
        frac = np.clip(current_a.ravel() / self.damper.max_current_a, 0.0, 1.0)
        return (edges[0] + frac * (edges[1] - edges[0])).reshape(current_a.shape)

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = _measured_columns(np.atleast_2d(np.asarray(obs, dtype=np.float64)))
        bad = ~np.all(np.isfinite(obs), axis=1)
        clean = np.where(np.isfinite(obs), obs, 0.0) if bad.any() else obs
        z = self._state(clean)
        stroke, rate = clean[:, _STROKE::_PER_SLOT], clean[:, _RATE::_PER_SLOT]
        force = np.zeros(stroke.shape)
        for k in np.flatnonzero(~bad).tolist():
            force[k] = self._first_moves(k, z[k], rate[k], stroke[k])
        self._memory["plans"][bad] = np.nan  # the next plan starts afresh
        self.counters["vehicle_steps"] += obs.shape[0]
        self.counters["nonfinite_steps"] += int(bad.sum())
        force = np.clip(force, -self.max_force_n, self.max_force_n)
        made = _made(self.damper, force.ravel(), stroke.ravel(), rate.ravel())
        self._push(made.reshape(force.shape))  # the line holds what the damper makes of them
        return np.clip(force / self.max_force_n, -1.0, 1.0)

    def _first_moves(self, k: int, z0: np.ndarray, rate: np.ndarray,
                     stroke: np.ndarray) -> np.ndarray:  # fmt: skip
        """Vehicle ``k``'s planned forces now, or the unconstrained LQ law's after a failed
        solve; the plan's predictions, shifted by one interval, are the next reference."""
        mem, m = self._memory, self.model.inputs
        ref = mem["plans"][k]
        t0 = time.perf_counter()
        result = self._solvers[k].plan(z0, np.zeros(0), rate, stroke,
                                        np.zeros_like(ref) if np.isnan(ref[0]) else ref,
                                        mem["strokes"][k])  # fmt: skip
        self.counters["solve_time_s"] += time.perf_counter() - t0
        self.counters["solves"] += result.solves
        if result.u is None or result.rate_m_s is None or result.stroke_m is None:
            self.counters["failed_solves"] += 1
            self.counters["fallback_steps"] += 1
            mem["plans"][k] = np.nan
            return -(self.qp.lq_gain @ z0)
        mem["plans"][k] = _shifted(result.rate_m_s, m)
        mem["strokes"][k] = _shifted(result.stroke_m, m)
        return result.u.reshape(m, -1)[:, 0]


def _measured_columns(obs: np.ndarray) -> np.ndarray:
    """The half-car's measured columns (8 a bogie) of ``obs`` (N, 16 + 2 P: a survey preview
    of P points a bogie after them is not read); ``ValueError`` for another observation."""
    width = 2 * _PER_SLOT
    if obs.ndim != 2 or obs.shape[1] < width or (obs.shape[1] - width) % 2:
        raise ValueError(f"observation must be the half-car's measured one (observation="
                         f"'measured': {width} columns, then any survey preview's), got shape "
                         f"{obs.shape}")  # fmt: skip
    return obs[:, :width]


def _shifted(rows: np.ndarray, inputs: int) -> np.ndarray:
    """Each input's predictions one interval on (the last held), input-major."""
    per = rows.reshape(inputs, -1)
    return np.concatenate([per[:, 1:], per[:, -1:]], axis=1).ravel()


def _made(damper: Any, force_n: np.ndarray, stroke_m: np.ndarray, rate_m_s: np.ndarray) -> Any:
    """What the env's inverse makes of a request: 0 A when it does not push the way the
    stroke moves, else the request clipped to the band."""
    edges = band_edges(damper, stroke_m, rate_m_s)
    low, high = np.minimum(edges[0], edges[1]), np.maximum(edges[0], edges[1])
    return np.where(force_n * rate_m_s <= 0.0, edges[0], np.clip(force_n, low, high))


def _check_window(speed_m_s: float, dt_s: float) -> None:
    """``ValueError`` naming ``speed_kmh`` and ``dt_s`` unless the wheelbase window (the
    wheelbase over the speed, in intervals) is at most :data:`MAX_WINDOW` long."""
    model = model_named("half_car")
    offsets = model.contact_offsets_m(model.params())
    wheelbase_m = float(offsets[0] - offsets[1])
    if int(np.floor(wheelbase_m / speed_m_s / dt_s)) + 1 > MAX_WINDOW:
        raise ValueError(f"speed_kmh and dt_s: the wheelbase window ({wheelbase_m:g} m / speed "
                         f"/ dt_s) must be at most {MAX_WINDOW} intervals; at dt_s={dt_s:g} s "
                         f"speed_kmh must be above {m_s_to_kmh(wheelbase_m / (MAX_WINDOW * dt_s)):.1f} "
                         f"km/h, got {m_s_to_kmh(speed_m_s):g}")  # fmt: skip
