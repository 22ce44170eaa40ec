"""Which policy to export: a shipped policy by name, or a saved policy set by its ``.zip``.

``NAME`` is a policy of ``capsule_env/pretrained/`` (``ppo-measured``, ``residual-ppo-mpc``,
...); a path is any policy set ``train.py`` saved (``runs/x/best_model.zip``, with its
``.vecnormalize.pkl`` and ``.json`` beside it), loaded and checked as ``evaluate.py --policy``
loads it (:meth:`~capsule_env.agents.learning.sb3_policy.SB3Policy.load`: digests, shapes, the
normalisation statistics required). A residual policy (its ``.json`` has a ``residual`` block)
is loaded as its network alone: the law it rides on is named, and built only when it has a C
form (:mod:`capsule_env.export.laws_c`), so an MPC residual exports without the MPC's solver.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy

__all__ = ["Residual", "PolicySource", "shipped_names", "resolve_policy"]

_STEM = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")


@dataclass(frozen=True)
class Residual:
    """The classical law a residual policy rides on: ``clip(law + scale * residual, -1, 1)``;
    ``law`` is the built law when it has a C form, else None (``reason`` says why)."""

    law_name: str
    scale: float
    law: Controller | None
    reason: str


@dataclass(frozen=True)
class PolicySource:
    """A policy to export: its output name, its ``.zip``, the loaded network and, for a
    residual policy, its law."""

    name: str
    zip_path: Path
    policy: SB3Policy
    residual: Residual | None

    @property
    def meta(self) -> dict[str, Any]:
        return self.policy.meta


def shipped_names() -> list[str]:
    """The names of the shipped policies."""
    return sorted(p.name[: -len(".zip")] for p in PRETRAINED_DIR.glob("*.zip"))


def _zip_of(name_or_path: str) -> Path:
    path = Path(name_or_path)
    if path.suffix == ".zip" or path.exists() or "/" in name_or_path or "\\" in name_or_path:
        if not path.is_file():
            raise ValueError(f"policy file {name_or_path!r} does not exist")
        return path
    if name_or_path not in shipped_names():
        raise ValueError(f"unknown policy {name_or_path!r}: give a shipped policy "
                         f"({', '.join(shipped_names())}) or a policy's .zip file")  # fmt: skip
    return PRETRAINED_DIR / f"{name_or_path}.zip"


def _residual(block: Any, path: Path, vehicle: str = "quarter_car") -> Residual | None:
    from capsule_env.agents.controllers.classical import FACTORIES, make_controller
    from capsule_env.agents.learning.sb3_policy import DECLARED_LAWS
    from capsule_env.export.laws_c import c_law_reason, law_class

    if block is None:
        return None
    if not isinstance(block, dict):
        raise ValueError(f'{path}: its metadata\'s residual must be an object {{"law": NAME, '
                         f'"scale": S}}, got {block!r:.80}')  # fmt: skip
    law_name, scale = block.get("law"), block.get("scale", 0.5)
    declared = vehicle != "quarter_car"  # a declared vehicle's law: one per damper slot
    if declared and law_name not in DECLARED_LAWS:
        raise ValueError(f"{path}: its residual law {law_name!r} is not one of the {vehicle}'s "
                         f"residual laws ({', '.join(DECLARED_LAWS)})")  # fmt: skip
    if not declared and (not isinstance(law_name, str) or law_class(law_name) is None):
        raise ValueError(f"{path}: its residual law {law_name!r} is not a classical controller; "
                         f"accepted: {', '.join(sorted(FACTORIES))}")  # fmt: skip
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0.0 < scale <= 2.0:
        raise ValueError(f"{path}: its residual scale must be a number in (0, 2], got {scale!r}")
    if declared:
        what = ("a semi-active MPC over both damper slots, a QP solve each step"
                if "mpc" in law_name.split("-")
                else "one law per damper slot on its own slot's columns")  # fmt: skip
        reason = (f"{law_name} on the {vehicle} is {what}; its C form is not generated: the rig "
                  "must provide it, and combine each slot's action with capsule_combine")  # fmt: skip
        return Residual(law_name, float(scale), None, reason)
    reason = c_law_reason(law_name)
    law = None if reason else make_controller(law_name)
    return Residual(law_name, float(scale), law, reason)


def resolve_policy(name_or_path: str, name: str | None = None) -> PolicySource:
    """The policy ``name_or_path`` (module docstring), exported as ``name`` (default: a
    shipped policy's name, or the policy's metadata ``name``). ``ValueError`` naming the
    reason for an unknown name, a missing or bad file or a bad output name."""
    path = _zip_of(name_or_path)
    policy = SB3Policy.load(path)
    out_name = name if name is not None else str(policy.meta.get("name", path.stem))
    if not _STEM.match(out_name):
        raise ValueError(f"--name must be a plain file stem (letters, digits, '_', '.', '+', "
                         f"'-'), got {out_name!r}")  # fmt: skip
    vehicle = str(policy.meta.get("env_kwargs", {}).get("vehicle", "quarter_car"))
    residual = _residual(policy.meta.get("residual"), path, vehicle)
    return PolicySource(out_name, path, policy, residual)
