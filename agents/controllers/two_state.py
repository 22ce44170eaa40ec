"""Two-state laws: the damper switched between its least and its most damping state.

On-off Skyhook, the acceleration-driven damper (ADD, Savaresi et al. 2005) and the mixed
Skyhook-ADD law (Savaresi & Spelta 2007) each decide, every step, only whether the damper
should be "hard" (``c_max``) or "soft" (``c_min``). They run in the env's current mode and
command the two states directly: ``c_min`` is 0 A, ``c_max`` the current ``i_on`` (tuned;
``a = 2 i_on / i_max - 1``). Why not force mode: the law asks for a damper *state*, not a
force; going through an inverse model would only add its model error and its sensitivity to
the stroke noise, and would not reproduce the law (the inverse clips a force request to the
achievable band rather than switching states). ``i_on`` below ``i_max`` is the tuned
"hardness" of the on state: full current is often too hard for comfort.

All read the ``measured`` observation by default (name suffix ``-meas``); ``x' = z_c' -
z_b'`` is the LVDT's stroke rate, ``z_c'`` the on-board velocity estimate, ``z_c''`` the
car-body accelerometer.
"""

from __future__ import annotations

import math

import numpy as np
from capsule_env.agents.controllers.law import ClassicalLaw, law_name

#: The damper's maximum coil current (A): the env's ``i_max`` (current mode maps
#: ``a in [-1, 1]`` onto ``[0, i_max]``).
DEFAULT_MAX_CURRENT_A = 1.5
#: Fallback "on" current (A) [reconstructed] of an untuned two-state law.
I_ON_FALLBACK_A = 1.0
#: Fallback frequency selector (s) of mixed SH-ADD: ``1 / (2 pi f_cross)`` with the crossing
#: at 2.5 Hz, between the body (1.30 Hz) and bogie (5.42 Hz) modes [reconstructed].
ALPHA_FALLBACK_S = 1.0 / (2.0 * math.pi * 2.5)


class TwoStateController(ClassicalLaw):
    """Base of the two-state laws: ``i = i_on`` where :meth:`hard` is True, else 0 A.

    ``i_on`` (A; scalar or one per vehicle; None: the tuned value) must lie in
    ``[0, max_current_a]``.
    """

    #: Name of the law on ideal sensors (``-meas`` is appended on the measured set).
    BASE_NAME = "two-state"
    #: The on current (A), scalar or one per vehicle (set by :meth:`_set_gains`).
    i_on: np.ndarray

    def __init__(
        self,
        i_on: float | np.ndarray | None = None,
        observation: str = "measured",
        max_current_a: float = DEFAULT_MAX_CURRENT_A,
        extra_units: dict[str, str] | None = None,
        extra_given: dict | None = None,
        extra_fallback: dict[str, float] | None = None,
    ) -> None:
        super().__init__(observation)
        self.env_kwargs = {"observation": observation, "action_mode": "current"}
        self.max_current_a = float(max_current_a)
        self.name = law_name(self.BASE_NAME, observation)
        self._set_gains(
            {"i_on": "a", **(extra_units or {})},
            {"i_on": i_on, **(extra_given or {})},
            {"i_on": I_ON_FALLBACK_A, **(extra_fallback or {})},
        )
        if np.any((self.i_on < 0.0) | (self.i_on > self.max_current_a)):
            raise ValueError(f"i_on must be in [0, {self.max_current_a:g}] A, got {i_on!r}")

    def hard(self, obs: np.ndarray) -> np.ndarray:
        """Boolean per vehicle: True for ``c_max`` (``i_on``), False for ``c_min`` (0 A)."""
        raise NotImplementedError

    def act(self, obs: np.ndarray) -> np.ndarray:
        on = 2.0 * self.i_on / self.max_current_a - 1.0
        return np.where(self.hard(obs), on, -1.0)


class SkyhookTwoStateController(TwoStateController):
    """On-off Skyhook as a two-state law: hard when ``z_c' x' > 0``."""

    BASE_NAME = "skyhook"
    SIGNALS = ("body_velocity", "relative_velocity")

    def hard(self, obs: np.ndarray) -> np.ndarray:
        return self.signal(obs, "body_velocity") * self.signal(obs, "relative_velocity") > 0.0


class ADDController(TwoStateController):
    """Acceleration-driven damper (Savaresi et al. 2005): hard when ``z_c'' x' > 0`` (the
    damper force ``-c x'`` then opposes the body's acceleration)."""

    BASE_NAME = "add"
    SIGNALS = ("body_acceleration", "relative_velocity")

    def hard(self, obs: np.ndarray) -> np.ndarray:
        return self.signal(obs, "body_acceleration") * self.signal(obs, "relative_velocity") > 0.0


class MixedSkyhookADDController(TwoStateController):
    """Mixed Skyhook-ADD (Savaresi & Spelta 2007), quasi-optimal among causal semi-active laws:
    hard if ``z_c'^2 - alpha^2 z_c''^2 <= 0`` and ``z_c'' x' > 0`` (ADD where the
    acceleration dominates: above the crossing frequency) or ``z_c'^2 - alpha^2 z_c''^2 > 0``
    and ``z_c' x' > 0`` (Skyhook where the velocity dominates); else soft.

    ``alpha`` (s, scalar or per vehicle; None: tuned) is the frequency selector, about
    ``1 / (2 pi f_cross)``.
    """

    BASE_NAME = "sh-add"
    SIGNALS = ("body_velocity", "body_acceleration", "relative_velocity")
    #: The frequency selector (s), scalar or one per vehicle (set by :meth:`_set_gains`).
    alpha: np.ndarray

    def __init__(
        self,
        i_on: float | np.ndarray | None = None,
        alpha: float | np.ndarray | None = None,
        observation: str = "measured",
        max_current_a: float = DEFAULT_MAX_CURRENT_A,
    ) -> None:
        super().__init__(
            i_on, observation, max_current_a,
            {"alpha": "s"}, {"alpha": alpha}, {"alpha": ALPHA_FALLBACK_S},
        )  # fmt: skip
        if np.any(self.alpha < 0.0):
            raise ValueError(f"alpha must be >= 0 s, got {alpha!r}")

    def hard(self, obs: np.ndarray) -> np.ndarray:
        vel = self.signal(obs, "body_velocity")
        acc = self.signal(obs, "body_acceleration")
        rel = self.signal(obs, "relative_velocity")
        skyhook_region = vel * vel - self.alpha * self.alpha * acc * acc > 0.0
        return np.where(skyhook_region, vel * rel > 0.0, acc * rel > 0.0)
