"""The sweep's one door to :mod:`capsule_env.agents.learning` (the ``train`` kind).

The learning modules need the ``rl`` extra (torch, stable-baselines3, PyYAML); the sweep's
other kinds (``gains``, ``oracle``), its study files and its runner do not, so
``import capsule_env.sweep`` works without the extra. The rule: no module of the sweep imports
``capsule_env.agents.learning`` itself, at its top or in a function; each reads it through
:func:`learning` (or :func:`train_module`) here, on first use. Everything else the sweep needs
from the package (the config, the evaluation, the classical controllers, the oracle, safe_io)
is imported at the top of its module; the one in-function import left is
``capsule_env.sweep.study`` in ``kinds.py`` (``study`` imports ``kinds``). A test in
``tests/test_house.py`` keeps it so.
"""

from __future__ import annotations

import importlib
from types import ModuleType


def learning(module: str) -> ModuleType:
    """``capsule_env.agents.learning.<module>``, imported on first use (the ``rl`` extra)."""
    return importlib.import_module(f"capsule_env.agents.learning.{module}")


def train_module() -> ModuleType:
    """:mod:`capsule_env.agents.learning.train` (what ``train.py`` and ``capsule-train`` run),
    imported on first use."""
    return learning("train")
