"""The controller interface shared by classical and learned controllers."""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.engine.config import FULL_STATE_NAMES, MEASURED_NAMES

#: Column of each full-state signal in the ``full_state`` observation.
FULL = {name: k for k, name in enumerate(FULL_STATE_NAMES)}
#: Column of each signal in the ``measured`` observation.
MEAS = {name: k for k, name in enumerate(MEASURED_NAMES)}
#: What each value of :attr:`Controller.observation` may read (the tables' group headers).
OBSERVATION_GROUPS = {
    "none": "open loop: reads no signal",
    "measured": "measured: only the capsule's own sensors (accelerometers, LVDT, gap, coil "
    "current) and on-board velocity estimates",
    "sensors": "sensors: accelerometers, stroke, stroke rate and the last current command",
    "full_state": "full_state, ideal sensors: true displacements, absolute velocities, "
    "guideway elevation (references)",
    "measured+preview": "measured + guideway preview: the measured signals and the surveyed "
    "elevations ahead (survey map and position known on board)",
    "full_state+preview": "full_state + guideway preview: ideal sensors and the surveyed "
    "elevations ahead (references)",
    "oracle+preview": "oracle: knows the whole guideway and sets the applied current directly, "
    "no noise, delay or inverse model (capsule_env.oracle; a local search: an upper bound on "
    "the clairvoyant optimum)",
}


def restarted_vehicles(episode_start: Any, observation: Any) -> list[int]:
    """The vehicles whose episode starts (SB3's ``episode_start``: one flag per row of
    ``observation``); ``ValueError`` naming ``episode_start`` for another number of flags."""
    start = np.asarray(episode_start).reshape(-1)
    rows = np.atleast_2d(np.asarray(observation)).shape[0]
    if start.shape != (rows,):
        raise ValueError(f"episode_start must hold one flag per vehicle ({rows}), got shape "
                         f"{np.shape(episode_start)}")  # fmt: skip
    return np.flatnonzero(start.astype(bool)).tolist()


class Controller:
    """Base class: a batched, stateless-by-default feedback law.

    Attributes
    ----------
    name : short identifier used in tables and JSON (e.g. ``"skyhook-biexp"``).
    env_kwargs : environment options this controller needs (merged into the env's).
    feedback : False for an open-loop law that reads no signal (then :attr:`observation` is
        ``"none"``).
    preview : True if it reads the guideway ahead of the vehicle (the surveyed elevations of
        the env's ``preview_points`` option).
    """

    name: str = "controller"
    env_kwargs: dict[str, Any] = {}
    feedback: bool = True

    @property
    def preview(self) -> bool:
        """True if the law reads the guideway preview (its env asks for ``preview_points``)."""
        return int(self.env_kwargs.get("preview_points", 0) or 0) > 0

    @property
    def observation(self) -> str:
        """The observation set the law reads: ``"measured"``, ``"full_state"``, ``"sensors"``
        (the env's options), or ``"none"`` for an open-loop law."""
        if not self.feedback:
            return "none"
        return str(self.env_kwargs.get("observation", "sensors"))

    @property
    def uses_unmeasured_signals(self) -> bool:
        """True if it reads states a vehicle measures only indirectly (absolute velocities
        and displacements, the guideway): the ``full_state`` observation."""
        return self.observation == "full_state"

    def gains(self) -> dict[str, Any]:
        """The law's gains, each key ending with its unit (``_n_s_m`` N s/m, ``_a`` A, ``_s``
        s, ``_rel`` dimensionless, ...); a float per gain, or a list for per-vehicle gains.
        Empty for a law without gains (and for learned policies: their parameters are
        network weights)."""
        return {}

    def reset(self) -> None:
        """Forget any internal state (called at episode start)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3-compatible: ``(actions (N, slots) float32, state)`` for observations ``(N, d)``
        (one action per damper slot: 1 on the quarter-car)."""
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float64))
        action = np.asarray(self.act(obs), dtype=np.float32).reshape(obs.shape[0], -1)
        return np.clip(action, -1.0, 1.0), state
