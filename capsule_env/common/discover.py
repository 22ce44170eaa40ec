"""Find a registry's built-in entries: every module of a package that exports ``MODEL``."""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

__all__ = ["modules_exporting_model"]


def modules_exporting_model(package_name: str, kind: type, not_models: frozenset[str]) -> list[Any]:
    """The ``MODEL`` of each module of ``package_name`` (not those in ``not_models`` or starting
    with ``_``) that is an instance of ``kind``, in module order."""
    package = importlib.import_module(package_name)
    found = []
    for info in pkgutil.iter_modules(package.__path__):
        if info.name in not_models or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{package_name}.{info.name}")
        model = getattr(module, "MODEL", None)
        if isinstance(model, kind):
            found.append(model)
    return found
