"""Run a compiled kernel over a batch of vehicles, on all cores when the batch is large, and
safely after ``fork()``.

Every kernel is written once, as a serial function of the range of vehicles ``[lo, hi)`` it
steps. :func:`parallel_kernel` wraps it in numba's ``prange`` over chunks of the batch, and
:func:`run_batched` picks one of the two: the serial kernel for small batches (a thread launch
costs more than they do), the parallel one for large batches. A vehicle's numbers do not depend
on its chunk or thread, so both give the same bits.

Fork: numba's fastest threading layer here is GNU OpenMP, which terminates a child process that
launches a parallel region after its parent did (``fork() called from a process already using
GNU OpenMP``; ``AsyncVectorEnv(context="fork")``, multiprocessing pools). A forked child of a
process that has launched one therefore runs the serial kernels: correct and as fast per core,
never killed. (Numba's fork-safe ``workqueue`` layer and a pool of Python threads were measured
slower than the serial kernel at N = 64: their thread wake-up costs 50-80 us a step.)
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from numba import njit, prange

__all__ = ["PARALLEL_THRESHOLD", "parallel_kernel", "run_batched"]

#: Batches at least this large are stepped by the multi-threaded kernel.
PARALLEL_THRESHOLD = 64

_launched_parallel = False  # this process has launched a parallel region
_serial_only = False  # a forked child of a process that had: never launch one


def _after_fork_in_child() -> None:
    global _serial_only
    _serial_only = _serial_only or _launched_parallel


os.register_at_fork(after_in_child=_after_fork_in_child)


@njit(cache=True)
def work_item_size(n: int) -> int:
    """Vehicles per work item of the parallel kernels: one 64-vehicle block for large
    batches, smaller (a multiple of 8, at least 4 items) for small ones so that every core gets
    work. A vehicle's result does not depend on its block mates, so this changes no number."""
    return min(64, max(8, ((n + 3) // 4 + 7) // 8 * 8))


def parallel_kernel(serial: Callable[..., None]) -> Callable[..., None]:
    """A numba ``parallel=True`` kernel ``(n, *args)`` that calls ``serial(lo, hi, *args)`` on
    chunks of ``[0, n)`` in parallel."""

    @njit(cache=True, parallel=True)
    def parallel(n, *args):
        chunk = work_item_size(n)
        for c in prange((n + chunk - 1) // chunk):
            serial(c * chunk, min(n, (c + 1) * chunk), *args)

    return parallel


def run_batched(
    serial: Callable[..., None], parallel: Callable[..., None], n: int, *args: Any
) -> None:
    """``serial(0, n, *args)`` for a small batch (or in a forked child, see the module
    docstring), ``parallel(n, *args)`` for a large one."""
    global _launched_parallel
    if n < PARALLEL_THRESHOLD or _serial_only:
        serial(0, n, *args)
        return
    _launched_parallel = True
    parallel(n, *args)
