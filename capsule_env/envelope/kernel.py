"""The envelope's per-step work in the env kernel: the trip's route and the EDS levitation.

Compiled only into the kernels of configurations with a trip (:mod:`capsule_env.envelope.options`).
Per vehicle, the reset stores (rows of ``EnvState.envelope``) the trip time at the episode's
start ``t0``, the route's start on its profile and the speed at ``t0`` (``v_ref``), and the
levitation's stiffness limit ``K_inf``. At window time ``t`` (trip time ``T = t0 + t``):

- speed ``v(t) = v_ref + a rise(T; 0, t1) - b rise(T; t2, t3)``, where ``rise(T; lo, hi)`` is
  how far ``clip(., lo, hi)`` has risen between ``t0`` and ``T``;
- position on the profile ``start + v_ref t + D(t)``, with the extra distance
  ``D(t) = a G(t; 0, t1) - b G(t; t2, t3)`` and ``G`` the integral of ``rise``. Both are sums
  of terms proportional to the accelerations: exactly ``v_ref`` and 0 for a trip that keeps
  its speed, so that such a trip gives the constant-speed env's numbers bit for bit.

Over a control interval ``[t, t + dt]`` the route (``start_m + speed_mps t``, what the plant
kernel reads) is set to the chord of that position, exact at both ends.
"""

from __future__ import annotations

from numba import njit

from capsule_env._fastmath import BORROWED, FAST
from capsule_env.engine.env_params import HIGH, LOW, envelope
from capsule_env.engine.layout import DAMP_LEVITATION, STIFF_LEVITATION, TIME

__all__ = ["ENV_T0", "ENV_START", "ENV_SPEED", "ENV_LIMIT", "envelope_interval",
           "envelope_observe", "trip_speed_change", "trip_extra_distance"]  # fmt: skip

#: Rows of ``EnvState.envelope``.
ENV_T0, ENV_START, ENV_SPEED, ENV_LIMIT = range(4)


@njit(**FAST, **BORROWED, inline="always")
def _rise(t0, t_end, lo, hi):
    """``(u0, e, m)``: the phase ``[lo, hi]`` as seen from ``t0``: it rises from ``u0`` to
    ``e``; ``m`` the point reached at ``t_end`` (clipped)."""
    u0 = max(t0, lo)
    e = max(hi, u0)
    return u0, e, min(max(t_end, u0), e)


@njit(**FAST, **BORROWED, inline="always")
def trip_speed_change(t0, t, trip):
    """``v(t) - v_ref`` (m/s) at window time ``t`` of a window starting at trip time ``t0``;
    ``trip = (a, b, t1, t2, t3)``."""
    u0, _, m = _rise(t0, t0 + t, 0.0, trip[2])
    u0b, _, mb = _rise(t0, t0 + t, trip[3], trip[4])
    return trip[0] * (m - u0) - trip[1] * (mb - u0b)


@njit(**FAST, **BORROWED, inline="always")
def _integral_of_rise(t0, t, lo, hi):
    u0, e, m = _rise(t0, t0 + t, lo, hi)
    return 0.5 * (m - u0) * (m - u0) + max(t0 + t - e, 0.0) * (e - u0)


@njit(**FAST, **BORROWED, inline="always")
def trip_extra_distance(t0, t, trip):
    """``D(t)``: the distance travelled beyond ``v_ref t`` in the window's first ``t``
    seconds (m)."""
    return trip[0] * _integral_of_rise(t0, t, 0.0, trip[2]) - trip[1] * _integral_of_rise(
        t0, t, trip[3], trip[4]
    )


@njit(**FAST, **BORROWED, inline="always")
def trip_acceleration(t0, t, trip):
    """The longitudinal acceleration (m/s^2) at window time ``t``."""
    T = t0 + t
    if 0.0 <= T < trip[2]:
        return trip[0]
    if trip[3] <= T < trip[4]:
        return -trip[1]
    return 0.0


@njit(**FAST, **BORROWED)
def envelope_interval(lo, hi, params, plant, state, eds_per_step):
    """Before the plant's step: the route of vehicles ``lo .. hi-1`` over the coming interval
    (the chord of their trip) and, with ``eds_per_step``, their levitation's ``k_p`` and
    ``c_p`` at the interval's mid-time speed."""
    trip, dt, route = params.trip, params.dt_s, state.route
    env = envelope(state)
    v_c, tau = params.eds[0], params.eds[1]
    for n in range(lo, hi):
        t, t0 = state.plant[n, TIME], env[ENV_T0, n]
        d0 = trip_extra_distance(t0, t, trip)
        slope = (trip_extra_distance(t0, t + dt, trip) - d0) / dt
        route.speed_mps[n] = env[ENV_SPEED, n] + slope
        route.start_m[n] = env[ENV_START, n] + d0 - slope * t
        if eds_per_step:
            v = env[ENV_SPEED, n] + trip_speed_change(t0, t + 0.5 * dt, trip)
            r2 = (v / v_c) * (v / v_c)
            k = env[ENV_LIMIT, n]
            plant.vehicle[n, STIFF_LEVITATION] = k * r2 / (1.0 + r2)
            plant.vehicle[n, DAMP_LEVITATION] = k * tau * (1.0 - r2) / ((1.0 + r2) * (1.0 + r2))


@njit(**FAST, **BORROWED)
def envelope_observe(lo, hi, params, state, obs):
    """After the step: the trip columns (speed, longitudinal acceleration) of vehicles
    ``lo .. hi-1``, clipped to the observation space."""
    trip, c, bounds = params.trip, params.trip_column, params.obs_bounds
    env = envelope(state)
    for n in range(lo, hi):
        t, t0 = state.plant[n, TIME], env[ENV_T0, n]
        v = env[ENV_SPEED, n] + trip_speed_change(t0, t, trip)
        obs[n, c] = min(max(v, bounds[LOW, c]), bounds[HIGH, c])
        acc = trip_acceleration(t0, t, trip)
        obs[n, c + 1] = min(max(acc, bounds[LOW, c + 1]), bounds[HIGH, c + 1])
