"""Controllers for CapsuleSuspension-v0, all with SB3's ``predict`` interface.

Every controller maps a batch of observations to a batch of actions with
``predict(obs, state=None, episode_start=None, deterministic=True) -> (actions, state)``, so the
same evaluation loop runs classical and learned controllers. A controller also says which
environment options it needs (:attr:`Controller.env_kwargs`: observation set, action mode,
inverse model, plant), which observation set it reads (:attr:`Controller.observation`),
whether that includes signals a real vehicle does not measure directly
(:attr:`Controller.uses_unmeasured_signals`), whether it previews the guideway
(:attr:`Controller.preview`) and its gains (:meth:`Controller.gains`).

Classical laws: :mod:`capsule_env.agents.controllers.law` (signals and gains), :mod:`capsule_env.agents.controllers.skyhook` (force-requesting
Skyhook and hybrid), :mod:`capsule_env.agents.controllers.two_state` (on-off Skyhook, ADD, mixed Skyhook-ADD),
:mod:`capsule_env.agents.controllers.lqr` (clipped-optimal), :mod:`capsule_env.agents.controllers.classical` (open-loop references and the
registry by name); their tuned gains: :mod:`capsule_env.agents.controllers.tuned` (the shipped file) and
:mod:`capsule_env.agents.controllers.tuning` (the search, ``python -m capsule_env.agents.controllers.tuning``). Learned controllers:
:mod:`capsule_env.agents.learning.sb3_policy` (a saved or in-memory SB3 policy). What ``train.py`` is made of
(needs the ``rl`` extra): :mod:`capsule_env.agents.learning.training` (the run), :mod:`capsule_env.agents.learning.checkpoints`
(saving, resume), :mod:`capsule_env.agents.learning.hyperparams` (the RL-Zoo yml).
"""

from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.controllers.classical import (
    ConstantCurrentController,
    PassiveController,
    classical_controllers,
    make_controller,
)
from capsule_env.agents.controllers.lqr import ClippedOptimalController
from capsule_env.agents.controllers.skyhook import HybridController, SkyhookController
from capsule_env.agents.controllers.two_state import (
    ADDController,
    MixedSkyhookADDController,
    SkyhookTwoStateController,
)

__all__ = [
    "ADDController",
    "Controller",
    "ClippedOptimalController",
    "ConstantCurrentController",
    "HybridController",
    "MixedSkyhookADDController",
    "PassiveController",
    "SkyhookController",
    "SkyhookTwoStateController",
    "classical_controllers",
    "make_controller",
]
