"""Controllers for CapsuleSuspension-v0, all with SB3's ``predict`` interface.

Every controller maps a batch of observations to a batch of actions with
``predict(obs, state=None, episode_start=None, deterministic=True) -> (actions, state)``, so the
same evaluation loop runs classical and learned controllers. A controller also says which
environment options it needs (:attr:`Controller.env_kwargs`: observation set, action mode,
inverse model, plant) and whether it reads signals a real vehicle does not measure directly
(:attr:`Controller.uses_unmeasured_signals`).

Learned controllers: :mod:`agents.sb3_policy` (a saved or in-memory SB3 policy). What
``train.py`` is made of (needs the ``rl`` extra): :mod:`agents.training` (the run),
:mod:`agents.checkpoints` (saving, resume), :mod:`agents.hyperparams` (the RL-Zoo yml).
"""

from agents.base import Controller
from agents.classical import (
    ClippedOptimalController,
    ConstantCurrentController,
    HybridController,
    PassiveController,
    SkyhookController,
    classical_controllers,
)

__all__ = [
    "Controller",
    "ClippedOptimalController",
    "ConstantCurrentController",
    "HybridController",
    "PassiveController",
    "SkyhookController",
    "classical_controllers",
]
