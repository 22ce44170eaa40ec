"""Many L-BFGS-B searches run in lockstep: one thread per search, their objective requests
gathered so that one batched kernel call evaluates them all (:class:`Lockstep`)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["Lockstep"]


class _Aborted(Exception):
    """Raised in a search thread when the evaluating thread failed."""


class Lockstep:
    """Runs one L-BFGS-B search per lane, each in its own thread, and gathers their objective
    requests: the calling thread evaluates all pending requests at once (one open-loop run of
    every lane per kernel call) when every live search waits for one."""

    def __init__(self, evaluate: Callable[[dict[int, np.ndarray]], dict[int, Any]]) -> None:
        self._evaluate = evaluate
        self._cond = threading.Condition()
        self._pending: dict[int, np.ndarray] = {}
        self._results: dict[int, Any] = {}
        self._live: set[int] = set()
        self._failed = False

    def request(self, lane: int, x: np.ndarray) -> Any:
        with self._cond:
            self._pending[lane] = np.array(x, dtype=np.float64)
            self._cond.notify_all()
            while lane not in self._results:
                if self._failed:
                    raise _Aborted
                self._cond.wait()
            return self._results.pop(lane)

    def _finish(self, lane: int) -> None:
        with self._cond:
            self._live.discard(lane)
            self._cond.notify_all()

    def run(self, searches: dict[int, Callable[[Callable[[np.ndarray], Any]], Any]]) -> dict:
        """Run ``searches[lane](objective)`` for every lane; returns their results."""
        results: dict[int, Any] = {}
        errors: list[BaseException] = []

        def work(lane: int, search: Callable) -> None:
            try:
                results[lane] = search(lambda x: self.request(lane, x))
            except _Aborted:
                pass
            except BaseException as exc:  # noqa: BLE001 - re-raised in the calling thread
                errors.append(exc)
                with self._cond:
                    self._failed = True
            finally:
                self._finish(lane)

        self._live = set(searches)
        threads = [
            threading.Thread(target=work, args=(lane, s), daemon=True)
            for lane, s in searches.items()
        ]
        for thread in threads:
            thread.start()
        try:
            while True:
                with self._cond:
                    while self._live and not self._failed and (
                        set(self._pending) != self._live
                    ):  # fmt: skip
                        self._cond.wait()
                    if not self._live or self._failed:
                        break
                    batch, self._pending = self._pending, {}
                out = self._evaluate(batch)
                with self._cond:
                    self._results.update(out)
                    self._cond.notify_all()
        except BaseException:
            with self._cond:
                self._failed = True
                self._cond.notify_all()
            raise
        finally:
            for thread in threads:
                thread.join()
        if errors:
            raise errors[0]
        return results
