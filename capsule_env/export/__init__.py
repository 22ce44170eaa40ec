"""Learned policies out of Python: ONNX, dependency-free C99 and a contract (issue 44).

    python -m capsule_env.export ppo-measured --format onnx,c --out exported/
    capsule-export runs/ppo/best_model.zip --out exported/ --name ppo-run1

One idea per module: :mod:`~capsule_env.export.source` (which policy),
:mod:`~capsule_env.export.network` (its deterministic action as data),
:mod:`~capsule_env.export.onnx_export` (``NAME.onnx``), :mod:`~capsule_env.export.c_export`
(``NAME.c``, ``NAME.h``), :mod:`~capsule_env.export.laws_c` (a residual's classical law in C),
:mod:`~capsule_env.export.contract` (``NAME.contract.json``),
:mod:`~capsule_env.export.base_law` (a residual's law, for the rig to rebuild; a quarter-car's:
:mod:`~capsule_env.export.quarter_law`),
:mod:`~capsule_env.export.artifacts` (build, then write atomically),
:mod:`~capsule_env.export.c_build` (compile the C with the system's compiler and call it from
Python: the tests, the benchmark and the HILS dry run). Needs the ``rl`` extra (the policy's
model) and, for ONNX, the ``export`` extra. docs/howto-export.md tells the whole story.
"""

from __future__ import annotations

__all__ = ["FORMATS", "export_policy"]

from capsule_env.export.artifacts import FORMATS, export_policy
