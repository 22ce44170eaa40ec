"""The compiler's machinery, in one room, kept out of the physics.

- :func:`ensure_cache_location`: where numba caches the compiled kernels (below);
- :func:`specialised`: a function compiled once per value of its literal arguments (a damper
  model's code, a kernel variant): the one helper in place of numba's stub/overload/impl
  triples;
- :data:`KERNEL_OPTIONS`: the options of a function inside the kernels (no wrappers, no
  reference counting, numpy's error model), :func:`kernel_function` and :func:`inlined`, the
  decorators the physics modules use;
- :func:`unique_symbol`: a kernel variant's own symbol name;
- :class:`Bundle`: named arrays boxed once and passed to compiled code as one pointer (numba's
  ``StructRef``);
- :class:`ForkGuard`: no parallel region in a forked child of a process that launched one;
- :func:`compiled_entry`: a compiled entry point with its leading arguments bound.

Cache location. Every kernel is compiled with ``cache=True``: numba writes the machine code
beside the module (``__pycache__``), or, when that folder is read-only, under the user's home
(``~/.cache/numba``). When neither can be written (a read-only ``site-packages`` and no
writable home: a container, a cluster node) numba refuses to decorate the function at import
("cannot cache function ...: no locator available"). :func:`ensure_cache_location` runs before
any kernel is defined (``capsule_env/__init__.py`` imports this module first): it leaves a
writable default, or the user's ``NUMBA_CACHE_DIR``, alone; otherwise it points numba at a
folder in the temporary directory and says so once (:class:`NumbaCacheWarning`). Numba's cache
of a function does not notice a change in the functions it calls: after editing a kernel's
callees, clear the cache (``find capsule_env -name "*.nb[ic]" -delete``) or point
``NUMBA_CACHE_DIR`` at an empty folder.
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
    "FORK_GUARD",
    "KERNEL_OPTIONS",
    "Bundle",
    "BundleType",
    "bundle_constructor",
    "ForkGuard",
    "NumbaCacheWarning",
    "compiled_entry",
    "ensure_cache_location",
    "fallback_cache_dir",
    "inlined",
    "kernel_function",
    "specialised",
    "unique_symbol",
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
from numba import njit, typeof, types  # noqa: E402
from numba.experimental import structref  # noqa: E402
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
    implementation (a plain function of the same arguments) or ``None`` when it has none.
    Called from Python (a script, a test, a controller written in Python), it compiles the
    implementation for the given values of the ``literal`` arguments once, as a plain
    ``njit`` function, and runs it (``TypeError`` when the factory has none for them).

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

        from_python: dict[tuple[Any, ...], Any] = {}

        @functools.wraps(factory)
        def stub(*args: Any) -> Any:
            key = tuple(args[k] for k in at)
            compiled = from_python.get(key)
            if compiled is None:
                given = [a if k in at else typeof(a) for k, a in enumerate(args)]
                impl = factory(*given)
                if impl is None:
                    raise TypeError(f"{factory.__qualname__} has no implementation for {key}")
                compiled = from_python[key] = njit(error_model="numpy")(impl)
            return compiled(*args)

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


# --------------------------------------------------------------------------- symbol names
def unique_symbol(variant: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Give a kernel closure a qualified name of its own (``<name>_<variant>``), before numba
    compiles it.

    Numba names a compiled function after its qualified name, a per-process counter and its
    argument types, and every variant of a kernel closure takes the same types. Two variants
    compiled in different processes (each the first kernel of its process) thus get the same
    symbol, and once both are loaded from the disk cache into one process, a function that
    calls one (the parallel kernel calling the serial one) could be linked to the other's
    code: different trajectories from the threaded kernel than from the serial one. A name
    per variant rules that out (and gives each variant its own cache index file)."""

    def rename(fn: Callable[..., Any]) -> Callable[..., Any]:
        fn.__qualname__ = f"{fn.__qualname__}_{variant}"
        fn.__name__ = f"{fn.__name__}_{variant}"
        return fn

    return rename


# --------------------------------------------------------------------------- structures
@structref.register
class BundleType(types.StructRef):
    """The numba type of a :class:`Bundle` (one per combination of field types; literal
    field types are widened, so that a bundle of the same arrays has one type)."""

    def preprocess_fields(self, fields: Any) -> tuple[tuple[str, Any], ...]:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Bundle(structref.StructRefProxy):
    """Named fields (arrays, named tuples of arrays) boxed once and passed to compiled code
    as one pointer (numba's ``StructRef``): a compiled call unboxes each array argument (a
    check, a reference and a small allocation each), a bundle only once. Its fields are
    readable in compiled code only; it refers to the arrays it was made from (their memory,
    not copies). Made in compiled code: ``structref.new(BundleType([(name, type), ...]))``,
    then its fields assigned (``capsule_env.engine.kernels.env_args``)."""


structref.define_boxing(BundleType, Bundle)


def bundle_constructor(name: str, field_names: tuple[str, ...]) -> Callable[..., Any]:
    """A function ``name(*fields)`` that compiled code calls to make a :class:`Bundle` with
    ``field_names`` from its arguments (the bundle's type follows the arguments' types).
    Numba needs each field assigned by name: the implementation is written out once per
    constructor here, so that no other module touches the ``StructRef`` machinery."""
    args = ", ".join(field_names)
    namespace: dict[str, Any] = {}
    exec(f"def {name}({args}):\n    pass\n", namespace)  # noqa: S102  (the typing stub)
    stub = namespace[name]
    stub.__doc__ = f"A Bundle of {', '.join(field_names)} (compiled code only)."

    def implementation(*fields: Any) -> Callable[..., Any]:
        bundle_type = BundleType(list(zip(field_names, fields)))
        body = "".join(f"    out.{f} = {f}\n" for f in field_names)
        scope: dict[str, Any] = {"new": structref.new, "bundle_type": bundle_type}
        exec(f"def impl({args}):\n    out = new(bundle_type)\n{body}    return out\n", scope)  # noqa: S102
        return scope["impl"]

    # numba matches the typing function's parameters to the implementation's, by name
    typing: dict[str, Any] = {"implementation": implementation}
    exec(f"def typer({args}):\n    return implementation({args})\n", typing)  # noqa: S102
    overload(stub)(typing["typer"])
    return stub


# --------------------------------------------------------------------------- fork guard
class ForkGuard:
    """Whether this process may launch a parallel region.

    Numba's fastest threading layer here is GNU OpenMP, which terminates a child process that
    launches a parallel region after its parent did (``fork() called from a process already
    using GNU OpenMP``: ``AsyncVectorEnv(context="fork")``, multiprocessing pools). A forked
    child of a process that has launched one is therefore ``serial_only``: its callers run
    the serial kernels (correct and as fast per core, never killed)."""

    def __init__(self) -> None:
        self.launched_parallel = False  # this process has launched a parallel region
        self.serial_only = False  # a forked child of a process that had: never launch one

    def after_fork_in_child(self) -> None:
        self.serial_only = self.serial_only or self.launched_parallel


#: The process's fork guard.
FORK_GUARD = ForkGuard()
os.register_at_fork(after_in_child=FORK_GUARD.after_fork_in_child)


# --------------------------------------------------------------------------- entry points
def compiled_entry(
    dispatcher: Any, head: tuple[Any, ...], args: tuple[Any, ...]
) -> Callable[..., Any] | None:
    """The compiled entry point of ``dispatcher`` for the argument types of ``(*head, *args)``
    (after a call compiled or loaded it), with ``head`` bound: calling it with arguments of
    the same types skips numba's argument dispatch (a few microseconds per call on
    named-structure arguments); None if there is none."""
    signature = tuple(dispatcher.typeof_pyval(a) for a in (*head, *args))
    compiled = dispatcher.overloads.get(signature)
    return None if compiled is None else functools.partial(compiled.entry_point, *head)


# --------------------------------------------------------------------------- decorators
def kernel_function(fn: Callable[..., Any] | None = None, *, inline: bool = False) -> Any:
    """Compile a function called only from the kernels with :data:`KERNEL_OPTIONS`;
    ``inline=True``: LLVM inlines it into every caller (``forceinline``, for the small
    functions of a SIMD loop's body). ``@kernel_function`` or ``@kernel_function(inline=True)``."""
    options = {**KERNEL_OPTIONS, "forceinline": True} if inline else KERNEL_OPTIONS
    if fn is None:
        return njit(**options)
    return njit(**options)(fn)


def inlined(fn: Callable[..., Any]) -> Any:
    """Compile a small function that numba copies into each caller before typing
    (``inline="always"``; numpy's error model, cached): for helpers that callers compiled
    with other options (reference counting, Python's error model) also use."""
    return njit(cache=True, error_model="numpy", inline="always")(fn)
