"""``reset(seed=...)`` of the native vector envs, read as Gymnasium's vector envs read it.

Gymnasium's ``VectorEnv.reset`` takes ``seed: int | list[int | None] | None``; in a list, a
``None`` leaves that sub-env's generator as it is (``SyncVectorEnv`` resets it with
``seed=None``). :func:`reseed` does the same for a batch of vehicles, whose generators are
``batch.rngs`` (:func:`capsule_env.engine.batch.vehicle_streams` for the ints).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from capsule_env.engine.batch import vehicle_streams
from capsule_env.engine.config import check_seed

__all__ = ["reseed"]


def reseed(batch: Any, seed: Any, num_envs: int, mask: np.ndarray | None = None) -> None:
    """Re-seed the vehicles of ``batch`` (those in ``mask``, or all) for ``reset(seed=seed)``:
    None keeps every stream; an int or a list of ``num_envs`` ints as
    :func:`~capsule_env.engine.batch.vehicle_streams`; a ``None`` in the list keeps that
    vehicle's stream. A seed of another type or value raises ``TypeError``/``ValueError``
    naming it (``seed[k]``), before any vehicle is re-seeded."""
    if seed is None:
        return
    streams: list[Any]
    entries = _entries(seed)
    if entries is not None and any(s is None for s in entries):
        if len(entries) != num_envs:
            raise ValueError(f"seed must be an int or a list of {num_envs} ints or None, "
                             f"got {len(entries)}")  # fmt: skip
        checked = [
            None if s is None else check_seed(f"seed[{k}]", s) for k, s in enumerate(entries)
        ]
        streams = [None if s is None else vehicle_streams([s], 1)[0] for s in checked]
    else:
        streams = vehicle_streams(seed, num_envs)
    for n in range(num_envs) if mask is None else np.flatnonzero(mask):
        if streams[n] is not None:
            batch.rngs[n] = streams[n]


def _entries(seed: Any) -> list[Any] | None:
    """The entries of a list of seeds (None for a single seed)."""
    if isinstance(seed, (list, tuple, np.ndarray)):
        return list(np.asarray(seed, dtype=object).reshape(-1))
    return None
