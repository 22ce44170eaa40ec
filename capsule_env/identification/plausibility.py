"""Plausibility checks of measured damper tests: refuse nonsense, warn about the doubtful.

A CSV or NumPy file whose columns parse may still hold the wrong quantity or the wrong unit:
a displacement in mm under a plain ``displacement`` header (read as metres), a current in mA
read as A, two columns swapped. Every fitter then returns numbers, none of them right (b0 of
about 6 instead of 6000 N s/m, "RMSE 0.0 N"). The checks here compare each column with what a
damper test can hold; each threshold is far outside any real test and within the factor of
1000 a wrong unit makes, so a unit error crosses it and a real test does not. Errors raise
``ValueError``; doubtful values warn with :class:`PlausibilityWarning`. Every message is one
line naming the file and the column. docs/howto-identify.md lists the checks and thresholds.

Errors:

- the stroke (displacement column) spans more than 1 m or less than 0.2 mm peak to peak;
- the stroke's dominant frequency is below 0.01 Hz or above 200 Hz;
- a velocity column's standard deviation is below 1/3 or above 3 times that of the
  displacement's derivative;
- the force swings by less than 1 N or more than 1 MN about its mean;
- a current (a column, ``current_a`` or a file name) is above :data:`MAX_CURRENT_A` (10 A).

Errors about the physics (issue 40: a sign-flipped loop fitted a negative damping, pure noise
fitted with an RMSE of 56 % of its peak, and the env took such parameters as its plant):

- a loop whose force does not dissipate: its work per cycle below
  :data:`~capsule_env.dampers.rig.MIN_DISSIPATION_RATIO` of ``rms(F) rms(v) T`` (measured loops
  0.85-0.96, noise about 0, a sign-flipped loop -0.96);
- a fitted model whose predicted force on the loops does not dissipate;
- no model fitting within :data:`MAX_FIT_RMSE_FRACTION` of the peak force (the measured loops'
  best fits: at most 0.14), unless ``allow_poor_fit``.

Warnings: the force swings by less than 10 N; a current column peaks above 0 but below half
the current resolution (every sample rounds to 0 A); after the fit (:func:`check_fit`), the
best model's RMSE is below 0.1 % of the peak force, or, with the force kept as recorded, the
Bouc-Wen fit's mean residual exceeds half its RMSE (a preload it cannot carry).
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from capsule_env.identification.loops import Loop
    from capsule_env.identification.results import IdentificationResult

__all__ = [
    "MAX_CURRENT_A",
    "MAX_FIT_RMSE_FRACTION",
    "check_dissipation",
    "check_fit_quality",
    "PlausibilityWarning",
    "check_column",
    "check_current",
    "check_current_resolution",
    "check_fit",
    "check_run",
]

#: Largest stroke peak to peak (m): no damper test strokes a metre; 1 mm read as 1 m does.
MAX_STROKE_SPAN_M = 1.0
#: Smallest stroke peak to peak (m): twice the models' 0.1 mm branch blend, within which the
#: branch fits drop samples; 0.2 m read as mm (0.2 mm) crosses it.
MIN_STROKE_SPAN_M = 2e-4
#: Stroke frequencies a damper test runs at (Hz): time in ms read as s divides by 1000.
STROKE_FREQUENCY_RANGE_HZ = (0.01, 200.0)
#: Accepted ratio of the velocity column's spread to that of the displacement's derivative.
VELOCITY_RATIO_RANGE = (1.0 / 3.0, 3.0)
#: Force amplitude limits (N): friction alone is tens of N (1 N: kN read as N); 1 MN is beyond
#: the largest MR damper built (about 0.2 to 0.4 MN: N read as kN of a 1 kN test crosses it).
MIN_FORCE_AMPLITUDE_N = 1.0
LOW_FORCE_AMPLITUDE_N = 10.0
MAX_FORCE_AMPLITUDE_N = 1e6
#: Largest coil current (A): MR damper coils take up to about 3 A; 1500 mA read as A does not.
MAX_CURRENT_A = 10.0
#: A fit closer than this fraction of the peak force is too good for a measurement.
TOO_GOOD_FRACTION = 1e-3
#: The Bouc-Wen mean residual, as a fraction of its RMSE, above which a kept preload is blamed.
OFFSET_RESIDUAL_FRACTION = 0.5


class PlausibilityWarning(UserWarning):
    """A measured file's values are unusual for a damper test (one line: file and column)."""


def _warn(message: str) -> None:
    warnings.warn(message, PlausibilityWarning, stacklevel=3)


def check_column(name: str, quantity: str, label: str, values: np.ndarray) -> None:
    """Check one column of a file (SI values) against what a damper test holds.

    ``name`` describes the file, ``label`` is the file's column name, ``quantity`` one of
    ``displacement``, ``force``, ``current`` (others pass). Raises ``ValueError`` naming both
    for a stroke or force beyond its limits or a current above :data:`MAX_CURRENT_A`; warns
    (:class:`PlausibilityWarning`) for a small force amplitude.
    """
    where = f"{name}, column {label!r}"
    if quantity == "displacement":
        span = float(np.ptp(values))
        if span > MAX_STROKE_SPAN_M:
            raise ValueError(
                f"{where} spans {span:.4g} m peak to peak, more than any damper test's stroke "
                f"({MAX_STROKE_SPAN_M:g} m): a wrong unit (mm read as m: write displacement[mm]) "
                "or a column swapped with another?"
            )
        if span < MIN_STROKE_SPAN_M:
            raise ValueError(
                f"{where} spans {span * 1e3:.3g} mm peak to peak, below "
                f"{MIN_STROKE_SPAN_M * 1e3:g} mm (twice the models' branch blend): is it in m "
                "under an [mm] unit?"
            )
    elif quantity == "force":
        amplitude = float(np.max(np.abs(values - np.mean(values))))
        if amplitude < MIN_FORCE_AMPLITUDE_N or amplitude > MAX_FORCE_AMPLITUDE_N:
            raise ValueError(
                f"{where} swings by {amplitude:.3g} N about its mean, outside "
                f"[{MIN_FORCE_AMPLITUDE_N:g}, {MAX_FORCE_AMPLITUDE_N:g}] N for a damper test: "
                "a wrong unit (write force[kN]) or a column swapped with another?"
            )
        if amplitude < LOW_FORCE_AMPLITUDE_N:
            _warn(
                f"{where} swings by only {amplitude:.3g} N about its mean (a damper's friction "
                f"alone is tens of N): is it in kN? write force[kN]"
            )
    elif quantity == "current":
        check_current(float(np.max(values)), where)


def check_current(current_a: float, what: str) -> None:
    """``ValueError`` naming ``what`` (a column, ``--current`` or a file name) when
    ``current_a`` exceeds :data:`MAX_CURRENT_A`: a current in mA read as A."""
    if current_a > MAX_CURRENT_A:
        raise ValueError(
            f"{what}: current {current_a:g} A is above {MAX_CURRENT_A:g} A, more than an MR "
            "damper's coil takes (the package's dampers stop at 1.5 A): is it in mA? write "
            "current[mA] (or 750mA in a file name)"
        )


def check_current_resolution(name: str, label: str, values: np.ndarray, resolution: float) -> None:
    """Warn when a current column peaks above 0 but below half ``resolution``: every sample then
    rounds to 0 A (a current in A under an [mA] unit)."""
    peak = float(np.max(values))
    if 0.0 < peak < 0.5 * resolution:
        _warn(
            f"{name}, column {label!r} peaks at {peak:.3g} A, below half the current resolution "
            f"({resolution:g} A): every sample rounds to 0 A; is it in A under an [mA] unit?"
        )


def check_run(
    name: str,
    labels: dict[str, str],
    time_s: np.ndarray,
    stroke_m: np.ndarray,
    velocity_m_s: np.ndarray | None,
    where: str = "",
) -> None:
    """Check one run of samples at one current: its stroke frequency and, when the file has a
    velocity column, that column against the derivative of the displacement.

    ``labels`` maps ``time``, ``displacement`` and ``velocity`` to the file's column names;
    ``where`` locates the run in a file of several. Raises ``ValueError`` naming the file and
    the column.
    """
    from capsule_env.identification.tabular import derive_velocity, dominant_period_samples

    dt = float(np.median(np.diff(time_s)))
    frequency = 1.0 / (dominant_period_samples(stroke_m) * dt)
    low, high = STROKE_FREQUENCY_RANGE_HZ
    if not low <= frequency <= high:
        raise ValueError(
            f"{name}, column {labels['time']!r}{where}: the stroke's frequency is "
            f"{frequency:.3g} Hz, outside [{low:g}, {high:g}] Hz for a damper test: is the time "
            "in ms? write time[ms]"
        )
    if velocity_m_s is None:
        return
    try:
        derived = derive_velocity(time_s, stroke_m)
    except ValueError:  # non-uniform sampling: a plain difference is enough for a ratio
        derived = np.gradient(stroke_m, time_s)
    ratio = float(np.std(velocity_m_s) / max(np.std(derived), 1e-300))
    low, high = VELOCITY_RATIO_RANGE
    if not low <= ratio <= high:
        raise ValueError(
            f"{name}, column {labels['velocity']!r}{where} is {ratio:.3g} times the derivative "
            f"of column {labels['displacement']!r} (accepted: {low:.3g} to {high:g}): their "
            "units disagree (mm/s against m?) or a column holds another quantity"
        )


#: The largest RMSE, as a share of the peak force, of the best-fitting model: the Labcontrol
#: loops' best fits reach 0.14 of their peak, the reference damper's 0.03; pure noise 0.26 or
#: more (Gaussian; uniform noise about 0.58).
MAX_FIT_RMSE_FRACTION = 0.25


def check_dissipation(loops: Sequence[Loop], name: str) -> None:
    """``ValueError`` when a loop's force does not dissipate: no damper's force feeds energy
    into the stroke (a sign flipped when recorded) or is uncorrelated with it (noise)."""
    from capsule_env.dampers.rig import MIN_DISSIPATION_RATIO, dissipation_ratio

    for loop in loops:
        ratio = dissipation_ratio(loop.time_s, loop.force_n, loop.stroke_rate_m_s)
        if not ratio >= MIN_DISSIPATION_RATIO:
            cause = ("is the force's sign flipped?" if ratio < 0 else
                     "is the force column noise, or another quantity?")  # fmt: skip
            raise ValueError(
                f"{name}: the loop at {loop.current_a:g} A does not dissipate: its work per "
                f"cycle is {ratio:.2f} of rms(F) rms(v) T (a damper's loop: >= "
                f"{MIN_DISSIPATION_RATIO}; measured loops 0.85-0.96): {cause}"
            )


def check_fit_quality(result: IdentificationResult, name: str, allow_poor_fit: bool) -> None:
    """``ValueError`` when a fitted model's force on the loops does not dissipate, or when no
    model fits within :data:`MAX_FIT_RMSE_FRACTION` of the peak force (unless
    ``allow_poor_fit``: a research escape hatch, the figure still reported)."""
    from capsule_env.dampers.rig import MIN_DISSIPATION_RATIO, dissipation_ratio
    from capsule_env.identification.predict import predict_force

    for fit in result.models.values():
        for loop in result.loops:
            force = predict_force(fit.damper, loop)
            ratio = dissipation_ratio(loop.time_s, force, loop.stroke_rate_m_s)
            if not ratio >= MIN_DISSIPATION_RATIO:
                raise ValueError(
                    f"{name}: the fitted {fit.name} model does not dissipate on the loop at "
                    f"{loop.current_a:g} A (work per cycle {ratio:.2f} of rms(F) rms(v) T, a "
                    f"damper's >= {MIN_DISSIPATION_RATIO}): its parameters would feed energy in"
                )
    best = min(result.models.values(), key=lambda fit: fit.rmse_n)
    share = best.rmse_n / result.peak_force_n
    if share > MAX_FIT_RMSE_FRACTION and not allow_poor_fit:
        raise ValueError(
            f"{name}: no model fits: the best, {best.name}, is off by RMSE {best.rmse_n:.4g} N, "
            f"{100 * share:.0f} % of the peak force (accepted: <= "
            f"{100 * MAX_FIT_RMSE_FRACTION:.0f} %; measured loops' best fits <= 14 %); "
            "allow_poor_fit=True (--allow-poor-fit) keeps it"
        )


def check_fit(result: IdentificationResult, name: str, force_kept: bool) -> None:
    """Warn (:class:`PlausibilityWarning`) about an identification of measured loops that is
    too good to be physical, or whose Bouc-Wen fit is spoilt by a kept force offset.

    ``name`` describes the file(s); ``force_kept``: the force was read as recorded (CSV and
    NumPy files without ``remove_force_offset``).
    """
    from capsule_env.identification.predict import predict_force

    peak = result.peak_force_n
    best = min(result.models.values(), key=lambda fit: fit.rmse_n)
    if best.rmse_n < TOO_GOOD_FRACTION * peak:
        _warn(
            f"{name}: the {best.name} model fits the force column within {best.rmse_n:.3g} N, "
            f"{100 * best.rmse_n / peak:.2g} % of its peak force; measured force has noise and "
            "hysteresis no model follows so closely: is the force column a copy of another "
            "(columns swapped?), or is the file synthetic?"
        )
    if not force_kept:
        return
    damper = result.models["bouc_wen"].damper
    residual = np.concatenate([predict_force(damper, lp) - lp.force_n for lp in result.loops])
    mean_residual = float(np.mean(residual))
    rmse_n = float(np.sqrt(np.mean(residual**2)))
    if abs(mean_residual) > OFFSET_RESIDUAL_FRACTION * rmse_n:
        mean_force = float(np.mean(np.concatenate([lp.force_n for lp in result.loops])))
        _warn(
            f"{name}: the force's mean, {mean_force:.1f} N, is kept (a preload?) and the "
            "Bouc-Wen model has no constant force term to carry it: its fit is off by "
            f"{-mean_residual:.1f} N on average (RMSE {rmse_n:.1f} N); add "
            "--remove-force-offset (remove_force_offset=True) to subtract the mean"
        )
