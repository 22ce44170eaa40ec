"""LQ optimal preview control (Tomizuka 1976; the standard discrete preview LQR) of the linear
2-DOF plant, for the semi-active damper through an inverse model.

The plant, sampled at the control interval ``dt`` (zero-order hold on the force and on the
guideway's vertical velocity over each interval):

- state ``x = [z_c - z_b, z_c', z_b - z_g, z_b']`` (stroke, body velocity, levitation gap,
  bogie velocity; the measured set gives each: LVDT, estimate, gap sensor, estimate);
- input ``F`` (N), the damper force (``m_c z_c'' = -k_s (z_c - z_b) - F``);
- disturbance ``d_k = z_g(k + 1) - z_g(k)`` (m), the guideway's rise over interval ``k``.

The preview is the next ``n_preview`` rises ``p_k = [d_k, ..., d_{k + n_preview - 1}]``, read
from the surveyed elevations ahead; the rises beyond it are unknown, zero-mean. A control
``delay_steps`` (the HILS one-step delay) applies the force requested ``delay_steps`` intervals
earlier: the requests still in flight are states too. The cost per interval is

    a_c^2 + q_stroke (z_c - z_b)^2 + q_gap (z_b - z_g)^2 + r_force F^2,

``a_c = (-k_s (z_c - z_b) - F) / m_c`` (the cross term kept), the continuous-time weights of the
clipped LQR (:mod:`capsule_env.agents.controllers.lqr`). The optimal law on the augmented state ``[x; in flight; p]`` is
linear, from the discrete algebraic Riccati equation of the plant and the requests in flight
(:func:`scipy.linalg.solve_discrete_are`) and, for the preview, a product per point ahead:

    F_k = -K_x x_k - K_u [F_{k-1}, ..., F_{k-delay}] - K_p p_k.

With the disturbance unknown beyond the window this is the exact optimum in expectation, and for
a guideway that is level beyond the window it is the deterministic optimum: the tests check the
gain against a brute-force solution of the finite-horizon problem. The semi-active damper then
produces as much of ``F`` as it can (the env's inverse model clips the request to the
dissipative band).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from capsule_env.agents.controllers.skyhook import DEFAULT_MAX_FORCE_N, ForceLaw
from scipy.linalg import expm, solve_discrete_are

from capsule_env.vehicles import VehicleParams, model_of_params, relative_model

__all__ = [
    "PreviewGains",
    "PreviewLQController",
    "plant_matrices",
    "preview_lq_gains",
    "preview_rises",
]


class PreviewGains(NamedTuple):
    """``F = -state @ state_gain - in_flight @ delay_gain - rises @ preview_gain``."""

    state_gain: (
        np.ndarray
    )  # (4,) on [stroke (m), body velocity (m/s), gap (m), bogie velocity (m/s)]
    delay_gain: np.ndarray  # (delay_steps,) on the requests in flight, newest first (N)
    preview_gain: np.ndarray  # (n_preview,) on the guideway rises ahead, nearest first (m)


def plant_matrices(
    vehicle: VehicleParams, dt_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """``(A, B, E, C, D)``: the plant sampled with a zero-order hold at ``dt_s``,
    ``x_{k+1} = A x_k + B F_k + E d_k``, and the body acceleration ``a_c = C x + D F``."""
    plant = relative_model(model_of_params(vehicle), vehicle)
    a, b, e = plant.a, plant.b[:, 0], plant.e_rate[:, 0]  # e: the gap falls as the guideway rises
    # zero-order hold of [F, z_g'] by the matrix exponential of the augmented system
    m = np.zeros((6, 6))
    m[:4, :4], m[:4, 4], m[:4, 5] = a, b, e
    phi = expm(m * dt_s)
    # a rise d_k over the interval is the velocity d_k / dt held over it
    return phi[:4, :4], phi[:4, 4], phi[:4, 5] / dt_s, plant.c_acc[0], plant.d_acc[0, 0]


def preview_lq_gains(
    vehicle: VehicleParams,
    dt_s: float,
    n_preview: int,
    q_stroke: float,
    q_gap: float,
    r_force: float,
    delay_steps: int = 0,
) -> PreviewGains:
    """The optimal preview gains (see the module docstring) for weights ``q_stroke``, ``q_gap``
    (1/s^4) and ``r_force`` (1/kg^2), ``n_preview`` rises ahead (0: plain discrete LQR) and
    ``delay_steps`` intervals of control delay."""
    if n_preview < 0 or delay_steps < 0:
        raise ValueError("n_preview and delay_steps must be >= 0")
    if q_stroke < 0 or q_gap < 0 or r_force <= 0:
        raise ValueError("q_stroke and q_gap must be >= 0 and r_force > 0")
    a, b, e, c, d = plant_matrices(vehicle, dt_s)
    nd, npv = int(delay_steps), int(n_preview)
    # the plant and the requests in flight: x = [plant (4); in flight, newest first (nd)]
    size = 4 + nd
    big_a = np.zeros((size, size))
    big_b, big_e = np.zeros(size), np.zeros(size)
    big_a[:4, :4], big_e[:4] = a, e
    if nd:  # the oldest request in flight acts now; the new one enters the line
        big_a[:4, size - 1] = b
        big_a[5:size, 4 : size - 1] = np.eye(nd - 1)
        big_b[4] = 1.0
    else:
        big_b[:4] = b
    # cost: (C x + D F_applied)^2 + q_s s^2 + q_g g^2 + r F_k^2 (F_applied is F_k without delay)
    c_big = np.zeros(size)
    c_big[:4] = c
    d_big = d
    if nd:  # the force acting now is a state (the oldest in flight)
        c_big[size - 1] = d
        d_big = 0.0
    q = np.outer(c_big, c_big)
    q[0, 0] += q_stroke
    q[2, 2] += q_gap
    r = d_big * d_big + r_force
    s = c_big * d_big
    p = solve_discrete_are(big_a, big_b[:, None], q, np.array([[r]]), s=s[:, None])
    g = 1.0 / (r + big_b @ p @ big_b)  # one input: a scalar
    k = g * (big_b @ p @ big_a + s)
    # The preview window p_k = [d_k .. d_{k+N-1}] shifts by one each interval and d_k enters
    # as E d_k. The augmented Riccati equation's cross block then gives (Tomizuka's form)
    # K_p[j] = g B' (A_c')^j P E with A_c = A - B K, the closed loop: one product per point.
    a_closed_t = (big_a - np.outer(big_b, k)).T
    column = p @ big_e
    preview = np.empty(npv)
    for j in range(npv):
        preview[j] = g * (big_b @ column)
        column = a_closed_t @ column
    return PreviewGains(k[:4].copy(), k[4:].copy(), preview)


def preview_rises(
    preview_m: np.ndarray, preview_step_s: float, dt_s: float, n_preview: int
) -> np.ndarray:
    """The guideway rises over the next ``n_preview`` control intervals, ``(N, n_preview)``,
    from preview columns ``(N, P)``: the surveyed elevation ``(j + 1) preview_step_s`` ahead of
    the bogie relative to the one under it (the env's preview observation), linear between
    points, the last point held beyond the window."""
    preview_m = np.atleast_2d(np.asarray(preview_m, dtype=float))
    n, points = preview_m.shape
    ahead_s = preview_step_s * np.arange(points + 1)
    elevation = np.concatenate([np.zeros((n, 1)), preview_m], axis=1)
    times = dt_s * np.arange(n_preview + 1)
    # linear interpolation of every row at the same times (np.interp is one row at a time)
    j = np.clip(np.searchsorted(ahead_s, times, side="right") - 1, 0, points - 1)
    f = np.clip((times - ahead_s[j]) / preview_step_s, 0.0, 1.0)
    at = elevation[:, j] * (1.0 - f) + elevation[:, j + 1] * f
    return np.diff(at, axis=1)


#: The preview the preview laws read [reconstructed: the window where the optimal preview gain
#: has most of its weight; with the default weights 63 % lies within 0.5 s, 87 % within 1 s].
DEFAULT_PREVIEW_POINTS = 32
DEFAULT_PREVIEW_HORIZON_S = 1.0


class PreviewLQController(ForceLaw):
    """LQ optimal preview control, clipped to the semi-active band through an inverse model.

    Reads the four states of :func:`preview_lq_gains` (measured: the LVDT stroke, the on-board
    velocity estimates, the gap sensor; ``full_state``: the true ones) and the guideway preview
    (the env's ``preview_points`` surveyed elevations over ``preview_horizon_s``, turned into
    the rises of the next ``preview_horizon_s / dt_s`` intervals), and remembers its own last
    ``delay_steps`` requests (the HILS one-step delay). Force mode.

    Parameters
    ----------
    inverse_model : ``"bi_exponential"``, ``"csdc"`` or ``"tanh"``.
    q_stroke, q_levitation (1/s^4), r_force (1/kg^2) : cost weights (scalars or one per
        vehicle); None: the tuned values, else those of the clipped LQR's fallback.
    preview_points, preview_horizon_s : the preview the env is asked for.
    delay_steps : control delay the law plans for (the ``hils`` setting's 1).
    dt_s : the control interval (the env's default 200 Hz).
    """

    SIGNALS = ("stroke", "body_velocity", "gap", "bogie_velocity")
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
        observation: str = "measured",
        preview_points: int = DEFAULT_PREVIEW_POINTS,
        preview_horizon_s: float = DEFAULT_PREVIEW_HORIZON_S,
        delay_steps: int = 1,
        dt_s: float = 0.005,
    ) -> None:
        super().__init__("preview-lq", inverse_model, max_force_n, observation)
        if int(preview_points) < 1:
            raise ValueError(f"preview_points must be >= 1, got {preview_points!r}")
        if not (1e-3 <= float(preview_horizon_s) <= 10.0):  # the env's range
            raise ValueError(
                f"preview_horizon_s must be in [0.001, 10] s, got {preview_horizon_s!r}"
            )
        if not float(dt_s) > 0.0 or int(delay_steps) < 0:
            raise ValueError(
                f"dt_s must be > 0 and delay_steps >= 0, got {dt_s!r}, {delay_steps!r}"
            )
        self.env_kwargs = {**self.env_kwargs, "preview_points": int(preview_points),
                           "preview_horizon_s": float(preview_horizon_s)}  # fmt: skip
        self.preview_points, self.preview_horizon_s = int(preview_points), float(preview_horizon_s)
        self.delay_steps, self.dt_s = int(delay_steps), float(dt_s)
        self.n_preview = max(1, int(round(self.preview_horizon_s / self.dt_s)))
        self._set_gains(
            {"q_stroke": "1_s4", "q_levitation": "1_s4", "r_force": "1_kg2"},
            {"q_stroke": q_stroke, "q_levitation": q_levitation, "r_force": r_force},
            {"q_stroke": 1.0e3, "q_levitation": 1.0e3, "r_force": 1.0e-9},
        )
        weights = np.broadcast_arrays(self.q_stroke, self.q_levitation, self.r_force)
        vehicle = vehicle or VehicleParams()
        cache: dict[tuple[float, float, float], PreviewGains] = {}
        rows = []
        for q_s, q_g, r_f in zip(*(w.ravel().tolist() for w in weights)):
            triple = (q_s, q_g, r_f)
            if triple not in cache:
                cache[triple] = preview_lq_gains(vehicle, self.dt_s, self.n_preview, q_s, q_g,
                                                 r_f, delay_steps=self.delay_steps)  # fmt: skip
            rows.append(cache[triple])
        shape = weights[0].shape
        self.state_gain = np.array([g.state_gain for g in rows]).reshape(*shape, 4)
        self.delay_gain = np.array([g.delay_gain for g in rows]).reshape(*shape, self.delay_steps)
        self.preview_gain = np.array([g.preview_gain for g in rows]).reshape(*shape, -1)
        # The rises are linear in the preview columns: fold the interpolation into the gain,
        # one weight per preview column (computed once, not every step).
        step = self.preview_horizon_s / self.preview_points
        rise_matrix = preview_rises(np.eye(self.preview_points), step, self.dt_s, self.n_preview)
        self.preview_weight = self.preview_gain @ rise_matrix.T  # (..., preview_points)
        self._in_flight: np.ndarray | None = None  # (N, delay_steps) N, newest first

    @property
    def signals_read(self) -> tuple[str, ...]:
        ahead = tuple(f"preview_ahead_{k}" for k in range(1, self.preview_points + 1))
        return (*super().signals_read, *ahead)

    def reset(self) -> None:
        self._in_flight = None

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """As :meth:`Controller.predict`; a vehicle whose ``episode_start`` is set forgets its
        requests in flight."""
        if episode_start is not None and self._in_flight is not None:
            self._in_flight[np.asarray(episode_start, dtype=bool)] = 0.0
        return super().predict(observation, state, episode_start, deterministic)

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        n = obs.shape[0]
        if self._in_flight is None or self._in_flight.shape[0] != n:
            self._in_flight = np.zeros((n, self.delay_steps))
        x = np.stack([self.signal(obs, s) for s in self.SIGNALS], axis=1)
        force = -(
            np.sum(x * self.state_gain, axis=-1)
            + np.sum(self._in_flight * self.delay_gain, axis=-1)
            + np.sum(obs[:, -self.preview_points :] * self.preview_weight, axis=-1)
        )
        requested = np.clip(force, -self.max_force_n, self.max_force_n)  # what the env takes
        if self.delay_steps:
            self._in_flight = np.concatenate([requested[:, None], self._in_flight[:, :-1]], axis=1)
        return force

    def gains(self) -> dict:
        out = super().gains()
        out.update({"preview_horizon_s": self.preview_horizon_s,
                    "preview_spacing_s": self.preview_horizon_s / self.preview_points,
                    "planned_delay_s": self.delay_steps * self.dt_s})  # fmt: skip
        return out
