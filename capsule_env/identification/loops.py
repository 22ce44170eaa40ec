"""Force loops: the samples a damper test rig records, and the helpers every fitter uses on them.

A :class:`Loop` is one test at a constant coil current: time, stroke, stroke rate and force.
:func:`reference_loops` makes steady loops of a damper model under a sinusoidal stroke
(docs/model.md 6); :mod:`capsule_env.identification.measured` reads laboratory files into loops.
The helpers check a list of loops, group it by current, stack its samples, and build the
warm-up sequence (one period of stroke ahead of the loop) that models with internal states
are simulated over.

Units: SI throughout (m, m/s, N, A, s).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from capsule_env.common.validation import check_in_range, check_positive
from capsule_env.dampers import DamperParams, ReferenceDamper
from capsule_env.dampers.rig import simulate_damper, sinusoidal_stroke

__all__ = [
    "DEFAULT_CURRENTS_A",
    "Loop",
    "check_int",
    "check_loops",
    "group_by_current",
    "reference_loops",
    "stack_loops",
    "warm_sequence",
]

#: Constant coil currents of the identification loops (A), 0 to i_max = 1.5 A in 0.25 A steps.
DEFAULT_CURRENTS_A: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5)


@dataclass(frozen=True, eq=False)
class Loop:
    """One force loop at a constant coil current: the samples a damper test rig records.

    Attributes
    ----------
    current_a : the constant coil current (A); 0 for a measured file whose current is unknown
        (then ``current_known`` is False).
    time_s, stroke_m, stroke_rate_m_s, force_n : 1-D arrays of equal length: time (s), stroke
        ``x`` (m, centred on zero), stroke rate ``v = dx/dt`` (m/s), damper force (N, positive
        when resisting ``v > 0``).
    source : where the loop comes from (model name and stroke, or the file name).
    force_offset_n : a constant removed from the recorded force before fitting (N; measured
        files: the mean force, e.g. accumulator preload or load-cell zero), 0 for simulated loops.
    periodic : True when the samples are exactly one steady period of the response (simulated
        loops): a model is then warmed up by running the loop twice. False for a record of
        several roughly periodic cycles (measured files): the warm-up is the record's first
        period.
    current_known : False when the file stated no current (no current column, no ``current_a``
        given, none in its name) and ``current_a`` is the 0 A a fit assumes; reports and
        figures then say "current unknown".
    """

    current_a: float
    time_s: np.ndarray
    stroke_m: np.ndarray
    stroke_rate_m_s: np.ndarray
    force_n: np.ndarray
    source: str = ""
    force_offset_n: float = 0.0
    periodic: bool = True
    current_known: bool = True

    def __post_init__(self) -> None:
        check_in_range("current_a", self.current_a, 0.0, math.inf)
        arrays = {}
        for name in ("time_s", "stroke_m", "stroke_rate_m_s", "force_n"):
            a = np.ascontiguousarray(getattr(self, name), dtype=np.float64)
            if a.ndim != 1:
                raise ValueError(f"Loop.{name} must be a 1-D array, got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"Loop.{name} must be finite (got NaN or inf)")
            arrays[name] = a
            object.__setattr__(self, name, a)
        n = arrays["time_s"].size
        if n < 8:
            raise ValueError(f"a Loop needs at least 8 samples, got {n}")
        for name, a in arrays.items():
            if a.size != n:
                raise ValueError(
                    f"Loop.{name} has {a.size} samples but time_s has {n}; all four arrays "
                    "must have the same length"
                )
        if np.any(np.diff(arrays["time_s"]) <= 0.0):
            raise ValueError("Loop.time_s must be strictly increasing")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.time_s.size)

    @property
    def peak_force_n(self) -> float:
        """Largest force magnitude in the loop (N)."""
        return float(np.max(np.abs(self.force_n)))

    @property
    def upper(self) -> np.ndarray:
        """Boolean mask of the upper-branch samples (``x >= 0``, docs/model.md 1)."""
        return self.stroke_m >= 0.0


def reference_loops(
    damper: DamperParams | None = None,
    currents: Iterable[float] = DEFAULT_CURRENTS_A,
    frequency_hz: float = 1.0,
    amplitude_m: float = 0.025,
    cycles: int = 3,
    samples_per_cycle: int = 1000,
    substeps: int = 4,
) -> list[Loop]:
    """Steady force loops of a damper model under a sinusoidal stroke (docs/model.md 6).

    The stroke ``x = amplitude sin(2 pi f t)`` runs for ``cycles`` periods at each constant
    ``current`` (the model's internal states start at zero,
    :func:`capsule_env.dampers.rig.simulate_damper`); the last full period is kept, sampled at
    ``samples_per_cycle`` points over ``[0, T)`` (it starts at ``x = 0``, ``v > 0``).

    Parameters
    ----------
    damper : any forward model of :mod:`capsule_env.dampers`; the reference (Spencer) damper
        when None.
    currents : constant coil currents (A), each in ``[0, damper.max_current_a]``.
    frequency_hz, amplitude_m : stroke frequency (Hz, > 0) and amplitude (m, > 0).
    cycles : periods simulated (>= 2; the first ``cycles - 1`` let the response settle).
    samples_per_cycle : samples per period (>= 16).
    substeps : integration substeps per sample of :func:`simulate_damper` (>= 1).
    """
    damper = ReferenceDamper() if damper is None else damper
    check_positive("frequency_hz", frequency_hz)
    check_positive("amplitude_m", amplitude_m)
    cycles = check_int("cycles", cycles, 2)
    samples_per_cycle = check_int("samples_per_cycle", samples_per_cycle, 16)
    substeps = check_int("substeps", substeps, 1)
    currents = [float(i) for i in currents]
    if not currents:
        raise ValueError("currents must hold at least one current (A)")
    i_max = getattr(damper, "max_current_a", math.inf)
    for i in currents:
        check_in_range("current", i, 0.0, i_max)
    t, x, v = sinusoidal_stroke(frequency_hz, amplitude_m, cycles, samples_per_cycle)
    keep = slice((cycles - 1) * samples_per_cycle, cycles * samples_per_cycle)
    source = f"{damper.name} damper, {frequency_hz:g} Hz, +-{amplitude_m * 1e3:g} mm sine"
    loops = []
    for i in currents:
        force = simulate_damper(damper, t, x, v, i, substeps=substeps)["force_n"]
        loops.append(
            Loop(
                current_a=i,
                time_s=t[keep] - t[keep][0],
                stroke_m=x[keep],
                stroke_rate_m_s=v[keep],
                force_n=force[keep],
                source=source,
            )
        )
    return loops


# ------------------------------------------------------------------------- argument checks
def check_int(name: str, value: int, low: int) -> int:
    """Return ``value`` as int, or raise ``ValueError`` naming ``name`` unless it is a whole
    number (an int, or a float with no fraction; not a bool) and ``>= low``."""
    if isinstance(value, bool) or int(value) != value or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def check_loops(loops: Sequence[Loop]) -> list[Loop]:
    """Return ``loops`` as a list, or raise ``ValueError`` when it is empty or holds anything
    but :class:`Loop` objects (naming the index)."""
    loops = list(loops)
    if not loops:
        raise ValueError("loops must hold at least one Loop")
    for k, loop in enumerate(loops):
        if not isinstance(loop, Loop):
            raise ValueError(f"loops[{k}] must be a Loop, got {type(loop).__name__}")
    return loops


# ---------------------------------------------------------------------------- loop helpers
def group_by_current(loops: Sequence[Loop]) -> tuple[np.ndarray, list[list[Loop]]]:
    """The distinct currents in increasing order (A) and, for each, the loops at it (in input
    order)."""
    currents = sorted({float(loop.current_a) for loop in loops})
    groups = [[loop for loop in loops if float(loop.current_a) == i] for i in currents]
    return np.asarray(currents), groups


def stack_loops(loops: Sequence[Loop]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """All samples of the loops end to end: ``(x, v, F, i)``, stroke (m), stroke rate (m/s),
    force (N) and the loop's current at each sample (A)."""
    x = np.concatenate([lp.stroke_m for lp in loops])
    v = np.concatenate([lp.stroke_rate_m_s for lp in loops])
    f = np.concatenate([lp.force_n for lp in loops])
    i = np.concatenate([np.full(lp.n_samples, lp.current_a) for lp in loops])
    return x, v, f, i


def _period_samples(loop: Loop) -> int:
    """Samples in one period of the stroke (the whole loop when it is one steady period)."""
    n = loop.n_samples
    if loop.periodic:
        return n
    x = loop.stroke_m - loop.stroke_m.mean()
    spectrum = np.abs(np.fft.rfft(x))
    spectrum[0] = 0.0
    k = int(np.argmax(spectrum))
    return int(min(n, max(8, round(n / max(k, 1)))))


def warm_sequence(loop: Loop) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(t, x, v, n_warm)``: one period of warm-up followed by the loop itself.

    The warm-up is the loop's first period of stroke (the whole loop when it is periodic, the
    dominant period of the stroke's spectrum otherwise), so a model started from zero state
    is in its steady response over the last ``loop.n_samples`` samples.
    """
    n_warm = _period_samples(loop)
    t = loop.time_s
    # Time runs on continuously: the loop starts one sample interval after the warm-up ends.
    shift = t[n_warm - 1] - t[0] + (t[1] - t[0])
    t2 = np.concatenate([t[:n_warm], t + shift])
    x2 = np.concatenate([loop.stroke_m[:n_warm], loop.stroke_m])
    v2 = np.concatenate([loop.stroke_rate_m_s[:n_warm], loop.stroke_rate_m_s])
    return t2, x2, v2, n_warm
