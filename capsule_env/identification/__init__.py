"""Identification of MR-damper forward models from force loops (docs/model.md, section 6).

The paper built its damper models from measured force loops: a sinusoidal stroke at a set of
constant coil currents, the force recorded against displacement and velocity. This package does
the same for three forward models of :mod:`capsule_env.dampers`, from loops of the reference
damper (the "hardware" in simulation, docs/model.md 4.2) or from measured laboratory files:

- **Bi-exponential** (docs/model.md 4.5, paper eq. 4): per current and stroke-sign branch, then
  linear laws in current (the paper's Table 2, Figures 5 and 6).
- **Bouc-Wen** (docs/model.md 4.3, n = 2): least squares of the simulated response over all loops
  at once, with ``A = 1`` fixed to remove the model's scale degeneracy.
- **tanh** (docs/model.md 4.4, paper eq. 3): ``c, k, alpha, f0`` linear in current, ``beta, delta``
  constant.

All three fits use *variable projection* (a search over a few shape parameters around a linear
least-squares solve). Modules, each one idea:

- :mod:`~capsule_env.identification.loops`: :class:`Loop`, :func:`reference_loops` and the
  loop helpers;
- :mod:`~capsule_env.identification.measured`: reading Labcontrol ``.mat`` files
  (:func:`measured_files`, :func:`load_measured_loop`);
- :mod:`~capsule_env.identification.tabular`: reading CSV and NumPy files, and any supported
  file (:func:`load_loops`; velocity derived when absent, :func:`derive_velocity`);
- :mod:`~capsule_env.identification.plausibility`: checks of measured files and fits against
  what a damper test holds (errors, :class:`PlausibilityWarning`);
- :mod:`~capsule_env.identification.least_squares`: the shared least-squares pieces and
  :func:`rmse`;
- :mod:`~capsule_env.identification.bi_exponential`, :mod:`~capsule_env.identification.bouc_wen`,
  :mod:`~capsule_env.identification.tanh`: one fitter each;
- :mod:`~capsule_env.identification.predict`: :func:`predict_force`, a model's force on a loop;
- :mod:`~capsule_env.identification.results`: whole runs (:func:`identify_reference`,
  :func:`identify_measured`, :func:`identify_files`), their results and JSON, and dataclass
  default lines.

The figures (:func:`plot_fits`) live in :mod:`capsule_env.plots`; ``plot_fits`` is importable
from here too, loaded on first use (:mod:`capsule_env.plots` imports this package, so importing
it here at once would be circular).

Units: SI throughout (m, m/s, N, A, s). Pure functions and frozen dataclasses; no Gym import.
"""

from __future__ import annotations

from typing import Any

from capsule_env.identification.bi_exponential import (
    D_RULES,
    BiExponentialTrends,
    fit_bi_exponential,
)
from capsule_env.identification.bouc_wen import fit_bouc_wen
from capsule_env.identification.least_squares import rmse
from capsule_env.identification.loops import DEFAULT_CURRENTS_A, Loop, reference_loops
from capsule_env.identification.measured import (
    MAX_MEASURED_MAGNITUDE,
    load_measured_loop,
    measured_files,
)
from capsule_env.identification.plausibility import PlausibilityWarning
from capsule_env.identification.predict import predict_force
from capsule_env.identification.results import (
    MODEL_NAMES,
    PAPER_RMSE_N,
    IdentificationResult,
    ModelFit,
    dataclass_default_lines,
    identify_files,
    identify_loops,
    identify_measured,
    identify_reference,
)
from capsule_env.identification.tabular import (
    SUPPORTED_SUFFIXES,
    derive_velocity,
    load_loops,
)
from capsule_env.identification.tanh import fit_tanh

__all__ = [
    "DEFAULT_CURRENTS_A",
    "D_RULES",
    "MAX_MEASURED_MAGNITUDE",
    "MODEL_NAMES",
    "PAPER_RMSE_N",
    "SUPPORTED_SUFFIXES",
    "BiExponentialTrends",
    "IdentificationResult",
    "Loop",
    "ModelFit",
    "PlausibilityWarning",
    "dataclass_default_lines",
    "derive_velocity",
    "fit_bi_exponential",
    "fit_bouc_wen",
    "fit_tanh",
    "identify_files",
    "identify_loops",
    "identify_measured",
    "identify_reference",
    "load_loops",
    "load_measured_loop",
    "measured_files",
    "plot_fits",
    "predict_force",
    "reference_loops",
    "rmse",
]


def __getattr__(name: str) -> Any:
    """``plot_fits`` from :mod:`capsule_env.plots`, imported on first use (PEP 562)."""
    if name == "plot_fits":
        from capsule_env.plots import plot_fits

        globals()["plot_fits"] = plot_fits
        return plot_fits
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names, ``plot_fits`` included before its first use."""
    return sorted(set(globals()) | {"plot_fits"})
