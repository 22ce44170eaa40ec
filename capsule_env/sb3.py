"""A stable-baselines3 ``VecEnv`` over the batched kernel, for fast training.

SB3's vector-env conventions differ from Gymnasium's: episodes reset in the *same* step that
ends them; the last observation of the finished episode is in ``infos[n]["terminal_observation"]``
and ``infos[n]["TimeLimit.truncated"]`` tells a time limit from a termination. This class
implements them directly on :class:`capsule_env.core.CapsuleBatch` (no per-env Python objects),
so a step of N vehicles costs one kernel call. ``seed(s)`` gives vehicle n the seed ``s + n``,
exactly as the native vector env and the single env with seed ``s + n``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from capsule_env.core import SIGNAL_NAMES, CapsuleBatch, EnvConfig
from capsule_env.envs.capsule_suspension import _render_one, _spaces

__all__ = ["CapsuleSuspensionSB3VecEnv", "make_sb3_vec_env"]


class CapsuleSuspensionSB3VecEnv(VecEnv):
    """``CapsuleSuspension-v0`` as an SB3 ``VecEnv`` of ``num_envs`` vehicles.

    Parameters
    ----------
    num_envs : number of vehicles.
    info_signals : add the physical signals and reward terms (``SIGNAL_NAMES``) to every
        step's info dicts (costs time for large batches; off by default).
    render_mode : None or ``"rgb_array"``.
    **kwargs : any ``CapsuleSuspension-v0`` argument (:class:`capsule_env.core.EnvConfig`).
    """

    def __init__(
        self,
        num_envs: int = 1,
        info_signals: bool = False,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        self.config = EnvConfig.from_kwargs(**kwargs)
        self.batch = CapsuleBatch(self.config, num_envs)
        action_space, observation_space = _spaces(self.config)
        self.render_mode = render_mode
        super().__init__(num_envs, observation_space, action_space)
        self.info_signals = bool(info_signals)
        self._actions = np.zeros(num_envs)

    def reset(self) -> np.ndarray:
        if self._seeds[0] is not None:
            self.batch.rngs = [np.random.default_rng(int(s)) for s in self._seeds]
        self._reset_seeds()
        self._reset_options()
        self.batch.reset()
        return self.batch.obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float64).reshape(self.num_envs)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        batch = self.batch
        batch.step(self._actions)
        reward = batch.reward.astype(np.float32)
        terminated = batch.terminated
        truncated = batch.step_count >= batch.max_steps
        dones = terminated | truncated
        if self.info_signals:
            rows = batch.signals.T.tolist()
            infos = [dict(zip(SIGNAL_NAMES, row, strict=True)) for row in rows]
        else:
            infos = [{} for _ in range(self.num_envs)]
        if dones.any():
            ended = np.flatnonzero(dones)
            for n in ended:
                infos[n]["terminal_observation"] = batch.obs[n].copy()
                infos[n]["TimeLimit.truncated"] = bool(truncated[n] and not terminated[n])
            batch.reset(dones)
        return batch.obs.copy(), reward, dones.copy(), infos

    def close(self) -> None:
        return None

    # ---- SB3 VecEnv plumbing: one object serves every index ----
    def _count(self, indices: VecEnvIndices) -> int:
        return len(self._get_indices(indices))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        target = self.config if hasattr(self.config, attr_name) else self
        return [getattr(target, attr_name)] * self._count(indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        if method_name == "render":
            return [_render_one(self.batch, n) for n in self._get_indices(indices)]
        method = getattr(self, method_name)
        return [method(*method_args, **kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False] * self._count(indices)

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [_render_one(self.batch, n) for n in range(self.num_envs)]

    def _get_indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices


def make_sb3_vec_env(num_envs: int = 8, seed: int | None = None, **kwargs: Any):
    """Build the SB3 VecEnv, wrapped in ``VecMonitor`` (episode returns for SB3's logger)."""
    from stable_baselines3.common.vec_env import VecMonitor

    env = CapsuleSuspensionSB3VecEnv(num_envs, **kwargs)
    if seed is not None:
        env.seed(seed)
    return VecMonitor(env)
