"""Rollouts of any controller as Minari datasets, and an offline baseline on them (issue 44).

    capsule-datasets --task CapsuleRide-v0 --controller mpc-biexp-meas --out datasets/mpc
    capsule-datasets --task CapsuleRide-v0 --controller oracle --episodes 10 --out datasets/oracle
    python -m capsule_env.datasets.bc --dataset-root datasets/mpc   # behaviour cloning

One idea per module: :mod:`~capsule_env.datasets.demonstrators` (which controller: a classical
law, a learned policy, the oracle), :mod:`~capsule_env.datasets.rollouts` (its episodes as
transitions), :mod:`~capsule_env.datasets.oracle_replay` (the oracle's applied currents
replayed through the env), :mod:`~capsule_env.datasets.minari_store` (Minari's format,
written atomically under a root of its own), :mod:`~capsule_env.datasets.record` (the checks,
the run, the write), :mod:`~capsule_env.datasets.bc` (behaviour cloning, evaluated like every
other row). Needs the ``datasets`` extra (minari, h5py); learned policies and behaviour cloning
the ``rl`` extra; the MPC the ``mpc`` extra. docs/howto-datasets.md tells the whole story.
"""

from __future__ import annotations

__all__ = ["record_dataset", "load_dataset"]

from capsule_env.datasets.minari_store import load_dataset
from capsule_env.datasets.record import record_dataset
