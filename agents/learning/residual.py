"""Residual policies: a learned correction added to a classical law's request.

Residual reinforcement learning (Johannink et al., "Residual reinforcement learning for robot
control", ICRA 2019; Silver et al., "Residual policy learning", arXiv:1812.06298, 2018) learns
``a = clip(a_law(obs) + scale * a_policy(obs), -1, 1)`` on top of a good controller instead of
from scratch. Here the law is any classical controller of :mod:`capsule_env.agents.controllers.classical`
that reads the env's observation (e.g. ``lqr-clipped-biexp-meas`` on ``CapsuleRide-v0``); the
policy sees the env's observation unchanged and outputs the residual in ``[-1, 1]``, scaled by
``scale`` (default 0.5: half the action range, 4 kN in force mode).

Three wrappers, one rule (:func:`combine_actions`), so any algorithm trains on it:

- :class:`ResidualEnv`: a Gymnasium ``Wrapper`` of a single env;
- :class:`ResidualVectorEnv`: a ``gymnasium.vector.VectorWrapper`` of the native vector env
  (every autoreset mode);
- :class:`ResidualVecEnv`: an SB3 ``VecEnvWrapper`` (what ``train.py`` trains on).

:class:`ResidualPolicy` is the same sum as a controller (for ``evaluate.py`` and
:func:`capsule_env.evaluation.episodes.run_episodes`), and :func:`zero_last_layer` zeroes an SB3
policy's output layer so that training starts from the law's behaviour exactly (the residual's
mean is 0; PPO's exploration noise still perturbs it while learning).

The law keeps its own state (the preview LQ law's record of its requests in flight records its
own request, not the sum the env receives).
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from capsule_env.agents.controllers.base import Controller

from capsule_env.envs._compat import AutoresetMode
from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

try:  # the SB3 wrapper needs the rl extra; the others do not
    from stable_baselines3.common.vec_env import VecEnvWrapper

    _HAS_SB3 = True
except ImportError:  # pragma: no cover - exercised only without stable-baselines3
    # mypy runs with the dev extra (stable-baselines3 installed): this branch is not checked
    VecEnvWrapper = object  # type: ignore[assignment,misc]
    _HAS_SB3 = False

__all__ = [
    "combine_actions",
    "check_law_fits",
    "ResidualEnv",
    "ResidualVectorEnv",
    "ResidualVecEnv",
    "ResidualPolicy",
    "zero_last_layer",
]


def combine_actions(base: np.ndarray, residual: np.ndarray, scale: float) -> np.ndarray:
    """``clip(base + scale * residual, -1, 1)`` as float32 (the env's action dtype)."""
    total = np.asarray(base, dtype=np.float64) + scale * np.asarray(residual, dtype=np.float64)
    return np.clip(total, -1.0, 1.0).astype(np.float32)


def _check_scale(scale: float) -> float:
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0.0 < scale <= 2.0:
        raise ValueError(f"scale must be a number in (0, 2], got {scale!r}")
    return float(scale)


def check_law_fits(law: Controller, config: Any) -> None:
    """Raise ``ValueError`` naming the option when the law cannot act on the env: it needs an
    observation set, a preview (points, and the horizon they span) or an action mode other than
    the env's (``config`` is the env's :class:`~capsule_env.engine.config.EnvConfig`)."""
    if not isinstance(law, Controller) or not law.feedback:
        raise ValueError(f"law must be a feedback Controller, got {law!r}")
    needs = {"observation": law.observation, "action_mode": law.env_kwargs.get("action_mode",
             "force"), "preview_points": int(law.env_kwargs.get("preview_points", 0) or 0)}  # fmt: skip
    if needs["preview_points"]:  # the law reads the points as spread over its own horizon
        needs["preview_horizon_s"] = float(law.env_kwargs["preview_horizon_s"])
    for key, value in needs.items():
        if getattr(config, key) != value:
            raise ValueError(
                f"law {law.name!r} needs the env option {key}={value!r}, the env has "
                f"{key}={getattr(config, key)!r}"
            )


def _base_actions(law: Controller, obs: np.ndarray, start: np.ndarray) -> np.ndarray:
    actions, _ = law.predict(np.atleast_2d(obs), episode_start=start, deterministic=True)
    return actions[:, 0]


class ResidualEnv(gym.Wrapper):
    """A single env whose action is the residual added to ``law``'s request."""

    def __init__(self, env: gym.Env, law: Controller, scale: float = 0.5) -> None:
        super().__init__(env)
        if not isinstance(env.unwrapped, CapsuleSuspensionEnv):
            raise ValueError(f"env must wrap CapsuleSuspensionEnv, got {env.unwrapped!r}")
        check_law_fits(law, env.unwrapped.config)
        self.law, self.scale = law, _check_scale(scale)
        self._obs: np.ndarray | None = None
        self._start = np.ones(1, dtype=bool)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self.law.reset()
        self._obs, self._start[:] = obs, True
        return obs, info

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        base = _base_actions(self.law, self._obs, self._start)
        self._start[:] = False
        total = combine_actions(base, np.reshape(action, (1,)), self.scale)
        obs, reward, terminated, truncated, info = self.env.step(total)
        self._obs = obs
        return obs, reward, terminated, truncated, info


class ResidualVectorEnv(gym.vector.VectorWrapper):
    """The native vector env (:class:`CapsuleSuspensionVectorEnv`) with residual actions; a
    vehicle's law state restarts with its episode, whatever the autoreset mode."""

    def __init__(self, env: gym.vector.VectorEnv, law: Controller, scale: float = 0.5) -> None:
        super().__init__(env)
        if not isinstance(env.unwrapped, CapsuleSuspensionVectorEnv):
            raise ValueError(f"env must be a CapsuleSuspensionVectorEnv, got {env.unwrapped!r}")
        check_law_fits(law, env.unwrapped.config)
        self.law, self.scale = law, _check_scale(scale)
        self._mode = AutoresetMode(env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP))
        self._obs: np.ndarray | None = None
        self._start = np.ones(self.num_envs, dtype=bool)
        self._resets_next = np.zeros(self.num_envs, dtype=bool)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self.law.reset()
        self._obs = obs
        self._start[:], self._resets_next[:] = True, False
        return obs, info

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        base = _base_actions(self.law, self._obs, self._start)
        total = combine_actions(base, np.reshape(actions, (self.num_envs,)), self.scale)
        obs, reward, terminated, truncated, info = self.env.step(total[:, None])
        done = terminated | truncated
        if self._mode == AutoresetMode.NEXT_STEP:
            # this step reset the vehicles that ended last step: their obs starts an episode
            self._start = self._resets_next.copy()
            self._resets_next = done
        else:  # SAME_STEP: the obs of an ended vehicle is its next episode's first
            self._start = done.copy()
        self._obs = obs
        return obs, reward, terminated, truncated, info


class ResidualPolicy(Controller):
    """``law`` plus a learned residual ``policy`` (anything with SB3's ``predict``), as one
    controller: what :class:`ResidualEnv` applies, for evaluation; one action per damper slot
    (a declared vehicle's law and policy act on each of its slots, e.g. the half-car's two).
    A vehicle whose observation holds a NaN or inf gets its law's action alone (the law
    decides what to do with it; the network does not read it)."""

    def __init__(self, law: Controller, policy: Any, scale: float = 0.5, name: str = "") -> None:
        self.law, self.policy, self.scale = law, policy, _check_scale(scale)
        self.name = name or f"residual-{law.name}"
        self.env_kwargs = dict(law.env_kwargs)
        self.meta: dict = {}  # a saved policy's metadata (sb3_policy.load_policy)
        self.path: Any = None  # the saved policy's .zip, when loaded from one
        self.obs_rms: Any = getattr(policy, "obs_rms", None)  # None: raw observations

    def reset(self) -> None:
        self.law.reset()

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        obs = np.atleast_2d(np.asarray(observation))
        start = (np.zeros(obs.shape[0], dtype=bool) if episode_start is None
                 else np.asarray(episode_start, dtype=bool))  # fmt: skip
        base, _ = self.law.predict(obs, episode_start=start, deterministic=True)  # (N, slots)
        finite = np.isfinite(obs)
        unread = ~np.all(finite, axis=1)  # the network cannot read these: the law acts alone
        network_obs = np.where(finite, obs, 0.0) if unread.any() else obs
        residual, state = self.policy.predict(network_obs.astype(np.float32), state=state,
                                              episode_start=start, deterministic=deterministic)  # fmt: skip
        residual = np.array(np.reshape(residual, base.shape), dtype=np.float64)
        residual[unread] = 0.0
        return combine_actions(base, residual, self.scale), state


def zero_last_layer(model: Any) -> None:
    """Zero the weights and bias of an SB3 model's action output layer (PPO/A2C's
    ``action_net``, SAC/TD3/TQC's actor ``mu``), so its deterministic action is 0 everywhere."""
    import torch

    policy = model.policy
    layer = getattr(policy, "action_net", None)
    if layer is None and hasattr(policy, "actor"):
        layer = getattr(policy.actor, "mu", None)
        if isinstance(layer, torch.nn.Sequential):  # TD3's mu ends with a Tanh
            layer = next(m for m in reversed(layer) if isinstance(m, torch.nn.Linear))
    if not isinstance(layer, torch.nn.Linear):
        raise ValueError(f"model has no linear action output layer to zero: {type(policy)}")
    with torch.no_grad():
        layer.weight.zero_()
        layer.bias.zero_()
    target = getattr(getattr(policy, "actor_target", None), "mu", None)
    if target is not None:
        policy.actor_target.load_state_dict(policy.actor.state_dict())


class ResidualVecEnv(VecEnvWrapper):
    """An SB3 VecEnv (:class:`~capsule_env.envs.sb3.CapsuleSuspensionSB3VecEnv`) with residual
    actions; SB3 resets a finished vehicle at once, so its next obs starts an episode."""

    def __init__(self, venv: Any, law: Controller, scale: float = 0.5) -> None:
        if not _HAS_SB3:
            raise ImportError(
                "ResidualVecEnv needs stable-baselines3: pip install 'capsule-env[rl]'"
            )
        super().__init__(venv)
        check_law_fits(law, venv.config)
        self.law, self.scale = law, _check_scale(scale)
        self._obs: np.ndarray | None = None
        self._start = np.ones(self.num_envs, dtype=bool)

    def reset(self) -> Any:
        obs = self.venv.reset()
        self._obs = np.asarray(obs)  # the same array (CapsuleSuspensionSB3VecEnv's)
        self.law.reset()
        self._start[:] = True
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        base = _base_actions(self.law, self._obs, self._start)
        total = combine_actions(base, np.reshape(actions, (self.num_envs,)), self.scale)
        self.venv.step_async(total[:, None])

    def step_wait(self) -> Any:
        obs, reward, done, infos = self.venv.step_wait()
        self._obs, self._start = np.asarray(obs), np.asarray(done, dtype=bool).copy()
        return obs, reward, done, infos
