"""The prediction model and the condensed quadratic programme of the semi-active MPC
(:mod:`capsule_env.agents.controllers.mpc`).

Prediction model: the 2-DOF plant of :func:`capsule_env.agents.controllers.preview_lq.plant_matrices`
(state ``x = [z_c - z_b, z_c', z_b - z_g, z_b']``, damper force ``F``, guideway rise ``d_k``
per interval), sampled exactly (zero-order hold) at the control interval, with

- the coil lag as a first-order lag of the damper force, ``tau F_act' = F_app - F_act``
  (``coil_time_constant_s``; 0: none, the force acts as requested), discretised with the
  plant by one matrix exponential;
- the control delay: ``delay_steps`` requests in flight, newest first, the oldest applied.

The augmented state is ``z = [x (4); F_act (1, with a lag); in flight (delay_steps)]`` and the
cost per interval ``a_c^2 + q_stroke s^2 + q_gap g^2 + r_force u^2`` with ``a_c = c.z + d u``
(the weights of :mod:`capsule_env.agents.controllers.lqr`). The terminal cost is the infinite-horizon LQ
cost-to-go: ``z' P z`` (discrete Riccati equation) plus, with a preview, the linear term of the
guideway rises known beyond the horizon, ``2 b' z`` with ``b = sum_m (A_c')^(m+1) P E d_(N+m)``
(``A_c`` the LQ closed loop): so an unconstrained MPC *is* the (preview) LQ law, whatever its
horizon, and only the constraint makes it differ.

Condensed, the plan ``U = T w`` (``T``: the move blocking) gives the cost
``1/2 w' H w + w' (F_z z_0 + F_d D)`` with ``D`` the rises, and the predicted stroke rate and
stroke at the start of each interval are affine in ``(z_0, w, D)``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit
from numba.core.errors import NumbaIRAssumptionWarning
from scipy.linalg import expm, solve_discrete_are
from scipy.signal import tf2ss

from capsule_env.dampers.inverse import affine_in_current
from capsule_env.vehicles import VehicleParams, model_of_params, relative_model

__all__ = ["PredictionModel", "CondensedQP", "prediction_model", "condense", "band_edges"]


@dataclass(frozen=True)
class PredictionModel:
    """``z_{k+1} = A z_k + B u_k + E d_k``; the cost's acceleration ``y = c.z + d u`` (the
    car body's, or its Wk-weighted value); stroke ``= z[0]``, stroke rate ``= z[1] - z[3]``;
    ``lag``: whether ``z[4]`` is the acting force; ``wk_states``: where the Wk filter's states
    are (an empty slice without it); ``wk_discrete``: that filter alone, ``(A_w, B_w)``,
    sampled with the acceleration held, to run on the measured acceleration."""

    a: np.ndarray
    b: np.ndarray
    e: np.ndarray
    c: np.ndarray
    d: float
    lag: bool
    delay_steps: int
    wk_states: slice = field(default_factory=lambda: slice(0, 0))
    wk_discrete: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def size(self) -> int:
        return self.a.shape[0]

    def rate_row(self) -> np.ndarray:
        """The stroke rate ``z_c' - z_b'`` as a row on ``z``."""
        row = np.zeros(self.size)
        row[1], row[3] = 1.0, -1.0
        return row


def wk_state_space() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C)`` of the ISO 2631-1 Wk weighting's acceleration-velocity transition and
    upward step (:func:`capsule_env.metrics.wk_weighting`, 4th order, strictly proper); its
    band limits (0.4 Hz high-pass, 100 Hz low-pass) are left out of the cost."""
    w3, w4, q4 = 2 * np.pi * 12.5, 2 * np.pi * 12.5, 0.63
    w5, q5, w6, q6 = 2 * np.pi * 2.37, 0.91, 2 * np.pi * 3.35, 0.91
    num = np.polymul([1.0 / w3, 1.0], [1.0, w5 / q5, w5 * w5])
    den = np.polymul([1.0 / w4**2, 1.0 / (q4 * w4), 1.0], [1.0, w6 / q6, w6 * w6])
    a, b, c, d = tf2ss(num, den)
    if abs(d[0, 0]) > 0.0:  # pragma: no cover - the transition makes it strictly proper
        raise AssertionError("the Wk state space has a direct term")
    return a, b[:, 0], c[0]


def _continuous(vehicle: VehicleParams, tau_s: float, wk: bool) -> tuple[Any, ...]:
    """The continuous ``(A, B, E, c, d, wk slice)`` on ``[x; F_act (lag); w (Wk)]``, inputs
    the applied request and the guideway's velocity."""
    plant = relative_model(model_of_params(vehicle), vehicle)
    lag = tau_s > 0.0
    n = 4 + int(lag) + (4 if wk else 0)
    a, b, e = np.zeros((n, n)), np.zeros(n), np.zeros(n)
    a[:4, :4] = plant.a
    force_col, d_force = plant.b[:, 0], plant.d_acc[0, 0]
    e[:4] = plant.e_rate[:, 0]  # the guideway's velocity lowers the gap
    acc = np.zeros(n)  # a_c = acc.z + acc_d u
    acc[:4] = plant.c_acc[0]
    if lag:  # tau F_act' = u - F_act
        a[:4, 4], a[4, 4], b[4], acc[4], acc_d = force_col, -1.0 / tau_s, 1.0 / tau_s, d_force, 0.0
    else:
        b[:4], acc_d = force_col, d_force
    if not wk:
        return a, b, e, acc, acc_d, slice(0, 0)
    aw, bw, cw = wk_state_space()
    ws = slice(n - 4, n)
    a[ws, ws] = aw
    a[ws, :] += np.outer(bw, acc)
    b[ws] += bw * acc_d
    cost = np.zeros(n)
    cost[ws] = cw
    return a, b, e, cost, 0.0, ws


def _zoh(a: np.ndarray, inputs: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold sampling: ``(Ad, Bd)`` of ``x' = A x + B u``."""
    n, m = a.shape[0], inputs.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = a, inputs
    phi = expm(big * dt_s)
    return phi[:n, :n], phi[:n, n:]


def prediction_model(
    vehicle: VehicleParams,
    dt_s: float,
    delay_steps: int,
    coil_time_constant_s: float,
    wk_cost: bool = False,
) -> PredictionModel:
    """The augmented prediction model (see the module docstring); ``wk_cost``: the cost's
    acceleration is Wk-weighted (the filter's states are appended to the plant's)."""
    a_c, b_c, e_c, base_c, base_d, ws = _continuous(vehicle, coil_time_constant_s, wk_cost)
    base_a, inputs = _zoh(a_c, np.stack([b_c, e_c], axis=1), dt_s)
    base_b, base_e = inputs[:, 0], inputs[:, 1] / dt_s  # a rise d over the interval: d / dt
    wk_discrete = None
    if wk_cost:
        aw, bw, _ = wk_state_space()
        wk_discrete = _zoh(aw, bw[:, None], dt_s)
    nd, nb = int(delay_steps), base_a.shape[0]
    size = nb + nd
    a, b, e, c = np.zeros((size, size)), np.zeros(size), np.zeros(size), np.zeros(size)
    a[:nb, :nb], e[:nb], c[:nb] = base_a, base_e, base_c
    d = base_d
    if nd:  # the oldest request in flight is applied; the new one enters the line
        a[:nb, size - 1] = base_b
        a[nb + 1 : size, nb : size - 1] = np.eye(nd - 1)
        b[nb] = 1.0
        c[size - 1], d = base_d, 0.0  # a direct term is the applied force's
    else:
        b[:nb] = base_b
    lag = coil_time_constant_s > 0.0
    return PredictionModel(a, b, e, c, float(d), lag, nd, ws, wk_discrete)


def lq_terms(
    model: PredictionModel, q_stroke: float, q_gap: float, r_force: float
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """``(Q, S, R, P, K)``: stage weights (``z'Qz + 2 z'S u + R u^2``), the Riccati solution
    and the LQ gain ``u = -K z``."""
    q = np.outer(model.c, model.c)
    q[0, 0] += q_stroke
    q[2, 2] += q_gap
    s = model.c * model.d
    r = model.d * model.d + r_force
    p = solve_discrete_are(model.a, model.b[:, None], q, np.array([[r]]), s=s[:, None])
    k = (model.b @ p @ model.a + s) / (r + model.b @ p @ model.b)
    return q, s, float(r), p, k


@dataclass(frozen=True)
class CondensedQP:
    """The condensed problem of one weight set (see the module docstring). Shapes: ``N``
    horizon (times ``inputs``), ``W`` blocked moves, ``n`` state size, ``R`` rises read."""

    h: np.ndarray  # (W, W) Hessian (of 1/2 w'Hw)
    f_z: np.ndarray  # (W, n) linear term on z_0
    f_d: np.ndarray  # (W, R) linear term on the rises
    blocking: np.ndarray  # (N, W) U = T w
    rate_z: np.ndarray  # (N, n) stroke rate at the start of interval j on z_0
    rate_w: np.ndarray  # (N, W) ... on w
    rate_d: np.ndarray  # (N, R) ... on the rises
    stroke_z: np.ndarray  # (N, n) stroke at the start of interval j
    stroke_w: np.ndarray  # (N, W)
    stroke_d: np.ndarray  # (N, R)
    lq_gain: np.ndarray  # (n,) the unconstrained law u = -K z - K_d D (the fallback)
    lq_rise_gain: np.ndarray  # (R,)
    #: Inputs (dampers) planned: the rows of ``blocking`` and ``rate_*``/``stroke_*`` are
    #: input-major (input ``i``'s interval ``j`` at ``i N + j``, ``N`` the rows per input);
    #: ``lq_gain`` is then ``(inputs, n)`` (:mod:`capsule_env.agents.controllers.half_car_mpc`).
    inputs: int = 1


def blocking_matrix(horizon: int, blocks: tuple[int, ...] | None) -> np.ndarray:
    """``T`` (N, W): move ``w_b`` held over block ``b`` (lengths ``blocks``, summing to N)."""
    blocks = tuple(blocks) if blocks else (1,) * horizon
    t = np.zeros((horizon, len(blocks)))
    start = 0
    for k, length in enumerate(blocks):
        t[start : start + length, k] = 1.0
        start += length
    return t


def condense(
    model: PredictionModel,
    weights: tuple[float, float, float],
    horizon: int,
    n_rises: int,
    blocks: tuple[int, ...] | None = None,
) -> CondensedQP:
    """The condensed QP for ``weights = (q_stroke, q_gap, r_force)`` over ``horizon``
    intervals, with ``n_rises >= horizon`` guideway rises read (0: no preview; the rises beyond
    the horizon enter the terminal cost)."""
    n, big_n = model.size, int(horizon)
    q, s, r, p, k = lq_terms(model, *weights)
    nr = max(int(n_rises), big_n)
    # stacked prediction z_j = Phi_j z0 + Gam_j U + Psi_j D, j = 0..N
    phi = np.zeros((big_n + 1, n, n))
    gam = np.zeros((big_n + 1, n, big_n))
    psi = np.zeros((big_n + 1, n, nr))
    phi[0] = np.eye(n)
    for j in range(big_n):
        phi[j + 1] = model.a @ phi[j]
        gam[j + 1] = model.a @ gam[j]
        gam[j + 1][:, j] += model.b
        psi[j + 1] = model.a @ psi[j]
        psi[j + 1][:, j] += model.e
    # terminal linear term from the rises beyond the horizon: b_N = sum (A_c')^(m+1) P E d
    a_closed_t = (model.a - np.outer(model.b, k)).T
    tail = np.zeros((n, nr))
    column = a_closed_t @ (p @ model.e)
    for m in range(big_n, nr):
        tail[:, m] = column
        column = a_closed_t @ column
    h = np.zeros((big_n, big_n))
    f_z, f_d = np.zeros((big_n, n)), np.zeros((big_n, nr))
    for j in range(big_n):  # stage j: z_j' Q z_j + 2 z_j' s u_j + r u_j^2
        gq = gam[j].T @ q
        h += gq @ gam[j]
        h += np.outer(gam[j].T @ s, np.eye(big_n)[j]) + np.outer(np.eye(big_n)[j], gam[j].T @ s)
        h[j, j] += r
        f_z += gq @ phi[j] + np.outer(np.eye(big_n)[j], s @ phi[j])
        f_d += gq @ psi[j] + np.outer(np.eye(big_n)[j], s @ psi[j])
    gp = gam[big_n].T @ p
    h += gp @ gam[big_n]
    f_z += gp @ phi[big_n]
    f_d += gp @ psi[big_n] + gam[big_n].T @ tail
    t = blocking_matrix(big_n, blocks)
    rate, stroke = model.rate_row(), np.eye(n)[0]
    return CondensedQP(
        h=2.0 * t.T @ h @ t, f_z=2.0 * t.T @ f_z, f_d=2.0 * t.T @ f_d, blocking=t,
        rate_z=np.einsum("i,jik->jk", rate, phi[:big_n]),
        rate_w=np.einsum("i,jik->jk", rate, gam[:big_n]) @ t,
        rate_d=np.einsum("i,jik->jk", rate, psi[:big_n]),
        stroke_z=np.einsum("i,jik->jk", stroke, phi[:big_n]),
        stroke_w=np.einsum("i,jik->jk", stroke, gam[:big_n]) @ t,
        stroke_d=np.einsum("i,jik->jk", stroke, psi[:big_n]),
        lq_gain=k, lq_rise_gain=_lq_rise_gain(model, p, k, r, s, nr),
    )  # fmt: skip


def _lq_rise_gain(
    model: PredictionModel, p: np.ndarray, k: np.ndarray, r: float, s: np.ndarray, nr: int
) -> np.ndarray:
    """Tomizuka's preview gain ``K_d[j] = g B' (A_c')^j P E`` (g = 1 / (r + B'PB))."""
    g = 1.0 / (r + model.b @ p @ model.b)
    a_closed_t = (model.a - np.outer(model.b, k)).T
    out, column = np.empty(nr), p @ model.e
    for j in range(nr):
        out[j] = g * (model.b @ column)
        column = a_closed_t @ column
    return out


_EDGES: dict[int, Any] = {}


def _edges(code: int, *args: Any) -> None:
    """The band edges of the model ``code`` (see :func:`band_edges`), by a kernel compiled
    once per model with the code as a compile-time constant (the damper registry dispatches on
    it; ``numba.literally`` would re-type every call)."""
    kernel = _EDGES.get(code)
    if kernel is None:
        kernel = _edges_kernel(int(code))
        with warnings.catch_warnings():  # numba's internal pedantic SSA check, not ours
            warnings.simplefilter("ignore", NumbaIRAssumptionWarning)
            kernel(*args)  # compiles
        _EDGES[code] = kernel
        return
    kernel(*args)


def _edges_kernel(code: int) -> Any:
    @njit
    def edges(p, i_max, stroke_m, rate_m_s, step_m_s, out):  # type: ignore[no-untyped-def]
        for j in range(rate_m_s.shape[0]):
            x, v = stroke_m[j], rate_m_s[j]
            sign = 1.0 if v >= 0.0 else -1.0
            f0, slope = affine_in_current(code, p, x, v, 0.0)
            f0b, slopeb = affine_in_current(code, p, x, v + sign * step_m_s, 0.0)
            lo, hi = f0, f0 + slope * i_max
            lob, hib = f0b, f0b + slopeb * i_max
            out[0, j], out[1, j] = lo, hi
            out[2, j] = (lob - lo) / (sign * step_m_s)
            out[3, j] = (hib - hi) / (sign * step_m_s)

    return edges


def band_edges(
    damper: Any, stroke_m: np.ndarray, rate_m_s: np.ndarray, secant_m_s: float = 1e-4
) -> np.ndarray:
    """``(4, N)``: the force at 0 A and at ``i_max`` of the inverted model at each stroke and
    stroke rate, and their slopes in the rate (N s/m): the secant to the rate ``secant_m_s``
    further from 0 (the side of the rate's sign; 1e-4 m/s: the tangent)."""
    out = np.empty((4, len(rate_m_s)))
    _edges(damper.code, damper.as_array(), float(damper.max_current_a),
           np.ascontiguousarray(stroke_m, dtype=float),
           np.ascontiguousarray(rate_m_s, dtype=float), float(secant_m_s), out)  # fmt: skip
    return out
