"""The two open/closed-loop policies the study runs through the env's own inverses.

The library does not import the controllers package (``agents/``, installed as
``capsule_env.agents``), so the study has its own copies of the two laws it needs, written to
give the same actions as ``passive`` and the paper-reproduction on-off Skyhooks
(``skyhook-biexp``, ``skyhook-csdc``): tests/test_paper_sensitivity.py checks that the study's
baseline is evaluate.py's paper rows.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.engine.config import FULL_STATE_NAMES

__all__ = ["ForceSkyhook", "PassivePolicy"]

_COL = {name: k for k, name in enumerate(FULL_STATE_NAMES)}


class PassivePolicy:
    """The passive suspension: the linear damper ``c_s``; the action is ignored."""

    env_kwargs = {"damper": "passive", "action_mode": "current"}

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        return np.zeros((np.atleast_2d(observation).shape[0], 1)), state


class ForceSkyhook:
    """On-off Skyhook on ideal sensors through the env's inverse (force mode): ``F_d = c_max
    v`` when ``z_c' v > 0``, else ``c_min v``, ``v = z_c' - z_b'``; the action is ``F_d /
    max_force_n`` (paper eq. 15).

    Parameters
    ----------
    inverse_model : ``"bi_exponential"`` or ``"csdc"`` (the env's ``inverse_model``).
    c_max, c_min : gains (N s/m).
    max_force_n : the env's force scale (N).
    """

    def __init__(self, inverse_model: str, c_max: float = 7.0e4, c_min: float = 0.0,
                 max_force_n: float = 8000.0) -> None:  # fmt: skip
        self.c_max, self.c_min, self.max_force_n = float(c_max), float(c_min), float(max_force_n)
        self.env_kwargs = {"observation": "full_state", "action_mode": "force",
                           "inverse_model": inverse_model, "max_force_n": self.max_force_n}  # fmt: skip

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        obs = np.atleast_2d(observation)
        body = obs[:, _COL["car_body_velocity_m_s"]]
        rel = body - obs[:, _COL["bogie_velocity_m_s"]]
        force = np.where(body * rel > 0.0, self.c_max * rel, self.c_min * rel)
        return (force / self.max_force_n).reshape(-1, 1), state
