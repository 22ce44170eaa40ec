"""Native batched env over a declared vehicle: ``num_envs`` vehicles, one compiled plant call
a step (:class:`capsule_env.engine.declared_batch.DeclaredBatch`).

Same dynamics, spaces, reward and options as
:class:`capsule_env.envs.declared_vehicle.DeclaredVehicleEnv`, plus ``num_envs`` and
``max_episode_steps`` (the earlier of it and the env's own length ends an episode). Autoreset in
Gymnasium's ``NEXT_STEP`` mode (the step after an episode ends resets that vehicle and returns
its first observation, reward 0, ``terminated = truncated = False``; its action is ignored).
``reset(seed=s)`` gives the vehicles the streams ``SeedSequence(s).spawn(num_envs)`` (vehicle 0
is the single env seeded ``s``); ``reset(seed=[s_0, ...])`` gives vehicle ``n`` the single
env's stream of ``s_n`` (None: vehicle ``n``'s stream goes on, as in ``SyncVectorEnv``).
``info``: a dict of arrays, one row per vehicle, each with its ``_key`` mask, as
``SyncVectorEnv`` over the single env gives it (the reward terms are 0 at a reset, and at an
autoreset step for the vehicles that restart: their info is the reset's). ``step`` before the
first ``reset`` raises ``gymnasium.error.ResetNeeded``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space

from capsule_env.engine.declared_batch import COST_NAMES
from capsule_env.envs._actions import real_actions
from capsule_env.envs._compat import AutoresetMode, check_autoreset_mode
from capsule_env.envs._seeds import reseed
from capsule_env.envs.declared_vehicle import declared_setup, declared_spaces, runs_compiled_kwargs
from capsule_env.envs.render import check_render_mode

__all__ = ["DeclaredVectorEnv", "make_suspension_vector_env"]


class DeclaredVectorEnv(VectorEnv):
    """``num_envs`` vehicles of a declared vehicle (module doc)."""

    metadata = {"render_modes": [], "render_fps": 200, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        autoreset_mode: Any = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        check_render_mode(render_mode, drawn=False)  # make_vec passes it on
        if check_autoreset_mode(autoreset_mode) is not AutoresetMode.NEXT_STEP:
            raise ValueError(f"autoreset_mode must be NEXT_STEP for a declared vehicle (the "
                             f"others are not built for it yet), got {autoreset_mode!r}")  # fmt: skip
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.num_envs = int(num_envs)
        self._batch = batch = declared_setup("DeclaredVectorEnv.__init__", kwargs, self.num_envs)
        if max_episode_steps is not None:
            if isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, int | np.integer
            ) or max_episode_steps < 1:  # fmt: skip
                raise ValueError(
                    f"max_episode_steps must be an integer >= 1, got {max_episode_steps!r}"
                )
            batch.max_steps = min(batch.max_steps, int(max_episode_steps))
        self.config = batch.config
        self.render_mode = None
        self.metadata = {**type(self).metadata, "render_fps": self.config.control_rate_hz}
        self.single_action_space, self.single_observation_space = declared_spaces(batch)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.observation_names = batch.observation_names()
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    @property
    def batch(self) -> Any:
        """The underlying simulation."""
        return self._batch

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every vehicle's episode: ``(observations, info)`` (module doc: the seeds)."""
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; accepted: none")
        reseed(self._batch, seed, self.num_envs)  # None in a list: that vehicle's stream on
        super().reset(seed=int(seed) if isinstance(seed, (int, np.integer)) else None)
        self._batch.reset()
        self._autoreset[:] = False
        self._started = True
        sig = self._batch.signals()
        return self._batch.observe(sig), _masked(sig)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """One control step of every vehicle, ``actions`` of shape ``(num_envs, slots)``:
        ``(observations, rewards, terminated, truncated, info)`` (``NEXT_STEP`` autoreset)."""
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        batch = self._batch
        shape = (self.num_envs, batch.n_slots)
        a = np.asarray(real_actions(actions), dtype=np.float64)  # not complex, strings
        if a.shape != shape and not (batch.n_slots == 1 and a.shape == shape[:1]):
            raise ValueError(f"actions must have shape {shape}, got {a.shape}")
        a = a.reshape(shape)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions must be finite")
        restart = self._autoreset.copy()
        sig, reward, terminated, costs, obs = batch.step_scored(np.clip(a, -1.0, 1.0))
        truncated = batch.step_count >= batch.max_steps
        if restart.any():  # NEXT_STEP: these vehicles start a new episode instead
            batch.reset(np.flatnonzero(restart))
            sig = batch.signals()
            reward[restart], terminated[restart], truncated[restart] = 0.0, False, False
            obs = batch.observe(sig)
        self._autoreset = terminated | truncated
        return obs, reward, terminated, truncated, _masked(sig, costs, restart)


def _masked(
    signals: dict[str, np.ndarray],
    costs: dict[str, np.ndarray] | None = None,
    restarted: np.ndarray | None = None,
) -> dict[str, Any]:
    """The info dict as Gymnasium's ``SyncVectorEnv`` builds it over the single env: each key
    with its ``_key`` mask (all True); the reward terms 0 at a reset (``costs`` None) and for
    the vehicles ``restarted`` at this step (NEXT_STEP: their info is the reset's)."""
    n = len(next(iter(signals.values())))
    every = np.ones(n, dtype=bool)
    if costs is None:
        costs = {name: np.zeros(n) for name in COST_NAMES}
    elif restarted is not None and restarted.any():
        costs = {name: np.where(restarted, 0.0, values) for name, values in costs.items()}
    info: dict[str, Any] = {}
    for key, values in {**signals, **costs}.items():
        info[key], info["_" + key] = values, every
    return info


def make_suspension_vector_env(num_envs: int = 1, **kwargs: Any) -> VectorEnv:
    """``CapsuleSuspension-v0``'s vector entry point: the quarter-car's native vector env for a
    vehicle of its form, :class:`DeclaredVectorEnv` for any other."""
    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv

    if runs_compiled_kwargs(kwargs):
        return CapsuleSuspensionVectorEnv(num_envs, **kwargs)
    return DeclaredVectorEnv(num_envs, **kwargs)
