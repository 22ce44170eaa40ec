"""Classical semi-active controllers (docs/model.md, section 11).

All force-requesting laws output ``a = F_d / max_force_n`` (the env's force mode); the env's
inverse model turns the request into a coil current and applies the semi-active rule. They
read absolute velocities from the ``full_state`` observation (in ``hils`` with measurement
noise), like the paper's Skyhook fed by the simulated vehicle model; they say so through
``uses_unmeasured_signals``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_continuous_are

from agents.base import FULL, Controller
from capsule_env.vehicle import VehicleParams

#: Default Skyhook gains (N s/m) [reconstructed, docs/model.md 11: about 0.7 of critical damping of
#: the body on the series stiffness].
C_SKY = 7.0e4
DEFAULT_MAX_FORCE_N = 8000.0
_INVERSE_TAG = {"bi_exponential": "biexp", "csdc": "csdc", "tanh": "tanh"}


def _full_state_kwargs(inverse_model: str) -> dict:
    return {"observation": "full_state", "action_mode": "force", "inverse_model": inverse_model}


class PassiveController(Controller):
    """The passive suspension: the linear secondary damper c_s (plant ``damper="passive"``);
    the action is ignored."""

    name = "passive"
    env_kwargs = {"damper": "passive", "action_mode": "current"}

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros(obs.shape[0])


class ConstantCurrentController(Controller):
    """The MR damper held at a constant current (passive-on / passive-off)."""

    def __init__(self, fraction_of_max: float, name: str | None = None) -> None:
        if not 0.0 <= fraction_of_max <= 1.0:
            raise ValueError(f"fraction_of_max must be in [0, 1], got {fraction_of_max!r}")
        self.fraction = float(fraction_of_max)
        self.name = name or f"mr-{fraction_of_max:g}imax"
        self.env_kwargs = {"action_mode": "current"}

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.full(obs.shape[0], 2.0 * self.fraction - 1.0)


class SkyhookController(Controller):
    """Skyhook (paper eq. 15), on-off or continuous, through an inverse model.

    With ``v = z_c' - z_b'``:
    on-off: ``F_d = c_max v`` if ``z_c' v > 0`` else ``c_min v``;
    continuous: ``F_d = c_sky z_c'`` if ``z_c' v > 0`` else 0.

    Parameters
    ----------
    inverse_model : ``"bi_exponential"``, ``"csdc"`` or ``"tanh"``.
    variant : ``"on_off"`` (default, the paper's) or ``"continuous"``.
    c_max, c_min, c_sky : gains (N s/m); defaults 7e4, 0, 7e4 [reconstructed].
    max_force_n : the env's force scale (must match the env's ``max_force_n``).
    """

    uses_unmeasured_signals = True

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        variant: str = "on_off",
        c_max: float = C_SKY,
        c_min: float = 0.0,
        c_sky: float = C_SKY,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
    ) -> None:
        if variant not in ("on_off", "continuous"):
            raise ValueError(f"variant must be 'on_off' or 'continuous', got {variant!r}")
        if inverse_model not in _INVERSE_TAG:
            raise ValueError(
                f"unknown inverse_model {inverse_model!r}; accepted: {', '.join(_INVERSE_TAG)}"
            )
        self.variant = variant
        self.c_max, self.c_min, self.c_sky = float(c_max), float(c_min), float(c_sky)
        self.max_force_n = float(max_force_n)
        suffix = "" if variant == "on_off" else "-cont"
        self.name = f"skyhook{suffix}-{_INVERSE_TAG[inverse_model]}"
        self.env_kwargs = {**_full_state_kwargs(inverse_model), "max_force_n": self.max_force_n}

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        body_vel = obs[:, FULL["car_body_velocity_m_s"]]
        rel_vel = body_vel - obs[:, FULL["bogie_velocity_m_s"]]
        on = body_vel * rel_vel > 0.0
        if self.variant == "on_off":
            return np.where(on, self.c_max * rel_vel, self.c_min * rel_vel)
        return np.where(on, self.c_sky * body_vel, 0.0)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.desired_force(obs) / self.max_force_n


class HybridController(SkyhookController):
    """Hybrid skyhook-groundhook: ``F_d = alpha F_sky + (1 - alpha) F_ground`` with the
    groundhook term ``F_ground = -c_gnd z_b'`` when ``-z_b' v > 0`` (damps the bogie)."""

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        alpha: float = 0.7,
        c_sky: float = C_SKY,
        c_ground: float = 3.0e4,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
    ) -> None:
        super().__init__(inverse_model, "continuous", c_sky=c_sky, max_force_n=max_force_n)
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1], got {alpha!r}")
        self.alpha, self.c_ground = float(alpha), float(c_ground)
        self.name = f"hybrid-{_INVERSE_TAG[inverse_model]}"

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        sky = super().desired_force(obs)
        bogie_vel = obs[:, FULL["bogie_velocity_m_s"]]
        rel_vel = obs[:, FULL["car_body_velocity_m_s"]] - bogie_vel
        ground = np.where(-bogie_vel * rel_vel > 0.0, -self.c_ground * bogie_vel, 0.0)
        return self.alpha * sky + (1.0 - self.alpha) * ground


class ClippedOptimalController(Controller):
    """Clipped-optimal control (Dyke et al. 1996): an LQR force law for the linear plant,
    ``F_d = -K x``, produced as far as the damper can (the inverse model clips it to the
    achievable, dissipative band).

    State ``x = [z_c - z_b, z_c', z_b - z_g, z_b']`` (all from ``full_state``). Cost
    ``J = integral( a_c^2 + q_stroke (z_c - z_b)^2 + q_lev (z_b - z_g)^2 + r F^2 )`` with
    ``a_c = (-k_s (z_c - z_b) - F) / m_c`` the car-body acceleration (the cross term is kept).
    """

    uses_unmeasured_signals = True

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        q_stroke: float = 1.0e3,
        q_levitation: float = 1.0e3,
        r_force: float = 1.0e-9,
        vehicle: VehicleParams | None = None,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
    ) -> None:
        vehicle = vehicle or VehicleParams()
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
        b = np.array([[0.0], [-1.0 / mc], [0.0], [1.0 / mb]])
        c_acc = np.array([[-ks / mc, 0.0, 0.0, 0.0]])
        d_acc = np.array([[-1.0 / mc]])
        q = c_acc.T @ c_acc + np.diag([q_stroke, 0.0, q_levitation, 0.0])
        r = d_acc.T @ d_acc + r_force
        n = c_acc.T @ d_acc
        p = solve_continuous_are(a, b, q, r, s=n)
        self.gain = np.linalg.solve(r, b.T @ p + n.T)[0]
        self.max_force_n = float(max_force_n)
        self.name = f"lqr-clipped-{_INVERSE_TAG[inverse_model]}"
        self.env_kwargs = {**_full_state_kwargs(inverse_model), "max_force_n": self.max_force_n}

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        x = np.stack(
            [
                obs[:, FULL["car_body_displacement_m"]] - obs[:, FULL["bogie_displacement_m"]],
                obs[:, FULL["car_body_velocity_m_s"]],
                obs[:, FULL["bogie_displacement_m"]] - obs[:, FULL["guideway_elevation_m"]],
                obs[:, FULL["bogie_velocity_m_s"]],
            ],
            axis=1,
        )
        return -x @ self.gain

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.desired_force(obs) / self.max_force_n


def classical_controllers() -> dict[str, Controller]:
    """Every classical controller by name."""
    ctrls: list[Controller] = [
        PassiveController(),
        ConstantCurrentController(0.0, "mr-0A"),
        ConstantCurrentController(1.0, "mr-imax"),
    ]
    for inverse in ("bi_exponential", "csdc", "tanh"):
        ctrls.append(SkyhookController(inverse, "on_off"))
        ctrls.append(SkyhookController(inverse, "continuous"))
    ctrls.append(HybridController("bi_exponential"))
    ctrls.append(ClippedOptimalController("bi_exponential"))
    return {c.name: c for c in ctrls}
