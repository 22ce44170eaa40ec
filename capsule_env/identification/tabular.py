"""Measured force loops from CSV and NumPy files: the data users usually have.

:func:`load_loops` reads one file of a damper test as :class:`Loop` objects: CSV or other
delimited text (``.csv``, ``.tsv``, ``.txt``), NumPy ``.npy`` and ``.npz``, and the Labcontrol
``.mat`` of :mod:`capsule_env.identification.measured`. The quantities, SI by default:

========================  ========  ========================================================
column                    unit      required
========================  ========  ========================================================
``time``                  s         yes
``displacement``          m         yes (the stroke; centred per loop, its mean removed)
``velocity``              m/s       no: derived from the displacement when absent
``force``                 N         yes (kept as recorded unless ``remove_force_offset``)
``current``               A         no: else one current per file (argument or file name)
========================  ========  ========================================================

**Column names.** From the file's header (CSV: a first line that is not all numbers; ``.npz``:
the array names; ``.npy``: the field names of a structured array), or given as ``columns``
(CLI ``--columns``), the file's columns in order, which overrides any header: e.g.
``"time,displacement[mm],force,skip,current"`` (``skip`` or ``-`` ignores a column). Names are
matched without case; aliases: ``t``; ``x``, ``stroke``, ``position``; ``v``, ``stroke_rate``;
``f`` (no one-letter alias for the current: ``i`` is often a row index). Header columns with
other names are ignored. A unit follows the name in brackets or parentheses,
``displacement [mm]``, ``force (kN)``, or as a suffix,
``displacement_mm``, ``velocity_mm_s``, ``time_s``: s or ms; m or mm; m/s or mm/s; N or kN; A
or mA. Text files: lines starting with ``#`` and blank lines are skipped; the delimiter is
``,`` if the first line holds one, else ``;``, else a tab, else whitespace (decimal points
only, no decimal commas; with whitespace as delimiter, write units without a space:
``displacement[mm]``).

**Velocity when absent** (:func:`derive_velocity`): a Savitzky-Golay derivative
(``scipy.signal.savgol_filter(x, window, polyorder, deriv=1, delta=dt)``), the derivative at
each sample of a least-squares polynomial of degree ``polyorder`` (3 by default) fitted to the
``window`` samples around it (ends: fitted to the first or last window). Default window: the
odd number of samples nearest to a tenth of the stroke's dominant period (from its spectrum),
at least ``polyorder + 2``. On a sine sampled at 100 to 1000 points per period its error is
below 1e-4 of the peak velocity away from the ends and below 5e-3 within half a window of
them (``tests/test_identify_files.py``), while it averages a tenth of a period of noise (on
a 1 kHz record with noise of 1e-3 of the stroke, 1.5e-3 RMS against 0.11 for
``numpy.gradient``). It needs
uniform sampling (steps within 1 % of their median). Override with ``velocity_window`` and
``velocity_polyorder`` (CLI ``--velocity-window``, ``--velocity-polyorder``).

**Current.** A ``current`` column: the constant current of each sample's test (the set point,
or a measurement rounded to ``current_resolution_a``, 0.01 A by default); each run of
consecutive samples at one current becomes a loop (at least 16 samples; time may restart at
each run). Without a column, the whole file is one loop at ``current_a`` (CLI ``--current``),
or else at the current in the file name, a number followed by ``A`` or ``mA`` after the start,
``_``, ``-`` or a space (``loop_0.75A.csv``, ``damper-750mA.npz``), or else at 0 A (as the
Labcontrol files, which record none: the fit then carries everything in its
current-independent coefficients).

A current column's sign is checked after the rounding: a measured 0 A a few mA below zero is
0 A. Every problem raises ``ValueError`` naming the file and, where there is one, the column,
and so do the plausibility checks (:mod:`~capsule_env.identification.plausibility`: stroke,
stroke frequency, velocity against the displacement's derivative, force amplitude, current),
which also warn about doubtful values.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from capsule_env.common.validation import check_in_range, check_positive
from capsule_env.identification.loops import Loop
from capsule_env.identification.measured import MAX_MEASURED_MAGNITUDE, load_measured_loop
from capsule_env.identification.plausibility import (
    check_column,
    check_current,
    check_current_resolution,
    check_run,
)

__all__ = [
    "QUANTITIES",
    "SUPPORTED_SUFFIXES",
    "current_from_file_name",
    "default_velocity_window",
    "derive_velocity",
    "dominant_period_samples",
    "load_loops",
    "parse_columns",
]

#: The quantities a file may hold, with their SI units.
QUANTITIES: dict[str, str] = {
    "time": "s",
    "displacement": "m",
    "velocity": "m/s",
    "force": "N",
    "current": "A",
}
_REQUIRED = ("time", "displacement", "force")
#: File name endings :func:`load_loops` reads.
SUPPORTED_SUFFIXES: tuple[str, ...] = (".mat", ".csv", ".tsv", ".txt", ".npy", ".npz")
_TEXT_SUFFIXES = (".csv", ".tsv", ".txt")
_UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3},
    "displacement": {"m": 1.0, "mm": 1e-3},
    "velocity": {"m/s": 1.0, "mm/s": 1e-3},
    "force": {"n": 1.0, "kn": 1e3},
    "current": {"a": 1.0, "ma": 1e-3},
}
_ALIASES: dict[str, tuple[str, ...]] = {
    "time": ("time", "t"),
    "displacement": ("displacement", "x", "stroke", "position"),
    "velocity": ("velocity", "v", "stroke_rate"),
    "force": ("force", "f"),
    "current": ("current",),
}
_SKIP = ("skip", "-", "")
_MIN_SAMPLES = 16
_NAME = re.compile(r"\s*([^\[\(]*?)\s*(?:[\[\(]\s*([^\]\)]*?)\s*[\]\)])?\s*")
_CURRENT_IN_NAME = re.compile(r"(?:^|[_\-\s])(\d+(?:\.\d+)?)\s*(mA|A)(?![A-Za-z])")


# ------------------------------------------------------------------------------ names
def _parse_name(raw: str) -> tuple[str, float] | None:
    """``(quantity, factor to SI)`` of a column name, or None when it names no quantity; a
    known name with an unknown unit raises ``ValueError`` (the caller adds the file)."""
    m = _NAME.fullmatch(raw)
    if m is None:
        return None
    name, unit = m.group(1).lower().replace(" ", "_"), m.group(2)
    for quantity, aliases in _ALIASES.items():
        units = _UNITS[quantity]
        if name in aliases:
            if unit is None:
                return quantity, 1.0
            factor = units.get(unit.lower().replace(" ", ""))
            if factor is None:
                raise ValueError(
                    f"column {raw!r}: unknown unit {unit!r} for {quantity}; accepted: "
                    f"{', '.join(_unit_names(quantity))}"
                )
            return quantity, factor
        if unit is None:  # a suffix unit: displacement_mm, velocity_m_s, time_s
            for alias in aliases:
                for u, factor in units.items():
                    if name == f"{alias}_{u.replace('/', '_')}":
                        return quantity, factor
    return None


def _unit_names(quantity: str) -> list[str]:
    return {"force": ["N", "kN"], "current": ["A", "mA"]}.get(quantity, list(_UNITS[quantity]))


def parse_columns(spec: str | Sequence[str]) -> list[str]:
    """The names of a ``columns`` specification (a comma-separated string or a list), checked:
    each a quantity (with an optional unit) or ``skip``/``-``; raises ``ValueError`` naming
    ``columns`` and the accepted names otherwise."""
    names = [s.strip() for s in spec.split(",")] if isinstance(spec, str) else list(spec)
    accepted = (
        f"accepted: {', '.join(QUANTITIES)} (or an alias), each with an optional unit, e.g. "
        "displacement[mm], or skip"
    )
    if not names or all(n.lower() in _SKIP for n in names):
        raise ValueError(f"columns must name the file's columns in order; {accepted}")
    for n in names:
        if n.lower() in _SKIP:
            continue
        try:
            parsed = _parse_name(n)
        except ValueError as exc:
            raise ValueError(f"columns: {exc}") from None
        if parsed is None:
            raise ValueError(f"columns: unknown column name {n!r}; {accepted}")
    return names


# ------------------------------------------------------------------------------ readers
def _read_text(path: Path, name: str) -> tuple[list[str] | None, list[np.ndarray]]:
    """Header (or None) and columns of a delimited text file."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"{name} is not a text file (not UTF-8)") from None
    lines = [(k + 1, ln) for k, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]  # fmt: skip
    if not lines:
        raise ValueError(f"{name} holds no data lines")
    first = lines[0][1]
    delim = next((d for d in (",", ";", "\t") if d in first), None)

    def split(line: str) -> list[str]:
        return [s.strip().strip('"') for s in (line.split(delim) if delim else line.split())]

    header = split(first)
    if all(_is_number(s) for s in header):
        header = None
    else:
        lines = lines[1:]
    width = len(header) if header is not None else len(split(first))
    rows = []
    for lineno, line in lines:
        fields = split(line)
        if len(fields) != width:
            raise ValueError(f"{name}, line {lineno}: {len(fields)} fields, expected {width}")
        rows.append(fields)
    if not rows:
        raise ValueError(f"{name} has a header but no data lines")
    columns = []
    for j in range(width):
        label = header[j] if header is not None else f"column {j + 1}"
        values = np.empty(len(rows))
        for k, row in enumerate(rows):
            try:
                values[k] = float(row[j])
            except ValueError:
                what = "is empty" if not row[j] else f"holds {row[j]!r}, not a number"
                raise ValueError(f"{name}, line {lines[k][0]}, column {label!r} {what}") from None
        columns.append(values)
    return header, columns


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _read_numpy(path: Path, name: str) -> tuple[list[str] | None, list[np.ndarray]]:
    """Names (or None) and columns of a ``.npy`` or ``.npz`` file."""
    try:
        loaded = np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for a bad file
        raise ValueError(f"cannot read {name} as a NumPy file: {exc}") from None
    if isinstance(loaded, np.ndarray):
        arrays = {None: loaded}
    else:
        with loaded:
            arrays = {key: loaded[key] for key in loaded.files}
    if not arrays:
        raise ValueError(f"{name} holds no arrays")
    if len(arrays) == 1:
        (key, a), = arrays.items()  # fmt: skip
        where = f"array {key!r}" if key else "the array"
        if a.dtype.names:  # a structured array: its fields are the columns
            return list(a.dtype.names), [_numeric(a[f], name, f) for f in a.dtype.names]
        if a.ndim == 2:
            return None, [_numeric(a[:, j], name, f"column {j + 1}") for j in range(a.shape[1])]
        if key is None:
            raise ValueError(
                f"{name}: {where} has shape {a.shape}; expected (n, k): one column per quantity"
            )
    shapes = {k: a.shape for k, a in arrays.items()}
    if any(a.ndim != 1 for a in arrays.values()):
        raise ValueError(
            f"{name} holds arrays of shapes {shapes}: expected 1-D arrays named after the "
            "columns (time, displacement, ...) or one 2-D array (n, k)"
        )
    return list(arrays), [_numeric(a, name, str(k)) for k, a in arrays.items()]


def _numeric(a: np.ndarray, name: str, label: str) -> np.ndarray:
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name}, column {label!r}: dtype {a.dtype} is not real numbers")
    return np.asarray(a, dtype=np.float64)


# ------------------------------------------------------------------------------ velocity
def dominant_period_samples(displacement: np.ndarray) -> float:
    """The stroke's dominant period in samples: the peak of the spectrum of the Hann-windowed,
    mean-free record, zero-padded to four times its length and refined by a parabola through
    the log magnitudes around the peak (good to about 1 % from two cycles on)."""
    x = np.asarray(displacement, dtype=np.float64)
    n = x.size
    n_fft = 4 * n
    spectrum = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), n_fft))
    spectrum[0] = 0.0
    k = int(np.argmax(spectrum))
    if k == 0:  # a constant record: no period
        return float(n)
    shift = 0.0
    if 0 < k < spectrum.size - 1 and np.all(spectrum[k - 1 : k + 2] > 0.0):
        a, b, c = np.log(spectrum[k - 1 : k + 2])
        if a - 2.0 * b + c < 0.0:
            shift = 0.5 * (a - c) / (a - 2.0 * b + c)
    return float(n_fft / (k + shift))


def default_velocity_window(displacement: np.ndarray, polyorder: int = 3) -> int:
    """The default Savitzky-Golay window (samples): the odd number nearest to a tenth of the
    stroke's dominant period (:func:`dominant_period_samples`), at least ``polyorder + 2``
    (rounded up to odd) and at most the record's length."""
    x = np.asarray(displacement, dtype=np.float64)
    window = 2 * int(math.floor(dominant_period_samples(x) / 20.0)) + 1
    low = polyorder + 2 if polyorder % 2 else polyorder + 1
    high = x.size if x.size % 2 else x.size - 1
    return min(max(window, low), high)


def derive_velocity(
    time_s: np.ndarray,
    displacement_m: np.ndarray,
    window: int | None = None,
    polyorder: int = 3,
) -> np.ndarray:
    """Stroke rate (m/s) of a uniformly sampled displacement (m): a Savitzky-Golay derivative,
    ``scipy.signal.savgol_filter(x, window, polyorder, deriv=1, delta=dt)`` (module docstring).

    ``window``: odd number of samples > ``polyorder``, at most the record's length; None for
    :func:`default_velocity_window`. ``polyorder``: 1 to 9. ``ValueError`` naming the
    parameter when one is out of range or when the time steps differ by more than 1 % of
    their median (the filter assumes uniform sampling)."""
    t = np.asarray(time_s, dtype=np.float64)
    x = np.asarray(displacement_m, dtype=np.float64)
    n = x.size
    if isinstance(polyorder, bool) or int(polyorder) != polyorder or not 1 <= polyorder <= 9:
        raise ValueError(f"velocity_polyorder must be an integer in [1, 9], got {polyorder!r}")
    polyorder = int(polyorder)
    if t.shape != x.shape or t.ndim != 1:
        raise ValueError("time_s and displacement_m must be 1-D arrays of the same length")
    if window is None:
        window = default_velocity_window(x, polyorder)
    if isinstance(window, bool) or int(window) != window or window % 2 == 0 or window <= polyorder:
        raise ValueError(
            f"velocity_window must be an odd integer > velocity_polyorder ({polyorder}), "
            f"got {window!r}"
        )
    window = int(window)
    if window > n:
        raise ValueError(f"velocity_window must be at most the record's {n} samples, got {window}")
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not dt > 0.0 or np.max(np.abs(steps - dt)) > 0.01 * dt:
        raise ValueError(
            f"the time steps range from {steps.min():.6g} to {steps.max():.6g} s: deriving the "
            "velocity needs uniform sampling (steps within 1 % of their median)"
        )
    return savgol_filter(x, window, polyorder, deriv=1, delta=dt)


# ------------------------------------------------------------------------------ loops
def current_from_file_name(path: str | Path) -> float | None:
    """The current (A) a file name states (``loop_0.75A.csv``: 0.75, ``run-750mA.npz``: 0.75),
    or None; ``ValueError`` when the name states more than one."""
    stem = Path(path).stem
    found = _CURRENT_IN_NAME.findall(stem)
    if len(found) > 1:
        raise ValueError(
            f"file name {Path(path).name!r} states {len(found)} currents "
            f"({', '.join(v + u for v, u in found)}); give the current with --current"
        )
    if not found:
        return None
    value, unit = found[0]
    return float(value) * (1e-3 if unit == "mA" else 1.0)


def load_loops(
    path: str | Path,
    *,
    columns: str | Sequence[str] | None = None,
    current_a: float | None = None,
    current_resolution_a: float = 0.01,
    velocity_window: int | None = None,
    velocity_polyorder: int = 3,
    remove_force_offset: bool = False,
) -> list[Loop]:
    """Read one damper test file as :class:`Loop` objects (one per current; module docstring).

    Parameters
    ----------
    path : a ``.csv``/``.tsv``/``.txt``, ``.npy``, ``.npz`` or Labcontrol ``.mat`` file.
    columns : the file's columns in order (overrides a header; not for ``.mat``).
    current_a : the file's one current (A, >= 0) when it has no current column; None: the
        current in the file name, or 0.
    current_resolution_a : a current column is rounded to this (A, > 0) before it is split
        into runs at constant current.
    velocity_window, velocity_polyorder : the Savitzky-Golay derivative of a file without
        velocity (:func:`derive_velocity`; None: the default window).
    remove_force_offset : subtract the file's mean force (kept in ``Loop.force_offset_n``);
        ``.mat`` files always do. By default the force is kept as recorded: the Bi-exponential
        and tanh models' constant terms carry a preload, the Bouc-Wen model only within
        ``k0 x0`` (``identify_measured`` warns when it cannot).

    Loops come in file order; ``Loop.periodic`` is False (a record of whole or partial cycles).
    """
    path = Path(path)
    name = f"measured data file {str(path)!r}"
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise ValueError(f"{name}: unknown file type; accepted: {', '.join(SUPPORTED_SUFFIXES)}")
    if not path.is_file():
        raise ValueError(f"{name} does not exist")
    if current_a is not None:
        current_a = check_in_range("current_a", current_a, 0.0, math.inf)
    check_positive("current_resolution_a", current_resolution_a)
    try:
        named_current = current_from_file_name(path)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None
    if suffix == ".mat":
        if columns is not None:
            raise ValueError(f"{name}: columns applies to CSV and NumPy files, not to .mat")
        return [load_measured_loop(path, _file_current(current_a, named_current, name))]
    if suffix in _TEXT_SUFFIXES:
        header, data = _read_text(path, name)
    else:
        header, data = _read_numpy(path, name)
    if columns is not None:
        names = parse_columns(columns)
        if len(names) != len(data):
            raise ValueError(
                f"{name}: columns names {len(names)} columns, the file has {len(data)}"
            )
    elif header is None:
        raise ValueError(
            f"{name} has no column names: give them with --columns (columns=...), e.g. "
            "time,displacement,force"
        )
    else:
        names = header
    found = _map_columns(names, data, name)
    return _loops(found, path, name, current_a, named_current, current_resolution_a,
                  velocity_window, velocity_polyorder, remove_force_offset)  # fmt: skip


def _file_current(current_a: float | None, named: float | None, name: str) -> float | None:
    """The one current of a file without a current column (``current_a``, else the one in its
    name, else None), checked (:func:`~capsule_env.identification.plausibility.check_current`)."""
    if current_a is not None:
        check_current(current_a, f"{name}: current_a (--current)")
        return current_a
    if named is not None:
        check_current(named, f"{name}: the current in its file name")
    return named


def _map_columns(
    names: Sequence[str], data: Sequence[np.ndarray], name: str
) -> dict[str, tuple[str, np.ndarray]]:
    """``{quantity: (the file's column name, values in SI)}``, checked."""
    found: dict[str, tuple[str, np.ndarray]] = {}
    for label, values in zip(names, data, strict=True):
        if str(label).lower() in _SKIP:
            continue
        try:
            parsed = _parse_name(str(label))
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None
        if parsed is None:
            continue  # a column of something else (temperature, ...)
        quantity, factor = parsed
        if quantity in found:
            raise ValueError(
                f"{name}: columns {found[quantity][0]!r} and {label!r} are both {quantity}"
            )
        found[quantity] = (str(label), values * factor)
    for quantity in _REQUIRED:
        if quantity not in found:
            raise ValueError(
                f"{name} has no {quantity!r} column (columns: {', '.join(map(str, names))}); "
                "name the columns in a header or with --columns"
            )
    n = found["time"][1].size
    if n < _MIN_SAMPLES:
        raise ValueError(f"{name} has {n} samples; a loop needs at least {_MIN_SAMPLES}")
    for quantity, (label, values) in found.items():
        _check_values(name, quantity, label, values)
    return found


def _check_values(name: str, quantity: str, label: str, values: np.ndarray) -> None:
    """One mapped column's values: finite, of a damper test's magnitude, not constant where
    the fit needs them to vary, and plausible (:func:`check_column`)."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ValueError(
            f"{name}, column {label!r}: NaN or infinite value at sample {int(bad[0]) + 1}"
        )
    peak = float(np.max(np.abs(values)))
    if peak > MAX_MEASURED_MAGNITUDE:
        raise ValueError(
            f"{name}, column {label!r} reaches {peak:.3g} {QUANTITIES[quantity]}, beyond "
            f"{MAX_MEASURED_MAGNITUDE:.0e}: not a damper test's values (check the unit)"
        )
    if quantity in ("displacement", "force") and np.ptp(values) == 0.0:
        raise ValueError(f"{name}, column {label!r} is constant: nothing to fit")
    check_column(name, quantity, label, values)


def _runs(
    current: np.ndarray, resolution: float, name: str, label: str
) -> list[tuple[int, int, float]]:
    """``(start, stop, current)`` of each run of consecutive samples at one rounded current;
    ``ValueError`` naming the file and column when a rounded current is below 0 A (the sign is
    checked after the rounding: a measured 0 A may be a few mA below zero)."""
    steps = np.round(current / resolution) + 0.0  # + 0.0: no -0.0
    negative = np.flatnonzero(steps < 0.0)
    if negative.size:
        k = int(negative[0])
        raise ValueError(
            f"{name}, column {label!r}: current {current[k]:.4g} A at sample {k + 1} is below "
            f"0 A after rounding to the current resolution ({resolution:g} A); currents must be "
            ">= 0 A"
        )
    edges = np.flatnonzero(np.diff(steps)) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [current.size]])
    return [(int(a), int(b), float(steps[a] * resolution)) for a, b in zip(starts, stops)]


def _run_velocity(
    found: dict[str, tuple[str, np.ndarray]],
    start: int,
    stop: int,
    time_s: np.ndarray,
    stroke_m: np.ndarray,
    filter_args: tuple[int | None, int],
    name: str,
    where: str,
) -> np.ndarray:
    """The stroke rate of the run ``start:stop`` (m/s): the velocity column, else derived
    (:func:`derive_velocity` with ``filter_args`` = window, polyorder); the run checked first
    (:func:`~capsule_env.identification.plausibility.check_run`)."""
    labels = {q: found[q][0] for q in ("time", "displacement", "velocity") if q in found}
    given = found["velocity"][1][start:stop] if "velocity" in found else None
    check_run(name, labels, time_s, stroke_m, given, where)
    if given is not None:
        return given
    try:
        return derive_velocity(time_s, stroke_m, *filter_args)
    except ValueError as exc:
        raise ValueError(f"{name}, column {labels['time']!r}{where}: {exc}") from None


def _loops(
    found: dict[str, tuple[str, np.ndarray]],
    path: Path,
    name: str,
    current_a: float | None,
    named_current: float | None,
    resolution: float,
    window: int | None,
    polyorder: int,
    remove_force_offset: bool,
) -> list[Loop]:
    time_label, time = found["time"]
    disp = found["displacement"][1]
    force = found["force"][1]
    offset = float(np.mean(force)) if remove_force_offset else 0.0
    if "current" in found:
        if current_a is not None:
            raise ValueError(
                f"{name} has a current column ({found['current'][0]!r}): do not also give "
                "its current (--current)"
            )
        label = found["current"][0]
        check_current_resolution(name, label, found["current"][1], resolution)
        runs = _runs(found["current"][1], resolution, name, label)
    else:
        file_current = _file_current(current_a, named_current, name)
        runs = [(0, time.size, float(file_current or 0.0))]
    known = "current" in found or current_a is not None or named_current is not None
    loops = []
    for start, stop, current in runs:
        where = "" if len(runs) == 1 else f" (samples {start + 1} to {stop}, {current:g} A)"
        if stop - start < _MIN_SAMPLES:
            raise ValueError(
                f"{name}, column {found['current'][0]!r}: a run of {stop - start} samples at "
                f"{current:g} A{where}; each current needs at least {_MIN_SAMPLES} samples "
                f"(round a measured current with --current-resolution, now {resolution:g} A)"
            )
        t = time[start:stop]
        back = np.flatnonzero(np.diff(t) <= 0.0)
        if back.size:
            raise ValueError(
                f"{name}, column {time_label!r}: time does not increase at sample "
                f"{start + int(back[0]) + 2}{where}"
            )
        x = disp[start:stop]
        v = _run_velocity(found, start, stop, t, x, (window, polyorder), name, where)
        source = path.name if len(runs) == 1 else f"{path.name} @ {current:g} A"
        loops.append(
            Loop(
                current_a=current,
                time_s=t - t[0],
                stroke_m=x - np.mean(x),
                stroke_rate_m_s=v,
                force_n=force[start:stop] - offset,
                source=source,
                force_offset_n=offset,
                periodic=False,
                current_known=known,
            )  # fmt: skip
        )
    return loops
