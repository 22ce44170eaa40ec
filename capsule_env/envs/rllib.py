"""``CapsuleSuspension-v0`` in RLlib, with the native (numba-batched) vector env::

    from ray.rllib.algorithms.ppo import PPOConfig
    from capsule_env.envs import rllib

    name = rllib.register()               # ray.tune.registry.register_env, returns the name
    config = (
        PPOConfig()
        .environment(name, env_config={"setting": "hils", "observation": "full_state"})
        .env_runners(num_envs_per_env_runner=32, **rllib.vector_env_runner_kwargs())
    )
    algo = config.build_algo()
    algo.train()

:func:`register` registers :func:`env_creator` under ``CapsuleSuspension-v0`` (or the name
given). Without ``num_envs`` in its config it makes the single env
(``CapsuleSuspensionEnv``); with it, the vector env (``CapsuleSuspensionVectorEnv``): RLlib's
``SingleAgentEnvRunner`` registers its ``vector_entry_point`` as ``creator(config |
{"num_envs": n})``, so ``gym_env_vectorize_mode="vector_entry_point"`` (what
:func:`vector_env_runner_kwargs` returns where the installed RLlib and Gymnasium know it) runs
all of an env runner's ``num_envs_per_env_runner`` vehicles in one kernel call instead of one
Python env per vehicle (Ray >= 2.52; older RLlib falls back to one env per vehicle). ``env_config`` takes the env's arguments (``setting``,
``action_mode``, ``observation``, ``episode_length_s``, ...).

Seeds: RLlib resets env runner ``k``'s vector env with ``seed + k`` (``config.debugging(seed=
...)``), and vehicle ``n`` of a vector env seeded ``s`` draws from stream ``n`` of
``numpy.random.SeedSequence(s)``, so env runners share no stream.

Needs ``ray[rllib]`` (``pip install 'capsule-env[rllib]'``, Ray >= 2.49), which pins its own
Gymnasium version (of the versions checked: Ray 2.49, 2.50, 2.52, 2.53 ``gymnasium==1.1.1``;
2.55, 2.60 ``1.2.2``; 2.41, 2.46, 2.47 ``1.0.0``, which this package cannot import): hence an
extra of its own, apart from ``[scale]``.
Tested with Ray 2.49.0 (Gymnasium 1.1.1, the fallback) and 2.60.0 (Gymnasium 1.2.2, the vector
env).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: The name :func:`register` uses by default (the Gymnasium id as well).
ENV_NAME = "CapsuleSuspension-v0"
#: RLlib's vectorisation mode that calls the registered ``vector_entry_point``.
VECTOR_MODE = "vector_entry_point"
#: The first Ray whose RLlib makes the registered env's vector env in that mode.
MIN_RAY_FOR_VECTOR_ENV = (2, 52)


def env_creator(config: Mapping[str, Any] | None = None) -> Any:
    """The env for an RLlib ``env_config``: the vector env when it holds ``num_envs``, else
    the single env. Every other key is an env argument."""
    from capsule_env.envs.capsule_suspension import (
        CapsuleSuspensionEnv,
        CapsuleSuspensionVectorEnv,
    )

    kwargs = dict(config or {})
    num_envs = kwargs.pop("num_envs", None)
    if num_envs is None:
        return CapsuleSuspensionEnv(**kwargs)
    return CapsuleSuspensionVectorEnv(num_envs=int(num_envs), **kwargs)


def register(name: str = ENV_NAME) -> str:
    """Register :func:`env_creator` with ``ray.tune.registry.register_env`` under ``name``
    (idempotent); returns ``name`` for ``AlgorithmConfig.environment(name)``."""
    from ray.tune.registry import register_env

    register_env(name, env_creator)
    return name


def supports_vector_entry_point() -> bool:
    """True if the installed RLlib can run the env's own vector env: Ray >= 2.52 (its
    ``SingleAgentEnvRunner`` registers a ``vector_entry_point`` for an env registered with
    ``register_env``; Ray 2.49 - 2.51 accept the mode but build no vector entry point) and a
    Gymnasium with ``VectorizeMode.VECTOR_ENTRY_POINT``."""
    import gymnasium as gym
    import ray

    major, minor = (int(part) for part in ray.__version__.split(".")[:2])
    modes = {m.value for m in getattr(gym, "VectorizeMode", [])}
    return (major, minor) >= MIN_RAY_FOR_VECTOR_ENV and VECTOR_MODE in modes


def vector_env_runner_kwargs() -> dict[str, Any]:
    """``{"gym_env_vectorize_mode": VectorizeMode.VECTOR_ENTRY_POINT}`` for
    ``AlgorithmConfig.env_runners`` where :func:`supports_vector_entry_point`, else ``{}``
    (RLlib's default: one Python env per vehicle in Gymnasium's ``SyncVectorEnv``). The enum
    member, not its string: RLlib 2.49 - 2.51 accept only members and names."""
    if not supports_vector_entry_point():
        return {}
    import gymnasium as gym

    return {"gym_env_vectorize_mode": gym.VectorizeMode(VECTOR_MODE)}
