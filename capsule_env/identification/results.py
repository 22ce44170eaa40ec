"""A whole identification run: fit every model to a set of loops and report how well each fits.

:func:`identify_loops` fits the Bi-exponential, Bouc-Wen and tanh models
(:mod:`~capsule_env.identification.bi_exponential`, :mod:`~capsule_env.identification.bouc_wen`,
:mod:`~capsule_env.identification.tanh`) and scores each with
:func:`~capsule_env.identification.predict.predict_force`; :func:`identify_reference` and
:func:`identify_measured` make the loops first (reference damper, or one measured file). The
result (:class:`IdentificationResult`) has a plain-JSON form, and
:func:`dataclass_default_lines` turns a fitted model into the default lines of its dataclass
in :mod:`capsule_env.dampers`.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.dampers import DamperParams
from capsule_env.identification.bi_exponential import BiExponentialTrends, fit_bi_exponential
from capsule_env.identification.bouc_wen import fit_bouc_wen
from capsule_env.identification.loops import (
    DEFAULT_CURRENTS_A,
    Loop,
    check_loops,
    group_by_current,
    reference_loops,
)
from capsule_env.identification.plausibility import (
    check_dissipation,
    check_fit,
    check_fit_quality,
)
from capsule_env.identification.predict import predict_force
from capsule_env.identification.tabular import load_loops
from capsule_env.identification.tanh import fit_tanh

__all__ = [
    "MODEL_NAMES",
    "PAPER_RMSE_N",
    "IdentificationResult",
    "ModelFit",
    "dataclass_default_lines",
    "identify_files",
    "identify_loops",
    "identify_measured",
    "identify_reference",
]

#: The identified models, in report order.
MODEL_NAMES: tuple[str, ...] = ("bi_exponential", "bouc_wen", "tanh")
#: The paper's RMSE at 1.5 A on its own damper's measured loops (N) [paper].
PAPER_RMSE_N: dict[str, float] = {"bi_exponential": 61.8, "bouc_wen": 695.3}


def _model_params(damper: DamperParams) -> dict[str, float]:
    return {f.name: float(getattr(damper, f.name)) for f in fields(damper)}


@dataclass(frozen=True, eq=False)
class ModelFit:
    """One identified forward model and how well it reproduces the loops.

    Attributes
    ----------
    name : ``"bi_exponential"``, ``"bouc_wen"`` or ``"tanh"``.
    damper : the fitted model (a :mod:`capsule_env.dampers` dataclass).
    rmse_per_current_n : RMSE (N) of the model force against the loops at each current (A).
    rmse_n : RMSE (N) at the reporting current (the largest, 1.5 A for the reference loops; the
        file itself for a measured loop).
    """

    name: str
    damper: DamperParams
    rmse_per_current_n: dict[float, float]
    rmse_n: float

    @property
    def params(self) -> dict[str, float]:
        """The fitted parameter values by dataclass field name (SI units)."""
        return _model_params(self.damper)


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """All identified models of one set of loops.

    Attributes
    ----------
    source : what the loops are (the simulated damper and stroke, or the file name).
    loops : the loops the models were fitted to.
    models : :class:`ModelFit` per model name (:data:`MODEL_NAMES`).
    bi_exponential : the Bi-exponential identification steps and the Table 2 analogue.
    peak_force_n : the largest force magnitude over all loops (N, after any offset removal).
    rmse_current_a : the current whose RMSE is reported as each model's ``rmse_n`` (A).
    force_offset_n : force offset removed from a measured loop (N; 0 for simulated loops).
    timings_s : fitting time of each model (s, wall clock).
    d_rule : the Bi-exponential ``d`` rule used (:data:`D_RULES`).
    """

    source: str
    loops: tuple[Loop, ...]
    models: dict[str, ModelFit]
    bi_exponential: BiExponentialTrends
    peak_force_n: float
    rmse_current_a: float
    force_offset_n: float = 0.0
    timings_s: dict[str, float] = field(default_factory=dict)
    d_rule: str = "mean"

    @property
    def current_known(self) -> bool:
        """False when no loop's file stated its current (each was fitted at 0 A,
        :attr:`Loop.current_known`)."""
        return any(lp.current_known for lp in self.loops)

    @property
    def table(self) -> dict[str, dict[str, float]]:
        """The Bi-exponential linear-law table (paper's Table 2): ``{branch: {a0, ..., d}}``."""
        return self.bi_exponential.table

    def to_json_dict(self) -> dict[str, Any]:
        """Plain-JSON summary: ``{"models": {name: {"rmse_n", "rmse_per_current_n", "params",
        ...}}, "peak_force_n", "source", "table", ...}``."""
        models = {}
        for name, fit in self.models.items():
            models[name] = {
                "rmse_n": float(fit.rmse_n),
                "rmse_fraction_of_peak": float(fit.rmse_n / self.peak_force_n),
                "rmse_per_current_n": {
                    f"{i:g}": float(e) for i, e in fit.rmse_per_current_n.items()
                },
                "params": fit.params,
            }
            if name in PAPER_RMSE_N:
                models[name]["paper_rmse_n"] = PAPER_RMSE_N[name]
        return {
            "source": self.source,
            "models": models,
            "peak_force_n": float(self.peak_force_n),
            "rmse_current_a": float(self.rmse_current_a),
            "current_known": self.current_known,
            "force_offset_n": float(self.force_offset_n),
            "d_rule": self.d_rule,
            "table": self.bi_exponential.to_json_dict()["table"],
            "bi_exponential_trends": self.bi_exponential.to_json_dict(),
            "paper_rmse_n": dict(PAPER_RMSE_N),
            "timings_s": {k: float(t) for k, t in self.timings_s.items()},
        }


def _rmse_per_current(damper: DamperParams, loops: Sequence[Loop]) -> dict[float, float]:
    """RMSE (N) of the model's force against the loops, per distinct current (A)."""
    currents, groups = group_by_current(loops)
    out = {}
    for i, group in zip(currents, groups):
        err = np.concatenate([predict_force(damper, lp) - lp.force_n for lp in group])
        out[float(i)] = float(np.sqrt(np.mean(err**2)))
    return out


def identify_loops(
    loops: Sequence[Loop],
    source: str | None = None,
    d_rule: str = "mean",
    allow_poor_fit: bool = False,
) -> IdentificationResult:
    """Fit the Bi-exponential, Bouc-Wen and tanh models to a set of loops (docs/model.md 6).

    Each model's RMSE is evaluated with the package's own forward model
    (:func:`predict_force`) on every loop; ``rmse_n`` is the RMSE at the largest current.
    ``d_rule`` picks the Bi-exponential ``d`` rule (:func:`fit_bi_exponential`). A loop that
    does not dissipate, a fitted model that does not, and (unless ``allow_poor_fit``) a best
    fit off by more than a quarter of the peak force are ``ValueError``
    (:func:`~capsule_env.identification.plausibility.check_fit_quality`).
    """
    loops = check_loops(loops)
    if max(lp.peak_force_n for lp in loops) == 0.0:
        raise ValueError("the loops' force is zero everywhere: nothing to identify")
    name = source if source is not None else (loops[0].source or "the loops")
    check_dissipation(loops, name)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    bi_exp, trends = fit_bi_exponential(loops, d_rule=d_rule)
    timings["bi_exponential"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    bouc_wen = fit_bouc_wen(loops)
    timings["bouc_wen"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    tanh = fit_tanh(loops)
    timings["tanh"] = time.perf_counter() - t0
    i_top = max(float(lp.current_a) for lp in loops)
    models = {}
    for name, damper in zip(MODEL_NAMES, (bi_exp, bouc_wen, tanh)):
        per = _rmse_per_current(damper, loops)
        models[name] = ModelFit(name, damper, per, per[i_top])
    result = IdentificationResult(
        source=source if source is not None else loops[0].source,
        loops=tuple(loops),
        models=models,
        bi_exponential=trends,
        peak_force_n=max(lp.peak_force_n for lp in loops),
        rmse_current_a=i_top,
        force_offset_n=float(np.mean([lp.force_offset_n for lp in loops])),
        timings_s=timings,
        d_rule=d_rule,
    )
    check_fit_quality(result, name, allow_poor_fit)
    return result


def identify_reference(
    damper: DamperParams | None = None,
    currents: Iterable[float] = DEFAULT_CURRENTS_A,
    frequency_hz: float = 1.0,
    amplitude_m: float = 0.025,
    cycles: int = 3,
    samples_per_cycle: int = 1000,
    d_rule: str = "mean",
) -> IdentificationResult:
    """Identify all models from loops of a damper model (the reference damper by default).

    Loops: :func:`reference_loops` (default 1 Hz, +-25 mm, 0 to 1.5 A in 0.25 A steps). The
    reported ``rmse_n`` is at the largest current (1.5 A by default), to compare with the
    paper's 61.8 N (Bi-exponential) and 695.3 N (Bouc-Wen) on its own damper. ``d_rule``: the
    Bi-exponential ``d`` rule, ``"mean"`` (the paper's) or ``"joint"`` (:func:`fit_bi_exponential`).
    """
    loops = reference_loops(damper, currents, frequency_hz, amplitude_m, cycles, samples_per_cycle)
    return identify_loops(loops, d_rule=d_rule)


def identify_measured(
    path: str | Path, d_rule: str = "mean", allow_poor_fit: bool = False, **load_options: Any
) -> IdentificationResult:
    """Identify all models from one measured file: a Labcontrol ``.mat``, a CSV or a NumPy
    file (:func:`~capsule_env.identification.tabular.load_loops`, which takes
    ``load_options``: ``columns``, ``current_a``, ``velocity_window``, ...).

    A Labcontrol file (SI units, centred stroke, mean force removed) records no current: it is
    fitted as a single loop at ``i = 0`` (or the ``current_a`` given): the
    current-independent coefficients carry everything, the per-ampere ones are 0, and each
    Bi-exponential branch keeps its own ``d``. A CSV or NumPy file with a current column gives
    one loop per current, and the fit has current laws. ``rmse_n`` is the RMSE at the largest
    current (over the whole record for one current).

    The file's columns are checked for plausibility as they are read (errors), and the fit
    after it: :mod:`~capsule_env.identification.plausibility` warns
    (:class:`~capsule_env.identification.plausibility.PlausibilityWarning`) about a fit too
    good for a measurement and about a kept force offset that the Bouc-Wen model cannot carry.
    """
    loops = load_loops(path, **load_options)
    result = identify_loops(loops, source=Path(path).name, d_rule=d_rule,
                            allow_poor_fit=allow_poor_fit)  # fmt: skip
    kept = Path(path).suffix.lower() != ".mat" and not load_options.get("remove_force_offset")
    check_fit(result, f"measured data file {str(path)!r}", force_kept=kept)
    return result


def identify_files(
    paths: Sequence[str | Path],
    d_rule: str = "mean",
    allow_poor_fit: bool = False,
    **load_options: Any,
) -> IdentificationResult:
    """Identify all models from the loops of several files at once, e.g. one file per current
    (``loop_0A.csv``, ``loop_0.5A.csv``, ...: the current laws across files). Each file is read
    by :func:`~capsule_env.identification.tabular.load_loops` with ``load_options``; the
    checks of :func:`identify_measured` apply."""
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("paths must hold at least one file")
    loops = [loop for p in paths for loop in load_loops(p, **load_options)]
    names = [p.name for p in paths]
    source = (
        ", ".join(names) if len(names) <= 3 else f"{len(names)} files ({names[0]} to {names[-1]})"
    )
    result = identify_loops(loops, source=source, d_rule=d_rule, allow_poor_fit=allow_poor_fit)
    kept = not load_options.get("remove_force_offset") and any(
        p.suffix.lower() != ".mat" for p in paths
    )
    check_fit(result, f"measured data files {source}", force_kept=kept)
    return result


# ------------------------------------------------------------------------ package defaults
def _format_5(value: float) -> str:
    """A float literal rounded to 5 significant digits, in the ``1.2345e5`` style."""
    if value == 0.0:
        return "0.0"
    s = f"{value:.5g}"
    if "e" in s:
        mant, exp = s.split("e")
        s = f"{mant}e{int(exp)}"
    elif "." not in s:
        s += ".0"
    return s


def dataclass_default_lines(damper: DamperParams) -> list[str]:
    """Dataclass field lines ``    name: float = value`` of a model's fitted parameters.

    Values are rounded to 5 significant digits; ``max_current_a`` and
    ``coil_time_constant_s`` (not identified) are left out.
    """
    return [
        f"    {f.name}: float = {_format_5(float(getattr(damper, f.name)))}"
        for f in fields(damper)
        if f.name not in ("max_current_a", "coil_time_constant_s")
    ]
