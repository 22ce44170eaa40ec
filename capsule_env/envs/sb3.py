"""A stable-baselines3 ``VecEnv`` over the batched kernel, for fast training.

SB3's vector-env conventions differ from Gymnasium's: episodes reset in the *same* step that
ends them; the last observation of the finished episode is in ``infos[n]["terminal_observation"]``
and ``infos[n]["TimeLimit.truncated"]`` tells a time limit from a termination. This class
implements them directly on :class:`capsule_env.engine.batch.CapsuleBatch` (no per-env Python objects),
so a step of N vehicles costs one kernel call. ``seed(s)`` gives the vehicles the streams of the
native vector env's ``reset(seed=s)`` (``numpy.random.SeedSequence(s).spawn(num_envs)``, not
SB3's usual ``s + n``, so that training seeds never share a vehicle's stream); the same seed
gives the same trajectories as the native vector env, bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig, check_num_envs, check_seed
from capsule_env.engine.layout import SIGNAL_NAMES
from capsule_env.envs._actions import real_actions
from capsule_env.envs.capsule_suspension import _check_options, env_spaces, render_fps
from capsule_env.envs.render import check_render_mode, render_vehicle

__all__ = [
    "CapsuleSuspensionSB3VecEnv",
    "check_settable",
    "check_vec_options",
    "make_sb3_vec_env",
]


def check_vec_options(options: Any, num_envs: int) -> None:
    """Check ``VecEnv.set_options(options)`` for envs whose ``reset`` takes no option: ``None``,
    an empty dict, or a list of ``num_envs`` empty dicts pass; an option is refused by name
    (``ValueError``) when it is set, rather than dropped at the next reset; another type or
    length raises ``TypeError``."""
    if options is None or isinstance(options, dict):
        _check_options(options)
        return
    if not isinstance(options, list | tuple) or len(options) != num_envs:
        raise TypeError(
            f"options must be None, a dict or a list of {num_envs} dicts (one per env), "
            f"got {type(options).__name__}"
            + (f" of length {len(options)}" if isinstance(options, list | tuple) else "")
        )
    for env_options in options:
        _check_options(env_options)


def check_settable(config: Any, attr_name: str, indices: Any, num_envs: int) -> None:
    """``VecEnv.set_attr(attr_name, ..., indices)`` of a VecEnv that is one object for every
    index and whose ``get_attr`` reads its options from ``config``: an option (frozen when the
    env is made) raises ``ValueError`` naming it, rather than setting an attribute nothing
    reads while ``get_attr`` keeps the old value; so do ``indices`` that are not all the
    vehicles (the value would be every vehicle's)."""
    if indices is not None:
        chosen = [indices] if isinstance(indices, (int, np.integer)) else list(indices)
        if sorted(chosen) != list(range(num_envs)):
            raise ValueError(
                f"set_attr sets {attr_name} of every vehicle (one object serves them all): "
                f"indices must be None or all {num_envs} of them, got {indices!r}"
            )
    if hasattr(config, attr_name):
        raise ValueError(
            f"{attr_name} is an option of the env, fixed when it is made: set_attr cannot "
            f"change it; make a new VecEnv with {attr_name}=..."
        )


class CapsuleSuspensionSB3VecEnv(VecEnv):
    """``CapsuleSuspension-v0`` as an SB3 ``VecEnv`` of ``num_envs`` vehicles.

    Parameters
    ----------
    num_envs : number of vehicles.
    info_signals : add the physical signals and reward terms (``SIGNAL_NAMES``) to every
        step's info dicts (costs time for large batches; off by default).
    render_mode : None or ``"rgb_array"`` (SB3's ``render(mode="human")`` shows its frames);
        another raises ``ValueError``.
    **kwargs : any ``CapsuleSuspension-v0`` argument (:class:`capsule_env.engine.config.EnvConfig`).
    """

    def __init__(
        self,
        num_envs: int = 1,
        info_signals: bool = False,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        self.config = EnvConfig.from_kwargs(
            "CapsuleSuspensionSB3VecEnv.__init__", ("num_envs", "info_signals", "render_mode"),
            **kwargs,
        )  # fmt: skip
        num_envs = check_num_envs(num_envs)
        # not "human": SB3 would call env_method("render"), which shows nothing; its
        # render(mode="human") shows the "rgb_array" frames
        check_render_mode(render_mode)
        self.batch = CapsuleBatch(self.config, num_envs)
        action_space, observation_space = env_spaces(self.config)
        self.render_mode = render_mode
        super().__init__(num_envs, observation_space, action_space)
        # one frame per control step: VecVideoRecorder writes real-time videos at this rate
        self.metadata: dict[str, Any] = {**self.metadata, "render_fps": render_fps(self.config)}
        self.info_signals = bool(info_signals)
        self._actions = np.zeros(num_envs)
        self._seed: int | None = None
        self._needs_reset = True

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seed the next ``reset``: the vehicles get ``SeedSequence(seed).spawn(num_envs)``."""
        self._seed = None if seed is None else check_seed("seed", seed)
        return [self._seed] * self.num_envs

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        """The env's ``reset`` takes no option: ``None``, ``{}`` or empty dicts pass; any key is
        refused here (:func:`check_vec_options`), not silently dropped at the next reset."""
        check_vec_options(options, self.num_envs)
        super().set_options(options)

    def reset(self) -> np.ndarray:
        if self._seed is not None:
            self.batch.seed(self._seed)
            self._seed = None
        self._reset_seeds()
        self._reset_options()
        self.batch.reset()
        self._needs_reset = False
        return self.batch.obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        if self._needs_reset:
            raise ResetNeeded("call reset() before step()")
        a = np.asarray(real_actions(actions), dtype=np.float64)
        if a.shape not in ((self.num_envs, 1), (self.num_envs,)):
            raise ValueError(f"actions must have shape ({self.num_envs}, 1), got {a.shape}")
        self._actions = a.reshape(self.num_envs)

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
        return len(list(self._get_indices(indices)))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        target = self.config if hasattr(self.config, attr_name) else self
        return [getattr(target, attr_name)] * self._count(indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of this one object (every index); an env option, or indices that
        are not all the vehicles, raise ``ValueError`` (:func:`check_settable`)."""
        check_settable(self.config, attr_name, indices, self.num_envs)
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        if method_name == "render":
            return [render_vehicle(self.batch, n) for n in self._get_indices(indices)]
        method = getattr(self, method_name)
        return [method(*method_args, **kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False] * self._count(indices)

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [render_vehicle(self.batch, n) for n in range(self.num_envs)]

    def _get_indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices


def make_sb3_vec_env(num_envs: int = 8, seed: int | None = None, **kwargs: Any) -> Any:
    """Build the SB3 VecEnv, wrapped in ``VecMonitor`` (episode returns for SB3's logger)."""
    from stable_baselines3.common.vec_env import VecMonitor

    env = CapsuleSuspensionSB3VecEnv(num_envs, **kwargs)
    if seed is not None:
        env.seed(seed)
    return VecMonitor(env)
