"""Skyhook and skyhook-groundhook laws that request a force through an inverse model.

They output ``a = F_d / max_force_n`` (the env's force mode); the env's inverse model turns
the request into a coil current and applies the semi-active rule. On ``full_state`` (ideal
sensors: the paper's Skyhook, fed by the simulated vehicle) they read the true absolute
velocities; on ``measured`` (name suffix ``-meas``) the on-board velocity estimates and the
LVDT's stroke rate (:mod:`capsule_env.agents.controllers.law`).

Why force mode: continuous Skyhook and the hybrid law ask for a force proportional to a
velocity, a continuum of damper states that only the inverse model can produce. The two-state
laws (:mod:`capsule_env.agents.controllers.two_state`) command the damper's two states directly.
"""

from __future__ import annotations

import numpy as np
from capsule_env.agents.controllers.law import ClassicalLaw, law_name

#: The paper-reproduction Skyhook gain (N s/m) [reconstructed, docs/model.md 11: about 0.7 of
#: critical damping of the body on the series stiffness]; the fallback of untuned Skyhooks.
C_SKY = 7.0e4
DEFAULT_MAX_FORCE_N = 8000.0
INVERSE_TAG = {"bi_exponential": "biexp", "csdc": "csdc", "tanh": "tanh"}


def force_mode_kwargs(observation: str, inverse_model: str, max_force_n: float) -> dict:
    """The env options of a force-requesting law."""
    if inverse_model not in INVERSE_TAG:
        raise ValueError(
            f"unknown inverse_model {inverse_model!r}; accepted: {', '.join(INVERSE_TAG)}"
        )
    return {"observation": observation, "action_mode": "force", "inverse_model": inverse_model,
            "max_force_n": float(max_force_n)}  # fmt: skip


class ForceLaw(ClassicalLaw):
    """A law that requests a damper force: :meth:`desired_force` (N) over ``max_force_n``,
    named ``{base_name}-{inverse tag}`` (``-meas`` appended on the measured set)."""

    def __init__(
        self, base_name: str, inverse_model: str, max_force_n: float, observation: str
    ) -> None:
        super().__init__(observation)
        self.env_kwargs = force_mode_kwargs(observation, inverse_model, max_force_n)
        self.max_force_n = float(max_force_n)
        self.name = law_name(f"{base_name}-{INVERSE_TAG[inverse_model]}", observation)

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.desired_force(obs) / self.max_force_n


class SkyhookController(ForceLaw):
    """Skyhook (paper eq. 15), on-off or continuous, through an inverse model.

    With ``v = z_c' - z_b'`` (the stroke rate):
    on-off: ``F_d = c_max v`` if ``z_c' v > 0`` else ``c_min v``;
    continuous: ``F_d = c_sky z_c'`` if ``z_c' v > 0`` else 0.

    Parameters
    ----------
    inverse_model : ``"bi_exponential"``, ``"csdc"`` or ``"tanh"``.
    variant : ``"on_off"`` (default, the paper's) or ``"continuous"``.
    c_max, c_min, c_sky : gains (N s/m), scalars or one per vehicle; None: the tuned value
        (``agents/controllers/tuned_gains.json``), else 7e4, 0, 7e4 [reconstructed].
    max_force_n : the env's force scale (must match the env's ``max_force_n``).
    observation : ``"full_state"`` (ideal sensors, the default) or ``"measured"``.
    """

    SIGNALS = ("body_velocity", "relative_velocity")
    # Gains (N s/m), scalar or one per vehicle, set by _set_gains: c_max and c_min in the
    # on_off variant, c_sky in the continuous one.
    c_max: np.ndarray
    c_min: np.ndarray
    c_sky: np.ndarray

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        variant: str = "on_off",
        c_max: float | np.ndarray | None = None,
        c_min: float | np.ndarray | None = None,
        c_sky: float | np.ndarray | None = None,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
        observation: str = "full_state",
    ) -> None:
        if variant not in ("on_off", "continuous"):
            raise ValueError(f"variant must be 'on_off' or 'continuous', got {variant!r}")
        base = "skyhook" if variant == "on_off" else "skyhook-cont"
        super().__init__(base, inverse_model, max_force_n, observation)
        self.variant = variant
        if variant == "on_off":
            units, given, fallback = (
                {"c_max": "n_s_m", "c_min": "n_s_m"},
                {"c_max": c_max, "c_min": c_min},
                {"c_max": C_SKY, "c_min": 0.0},
            )
        else:
            units, given, fallback = {"c_sky": "n_s_m"}, {"c_sky": c_sky}, {"c_sky": C_SKY}
        self._set_gains(units, given, fallback)

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        body_vel = self.signal(obs, "body_velocity")
        rel_vel = self.signal(obs, "relative_velocity")
        on = body_vel * rel_vel > 0.0
        if self.variant == "on_off":
            return np.where(on, self.c_max * rel_vel, self.c_min * rel_vel)
        return np.where(on, self.c_sky * body_vel, 0.0)


class HybridController(ForceLaw):
    """Hybrid skyhook-groundhook: ``F_d = alpha F_sky + (1 - alpha) F_ground`` with the
    continuous Skyhook term ``F_sky = c_sky z_c'`` when ``z_c' v > 0`` (damps the body) and
    the groundhook term ``F_ground = -c_ground z_b'`` when ``-z_b' v > 0`` (damps the bogie);
    ``alpha = 0`` is pure groundhook, 1 pure Skyhook. Gains None: the tuned values, else
    alpha 0.7, c_sky 7e4, c_ground 3e4 [reconstructed]. The search tunes ``alpha`` and one
    gain ``c_sky = c_ground`` (the usual hybrid form; the pair of effective gains
    ``alpha c_sky``, ``(1 - alpha) c_ground`` spans the same laws)."""

    SIGNALS = ("body_velocity", "bogie_velocity", "relative_velocity")
    # Gains, scalar or one per vehicle, set by _set_gains: alpha (dimensionless), c_sky and
    # c_ground (N s/m).
    alpha: np.ndarray
    c_sky: np.ndarray
    c_ground: np.ndarray

    def __init__(
        self,
        inverse_model: str = "bi_exponential",
        alpha: float | np.ndarray | None = None,
        c_sky: float | np.ndarray | None = None,
        c_ground: float | np.ndarray | None = None,
        max_force_n: float = DEFAULT_MAX_FORCE_N,
        observation: str = "full_state",
    ) -> None:
        super().__init__("hybrid", inverse_model, max_force_n, observation)
        self._set_gains(
            {"alpha": "rel", "c_sky": "n_s_m", "c_ground": "n_s_m"},
            {"alpha": alpha, "c_sky": c_sky, "c_ground": c_ground},
            {"alpha": 0.7, "c_sky": C_SKY, "c_ground": 3.0e4},
        )
        if np.any((self.alpha < 0.0) | (self.alpha > 1.0)):
            raise ValueError(f"alpha must be in [0, 1], got {alpha!r}")

    def desired_force(self, obs: np.ndarray) -> np.ndarray:
        body_vel = self.signal(obs, "body_velocity")
        bogie_vel = self.signal(obs, "bogie_velocity")
        rel_vel = self.signal(obs, "relative_velocity")
        sky = np.where(body_vel * rel_vel > 0.0, self.c_sky * body_vel, 0.0)
        ground = np.where(-bogie_vel * rel_vel > 0.0, -self.c_ground * bogie_vel, 0.0)
        return self.alpha * sky + (1.0 - self.alpha) * ground
