"""The plant integrated by SciPy's variable-step solvers: the solver factor of issue 27.

The env integrates the quarter-car and its damper with fixed RK4 substeps and the closed-form
Bouc-Wen update (:mod:`capsule_env.plant.rk4`). The paper ran Simulink, whose default solver is
the variable-step ``ode45`` (Dormand-Prince, relative tolerance 1e-3). This module integrates
the same equations (docs/model.md 1-4), the vehicle's from its declaration's linear model
(:func:`capsule_env.vehicles.absolute_model`: ``x' = A x + B F + E z_g + E_rate z_g'``, for
the 1/4-car)::

    m_c z_c'' = -(k_s (z_c - z_b) + F)
    m_b z_b'' =   k_s (z_c - z_b) + F - k_p (z_b - z_g(t)) - c_p (z_b' - z_g'(t))
    F, y', w = damper_eval(model, x = z_c - z_b, v = z_c' - z_b', y, z, i)
    z' = -gamma |w| z |z| - beta w z^2 + A w            (Bouc-Wen, reference damper)
    i' = (i_cmd - i) / tau                              (tau > 0; else i = i_cmd)

with :func:`scipy.integrate.solve_ivp` (``"RK45"``, the same Dormand-Prince pair as ``ode45``;
``"LSODA"``, which switches to a stiff method; or any other method it accepts), the command
held over each control interval (a zero-order hold, as a discrete controller in Simulink) and
the guideway read as the env reads it (linear between profile samples). ``z`` is a state of
the ODE, integrated like the others, as a Simulink Bouc-Wen block integrates it.

Tolerances: ``rtol`` (default 1e-3, Simulink's) and per state an absolute tolerance ``rtol x
scale``, the scales 1 cm, 0.1 m/s, 1 cm, 0.1 m/s, the model's ``z`` saturation level
``sqrt(A / (gamma + beta))``, 1 cm and ``i_max``: Simulink's ``auto`` tolerance is likewise
relative to each state's size, and ``z`` of the identified Bouc-Wen lives on a 7 µm scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

from capsule_env.dampers import DamperParams
from capsule_env.dampers.dispatch import damper_eval
from capsule_env.dampers.dispatch import hysteresis_params as _hysteresis_params
from capsule_env.dampers.hysteresis import hysteresis_rate, saturation_level
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.layout import COIL_TAU
from capsule_env.plant.block import guideway_elevation
from capsule_env.vehicles import VehicleParams, absolute_model, model_of_params

__all__ = ["ODE_STATE_NAMES", "VariableStepPlant", "simulate_variable_step"]

#: The ODE's states, in order.
ODE_STATE_NAMES = ("z_c", "v_c", "z_b", "v_b", "z", "y", "i")


_RHS: dict[int, Any] = {}


def _rhs_of(model: int) -> Any:
    """The ODE's right-hand side for the damper model ``model``, compiled once per model with
    the code as a compile-time constant (the damper registry dispatches on it)."""
    if model not in _RHS:
        _RHS[model] = _make_rhs(int(model))
    return _RHS[model]


@njit
def _slope(profiles, spacing, position):  # type: ignore[no-untyped-def]
    """The slope (m/m) of profile 0, linear between samples, at ``position`` (m; 0 beyond
    its ends, where :func:`guideway_elevation` holds the end values)."""
    s = position / spacing
    last = profiles.shape[1] - 1
    if s < 0.0 or s >= last:
        return 0.0
    j = int(s)
    return (profiles[0, j + 1] - profiles[0, j]) / spacing


def _make_rhs(model: int) -> Any:
    @njit
    def rhs(t, s, p, lin, i_cmd, route, profiles, spacing):  # type: ignore[no-untyped-def]
        a, b, e, e_rate, stroke = lin  # the vehicle's absolute linear model, one damper slot
        n = a.shape[0]
        x = s[:n]
        z, y, ic = s[n], s[n + 1], s[n + 2]
        tau = p[COIL_TAU]
        i_now = ic if tau > 0.0 else i_cmd
        zg = route[2] * guideway_elevation(profiles, 0, spacing, profiles.shape[1] - 1.0,
                                           route[0] + route[1] * t)  # fmt: skip
        zg_rate = route[2] * route[1] * _slope(profiles, spacing, route[0] + route[1] * t)
        deflection, rate = 0.0, 0.0
        for j in range(0, n, 2):
            deflection += stroke[j] * x[j]
            rate += stroke[j] * x[j + 1]
        force, y_dot, w = damper_eval(model, p, deflection, rate, y, z, i_now)
        a_coef, gamma, beta = _hysteresis_params(model, p)
        out = np.empty(n + 3)
        out[:n] = a @ x + b * force + e * zg + e_rate * zg_rate
        out[n] = hysteresis_rate(z, w, a_coef, gamma, beta) if a_coef > 0.0 else 0.0
        out[n + 1] = y_dot
        out[n + 2] = (i_cmd - ic) / tau if tau > 0.0 else 0.0
        return out, force, zg

    return rhs


def _hysteresis_coefficients(damper: DamperParams, p: np.ndarray) -> tuple[float, float, float]:
    """``(A, gamma, beta)`` of the damper's hysteresis from its registry entry (zeros
    without one)."""
    hyst = model_of_code(damper.code).hysteresis
    if hyst is None:
        return 0.0, 0.0, 0.0
    return float(p[hyst.a_coef]), float(p[hyst.gamma]), float(p[hyst.beta])


@dataclass
class VariableStepPlant:
    """One vehicle on one guideway profile, advanced a control interval at a time by
    :func:`scipy.integrate.solve_ivp` (module doc).

    Parameters
    ----------
    damper : the plant's damper (any model of :mod:`capsule_env.dampers`).
    profile_m : the guideway profile (m), sampled every ``spacing_m``.
    spacing_m : its sample spacing (m).
    speed_mps : the vehicle's speed (m/s); ``start_m`` its start on the profile (m);
        ``gain`` a scale of the profile (the env's route).
    vehicle : the vehicle (default :class:`~capsule_env.vehicles.modes.VehicleParams`).
    method, rtol, atol : the solver, its relative tolerance, and per-state absolute
        tolerances (None: ``rtol x`` the scales of the module doc).
    """

    damper: DamperParams
    profile_m: np.ndarray
    spacing_m: float
    speed_mps: float
    start_m: float = 0.0
    gain: float = 1.0
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    method: str = "RK45"
    rtol: float = 1e-3
    atol: np.ndarray | None = None
    state: np.ndarray = field(default_factory=lambda: np.zeros(7))
    time_s: float = 0.0
    nfev: int = 0

    def __post_init__(self) -> None:
        if not (self.rtol > 0.0 and math.isfinite(self.rtol)):
            raise ValueError(f"rtol must be a positive number, got {self.rtol!r}")
        if self.speed_mps <= 0.0 or self.spacing_m <= 0.0:
            raise ValueError("speed_mps and spacing_m must be > 0")
        self._p = self.damper.as_array()
        plant = absolute_model(model_of_params(self.vehicle), self.vehicle)
        if plant.b.shape[1] != 1 or plant.e.shape[1] != 1:
            raise ValueError(
                "the reference solver runs vehicles of one damper slot and one contact"
            )
        self._lin = (plant.a, plant.b[:, 0].copy(), plant.e[:, 0].copy(),
                     plant.e_rate[:, 0].copy(), plant.stroke[0].copy())  # fmt: skip
        self._profiles = np.ascontiguousarray(np.atleast_2d(self.profile_m), dtype=float)
        self._route = np.array([self.start_m, self.speed_mps, self.gain], dtype=float)
        if self.atol is None:
            a, g, b = _hysteresis_coefficients(self.damper, self._p)
            z_scale = saturation_level(a, g, b) if a > 0.0 else 1.0
            i_scale = getattr(self.damper, "max_current_a", 1.0)
            scales = np.array([0.01, 0.1, 0.01, 0.1, z_scale, 0.01, i_scale])
            self.atol = self.rtol * scales

    def _fun(self, i_cmd: float):
        rhs, p, lin = _rhs_of(self.damper.code), self._p, self._lin
        route, profiles, spacing = self._route, self._profiles, float(self.spacing_m)

        def fun(t: float, s: np.ndarray) -> np.ndarray:
            return rhs(t, s, p, lin, i_cmd, route, profiles, spacing)[0]

        return fun

    def outputs(self, i_cmd: float) -> tuple[float, float, float, float]:
        """``(damper force N, body acceleration, bogie acceleration m/s^2, guideway m)`` at the
        present state under the command ``i_cmd``."""
        s = self.state
        d, force, zg = _rhs_of(self.damper.code)(self.time_s, s, self._p, self._lin, i_cmd,
                                                 self._route, self._profiles,
                                                 float(self.spacing_m))  # fmt: skip
        return float(force), float(d[1]), float(d[3]), float(zg)

    def step(self, current_command_a: float, dt_s: float) -> None:
        """Advance by ``dt_s`` with the command held (clipped to ``[0, i_max]``)."""
        i_max = getattr(self.damper, "max_current_a", 0.0)  # 0 for a damper without a coil
        i_cmd = min(max(float(current_command_a), 0.0), i_max)
        if self._p[COIL_TAU] <= 0.0:
            self.state[6] = i_cmd
        t0, t1 = self.time_s, self.time_s + dt_s
        sol = solve_ivp(self._fun(i_cmd), (t0, t1), self.state, method=self.method,
                        rtol=self.rtol, atol=self.atol)  # fmt: skip
        if not sol.success:
            raise RuntimeError(f"solve_ivp ({self.method}) failed at t = {t0:g} s: {sol.message}")
        self.nfev += int(sol.nfev)
        self.state = sol.y[:, -1].copy()
        self.time_s = t1


def simulate_variable_step(
    damper: DamperParams,
    profile_m: np.ndarray,
    spacing_m: float,
    speed_mps: float,
    current_command_a: np.ndarray | float,
    duration_s: float,
    dt_s: float = 0.005,
    vehicle: VehicleParams | None = None,
    method: str = "RK45",
    rtol: float = 1e-3,
    atol: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Open-loop run of one vehicle, as :func:`capsule_env.engine.simulate.simulate` but
    integrated by ``solve_ivp``: the command (a scalar or one per control interval) held over
    each interval. Returns ``time_s`` and the columns ``car_body_displacement_m``,
    ``car_body_velocity_m_s``, ``bogie_displacement_m``, ``bogie_velocity_m_s``,
    ``hysteretic_z_m``, ``coil_current_a`` at the end of each interval (t = 0 first), and
    ``nfev`` (right-hand-side evaluations)."""
    n_steps = int(round(duration_s / dt_s))
    commands = np.broadcast_to(np.asarray(current_command_a, float), (n_steps,))
    plant = VariableStepPlant(damper, profile_m, spacing_m, speed_mps,
                              vehicle=vehicle or VehicleParams(), method=method, rtol=rtol,
                              atol=atol)  # fmt: skip
    states = np.empty((n_steps + 1, 7))
    states[0] = plant.state
    for k in range(n_steps):
        plant.step(commands[k], dt_s)
        states[k + 1] = plant.state
    names = ("car_body_displacement_m", "car_body_velocity_m_s", "bogie_displacement_m",
             "bogie_velocity_m_s", "hysteretic_z_m")  # fmt: skip
    out = {"time_s": dt_s * np.arange(n_steps + 1)}
    out.update({name: states[:, j] for j, name in enumerate(names)})
    out["coil_current_a"] = states[:, 6]
    out["nfev"] = np.array(plant.nfev)
    return out
