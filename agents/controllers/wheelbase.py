"""Wheelbase preview: the rear bogie meets, ``tau = (a + b) / v`` later, the guideway the front
bogie has just measured (89 ms at 810 km/h), so a law for both dampers can preview the rear's
input from the front's signals (Tomizuka's discrete preview LQ on the half-car).

The plant: the half-car's relative form (:func:`capsule_env.vehicles.relative_model`), sampled
at ``dt`` with a zero-order hold on the forces and on each contact's guideway velocity; the
disturbances ``d_f(k)``, ``d_r(k)``: each contact's guideway rise over interval ``k``. The rear's
is the front's, ``tau`` earlier: ``d_r(k) = (1 - f) d_f(k - D) + f d_f(k - D - 1)`` with ``tau /
dt = D + f``. The window ``p_k = [d_f(k - D - 1), ..., d_f(k - 1)]`` of the front's past rises
is known at step ``k``; the front's own future rises are unknown, zero-mean. With the requests
in flight (the control delay), the augmented state ``z = [x; in flight; p]`` is linear and the
optimal law ``F = -K z`` comes from one discrete algebraic Riccati equation
(:func:`scipy.linalg.solve_discrete_are`), with the clipped LQR's weights: the comfort points'
accelerations squared, ``q_stroke`` on each slot's stroke, ``q_gap`` on each levitation gap,
``r_force`` on each force (per interval, as the quarter-car's preview LQ).

The front's rises are estimated from its measured signals: ``z_g = z_b - gap``, so ``d_f(k - 1)
= (v_b(k - 1) + v_b(k)) dt / 2 - (gap(k) - gap(k - 1))`` with ``v_b`` the bogie's on-board
velocity estimate and ``gap`` the levitation gap sensor. Signals read: the half-car task's
``measured`` observation (nothing else: no survey map).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from capsule_env.agents.controllers.base import Controller, restarted_vehicles
from capsule_env.agents.controllers.declared_lqr import DeclaredClippedLQR
from capsule_env.agents.controllers.lqr import state_weights
from capsule_env.agents.controllers.preview_lq import preview_rises
from scipy.linalg import expm, solve_discrete_are

from capsule_env.common.units import kmh_to_m_s
from capsule_env.vehicles import model_named, relative_model

__all__ = [
    "WheelbaseGains",
    "wheelbase_gains",
    "survey_preview_gains",
    "WheelbasePreviewLQ",
    "WheelbaseExactPreviewLQ",
    "SurveyPreviewLQ",
]

#: Measured columns per slot (``capsule_env.engine.declared_batch``): stroke, rate, the two
#: accelerations, the gap, the two velocity estimates, the last command.
_PER_SLOT, _GAP, _LOWER_VELOCITY = 8, 4, 6


class WheelbaseGains:
    """``F = -K_x x - K_u u_in_flight - K_p p`` (forces per slot)."""

    def __init__(self, k_x: np.ndarray, k_u: np.ndarray, k_p: np.ndarray, frac: float):
        self.k_x, self.k_u, self.k_p, self.frac = k_x, k_u, k_p, frac


def _sampled(model: Any, params: Any, dt_s: float) -> tuple[np.ndarray, ...]:
    """``(A, B, E, C, D)``: ``x_{k+1} = A x + B F + E d`` (``d``: each contact's rise over the
    interval), comfort accelerations ``C x + D F``."""
    plant = relative_model(model, params)
    n, m, g = plant.a.shape[0], plant.b.shape[1], plant.e_rate.shape[1]
    big = np.zeros((n + m + g, n + m + g))
    big[:n, :n], big[:n, n : n + m], big[:n, n + m :] = plant.a, plant.b, plant.e_rate
    phi = expm(big * dt_s)
    return phi[:n, :n], phi[:n, n : n + m], phi[:n, n + m :] / dt_s, plant.c_acc, plant.d_acc


def wheelbase_gains(
    vehicle: str, dt_s: float, speed_m_s: float, q_stroke: float, q_gap: float, r_force: float,
    delay_steps: int = 1, preview: bool = True, vehicle_params: dict | None = None,
) -> WheelbaseGains:  # fmt: skip
    """The optimal gains (module doc); ``preview=False``: the same design without the window
    (the discrete LQR the preview adds to)."""
    return _design(vehicle, dt_s, speed_m_s, q_stroke, q_gap, r_force, delay_steps, preview,
                   vehicle_params)[0]  # fmt: skip


def survey_preview_gains(
    vehicle: str, dt_s: float, q_stroke: float, q_gap: float, r_force: float, n_preview: int,
    delay_steps: int = 1, vehicle_params: dict | None = None,
) -> tuple[WheelbaseGains, np.ndarray]:  # fmt: skip
    """The survey-preview LQ's gains (:class:`SurveyPreviewLQ`): the discrete LQR without the
    wheelbase window and each contact's gains on its next ``n_preview`` rises, ``(contacts,
    slots, n_preview)`` (N per m of rise)."""
    if int(n_preview) < 1:
        raise ValueError(f"n_preview must be >= 1, got {n_preview!r}")
    return _design(vehicle, dt_s, 1.0, q_stroke, q_gap, r_force, delay_steps, False,
                   vehicle_params, int(n_preview))  # fmt: skip


def _design(
    vehicle: str, dt_s: float, speed_m_s: float, q_stroke: float, q_gap: float, r_force: float,
    delay_steps: int, preview: bool, vehicle_params: dict | None, survey_steps: int = 0,
) -> tuple[WheelbaseGains, np.ndarray]:  # fmt: skip
    """The gains and, for the survey's preview, each contact's preview gains ``(contacts, m,
    j)`` by Tomizuka's product ``K_c[j] = G B' (A_c')^j P E_c`` (``G = (R + B' P B)^-1``,
    ``A_c = A - B K``: :func:`capsule_env.agents.controllers.preview_lq.preview_lq_gains`'s,
    one input per slot), ``j < survey_steps``."""
    model = model_named(vehicle)
    params = model.params(**(vehicle_params or {}))
    offsets = model.contact_offsets_m(params)
    if len(offsets) != 2 or len(model.dampers) != 2:
        raise ValueError(f"vehicle {vehicle!r}: wheelbase preview needs two contacts and two slots")
    a, b, e, c, d = _sampled(model, params, dt_s)
    n, m = a.shape[0], b.shape[1]
    delay = (offsets[0] - offsets[1]) / speed_m_s / dt_s
    whole, frac = int(np.floor(delay)), float(delay - np.floor(delay))
    w = whole + 1 if preview else 0  # the window's length
    nd = int(delay_steps)
    size = n + m * nd + w
    big_a, big_b = np.zeros((size, size)), np.zeros((size, m))
    big_a[:n, :n] = a
    if nd:  # the oldest requests in flight act now; the new ones enter the line
        big_a[:n, n + m * (nd - 1) : n + m * nd] = b
        big_a[n + m : n + m * nd, n : n + m * (nd - 1)] = np.eye(m * (nd - 1))
        big_b[n : n + m] = np.eye(m)
    else:
        big_b[:n] = b
    if w:  # p = [d_f(k-D-1) .. d_f(k-1)]: the rear's rise now, then the shift
        big_a[:n, n + m * nd] += e[:, 1] * frac
        big_a[:n, n + m * nd + 1] += e[:, 1] * (1.0 - frac)
        big_a[n + m * nd : size - 1, n + m * nd + 1 : size] = np.eye(w - 1)
    c_big = np.zeros((c.shape[0], size))
    c_big[:, :n] = c
    d_big = d.copy()
    if nd:
        c_big[:, n + m * (nd - 1) : n + m * nd] = d
        d_big = 0.0 * d
    q = c_big.T @ c_big
    q[:n, :n] += state_weights(model, relative_model(model, params), q_stroke, q_gap)
    r = d_big.T @ d_big + r_force * np.eye(m)
    s = c_big.T @ d_big
    p = solve_discrete_are(big_a, big_b, q, r, s=s)
    g = np.linalg.inv(r + big_b.T @ p @ big_b)
    k = g @ (big_b.T @ p @ big_a + s.T)
    gains = WheelbaseGains(k[:, :n], k[:, n : n + m * nd], k[:, n + m * nd :], frac)
    # each contact's rise enters the plant as E d; the window's rises reach it through the
    # closed loop (module doc of preview_lq): the columns of (A_c')^j P E, one product a step
    column = p[:, :n] @ e  # (size, contacts)
    a_closed_t = (big_a - big_b @ k).T
    return gains, _products(g @ big_b.T, a_closed_t, column, survey_steps)


def _products(gb: np.ndarray, a_closed_t: np.ndarray, column: np.ndarray, steps: int) -> np.ndarray:
    """``gb (A_c')^j column`` for ``j = 0 .. steps - 1``: ``(contacts, m, steps)``."""
    out = np.empty((column.shape[1], gb.shape[0], steps))
    for j in range(steps):
        out[:, :, j] = (gb @ column).T
        column = a_closed_t @ column
    return out


class WheelbasePreviewLQ(Controller):
    """Wheelbase-preview LQ of the half-car on its measured signals (module doc), through the
    Bi-exponential inverse. Weights default to the coupled clipped LQR's tuned ones."""

    def __init__(
        self, q_stroke: float, q_levitation: float, r_force: float, vehicle: str = "half_car",
        dt_s: float = 0.005, speed_kmh: float = 810.0, delay_steps: int = 1,
        max_force_n: float = 8000.0, preview: bool = True,
    ) -> None:  # fmt: skip
        self.name = "wheelbase-lq-biexp-meas" if preview else "lq-discrete-biexp-meas"
        self.state_law = DeclaredClippedLQR(vehicle, None, q_stroke, q_levitation, r_force,
                                            observation="measured")  # fmt: skip
        self.gains_ = wheelbase_gains(vehicle, dt_s, kmh_to_m_s(speed_kmh), q_stroke, q_levitation,
                                      r_force, delay_steps, preview)  # fmt: skip
        self.dt_s, self.max_force_n = float(dt_s), float(max_force_n)
        self.delay_steps = int(delay_steps)
        self.env_kwargs = {"vehicle": vehicle, "action_mode": "force", "observation": "measured",
                           "inverse_model": "bi_exponential", "max_force_n": self.max_force_n}  # fmt: skip
        self._memory: dict[str, np.ndarray] = {}

    def reset(self) -> None:
        self._memory = {}

    def predict(  # type: ignore[no-untyped-def]  # Controller.predict's signature
        self, observation, state=None, episode_start=None, deterministic=True
    ):
        """As :meth:`Controller.predict`; a vehicle whose ``episode_start`` is set starts as
        under a fresh law (its memories: the rise estimate's last sample, the window, the
        requests in flight), the others untouched."""
        if episode_start is not None:
            vehicles = restarted_vehicles(episode_start, observation)
            obs = np.atleast_2d(np.asarray(observation, dtype=np.float64))
            in_flight = self._memory.get("in_flight")
            if vehicles and in_flight is not None and in_flight.shape[0] == obs.shape[0]:
                self._restart(obs, vehicles)  # (another batch: the next step sets all afresh)
        return super().predict(observation, state, episode_start, deterministic)

    def _restart(self, obs: np.ndarray, vehicles: list[int]) -> None:
        """``vehicles``' memories as a fresh law's after its first step's ``obs``: the rise
        estimate's last sample that observation's (no rise read across the restart), the
        rest zero."""
        sampled = self._sampled_columns()
        for key, memory in self._memory.items():
            memory[vehicles] = obs[vehicles, sampled[key]] if key in sampled else 0.0

    def _sampled_columns(self) -> dict[str, int]:
        """The memories holding the last step's observation, and their columns."""
        return {"gap": _GAP, "v_b": _LOWER_VELOCITY}

    def gains(self) -> dict[str, Any]:
        g = self.gains_
        return {"k_x": g.k_x.tolist(), "k_u": g.k_u.tolist(), "k_p": g.k_p.tolist()}

    def _estimate_rise(self, obs: np.ndarray) -> np.ndarray:
        """The front guideway's rise over the last interval (module doc), per vehicle."""
        gap, v_b = obs[:, _GAP], obs[:, _LOWER_VELOCITY]
        mem = self._memory
        if "gap" not in mem or mem["gap"].shape != gap.shape:
            mem.update(gap=gap.copy(), v_b=v_b.copy(), window=np.zeros((len(gap), self.gains_.k_p.shape[1])),
                       in_flight=np.zeros((len(gap), self.gains_.k_u.shape[1])))  # fmt: skip
        rise = 0.5 * (mem["v_b"] + v_b) * self.dt_s - (gap - mem["gap"])
        mem["gap"], mem["v_b"] = gap.copy(), v_b.copy()
        return rise

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        rise = self._estimate_rise(obs)
        mem, g = self._memory, self.gains_
        if g.k_p.shape[1]:
            mem["window"][:, :-1] = mem["window"][:, 1:]
            mem["window"][:, -1] = rise
        x = self.state_law.relative_state(obs)
        force = -(x @ g.k_x.T + mem["in_flight"] @ g.k_u.T + mem["window"] @ g.k_p.T)
        return self._push(force)

    def _push(self, force: np.ndarray) -> np.ndarray:
        """Remember the requests ``force`` (N, slots) in flight; the action asking for them."""
        in_flight, m = self._memory["in_flight"], force.shape[1]
        if in_flight.shape[1]:  # newest first: the line shifts by one slot set
            in_flight[:, m:] = in_flight[:, :-m]
            in_flight[:, :m] = force
        return np.clip(force / self.max_force_n, -1.0, 1.0)


class WheelbaseExactPreviewLQ(WheelbasePreviewLQ):
    """The same law on the ``full_state`` observation: the true relative state and the front
    contact's true guideway (its rises exact). It reads signals a capsule does not measure:
    the reference for what the estimate of the front's guideway loses."""

    def __init__(self, q_stroke: float, q_levitation: float, r_force: float, **kwargs: Any):
        super().__init__(q_stroke, q_levitation, r_force, **kwargs)
        self.name = self.name.replace("-meas", "-exact")
        vehicle = self.env_kwargs["vehicle"]
        self.state_law = DeclaredClippedLQR(vehicle, None, q_stroke, q_levitation, r_force)
        self.env_kwargs = dict(self.env_kwargs, observation="full_state")
        self._front_column = int(self.state_law._zg_cols[0])

    def _sampled_columns(self) -> dict[str, int]:
        return {"z": self._front_column}

    def _estimate_rise(self, obs: np.ndarray) -> np.ndarray:
        z_front = obs[:, self._front_column]
        mem = self._memory
        if "z" not in mem or mem["z"].shape != z_front.shape:
            mem.update(z=z_front.copy(), window=np.zeros((len(z_front), self.gains_.k_p.shape[1])),
                       in_flight=np.zeros((len(z_front), self.gains_.k_u.shape[1])))  # fmt: skip
        rise = z_front - mem["z"]
        mem["z"] = z_front.copy()
        return rise


class SurveyPreviewLQ(WheelbasePreviewLQ):
    """Tomizuka's preview LQ of the half-car on the survey (``CapsuleHalfRidePreview-v0``): the
    discrete LQR of :func:`wheelbase_gains` without the wheelbase window, plus, for each bogie,
    the gains on its own guideway's rises over the next ``preview_horizon_s`` (read from its
    ``preview_points`` surveyed elevations, linear between them:
    :func:`capsule_env.agents.controllers.preview_lq.preview_rises`, folded into one weight
    per preview column). The rear's preview is its own (it starts at the rear bogie), so the
    wheelbase window adds nothing the survey has not. Reads the ``measured`` set and the preview;
    through the Bi-exponential inverse."""

    def __init__(
        self, q_stroke: float, q_levitation: float, r_force: float,
        preview_points: int = 32, preview_horizon_s: float = 0.5, **kwargs: Any,
    ) -> None:  # fmt: skip
        super().__init__(q_stroke, q_levitation, r_force, preview=False, **kwargs)
        self.name = "survey-preview-lq-biexp-meas"
        self.points, self.horizon_s = int(preview_points), float(preview_horizon_s)
        n_preview = max(1, int(round(self.horizon_s / self.dt_s)))
        self.gains_, k_c = survey_preview_gains(self.env_kwargs["vehicle"], self.dt_s, q_stroke,
                                                q_levitation, r_force, n_preview,
                                                self.delay_steps)  # fmt: skip
        rises = preview_rises(np.eye(self.points), self.horizon_s / self.points, self.dt_s,
                              n_preview)  # (points, n_preview)  # fmt: skip
        self.preview_weight = k_c @ rises.T  # (contacts, slots, points)
        self.env_kwargs = dict(self.env_kwargs, preview_points=self.points,
                               preview_horizon_s=self.horizon_s)  # fmt: skip

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        n, (contacts, _, points) = obs.shape[0], self.preview_weight.shape
        mem, g = self._memory, self.gains_
        if "in_flight" not in mem or mem["in_flight"].shape[0] != n:
            mem["in_flight"] = np.zeros((n, g.k_u.shape[1]))
        ahead = obs[:, obs.shape[1] - contacts * points :].reshape(n, contacts, points)
        feedforward = np.einsum("ncp,csp->ns", ahead, self.preview_weight)
        x = self.state_law.relative_state(obs)
        return self._push(-(x @ g.k_x.T + mem["in_flight"] @ g.k_u.T + feedforward))
