"""Record whole episodes of a controller: observations, actions, rewards, ends and signals.

One native vector env (:class:`~capsule_env.envs.capsule_suspension.CapsuleSuspensionVectorEnv`)
runs every episode at once, episode ``k`` the single env seeded ``seeds[k]`` (the vector env's
``reset(seed=[...])``: bit for bit the single env's episode, as
:func:`capsule_env.evaluation.episodes.run_episodes` runs them). Each episode is cut at its
first ``terminated`` (the bump stop) or ``truncated`` (its length) step; what the vector env's
autoreset runs after that is not recorded.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv
from capsule_env.evaluation.episodes import RECORDED, Policy

__all__ = ["Episode", "record_episodes"]


@dataclass
class Episode:
    """One recorded episode of ``T`` steps, in Minari's layout.

    Attributes
    ----------
    seed : the single env's reset seed.
    observations : (T + 1, obs_dim) float32, the reset's observation first.
    actions : (T, action_dim) float32, what the env was given (in ``[-1, 1]``).
    rewards : (T,) the env's rewards.
    terminations, truncations : (T,) bool.
    infos : signal name -> (T + 1,) float64, the reset's info first (units in the names).
    """

    seed: int
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict[str, np.ndarray]

    @property
    def steps(self) -> int:
        return int(self.rewards.shape[0])


def _stack(rows: list[np.ndarray], k: int, stop: int) -> np.ndarray:
    return np.stack([row[k] for row in rows[:stop]])


def _episodes(record: dict[str, Any], seeds: Sequence[int], ends: np.ndarray) -> list[Episode]:
    """Cut each vehicle's rows at its episode's end (``ends[k]`` steps)."""
    out = []
    for k, seed in enumerate(seeds):
        t = int(ends[k])
        infos = {name: np.array([row[k] for row in rows[: t + 1]], dtype=np.float64)
                 for name, rows in record["infos"].items()}  # fmt: skip
        out.append(Episode(
            seed=int(seed),
            observations=_stack(record["obs"], k, t + 1).astype(np.float32),
            actions=_stack(record["actions"], k, t).astype(np.float32),
            rewards=np.array([row[k] for row in record["rewards"][:t]]),
            terminations=np.array([row[k] for row in record["terminated"][:t]], dtype=bool),
            truncations=np.array([row[k] for row in record["truncated"][:t]], dtype=bool),
            infos=infos,
        ))  # fmt: skip
    return out


def record_episodes(
    policy: Policy,
    env_kwargs: dict[str, Any],
    seeds: Sequence[int],
    episode_length_s: float,
    signals: Sequence[str] = RECORDED,
) -> list[Episode]:
    """Run ``policy`` (anything with SB3's ``predict``; its ``reset()`` is called first, when
    it has one) for one episode per seed of ``seeds`` in the env of ``env_kwargs`` (the
    guideway bank is theirs: the env's default, the training bank, unless they name one),
    recording the ``info`` entries ``signals`` besides the transitions."""
    env = CapsuleSuspensionVectorEnv(num_envs=len(seeds), episode_length_s=episode_length_s,
                                     **env_kwargs)  # fmt: skip
    obs, info = env.reset(seed=[int(s) for s in seeds])
    if hasattr(policy, "reset"):
        policy.reset()
    record: dict[str, Any] = {"obs": [obs.copy()], "actions": [], "rewards": [],
                              "terminated": [], "truncated": [],
                              "infos": {name: [np.array(info[name])] for name in signals}}  # fmt: skip
    ends = np.full(len(seeds), -1)
    start = np.ones(len(seeds), dtype=bool)
    state = None
    for t in range(env.batch.max_steps):
        actions, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start[:] = False
        actions = np.asarray(actions, dtype=np.float32).reshape(len(seeds), -1)
        obs, reward, terminated, truncated, info = env.step(actions)
        for key, value in (("obs", obs), ("actions", actions), ("rewards", reward),
                           ("terminated", terminated), ("truncated", truncated)):  # fmt: skip
            record[key].append(np.array(value, copy=True))
        for name in signals:
            record["infos"][name].append(np.array(info[name]))
        ends[(ends < 0) & (terminated | truncated)] = t + 1
        if np.all(ends > 0):
            break
    env.close()
    ends[ends < 0] = env.batch.max_steps
    return _episodes(record, seeds, ends)
