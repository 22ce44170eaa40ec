"""The learning algorithms ``train.py`` runs, by name: stable-baselines3's and sb3-contrib's.

=================  =================================  ===========================================
name               class                              what it is
=================  =================================  ===========================================
``ppo``            ``stable_baselines3.PPO``          clipped policy gradient (on-policy)
``sac``            ``stable_baselines3.SAC``          maximum-entropy actor-critic
``td3``            ``stable_baselines3.TD3``          twin delayed deterministic policy gradient
``tqc``            ``sb3_contrib.TQC``                SAC with truncated quantile critics
``crossq``         ``sb3_contrib.CrossQ``             SAC without target networks, batch norm
``recurrentppo``   ``sb3_contrib.RecurrentPPO``       PPO with an LSTM policy (on-policy)
=================  =================================  ===========================================

sb3-contrib is part of the ``rl`` extra. Each algorithm's hyperparameters are
``hyperparams/<name>.yml`` (RL-Zoo format).
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["ALGORITHMS", "ON_POLICY", "algorithm_class", "check_algorithm"]

#: Module and class of each algorithm, by the name ``train.py --algo`` takes.
ALGORITHMS: dict[str, tuple[str, str]] = {
    "ppo": ("stable_baselines3", "PPO"),
    "sac": ("stable_baselines3", "SAC"),
    "td3": ("stable_baselines3", "TD3"),
    "tqc": ("sb3_contrib", "TQC"),
    "crossq": ("sb3_contrib", "CrossQ"),
    "recurrentppo": ("sb3_contrib", "RecurrentPPO"),
}
#: The algorithms that learn from whole rollouts of ``n_steps`` per vehicle.
ON_POLICY = ("ppo", "recurrentppo")


def check_algorithm(name: Any) -> str:
    """``name`` if it is one of :data:`ALGORITHMS`, else ``ValueError`` naming them."""
    if name not in ALGORITHMS:
        raise ValueError(f"algo must be one of {', '.join(ALGORITHMS)}, got {name!r}")
    return str(name)


def algorithm_class(name: str) -> Any:
    """The SB3 class of the algorithm ``name`` (sb3-contrib's imported on first use)."""
    module, cls = ALGORITHMS[check_algorithm(name)]
    try:
        return getattr(importlib.import_module(module), cls)
    except ImportError as err:
        raise ImportError(f"algo {name!r} needs {module}: pip install 'capsule-env[rl]'") from err
