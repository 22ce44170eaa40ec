"""Controllers for CapsuleSuspension-v0, all with SB3's ``predict`` interface.

Every controller maps a batch of observations to a batch of actions with
``predict(obs, state=None, episode_start=None, deterministic=True) -> (actions, state)``, so the
same evaluation loop runs classical and learned controllers. A controller also says which
environment options it needs (:attr:`Controller.env_kwargs`: observation set, action mode,
inverse model, plant), which observation set it reads (:attr:`Controller.observation`),
whether that includes signals a real vehicle does not measure directly
(:attr:`Controller.uses_unmeasured_signals`), whether it previews the guideway
(:attr:`Controller.preview`) and its gains (:meth:`Controller.gains`).

Classical laws: :mod:`agents.law` (signals and gains), :mod:`agents.skyhook` (force-requesting
Skyhook and hybrid), :mod:`agents.two_state` (on-off Skyhook, ADD, mixed Skyhook-ADD),
:mod:`agents.lqr` (clipped-optimal), :mod:`agents.classical` (open-loop references and the
registry by name); their tuned gains: :mod:`agents.tuned` (the shipped file) and
:mod:`agents.tuning` (the search, ``python -m agents.tuning``). Learned controllers:
:mod:`agents.sb3_policy` (a saved or in-memory SB3 policy). What ``train.py`` is made of
(needs the ``rl`` extra): :mod:`agents.training` (the run), :mod:`agents.checkpoints`
(saving, resume), :mod:`agents.hyperparams` (the RL-Zoo yml).
"""

from agents.base import Controller
from agents.classical import (
    ConstantCurrentController,
    PassiveController,
    classical_controllers,
    make_controller,
)
from agents.lqr import ClippedOptimalController
from agents.skyhook import HybridController, SkyhookController
from agents.two_state import ADDController, MixedSkyhookADDController, SkyhookTwoStateController

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
