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

import functools
import inspect
import os
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = [
    "KERNEL_OPTIONS",
    "NumbaCacheWarning",
    "ensure_cache_location",
    "fallback_cache_dir",
    "specialised",
]


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

# Numba is imported after the cache location is settled (the decorators below read it).
from numba import types  # noqa: E402
from numba.extending import overload  # noqa: E402

from capsule_env._fastmath import BORROWED, FAST  # noqa: E402

# --------------------------------------------------------------------------- specialisation
#: Decorator options of a compiled function inside the kernels: no CPython or C wrapper
#: (only numba calls it) and no reference counting (it allocates nothing; see
#: :data:`capsule_env._fastmath.BORROWED`), numpy's error model (no division check, so that
#: loops vectorise).
KERNEL_OPTIONS: dict[str, Any] = {**FAST, **BORROWED}


def specialised(
    *literal: str, plain: tuple[str, ...] = (), inline: str = "never", **jit_options: Any
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Compile a function once per value of its ``literal`` arguments (a damper model's code,
    a kernel variant), choosing the code to compile in Python, at typing.

    The decorated function is a *factory*: numba calls it with the values of the ``literal``
    arguments (Python ints or bools) and the numba types of the others, and it returns the
    implementation (a plain function of the same arguments) or ``None`` when it has none. It
    is called from compiled code only; calling it from Python raises ``NotImplementedError``.

    Why: a plain numba function specialised on a literal argument still types, lowers and
    optimises every branch of ``if model == ...`` (numba prunes branches on constants and
    closure variables, not on literal arguments): with every damper law behind such branches,
    a kernel compiled the code of every model. A literal argument must be given as a constant
    (a global, a closure variable, a literal value) by the caller.

    Parameters
    ----------
    literal : names of the arguments to specialise on.
    plain : names of arguments that must not be literal: a call typing one of them as a
        literal (a constant ``0``) is refused rather than compiled once more for the value.
    inline : numba's IR inlining of the implementation (``"never"``: LLVM decides; small
        functions are inlined by it).
    jit_options : options of the implementation, :data:`KERNEL_OPTIONS` by default.
    """
    options = jit_options or KERNEL_OPTIONS

    def decorate(factory: Callable[..., Any]) -> Callable[..., Any]:
        signature = inspect.signature(factory)
        names = list(signature.parameters)
        at = [names.index(n) for n in literal]
        plain_at = [names.index(n) for n in plain]

        @functools.wraps(factory)
        def stub(*args: Any) -> Any:
            raise NotImplementedError(f"{factory.__qualname__} is compiled code only")

        def typer(*args: Any) -> Any:
            if not all(isinstance(args[k], types.Literal) for k in at):
                return None
            if any(isinstance(args[k], types.Literal) for k in plain_at):
                return None
            values = list(args)
            for k in at:
                values[k] = args[k].literal_value
            return factory(*values)

        typer.__signature__ = signature  # type: ignore[attr-defined]
        overload(stub, prefer_literal=True, jit_options=options, inline=inline)(typer)
        return stub

    return decorate
