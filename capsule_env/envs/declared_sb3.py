"""A stable-baselines3 ``VecEnv`` over a declared vehicle's batch (the half-car's), for training.

SB3's conventions, as :class:`capsule_env.envs.sb3.CapsuleSuspensionSB3VecEnv` implements them
for the quarter-car: an episode resets in the step that ends it, its last observation in
``infos[n]["terminal_observation"]``, ``infos[n]["TimeLimit.truncated"]`` telling a time limit
from the bump stop. ``seed(s)`` gives the vehicles ``SeedSequence(s).spawn(num_envs)``: vehicle
``n`` runs the episodes of the single env seeded from that stream, whatever the batch.
``step_async`` before the first ``reset`` raises ``gymnasium.error.ResetNeeded``; actions of
another shape, NaN or infinity raise ``ValueError``, complex ones or strings ``TypeError``
(the others are clipped to [-1, 1]). ``set_options`` refuses any option by name (``reset``
takes none), as the quarter-car's does (:func:`capsule_env.envs.sb3.check_vec_options`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from capsule_env.engine.config import check_num_envs, check_seed
from capsule_env.envs._actions import real_actions
from capsule_env.envs.declared_vehicle import declared_setup, declared_spaces
from capsule_env.envs.render import check_render_mode
from capsule_env.envs.sb3 import check_settable, check_vec_options

__all__ = ["DeclaredSB3VecEnv"]


class DeclaredSB3VecEnv(VecEnv):
    """``num_envs`` vehicles of a declared vehicle as an SB3 ``VecEnv`` (``kwargs``: the env's
    options, e.g. ``CapsuleHalfRide-v0``'s)."""

    def __init__(self, num_envs: int = 1, render_mode: str | None = None, **kwargs: Any) -> None:
        check_render_mode(render_mode, drawn=False)  # no picture of a declared vehicle
        num_envs = check_num_envs(num_envs)
        self.batch = declared_setup("DeclaredSB3VecEnv.__init__", kwargs, num_envs)
        self.config = self.batch.config
        action_space, observation_space = declared_spaces(self.batch)
        self.render_mode = None
        super().__init__(num_envs, observation_space, action_space)
        self._actions = np.zeros((num_envs, self.batch.n_slots))
        self._seed: int | None = None
        self._needs_reset = True
        self._obs = np.zeros((num_envs, observation_space.shape[0]), dtype=np.float32)

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        self._seed = None if seed is None else check_seed("seed", seed)
        return [self._seed] * self.num_envs

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        """``reset`` takes no option: ``None``, ``{}`` or empty dicts pass, any key raises
        ``ValueError`` here rather than being dropped at the next reset."""
        check_vec_options(options, self.num_envs)
        super().set_options(options)

    def reset(self) -> np.ndarray:
        if self._seed is not None:
            self.batch.seed(self._seed)
            self._seed = None
        self._reset_options()
        self.batch.reset()
        self._needs_reset = False
        self._obs = self.batch.observe(self.batch.signals())
        return self._obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        if self._needs_reset:
            raise ResetNeeded("call reset() before step()")
        a = np.asarray(real_actions(actions), dtype=np.float64)  # not complex, strings
        if a.shape != self._actions.shape:
            raise ValueError(f"actions must have shape {self._actions.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("actions must be finite (no NaN or infinity)")
        self._actions = np.clip(a, -1.0, 1.0)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        batch = self.batch
        _, reward, terminated, _, obs = batch.step_scored(self._actions)
        truncated = batch.step_count >= batch.max_steps
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if dones.any():
            ended = np.flatnonzero(dones)
            for n in ended:
                infos[n]["terminal_observation"] = obs[n].copy()
                infos[n]["TimeLimit.truncated"] = bool(truncated[n] and not terminated[n])
            batch.reset(ended)
            obs[ended] = batch.observe(batch.signals())[ended]
        self._obs = obs
        return obs.copy(), reward.astype(np.float32), dones, infos

    def close(self) -> None:
        return None

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        target = self.config if hasattr(self.config, attr_name) else self
        return [getattr(target, attr_name)] * len(list(self._indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        check_settable(self.config, attr_name, indices, self.num_envs)  # options, some indices
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        method = getattr(self, method_name)
        return [method(*method_args, **kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(list(self._indices(indices)))

    def _indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        return [indices] if isinstance(indices, int) else indices
