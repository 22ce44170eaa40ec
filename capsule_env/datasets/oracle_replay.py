"""The oracle's episodes as transitions: its applied currents replayed through the env.

:func:`capsule_env.oracle.clairvoyant_bound` searches, per episode, the coil-current sequence
applied to the plant (A, in ``[0, i_max]``), knowing the whole guideway; it does not step the
env, so it has no observations or rewards of its own. Here each sequence is replayed in the
task's env with ``action_mode="current"`` (action ``a`` commands the current
``(a + 1) / 2 * i_max``) and ``control_delay_steps=0`` (the command of step ``t`` is applied in
step ``t``): the recorded action *is* the applied current, scaled to ``[-1, 1]``. The coil's
lag, where the setting has one, acts on it as in the search (physics, not control); the
observations carry the task's sensor noise, which the search never read. The replay is
checked against the search's own run: the car-body acceleration agrees to
:data:`REPLAY_TOLERANCE_M_S2` (the actions are float32, the env's action dtype: the current is
rounded to about 1e-7 of ``i_max``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from capsule_env.agents.controllers.base import Controller
from capsule_env.datasets.rollouts import Episode, record_episodes

__all__ = ["REPLAY_TOLERANCE_M_S2", "CurrentReplay", "oracle_episodes"]

#: Largest difference of the car-body acceleration (m/s^2) between the search's run and the
#: env's replay of its float32 actions (measured: 8e-9 on CapsuleRide-v0).
REPLAY_TOLERANCE_M_S2 = 1e-5


class CurrentReplay(Controller):
    """Open loop: at its ``t``-th call, row ``t`` of ``currents_a`` (E, T) as current-mode
    actions ``2 u / i_max - 1`` (one row per episode of the batch)."""

    name = "oracle"
    env_kwargs = {"action_mode": "current", "control_delay_steps": 0}
    feedback = False

    def __init__(self, currents_a: np.ndarray, i_max_a: float) -> None:
        self.actions = 2.0 * np.asarray(currents_a, dtype=np.float64) / float(i_max_a) - 1.0
        self.t = 0

    def reset(self) -> None:
        self.t = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        column = self.actions[:, min(self.t, self.actions.shape[1] - 1)]
        self.t += 1
        return column


def oracle_episodes(
    env_kwargs: dict[str, Any],
    seeds: Sequence[int],
    episode_length_s: float,
    search: dict[str, Any] | None = None,
) -> tuple[list[Episode], dict[str, Any]]:
    """The oracle's episodes on ``seeds`` in the env of ``env_kwargs`` (its guideway bank
    theirs: the env's default unless they name one), recorded as transitions (module
    docstring), and the search's summary (:meth:`~capsule_env.oracle.OracleResult.summary`).
    ``search``: options of :func:`~capsule_env.oracle.clairvoyant_bound` (``max_iter``,
    ``restarts``, ...). ``RuntimeError`` when the replay departs from the search's run."""
    from capsule_env.engine.config import EnvConfig
    from capsule_env.oracle import clairvoyant_bound

    kwargs = {"guideway_seed": EnvConfig().guideway_seed, **env_kwargs}
    result = clairvoyant_bound(kwargs, list(seeds), episode_length_s, **(search or {}))
    replay_kwargs = {**kwargs, **CurrentReplay.env_kwargs}
    i_max = EnvConfig.from_kwargs(**replay_kwargs, episode_length_s=episode_length_s).max_current_a
    episodes = record_episodes(CurrentReplay(result.currents_a, i_max), replay_kwargs, seeds,
                               episode_length_s)  # fmt: skip
    searched = result.signals["car_body_acceleration_m_s2"]
    for k, episode in enumerate(episodes):
        replayed = episode.infos["car_body_acceleration_m_s2"][1:]
        gap = float(np.max(np.abs(replayed - searched[k, : replayed.size])))
        if not gap <= REPLAY_TOLERANCE_M_S2:
            raise RuntimeError(f"the env's replay of the oracle's currents departs from the "
                               f"search's run on seed {episode.seed} by {gap:.3g} m/s^2")  # fmt: skip
    return episodes, result.summary()
