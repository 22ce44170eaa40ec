"""The controller interface shared by classical and learned controllers."""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.config import FULL_STATE_NAMES

#: Column of each full-state signal in the ``full_state`` observation.
FULL = {name: k for k, name in enumerate(FULL_STATE_NAMES)}


class Controller:
    """Base class: a batched, stateless-by-default feedback law.

    Attributes
    ----------
    name : short identifier used in tables and JSON (e.g. ``"skyhook-biexp"``).
    env_kwargs : environment options this controller needs (merged into the env's).
    uses_unmeasured_signals : True if it reads states a vehicle measures only indirectly
        (absolute velocities, the guideway), i.e. needs ``observation="full_state"``.
    """

    name: str = "controller"
    env_kwargs: dict[str, Any] = {}
    uses_unmeasured_signals: bool = False

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
        """SB3-compatible: ``(actions (N, 1) float32, state)`` for observations ``(N, d)``."""
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float64))
        action = np.asarray(self.act(obs), dtype=np.float32).reshape(obs.shape[0], 1)
        return np.clip(action, -1.0, 1.0), state
