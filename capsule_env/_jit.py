"""The compiler's machinery, kept out of the physics: where numba caches the compiled kernels.

Every kernel is compiled with ``cache=True``: numba writes the machine code beside the module
(``__pycache__``), or, when that folder is read-only, under the user's home
(``~/.cache/numba``). When neither can be written (a read-only ``site-packages`` and no
writable home: a container, a cluster node) numba refuses to decorate the function at import
("cannot cache function ...: no locator available"). :func:`ensure_cache_location` runs before
any kernel is defined (``capsule_env/__init__.py`` imports this module first): it leaves a
writable default, or the user's ``NUMBA_CACHE_DIR``, alone; otherwise it points numba at a
folder in the temporary directory and says so once (:class:`NumbaCacheWarning`).
"""

from __future__ import annotations

import os
import tempfile
import warnings
from pathlib import Path

__all__ = ["NumbaCacheWarning", "ensure_cache_location", "fallback_cache_dir"]


class NumbaCacheWarning(UserWarning):
    """Numba's cache had to move to a temporary folder (set ``NUMBA_CACHE_DIR`` to choose)."""


def _probe() -> None:
    """A function numba's cache locators are asked about (they read its file and line)."""


def fallback_cache_dir() -> Path:
    """The folder used when numba has nowhere to cache: one per user in the temporary
    directory, so that later processes find what earlier ones compiled."""
    user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    return Path(tempfile.gettempdir()) / f"capsule_env-numba-cache-{user}"


def _default_locator_found() -> bool:
    """Whether one of numba's own cache locators can write for a module of this package."""
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # numba < 0.61: private
    source = str(Path(__file__).resolve())
    return any(cls.from_function(_probe, source) is not None for cls in impl._locator_classes)


def ensure_cache_location() -> None:
    """Give numba a writable cache folder when it has none (see the module's docstring)."""
    from numba.core import config

    if config.CACHE_DIR or getattr(config, "CACHE_LOCATOR_CLASSES", "") or _default_locator_found():
        return  # the user's choice, or numba's own default, works
    folder = fallback_cache_dir()
    config.CACHE_DIR = str(folder)
    warnings.warn(
        "capsule_env: numba cannot cache the compiled kernels beside the package or in your "
        f"home folder (both read-only); caching them in {folder} instead. Set NUMBA_CACHE_DIR "
        "to a writable folder to choose the place.",
        NumbaCacheWarning,
        stacklevel=3,
    )


ensure_cache_location()
