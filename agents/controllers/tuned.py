"""The shipped, tuned gains of the classical controllers (``agents/controllers/tuned_gains.json``).

The file is written by the gain search (``python -m capsule_env.agents.controllers.tuning``, :mod:`capsule_env.agents.controllers.tuning`):
for each tuned controller, its gains (keys with units, as :meth:`Controller.gains` gives them),
the training-bank result of those gains and how many candidates the search evaluated; at the
top, the search's settings and date. The controllers' constructors take their default gains
from here (:func:`tuned_gains`); a controller the file does not list keeps its documented
reconstructed defaults (the paper-reproduction Skyhook rows).
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

TUNED_GAINS_PATH = Path(__file__).resolve().with_name("tuned_gains.json")


@lru_cache(maxsize=4)
def load_tuned(path: Path = TUNED_GAINS_PATH) -> dict[str, Any]:
    """The whole file (``{}`` when it does not exist yet: before the first search)."""
    if not path.is_file():
        return {}
    data = json.loads(path.read_text())
    if not isinstance(data, dict) or not isinstance(data.get("controllers", {}), dict):
        raise ValueError(f"{path} is not a tuned-gains file (a JSON object with 'controllers')")
    return data


def tuned_gains(name: str, path: Path = TUNED_GAINS_PATH) -> dict[str, float] | None:
    """The shipped gains of controller ``name`` (keys with units), or None if not tuned."""
    entry = load_tuned(path).get("controllers", {}).get(name)
    return None if entry is None else dict(entry["gains"])


def tuning_env_kwargs(path: Path = TUNED_GAINS_PATH) -> dict[str, Any]:
    """The env options the shipped gains were tuned in, besides each controller's own
    options: the ``setting`` of the file's ``settings`` (the search runs a controller in its
    own options and that setting, every other option at the env's default, on the training
    bank: :func:`capsule_env.agents.controllers.tuning._training_rollout`; the settings'
    ``stroke_limit_m`` is the search's constraint, not the env's option)."""
    from capsule_env.agents.controllers.tuning import TuningSettings  # the search's default setting

    settings = load_tuned(path).get("settings", {})
    return {"setting": settings.get("setting", TuningSettings.setting)}


def tuning_task_kwargs(name: str, path: Path = TUNED_GAINS_PATH) -> dict[str, Any]:
    """The env options of the registered task controller ``name`` was tuned in (its entry's
    ``task``: :attr:`capsule_env.agents.learning.search_space.SearchSpace.task`), on top of
    :func:`tuning_env_kwargs`; ``{}`` when it was tuned in the env's defaults."""
    entry = load_tuned(path).get("controllers", {}).get(name) or {}
    if not entry.get("task"):
        return {}
    from capsule_env.tasks import task_named

    return dict(task_named(entry["task"]).kwargs)
