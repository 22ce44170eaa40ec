"""Measured force loops: reading laboratory damper test files as :class:`Loop` objects.

The format here is the Labcontrol MR-damper test file (MATLAB v5 ``.mat``: ``x_F`` =
displacement mm, velocity mm/s, force N; time ``Tout`` or sample period ``Ts``), read by
:func:`load_measured_loop`; :func:`measured_files` lists a folder of measured files.

The reader has two steps: a format-specific one that gets the time (s) and the three ``x_F``
columns out of the file (:func:`_read_mat`), and :func:`_loop_from_samples`, which checks the
samples (finite, plausible magnitudes, no constant column, increasing time) and converts them
to a centred SI :class:`Loop`. :func:`scale_loop` maps a loop onto another damper's scale
(stroke, time and force scaled, a current attached). CSV and NumPy files, whose columns have names, units and
perhaps no velocity, are read by :mod:`capsule_env.identification.tabular`, with the same
limits (:data:`MAX_MEASURED_MAGNITUDE`) and errors that name the file and the column.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import io as sio

from capsule_env.common.validation import check_in_range
from capsule_env.identification.loops import Loop

__all__ = ["MAX_MEASURED_MAGNITUDE", "load_measured_loop", "measured_files", "scale_loop"]

#: Largest sample magnitude accepted in a measured file (mm, mm/s or N): far beyond any damper
#: test, and small enough that the fits' sums of squares cannot overflow.
MAX_MEASURED_MAGNITUDE = 1e9
_X_F_COLUMNS = ("displacement (mm)", "velocity (mm/s)", "force (N)")


def _natural_key(path: Path) -> list[Any]:
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", path.name)]


def measured_files(folder: str | Path, suffixes: Sequence[str] = (".mat",)) -> list[Path]:
    """The files of a folder of measured loops with one of ``suffixes`` (default: ``.mat``;
    any case), sorted by name (numbers numerically).

    Raises ``ValueError`` when the folder does not exist or holds no such file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"measured-data folder {str(folder)!r} does not exist or is not a folder")
    wanted = {s.lower() for s in suffixes}
    files = sorted((p for p in folder.iterdir() if p.suffix.lower() in wanted and p.is_file()),
                   key=_natural_key)  # fmt: skip
    if not files:
        raise ValueError(
            f"measured-data folder {str(folder)!r} holds no {', '.join(suffixes)} files"
        )
    return files


def load_measured_loop(path: str | Path, current_a: float | None = None) -> Loop:
    """Read one Labcontrol MR-damper test file (MATLAB v5 ``.mat``) as a :class:`Loop`.

    The file holds ``x_F`` (n, 3): displacement (mm), velocity (mm/s) and force (N), and the
    time ``Tout`` (n, 1) in s (or the sample period ``Ts``). The loop is returned in SI units
    with the displacement centred (its mean removed: the rig records e.g. 0 to 25 mm) and the
    mean force removed (a static preload or load-cell zero), which is kept in
    :attr:`Loop.force_offset_n`. ``current_a`` is the constant current to attach: the files do
    not record their coil voltage, so the default (None) attaches 0 A with
    ``Loop.current_known`` False, and a fit carries everything in its current-independent
    coefficients. ``periodic`` is False (a record of several cycles).

    Raises ``ValueError`` naming the path and the problem for a missing, unreadable or
    malformed file: no ``x_F`` of shape (n, 3), complex or non-numeric values, an empty or
    non-positive ``Ts``, NaN/inf samples or magnitudes beyond
    :data:`MAX_MEASURED_MAGNITUDE`, a constant column, a time that does not increase.
    """
    path = Path(path)
    name = f"measured data file {str(path)!r}"
    time, x_f = _read_mat(path, name)
    return _loop_from_samples(time, x_f, name, path.name, current_a)


def _read_mat(path: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """``(time, x_F)`` of a Labcontrol ``.mat`` file: time (s, n samples) and ``x_F`` (n, 3),
    in the file's units; ``ValueError`` naming the file (``name``) when the file is missing,
    unreadable, or lacks the variables or their shapes."""
    if not path.is_file():
        raise ValueError(f"{name} does not exist")
    try:
        data = sio.loadmat(str(path))
    except Exception as exc:  # scipy raises several types for a bad file
        raise ValueError(f"cannot read {name} as a MATLAB .mat file: {exc}") from exc
    if "x_F" not in data:
        raise ValueError(
            f"{name} has no variable 'x_F' (n x 3: displacement mm, velocity mm/s, force N)"
        )
    x_f = _real_array(data, "x_F", name)
    if x_f.ndim != 2 or x_f.shape[1] != 3 or x_f.shape[0] < 16:
        raise ValueError(f"{name}: 'x_F' must have shape (n, 3) with n >= 16, got {x_f.shape}")
    n = x_f.shape[0]
    time = None
    if "Tout" in data:
        time = _real_array(data, "Tout", name).ravel()
        if time.size != n:
            time = None
    if time is None:
        if "Ts" not in data:
            raise ValueError(
                f"{name} has neither a time vector 'Tout' of {n} samples nor a sample period 'Ts'"
            )
        ts_values = _real_array(data, "Ts", name)
        if ts_values.size != 1:
            raise ValueError(
                f"{name}: the sample period 'Ts' must be one number, got an array of shape "
                f"{ts_values.shape}"
            )
        ts = float(ts_values.ravel()[0])
        if not ts > 0.0:
            raise ValueError(f"{name}: sample period Ts must be > 0, got {ts!r}")
        time = np.arange(n) * ts
    return time, x_f


def _real_array(data: dict[str, Any], key: str, name: str) -> np.ndarray:
    """``data[key]`` as a float64 array; ``ValueError`` naming the file when it is complex or
    not numeric."""
    value = data[key]
    if np.iscomplexobj(value):
        raise ValueError(f"{name}: {key!r} holds complex values; the measurements must be real")
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: {key!r} is not numeric") from None


def _loop_from_samples(
    time: np.ndarray, x_f: np.ndarray, name: str, source: str, current_a: float | None
) -> Loop:
    """Check a measured record and return it as a centred SI :class:`Loop` (any file format).

    ``time`` (s, n samples) and ``x_f`` (n, 3: displacement mm, velocity mm/s, force N) as the
    reader found them; ``name`` describes the file in error messages, ``source`` becomes
    :attr:`Loop.source`; ``current_a`` None: 0 A, unknown. Raises ``ValueError`` for NaN/inf
    samples, magnitudes beyond :data:`MAX_MEASURED_MAGNITUDE`, a constant column or a time that
    does not increase.
    """
    if not (np.all(np.isfinite(x_f)) and np.all(np.isfinite(time))):
        raise ValueError(f"{name} holds NaN or infinite samples")
    for k, column in enumerate(_X_F_COLUMNS):
        peak = float(np.max(np.abs(x_f[:, k])))
        if peak > MAX_MEASURED_MAGNITUDE:
            raise ValueError(
                f"{name}: the {column} column of 'x_F' reaches {peak:.3g}, beyond "
                f"{MAX_MEASURED_MAGNITUDE:.0e}: not a damper test's values (and they overflow "
                "in the fits)"
            )
        if np.ptp(x_f[:, k]) == 0.0:
            raise ValueError(
                f"{name}: the {column} column of 'x_F' is constant ({x_f[0, k]:g}): nothing to fit"
            )
    if np.any(np.diff(time) <= 0.0):
        raise ValueError(f"{name}: time 'Tout' is not increasing")
    disp_m = x_f[:, 0] * 1e-3
    force = x_f[:, 2]
    offset = float(np.mean(force))
    return Loop(
        current_a=0.0 if current_a is None else check_in_range("current_a", current_a, 0, math.inf),
        time_s=time - time[0],
        stroke_m=disp_m - np.mean(disp_m),
        stroke_rate_m_s=x_f[:, 1] * 1e-3,
        force_n=force - offset,
        source=source,
        force_offset_n=offset,
        periodic=False,
        current_known=current_a is not None,
    )


def scale_loop(
    loop: Loop, stroke_scale: float, time_scale: float, force_scale: float, current_a: float
) -> Loop:
    """``loop`` mapped onto another damper's scale, kinematics kept consistent: stroke times
    ``stroke_scale``, time times ``time_scale`` (so frequency divided by it), stroke rate times
    ``stroke_scale / time_scale``, force (and its removed offset) times ``force_scale``; the
    current ``current_a`` (A) is attached as known. Each scale must be in (0, 1e6]
    (``ValueError`` naming it)."""
    for name, value in (("stroke_scale", stroke_scale), ("time_scale", time_scale),
                        ("force_scale", force_scale)):  # fmt: skip
        check_in_range(name, value, 0.0, 1e6)
        if value == 0.0:
            raise ValueError(f"{name} must be in (0, 1e6], got 0")
    return Loop(
        current_a=check_in_range("current_a", current_a, 0.0, math.inf),
        time_s=loop.time_s * time_scale,
        stroke_m=loop.stroke_m * stroke_scale,
        stroke_rate_m_s=loop.stroke_rate_m_s * (stroke_scale / time_scale),
        force_n=loop.force_n * force_scale,
        source=f"{loop.source} (scaled)",
        force_offset_n=loop.force_offset_n * force_scale,
        periodic=loop.periodic,
        current_known=True,
    )
