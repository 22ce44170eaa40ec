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
clipped LQR (:mod:`agents.lqr`). The optimal law on the augmented state ``[x; in flight; p]`` is
linear, from one discrete algebraic Riccati equation (:func:`scipy.linalg.solve_discrete_are`):

    F_k = -K_x x_k - K_u [F_{k-1}, ..., F_{k-delay}] - K_p p_k.

With the disturbance unknown beyond the window this is the exact optimum in expectation, and for
a guideway that is level beyond the window it is the deterministic optimum: the tests check the
gain against a brute-force solution of the finite-horizon problem. The semi-active damper then
produces as much of ``F`` as it can (the env's inverse model clips the request to the
dissipative band).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from capsule_env.vehicle import VehicleParams

__all__ = ["PreviewGains", "plant_matrices", "preview_lq_gains", "preview_rises"]


class PreviewGains(NamedTuple):
    """``F = -state @ state_gain - in_flight @ delay_gain - rises @ preview_gain``."""

    state_gain: (
        np.ndarray
    )  # (4,) on [stroke (m), body velocity (m/s), gap (m), bogie velocity (m/s)]
    delay_gain: np.ndarray  # (delay_steps,) on the requests in flight, newest first (N)
    preview_gain: np.ndarray  # (n_preview,) on the guideway rises ahead, nearest first (m)


def plant_matrices(
    vehicle: VehicleParams, dt_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, E, C, D)``: the plant sampled with a zero-order hold at ``dt_s``,
    ``x_{k+1} = A x_k + B F_k + E d_k``, and the body acceleration ``a_c = C x + D F``."""
    mc, mb = vehicle.car_body_mass_kg, vehicle.bogie_mass_kg
    ks, kp = vehicle.secondary_stiffness_n_per_m, vehicle.levitation_stiffness_n_per_m
    a = np.array(
        [
            [0.0, 1.0, 0.0, -1.0],
            [-ks / mc, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [ks / mb, 0.0, -kp / mb, 0.0],
        ]
    )
    b = np.array([0.0, -1.0 / mc, 0.0, 1.0 / mb])
    e = np.array([0.0, 0.0, -1.0, 0.0])  # the gap falls as the guideway rises (velocity input)
    # zero-order hold of [F, z_g'] by the matrix exponential of the augmented system
    m = np.zeros((6, 6))
    m[:4, :4], m[:4, 4], m[:4, 5] = a, b, e
    phi = expm(m * dt_s)
    # a rise d_k over the interval is the velocity d_k / dt held over it
    return phi[:4, :4], phi[:4, 4], phi[:4, 5] / dt_s, np.array([-ks / mc, 0, 0, 0]), -1.0 / mc


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
    size = 4 + nd + npv
    big_a = np.zeros((size, size))
    big_b = np.zeros(size)
    big_a[:4, :4] = a
    if nd:  # the oldest request in flight acts now; the new one enters the line
        big_a[:4, 4 + nd - 1] = b
        big_a[5 : 4 + nd, 4 : 4 + nd - 1] = np.eye(nd - 1)
        big_b[4] = 1.0
    else:
        big_b[:4] = b
    if npv:  # this interval's rise acts now; the window shifts by one
        big_a[:4, 4 + nd] = e
        big_a[4 + nd : size - 1, 4 + nd + 1 :] = np.eye(npv - 1)
    # cost: (C x + D F_applied)^2 + q_s s^2 + q_g g^2 + r F_k^2 (F_applied is F_k without delay)
    c_big = np.zeros(size)
    c_big[:4] = c
    d_big = d
    if nd:  # the force acting now is a state (the oldest in flight)
        c_big[4 + nd - 1] = d
        d_big = 0.0
    q = np.outer(c_big, c_big)
    q[0, 0] += q_stroke
    q[2, 2] += q_gap
    r = np.array([[d_big * d_big + r_force]])
    s = (c_big * d_big)[:, None]
    p = solve_discrete_are(big_a, big_b[:, None], q, r, s=s)
    k = (big_b @ p @ big_a + s[:, 0]) / (r[0, 0] + big_b @ p @ big_b)  # one input: a scalar
    return PreviewGains(k[:4].copy(), k[4 : 4 + nd].copy(), k[4 + nd :].copy())


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
