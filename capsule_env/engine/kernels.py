"""The one kernel factory: compiled kernels for a damper model, serial and on all cores.

Two kinds of kernel step a batch of vehicles by one control interval: the plant alone
(:func:`capsule_env.engine.simulate.step_batch`) and the whole env step
(:class:`capsule_env.engine.batch.CapsuleBatch`: commands, plant, sensors, reward). For each (kind,
damper model, kernel mode, and for the env its command path, whether it previews the guideway,
the envelope's flags and the sensing's: sensor noise, the reward's filter), :func:`kernels`
makes a pair:

- ``serial(lo, hi, *args)`` steps vehicles ``lo .. hi-1``, a block of up to 64 at a time;
- ``parallel(n, *args)`` steps ``[0, n)`` in chunks on all cores (numba ``prange``);

``args``: for an ``ENV`` kernel ``(actions, signals, EnvArgs)``, where :class:`EnvArgs` holds
the batch's ``EnvParams``, ``PlantParams``, ``EnvState`` and the other outputs (made once per
batch by :func:`env_args`); for a ``PLANT`` kernel ``(PlantParams, state, current_command_a,
Route, dt_s, plant_outputs)``.

The kind, model, mode, command path and the flags are closure constants, so numba compiles
each pair only for what it uses (the model-specific code is chosen at typing: see
:mod:`capsule_env.plant.block` and :mod:`capsule_env.plant.rk4`; a noise-free env without a
reward filter compiles neither: :func:`capsule_env.engine.env_kernel.env_sense_variant`) and caches
it on disk. The
parallel kernel's chunks call the serial one: one function between the Python call and the
block kernels (each nesting level of numba functions re-optimises and re-emits the machine code
of everything below it). A vehicle's numbers do not depend on its chunk or thread: both kernels
give the same bits. :class:`BatchedKernel` calls the right one for a batch size and skips
numba's argument dispatch once the kernel is compiled (it would cost a few microseconds per
call on the named-structure arguments: a large part of a single env's step).

Why :class:`EnvArgs`: a compiled call unboxes each array argument (a check, a reference and a
small allocation each). The env kernel reads about 26 arrays through its named structures;
passed as tuples they cost about 1.4 us a call (measured: 1.84 us against 0.41 us for one
``EnvArgs``), a fifth of a single env's step. ``EnvArgs`` is a numba ``StructRef``: boxed once
per batch, it holds the same arrays (their memory, not copies) and unboxes as one pointer.
Inside, every function below the serial kernel allocates nothing (their scratch comes from the
serial kernel) and is compiled without reference counting
(:data:`capsule_env._fastmath.BORROWED`). The serial kernel itself still counts references when
it reads the structures out of ``EnvArgs`` (numba's ``StructRef`` access needs its runtime): 78
atomic operations a single-env step, counted with a debugger, against about 240 before.

Fork: a forked child of a process that has launched a parallel region runs the serial kernels
(GNU OpenMP would terminate it: :class:`capsule_env._jit.ForkGuard`). (Numba's fork-safe
``workqueue`` layer and a pool of Python threads were measured slower than the serial kernel at
N = 64: their thread wake-up costs 50-80 us a step.) The compiler's machinery (the StructRef,
the variants' symbol names, the compiled entry points) lives in :mod:`capsule_env._jit`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange

from capsule_env._jit import FORK_GUARD, Bundle, bundle_constructor, compiled_entry, unique_symbol
from capsule_env.engine.env_kernel import (
    SENSE_ALL,
    SENSE_SCRATCH_SHAPE,
    EnvOutputs,
    env_commands,
    env_preview,
    env_sense_variant,
)
from capsule_env.engine.env_params import applied_current
from capsule_env.envelope.kernel import envelope_interval, envelope_observe
from capsule_env.envelope.options import ENVELOPE_EDS_PER_STEP, ENVELOPE_TRIP
from capsule_env.plant.block import (
    BLOCK,
    KERNEL_LEVITATION_DAMPED,
    KERNEL_SCALAR,
    block_scratch,
    block_step,
    kernel_family,
)
from capsule_env.plant.params import PlantParams, Route
from capsule_env.plant.scalar import scalar_step

__all__ = ["ENV", "PLANT", "PARALLEL_THRESHOLD", "BatchedKernel", "EnvArgs", "env_args", "kernels"]

#: Kernel kinds.
ENV, PLANT = 0, 1
#: Batches at least this large are stepped by the multi-threaded kernel.
PARALLEL_THRESHOLD = 64


@njit(cache=True)
def work_item_size(n: int) -> int:
    """Vehicles per work item of the parallel kernels: one block for large batches, smaller (a
    multiple of 8, at least 4 items) for small ones so that every core gets work."""
    return min(BLOCK, max(8, ((n + 3) // 4 + 7) // 8 * 8))


#: The env kernel's arguments that stay the same from step to step, as one object (a
#: :class:`capsule_env._jit.Bundle` made by :func:`env_args`; fields ``params``, ``plant``,
#: ``state``, ``obs``, ``reward``, ``terminated``, ``plant_out``, readable in compiled code
#: only). It refers to the arrays it was made from (their memory, not copies): the kernel
#: writes into them, and arrays assigned afterwards in their place are not seen. ``signals``
#: is not in it: the vector envs give it a new buffer every step.
EnvArgs = Bundle

_ENV_ARGS_FIELDS = ("params", "plant", "state", "obs", "reward", "terminated", "plant_out")


#: Makes an :data:`EnvArgs` in compiled code (:func:`capsule_env._jit.bundle_constructor`).
_new_env_args = bundle_constructor("_new_env_args", _ENV_ARGS_FIELDS)


@njit(cache=True, no_cfunc_wrapper=True)  # called from Python only
def env_args(params, plant, state, obs, reward, terminated, plant_out):  # noqa: ANN001, ANN201
    """:class:`EnvArgs` of ``EnvParams``, ``PlantParams``, ``EnvState`` and the output arrays
    ``obs``, ``reward``, ``terminated``, ``plant_out`` (``EnvOutputs`` but ``signals``)."""
    return _new_env_args(params, plant, state, obs, reward, terminated, plant_out)


def _make_kernels(
    kind: int, model: int, mode: int, command: int, preview: bool, envelope: int, sense: int
) -> tuple[Any, Any]:
    # numba's parallel loops cannot capture tuples (the named structures): the parallel
    # plant kernel takes them apart into arrays and scalars before the loop and puts them
    # together again in each chunk (the env kernel's EnvArgs can be captured as it is).
    # Called from Python (a CPython wrapper), never through a C pointer (no cfunc wrapper).
    # Each variant gets a name of its own (_jit.unique_symbol): see there.
    variant = f"k{kind}_m{model}_d{mode}_c{command}_p{int(preview)}".replace("-", "n")
    if envelope:  # the paper's kernels keep their names (and numba's cache files)
        variant += f"_e{envelope}"
    if sense != SENSE_ALL:
        variant += f"_s{sense}"
    if kind == ENV:
        return _env_kernels(variant, model, mode, command, preview, envelope, sense)
    return _plant_kernels(variant, model, mode)


def _env_kernels(
    variant: str, model: int, mode: int, command: int, preview: bool, envelope: int, sense: int
) -> tuple[Any, Any]:
    """The env kernels ``(serial, parallel)``: commands -> (envelope) -> plant -> sense ->
    observe."""
    family, damped = kernel_family(mode), (mode & KERNEL_LEVITATION_DAMPED) != 0
    trip = (envelope & ENVELOPE_TRIP) != 0
    eds_per_step = (envelope & ENVELOPE_EDS_PER_STEP) != 0

    @njit(cache=True, no_cfunc_wrapper=True)
    @unique_symbol(variant)
    def serial(lo, hi, actions, signals, args):
        params, plant, state = args.params, args.plant, args.state
        out = EnvOutputs(args.obs, args.reward, args.terminated, signals, args.plant_out)
        # scratch of the sensing and block_step, one per call (they allocate nothing)
        scratch = np.empty(SENSE_SCRATCH_SHAPE)
        lanes, counts = block_scratch()
        for b in range(lo, hi, BLOCK):
            e = min(hi, b + BLOCK)
            env_commands(command, b, e, actions, params, state, out)
            if trip:
                envelope_interval(b, e, params, plant, state, eds_per_step)
            x, i_cmd, route = state.plant, applied_current(state), state.route
            if family == KERNEL_SCALAR:
                scalar_step(model, damped, b, e, plant, x, i_cmd, route, params.dt_s, out.plant)
            else:
                block_step(
                    model, mode, b, e, plant, x, i_cmd, route, params.dt_s, out.plant,
                    lanes, counts,
                )  # fmt: skip
            env_sense_variant(sense, b, e, params, plant, state, out, scratch)
            if trip:
                envelope_observe(b, e, params, state, out.obs)
            if preview:
                env_preview(b, e, params, plant, state, out.obs)

    @njit(cache=True, parallel=True, no_cfunc_wrapper=True)
    @unique_symbol(variant)
    def parallel(n, actions, signals, args):
        chunk = work_item_size(n)
        for c in prange((n + chunk - 1) // chunk):
            serial(c * chunk, min(n, (c + 1) * chunk), actions, signals, args)

    return serial, parallel


def _plant_kernels(variant: str, model: int, mode: int) -> tuple[Any, Any]:
    """The plant kernels ``(serial, parallel)``: the plant alone over a control interval."""
    family, damped = kernel_family(mode), (mode & KERNEL_LEVITATION_DAMPED) != 0

    @njit(cache=True, no_cfunc_wrapper=True)
    @unique_symbol(variant)
    def serial(lo, hi, plant, x, i_cmd, route, dt, out):
        lanes, counts = block_scratch()
        for b in range(lo, hi, BLOCK):
            e = min(hi, b + BLOCK)
            if family == KERNEL_SCALAR:
                scalar_step(model, damped, b, e, plant, x, i_cmd, route, dt, out)
            else:
                block_step(model, mode, b, e, plant, x, i_cmd, route, dt, out, lanes, counts)

    @njit(cache=True, parallel=True, no_cfunc_wrapper=True)
    @unique_symbol(variant)
    def parallel(n, plant, x, i_cmd, route, dt, out):
        dp, vp, table, constants, profiles, spacing, offsets = plant
        r0, r1, r2, r3 = route
        chunk = work_item_size(n)
        for c in prange((n + chunk - 1) // chunk):
            serial(c * chunk, min(n, (c + 1) * chunk),
                   PlantParams(dp, vp, table, constants, profiles, spacing, offsets), x, i_cmd,
                   Route(r0, r1, r2, r3), dt, out)  # fmt: skip

    return serial, parallel


_KERNELS: dict[tuple[int, int, int, int, bool, int, int], tuple[Any, Any]] = {}


def kernels(
    kind: int, model: int, mode: int, command: int = 0, preview: bool = False, envelope: int = 0,
    sense: int = SENSE_ALL,
) -> tuple[Any, Any]:  # fmt: skip
    """``(serial, parallel)`` compiled kernels of a kind for a damper model and kernel mode,
    and for ``ENV`` kernels a command path (``env_kernel.command_path``), whether the
    observations carry guideway preview, the envelope's flags (``Envelope.flags``: trips,
    EDS levitation per step) and the sensing's (``env_kernel.sense_flags``: sensor noise, the
    reward's filter; ``SENSE_ALL``: both, decided at run time) (memoised; compiled when first
    called, then loaded from numba's disk cache)."""
    env = kind == ENV
    key = (int(kind), int(model), int(mode), int(command) if env else 0, bool(preview) and env,
           int(envelope) if env else 0, int(sense) if env else SENSE_ALL)  # fmt: skip
    if key not in _KERNELS:
        _KERNELS[key] = _make_kernels(*key)
    return _KERNELS[key]


class BatchedKernel:
    """Calls ``serial(0, n, *args)`` for a small batch (or in a forked child, see the module
    docstring) and ``parallel(n, *args)`` for a large one, through the compiled entry points
    once they exist (the argument types of a batch never change)."""

    def __init__(
        self, kind: int, model: int, mode: int, num_envs: int, command: int = 0,
        preview: bool = False, envelope: int = 0, sense: int = SENSE_ALL,
    ) -> None:  # fmt: skip
        self._key = (kind, model, mode, num_envs, command, preview, envelope, sense)
        self.serial, self.parallel = kernels(kind, model, mode, command, preview, envelope, sense)
        self.num_envs = num_envs
        self._threaded = num_envs >= PARALLEL_THRESHOLD
        # compiled entry points with their leading arguments bound, by "threaded"; _entry is
        # the one a call normally takes (the serial one in a forked child is in _entries)
        self._entries: dict[bool, Any] = {}
        self._entry: Any = None

    def __getstate__(self) -> tuple[Any, ...]:
        # what it is, not its compiled entry points (which cannot be pickled): a copy or an
        # unpickled batch finds (or compiles, or loads from the cache) its own
        return self._key

    def __setstate__(self, key: tuple[Any, ...]) -> None:
        self.__init__(*key)

    def __call__(self, *args: Any) -> None:
        entry = self._entry
        if entry is not None and not (self._threaded and FORK_GUARD.serial_only):
            entry(*args)
            return
        self._call_slow(args)

    def _call_slow(self, args: tuple[Any, ...]) -> None:
        n = self.num_envs
        threaded = self._threaded and not FORK_GUARD.serial_only
        entry = self._entries.get(threaded)
        if entry is not None:
            entry(*args)
            return
        head = (n,) if threaded else (0, n)
        dispatcher = self.parallel if threaded else self.serial
        FORK_GUARD.launched_parallel |= threaded
        dispatcher(*head, *args)  # compiles (or loads from the cache) on the first call
        entry = compiled_entry(dispatcher, head, args)
        if entry is not None:
            self._entries[threaded] = entry
            if threaded == self._threaded:
                self._entry = entry
