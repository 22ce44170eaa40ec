"""The plant's RK4 integration lifted over a whole episode: every damper force the simulator
evaluates is a free variable, everything else is affine in them.

The env advances the quarter-car by ``n_sub`` classical RK4 substeps per control step
(:func:`capsule_env.plant.rk4.rk4_substep`) and reports, after each step, the body acceleration
at the new state (:func:`capsule_env.plant.rk4.plant_outputs`). The vehicle's equations
(:mod:`capsule_env.plant.equations`) are linear in the state, the guideway elevation and the
damper force ``F``. So, if each of the ``4 n_sub`` stage forces of a step and the force at its
sample point are taken as free variables ``F_s`` (``N = T (4 n_sub + 1)`` of them), the stroke
``x_s`` and stroke rate ``v_s`` each force is evaluated at, and the ``T`` sampled body
accelerations, are *exactly* affine in ``F`` (the same arithmetic as the kernel, in another
order): ``v = A F + alpha``, ``x = B F + beta``, ``acc = G F + g``. ``A`` and ``B`` are strictly
causal (a stage's motion depends on earlier forces only).

Supported: any damper model whose force depends on the plant state only through the stroke
and its rate and the coil current (no internal state: the Bi-exponential and passive linear
models), the env's substep count the same at every current (a controller could otherwise change
the integration), constant speed or a trip (its per-step route and vehicle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capsule_env.engine.layout import BODY_DISP, BODY_VEL, BOGIE_DISP, BOGIE_VEL, TIME
from capsule_env.oracle.plant import OracleEpisodes

__all__ = ["LiftedEpisode", "lift_episode", "guideway_elevation_np", "closed_loop"]

# vehicle columns (layout.VEHICLE_PARAM_NAMES): m_c, m_b, k_s, k_p, c_p
_MC, _MB, _KS, _KP, _CP = range(5)


@dataclass(frozen=True)
class LiftedEpisode:
    """One episode's lifted plant. ``N`` forces, ``T`` samples; rows indexed by force.

    v_rows, x_rows : (N, N + 1); ``v = v_rows[:, :N] @ F + v_rows[:, N]`` (m/s, m).
    acc_rows : (T, N + 1); the sampled body accelerations (m/s^2).
    step_of : (N,) the control step each force belongs to; is_output : (N,) bool, the force
    at a sample point (evaluated with the step's own current after the step).
    """

    v_rows: np.ndarray
    x_rows: np.ndarray
    acc_rows: np.ndarray
    step_of: np.ndarray
    is_output: np.ndarray
    dt_s: float
    n_sub: int
    #: per substep ``(zg0, zg_half, zg1, zg_rate, step)`` as :func:`_substep` took them, then
    #: per step the output's ``(zg, zg_rate)``, the vehicle rows (T, 5) and the start state
    #: (4,): the inputs to rebuild the lift substep by substep (:mod:`.branch`'s sparse QP)
    substep_inputs: np.ndarray | None = None
    output_inputs: np.ndarray | None = None
    vehicles: np.ndarray | None = None
    state0: np.ndarray | None = None

    @property
    def n_forces(self) -> int:
        return int(self.v_rows.shape[0])

    def affine(self, rows: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """``rows[:, :N] @ forces + rows[:, N]``."""
        return rows[:, :-1] @ forces + rows[:, -1]


def guideway_elevation_np(
    profiles: np.ndarray, k: int, spacing_m: float, position_m: np.ndarray
) -> np.ndarray:
    """:func:`capsule_env.plant.block.guideway_elevation` in numpy (same arithmetic)."""
    last = profiles.shape[1] - 1.0
    s = np.minimum(np.maximum(np.asarray(position_m, dtype=float) / spacing_m, 0.0), last)
    j = np.minimum(s.astype(np.int64), int(last) - 1)
    f = s - j
    return profiles[k, j] * (1.0 - f) + profiles[k, j + 1] * f


def _elevation(ep: OracleEpisodes, k: int, t: int, time_s: np.ndarray) -> np.ndarray:
    """The guideway under episode ``k``'s vehicle at times ``time_s`` of step ``t``."""
    prof, gain = int(ep.route.profile[k]), float(ep.route.gain[k])
    start, speed = float(ep.route.start_m[k]), float(ep.route.speed_mps[k])
    if ep.schedule is not None:
        start, speed = float(ep.schedule.start_m[t, k]), float(ep.schedule.speed_mps[t, k])
    pos = start + speed * time_s
    z = gain * guideway_elevation_np(ep.profiles, prof, ep.spacing_m, pos)
    if ep.offsets.shape[0] > 0:
        z = z + guideway_elevation_np(ep.offsets, prof, ep.spacing_m, pos)
    return z


def check_liftable(ep: OracleEpisodes, k: int) -> int:
    """The substep count of episode ``k``; ValueError where the plant cannot be lifted."""
    from capsule_env.dampers.registry import model_of_code

    model = model_of_code(ep.code)
    if model.hysteresis is not None or model.internal_displacement:
        raise ValueError(
            f"certified_floor: the plant damper {model.name!r} has internal state (hysteresis "
            "or an internal displacement); supported plant dampers: bi_exponential (the sim "
            "setting), passive"
        )
    table = ep.env_tables[k]
    if np.any(table != table[0]):
        raise ValueError(
            "certified_floor: the env's substep count depends on the current for this plant "
            f"({table.tolist()}); the lifted plant needs one count at every current"
        )
    return int(table[0])


class _Affine:
    """The four mechanical states as affine functions of the forces: (4, N + 1)."""

    def __init__(self, n: int, state0: np.ndarray) -> None:
        self.rows = np.zeros((4, n + 1))
        self.rows[:, n] = state0


def _rates(s: np.ndarray, f_col: int, zg: float, zg_rate: float, veh: np.ndarray) -> np.ndarray:
    """d/dt of (z_c, z_c', z_b, z_b') as affine rows, the damper force the variable ``f_col``
    (:func:`capsule_env.plant.equations.accelerations`)."""
    secondary = veh[_KS] * (s[0] - s[2])
    secondary[f_col] += 1.0
    lev = veh[_KP] * s[2] + veh[_CP] * s[3]
    lev[-1] -= veh[_KP] * zg + veh[_CP] * zg_rate
    return np.stack([s[1], -secondary / veh[_MC], s[3], (secondary - lev) / veh[_MB]])


def lift_episode(ep: OracleEpisodes, k: int) -> LiftedEpisode:
    """Lift episode ``k`` of ``ep`` (:class:`LiftedEpisode`); see the module's docstring."""
    n_sub = check_liftable(ep, k)
    n_steps, per = ep.n_steps, 4 * n_sub + 1
    n = n_steps * per
    state0 = ep.state0[k, [BODY_DISP, BODY_VEL, BOGIE_DISP, BOGIE_VEL]].astype(float)
    state = _Affine(n, state0).rows
    sub_in, out_in, vehicles = [], [], []
    v_rows, x_rows = np.zeros((n, n + 1)), np.zeros((n, n + 1))
    acc_rows = np.zeros((n_steps, n + 1))
    t = float(ep.state0[k, TIME])
    h = ep.dt_s / n_sub
    col = 0
    for step in range(n_steps):
        veh = ep.vehicle_params[k] if ep.schedule is None else ep.schedule.vehicle[step, k]
        vehicles.append(np.asarray(veh, dtype=float))
        zg0 = float(_elevation(ep, k, step, np.array([t]))[0])
        zgh = zg1 = zg0
        for _ in range(n_sub):
            zgh, zg1 = _elevation(ep, k, step, np.array([t + 0.5 * h, t + h]))
            zg_rate = (zg1 - zg0) / h if veh[_CP] != 0.0 else 0.0
            sub_in.append((zg0, zgh, zg1, zg_rate, step))
            state, col = _substep(state, col, (zg0, zgh, zg1), zg_rate, h, veh, v_rows, x_rows)
            t, zg0 = t + h, zg1
        x_rows[col], v_rows[col] = state[0] - state[2], state[1] - state[3]
        zg_rate = (zg1 - zgh) * 2.0 / h if veh[_CP] != 0.0 else 0.0
        out_in.append((zg0, zg_rate))
        acc_rows[step] = _rates(state, col, zg0, zg_rate, veh)[1]
        col += 1
    step_of = np.repeat(np.arange(n_steps), per)
    is_output = np.zeros(n, dtype=bool)
    is_output[per - 1 :: per] = True
    return LiftedEpisode(v_rows, x_rows, acc_rows, step_of, is_output, ep.dt_s, n_sub,
                         np.array(sub_in), np.array(out_in), np.array(vehicles), state0)  # fmt: skip


def _substep(
    state: np.ndarray,
    col: int,
    zg: tuple[float, float, float],
    zg_rate: float,
    h: float,
    veh: np.ndarray,
    v_rows: np.ndarray,
    x_rows: np.ndarray,
) -> tuple[np.ndarray, int]:
    """One RK4 substep (:func:`capsule_env.plant.rk4.rk4_substep`) on affine rows: records the
    stroke and stroke rate of its four stages (forces ``col .. col + 3``)."""
    ks = []
    stage = state
    for j, (weight, elev) in enumerate(((0.5, zg[0]), (0.5, zg[1]), (1.0, zg[1]), (0.0, zg[2]))):
        x_rows[col + j], v_rows[col + j] = stage[0] - stage[2], stage[1] - stage[3]
        ks.append(_rates(stage, col + j, elev, zg_rate, veh))
        stage = state + weight * h * ks[-1]
    new = state + (h / 6.0) * (ks[0] + 2.0 * ks[1] + 2.0 * ks[2] + ks[3])
    return new, col + 4


def closed_loop(lifted: LiftedEpisode, law: object) -> np.ndarray:
    """The forces of the lifted plant closed with ``law(x, v, step) -> F`` (N), evaluated in
    causal order (each stage's stroke and rate from the forces before it): the simulator's own
    trajectory when ``law`` is the plant damper's force at the applied currents."""
    n = lifted.n_forces
    forces = np.zeros(n)
    a_v, a_x = lifted.v_rows, lifted.x_rows
    for s in range(n):
        v = float(a_v[s, :s] @ forces[:s] + a_v[s, n])
        x = float(a_x[s, :s] @ forces[:s] + a_x[s, n])
        forces[s] = law(x, v, int(lifted.step_of[s]))  # type: ignore[operator]
    return forces
