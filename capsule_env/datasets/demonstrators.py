"""Which controller's rollouts to record: a classical law, a learned policy or the oracle.

``NAME_OR_PATH`` is, in this order:

- ``oracle``: the clairvoyant search (:func:`capsule_env.oracle.clairvoyant_bound`), whose
  episodes are applied-current sequences; recorded in the env with ``action_mode="current"``
  and ``control_delay_steps=0`` (:mod:`capsule_env.datasets.oracle_replay`);
- a classical law by name (:func:`capsule_env.agents.controllers.classical.make_controller`:
  ``mpc-biexp-meas``, ``lqr-clipped-biexp-meas``, ``passive``, ...);
- a shipped policy by name (``ppo-measured``, ``residual-ppo-mpc``, ...), or a policy set
  ``train.py`` saved (``runs/x/best_model.zip``, its ``.vecnormalize.pkl`` and ``.json`` beside
  it), loaded as ``evaluate.py --policy`` loads it
  (:func:`capsule_env.agents.learning.sb3_policy.load_policy`).

Each comes with the env options it declares (how it reads and acts:
:attr:`~capsule_env.agents.controllers.base.Controller.env_kwargs`), which the recording env
takes over the task's, as ``evaluate.py`` runs every controller.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from capsule_env.agents.controllers.base import Controller

__all__ = ["ORACLE", "ORACLE_ENV_KWARGS", "Demonstrator", "demonstrator_names",
           "resolve_demonstrator"]  # fmt: skip

#: The name that selects the clairvoyant oracle.
ORACLE = "oracle"
#: The env options the oracle's episodes are recorded with: its sequences are the applied
#: current, which the env applies without delay in current mode.
ORACLE_ENV_KWARGS: dict[str, Any] = {"action_mode": "current", "control_delay_steps": 0}
_NAME = re.compile(r"[^-\w]", re.ASCII)


@dataclass(frozen=True)
class Demonstrator:
    """A controller to record.

    Attributes
    ----------
    name : the dataset's name for it (letters, digits, ``-`` and ``_``).
    kind : ``"classical"``, ``"learned"`` or ``"oracle"``.
    controller : the controller (None for the oracle, which is a search, not a feedback law).
    env_kwargs : the env options it declares (over the task's).
    source : what it was loaded from (the law's name, the policy's file, ``oracle``).
    """

    name: str
    kind: str
    controller: Controller | None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    source: str = ""


def _shipped() -> list[str]:
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR

    return sorted(p.name[: -len(".zip")] for p in PRETRAINED_DIR.glob("*.zip"))


def demonstrator_names() -> list[str]:
    """Every name accepted (besides a policy's ``.zip``): the classical laws, the shipped
    policies and ``oracle``."""
    from capsule_env.agents.controllers.classical import FACTORIES

    return [*FACTORIES, *_shipped(), ORACLE]


def _classical(name: str) -> Demonstrator:
    from capsule_env.agents.controllers.classical import make_controller
    from capsule_env.agents.controllers.mpc_solver import solver_available

    if "mpc" in name.split("-") and not solver_available():
        raise ValueError(f"--controller {name} needs a QP solver: pip install 'capsule-env[mpc]'")
    law = make_controller(name)
    return Demonstrator(name, "classical", law, dict(law.env_kwargs), name)


def _learned(path: Path, shown: str) -> Demonstrator:
    try:
        from capsule_env.agents.learning.sb3_policy import load_policy, use_one_torch_thread
    except ImportError as exc:
        raise ImportError(f"--controller {shown} is a learned policy, which needs the rl extra "
                          f"(pip install 'capsule-env[rl]'): {exc}") from None  # fmt: skip
    use_one_torch_thread()
    policy = load_policy(path)
    name = _NAME.sub("_", str(getattr(policy, "name", path.stem)))
    return Demonstrator(name, "learned", policy, dict(policy.env_kwargs), shown)


def resolve_demonstrator(name_or_path: str) -> Demonstrator:
    """The controller ``name_or_path`` (module docstring); ``ValueError`` listing the accepted
    names for an unknown one, naming the reason for a bad policy file or a missing solver."""
    from capsule_env.agents.controllers.classical import FACTORIES

    if name_or_path == ORACLE:
        return Demonstrator(ORACLE, ORACLE, None, dict(ORACLE_ENV_KWARGS), ORACLE)
    if name_or_path in FACTORIES:
        return _classical(name_or_path)
    if name_or_path in _shipped():
        from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR

        return _learned(PRETRAINED_DIR / f"{name_or_path}.zip", name_or_path)
    path = Path(name_or_path)
    if path.suffix == ".zip" or "/" in name_or_path or "\\" in name_or_path:
        if not path.is_file():
            raise ValueError(f"--controller: policy file {name_or_path!r} does not exist")
        return _learned(path, name_or_path)
    raise ValueError(f"--controller must be a classical law, a shipped policy, 'oracle' or a "
                     f"policy's .zip; accepted names: {', '.join(demonstrator_names())}; got "
                     f"{name_or_path!r}")  # fmt: skip
