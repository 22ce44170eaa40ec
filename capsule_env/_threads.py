"""Run a compiled kernel over a batch on several threads, fork-safely.

The kernels are compiled with ``nogil=True`` and take the range of vehicles ``[lo, hi)`` they
step; :func:`run_batched` splits a large batch into contiguous chunks and runs them on a small
pool of Python threads (the calling thread takes the first chunk). The kernels release the GIL,
so the chunks run in parallel. Unlike numba's ``parallel=True`` (whose GNU OpenMP layer kills a
child process forked after it ran: ``fork() called from a process already using GNU OpenMP``),
this survives ``fork()``: the pool is rebuilt lazily in the child. A vehicle's numbers do not
depend on which chunk or thread steps it, so the results are the same bits for any number of
threads.

Threads: ``CAPSULE_ENV_NUM_THREADS`` if set, else the CPUs this process may run on; change it
with :func:`set_num_threads`.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

__all__ = ["PARALLEL_THRESHOLD", "get_num_threads", "run_batched", "set_num_threads"]

#: Batches at least this large are split across threads (smaller ones: one call, no pool).
PARALLEL_THRESHOLD = 64
#: Chunks are whole multiples of this many vehicles (the block kernel's SIMD groups).
_CHUNK_MULTIPLE = 8


def _default_threads() -> int:
    text = os.environ.get("CAPSULE_ENV_NUM_THREADS")
    if text:
        try:
            value = int(text)
        except ValueError:
            raise ValueError(
                f"CAPSULE_ENV_NUM_THREADS must be an integer >= 1, got {text!r}"
            ) from None
        if value < 1:
            raise ValueError(f"CAPSULE_ENV_NUM_THREADS must be an integer >= 1, got {text!r}")
        return value
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


_lock = threading.Lock()
_num_threads = _default_threads()
_pool: ThreadPoolExecutor | None = None


def get_num_threads() -> int:
    """Threads used to step a large batch."""
    return _num_threads


def set_num_threads(n: int) -> None:
    """Use ``n`` threads (>= 1) to step large batches from now on."""
    global _num_threads, _pool
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    with _lock:
        _num_threads = n
        if _pool is not None:
            _pool.shutdown(wait=False)
            _pool = None


def _forget_pool_in_child() -> None:
    # The parent's worker threads do not exist in a forked child: start a new pool there.
    global _pool, _lock
    _pool = None
    _lock = threading.Lock()


os.register_at_fork(after_in_child=_forget_pool_in_child)


def _get_pool(workers: int) -> ThreadPoolExecutor:
    global _pool
    with _lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(workers, thread_name_prefix="capsule-env")
        return _pool


def chunk_bounds(n: int, threads: int) -> list[int]:
    """Chunk boundaries ``[0, ..., n]``: ``threads`` chunks of nearly equal size, each a
    multiple of 8 vehicles except the last."""
    size = -(-n // threads)
    size = -(-size // _CHUNK_MULTIPLE) * _CHUNK_MULTIPLE
    return [*range(0, n, size), n]


def run_batched(kernel: Callable[..., Any], n: int, *args: Any) -> None:
    """``kernel(lo, hi, *args)`` over ``[0, n)``: one call for a small batch, else chunks on
    :func:`get_num_threads` threads. Exceptions from any chunk are raised here."""
    threads = _num_threads
    if n < PARALLEL_THRESHOLD or threads == 1:
        kernel(0, n, *args)
        return
    bounds = chunk_bounds(n, threads)
    pool = _get_pool(threads - 1)
    futures = [pool.submit(kernel, lo, hi, *args) for lo, hi in zip(bounds[1:-1], bounds[2:])]
    try:
        kernel(bounds[0], bounds[1], *args)
    finally:
        for future in futures:
            future.result()
