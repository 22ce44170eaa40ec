"""Identification of MR-damper forward models from force loops (MODEL.md section 6).

The paper built its damper models from measured force loops: a sinusoidal stroke at a set of
constant coil currents, the force recorded against displacement and velocity. This module does
the same for three forward models of :mod:`capsule_env.dampers`, from loops of the reference
damper (the "hardware" in simulation, MODEL.md 4.1) or from measured laboratory files:

- **Bi-exponential** (MODEL.md 4.4, paper eq. 4): split each loop by the sign of the stroke
  (upper branch ``x >= 0``, lower ``x < 0``); per current and branch fit ``a, b, c, d`` of
  ``F = a S_d(v) + b v + c`` with ``S_d(v) = sign(v) (1 - exp(-d |v|))``; set ``d`` per branch to
  the mean over currents; refit ``a, b, c`` at that ``d``; fit each as a line in current. This
  is the paper's Table 2 (:attr:`BiExponentialTrends.table`) and its Figures 5 and 6. An
  alternative rule (``d_rule="joint"``) fits ``d`` and the linear laws to all currents at once.
- **Bouc-Wen** (MODEL.md 4.2, n = 2): least squares of the simulated response over all loops at
  once. The model has a scale degeneracy (``z -> s z``, ``A -> s A``, ``gamma, beta -> /s``,
  ``alpha -> /s`` leave the force unchanged), removed by fixing ``A = 1``: ``z`` is then in
  metres and saturates at the yield displacement ``z_y = 1/sqrt(gamma + beta)``.
- **tanh** (MODEL.md 4.3, paper eq. 3): ``F = c v + k x + alpha tanh(beta v + delta sign(x)) + f0``
  with ``c, k, alpha, f0`` linear in current and ``beta, delta`` constant.

All three fits use *variable projection*: each model is linear in most of its coefficients once
a few shape parameters are fixed (``d``; ``beta, delta``; ``z_y`` and the loop-shape ratio
``(beta - gamma)/(beta + gamma)``), so an outer search over the shape parameters (grid for a good
start, then a bounded scalar search or :func:`scipy.optimize.least_squares`) wraps an inner
linear least-squares solve. The result is the joint least-squares optimum of all coefficients
(within the stated bounds), found in a fraction of a second and far less prone to local minima
than a search over all coefficients at once.

The Bouc-Wen response is simulated with the exact closed-form ``n = 2`` hysteresis update
(:func:`capsule_env.hysteresis.hysteresis_update`) on the loop's stroke samples, linear between
samples (exact for a piecewise-monotone stroke, no ODE solver), from ``z = 0`` over one
preceding period of the stroke, so that the fitted part is the steady response.

Units: SI throughout (m, m/s, N, A, s). Pure functions and frozen dataclasses; no Gym import.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit
from scipy import io as sio
from scipy import linalg, optimize

from capsule_env._validation import check_in_range, check_positive
from capsule_env.dampers import (
    BOUC_WEN,
    REFERENCE,
    BiExponentialDamper,
    BoucWenDamper,
    DamperParams,
    ReferenceDamper,
    TanhDamper,
    branch_weights,
    damper_force,
)
from capsule_env.dynamics import simulate_damper, sinusoidal_stroke
from capsule_env.hysteresis import hysteresis_update

__all__ = [
    "DEFAULT_CURRENTS_A",
    "D_RULES",
    "MODEL_NAMES",
    "PAPER_RMSE_N",
    "BiExponentialTrends",
    "IdentificationResult",
    "Loop",
    "ModelFit",
    "dataclass_default_lines",
    "fit_bi_exponential",
    "fit_bouc_wen",
    "fit_tanh",
    "identify_loops",
    "identify_measured",
    "identify_reference",
    "load_measured_loop",
    "measured_files",
    "plot_fits",
    "predict_force",
    "reference_loops",
    "rmse",
]

#: Constant coil currents of the identification loops (A), 0 to i_max = 1.5 A in 0.25 A steps.
DEFAULT_CURRENTS_A: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5)
#: The identified models, in report order.
MODEL_NAMES: tuple[str, ...] = ("bi_exponential", "bouc_wen", "tanh")
#: The paper's RMSE at 1.5 A on its own damper's measured loops (N) [paper].
PAPER_RMSE_N: dict[str, float] = {"bi_exponential": 61.8, "bouc_wen": 695.3}
#: Largest sample magnitude accepted in a measured file (mm, mm/s or N): far beyond any damper
#: test, and small enough that the fits' sums of squares cannot overflow.
MAX_MEASURED_MAGNITUDE = 1e9
_X_F_COLUMNS = ("displacement (mm)", "velocity (mm/s)", "force (N)")
_BRANCHES = ("upper", "lower")
#: Rules for the Bi-exponential d (:func:`fit_bi_exponential`): the paper's mean, or a joint fit.
D_RULES: tuple[str, ...] = ("mean", "joint")


# ------------------------------------------------------------------------------------ loops
@dataclass(frozen=True, eq=False)
class Loop:
    """One force loop at a constant coil current: the samples a damper test rig records.

    Attributes
    ----------
    current_a : the constant coil current (A); 0 for a measured file whose current is unknown.
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
    """

    current_a: float
    time_s: np.ndarray
    stroke_m: np.ndarray
    stroke_rate_m_s: np.ndarray
    force_n: np.ndarray
    source: str = ""
    force_offset_n: float = 0.0
    periodic: bool = True

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
        """Boolean mask of the upper-branch samples (``x >= 0``, MODEL.md 1)."""
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
    """Steady force loops of a damper model under a sinusoidal stroke (MODEL.md 6.1).

    The stroke ``x = amplitude sin(2 pi f t)`` runs for ``cycles`` periods at each constant
    ``current`` (the model's internal states start at zero,
    :func:`capsule_env.dynamics.simulate_damper`); the last full period is kept, sampled at
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
    cycles = _check_int("cycles", cycles, 2)
    samples_per_cycle = _check_int("samples_per_cycle", samples_per_cycle, 16)
    substeps = _check_int("substeps", substeps, 1)
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


# ----------------------------------------------------------------------------- measured data
def _natural_key(path: Path) -> list[Any]:
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", path.name)]


def measured_files(folder: str | Path) -> list[Path]:
    """The ``.mat`` files of a folder of measured loops, sorted by name (numbers numerically).

    Raises ``ValueError`` when the folder does not exist or holds no ``.mat`` file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"measured-data folder {str(folder)!r} does not exist or is not a folder")
    files = sorted((p for p in folder.iterdir() if p.suffix == ".mat" and p.is_file()),
                   key=_natural_key)  # fmt: skip
    if not files:
        raise ValueError(f"measured-data folder {str(folder)!r} holds no .mat files")
    return files


def load_measured_loop(path: str | Path, current_a: float = 0.0) -> Loop:
    """Read one Labcontrol MR-damper test file (MATLAB v5 ``.mat``) as a :class:`Loop`.

    The file holds ``x_F`` (n, 3): displacement (mm), velocity (mm/s) and force (N), and the
    time ``Tout`` (n, 1) in s (or the sample period ``Ts``). The loop is returned in SI units
    with the displacement centred (its mean removed: the rig records e.g. 0 to 25 mm) and the
    mean force removed (a static preload or load-cell zero), which is kept in
    :attr:`Loop.force_offset_n`. ``current_a`` is the constant current to attach: the files do
    not record their coil voltage, so the default 0 makes a fit carry everything in its
    current-independent coefficients. ``periodic`` is False (a record of several cycles).

    Raises ``ValueError`` naming the path and the problem for a missing, unreadable or
    malformed file: no ``x_F`` of shape (n, 3), complex or non-numeric values, an empty or
    non-positive ``Ts``, NaN/inf samples or magnitudes beyond
    :data:`MAX_MEASURED_MAGNITUDE`, a constant column, a time that does not increase.
    """
    path = Path(path)
    name = f"measured data file {str(path)!r}"
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
        current_a=check_in_range("current_a", current_a, 0.0, math.inf),
        time_s=time - time[0],
        stroke_m=disp_m - np.mean(disp_m),
        stroke_rate_m_s=x_f[:, 1] * 1e-3,
        force_n=force - offset,
        source=path.name,
        force_offset_n=offset,
        periodic=False,
    )


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


# --------------------------------------------------------------------------------- helpers
def _check_int(name: str, value: int, low: int) -> int:
    if isinstance(value, bool) or int(value) != value or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _check_loops(loops: Sequence[Loop]) -> list[Loop]:
    loops = list(loops)
    if not loops:
        raise ValueError("loops must hold at least one Loop")
    for k, loop in enumerate(loops):
        if not isinstance(loop, Loop):
            raise ValueError(f"loops[{k}] must be a Loop, got {type(loop).__name__}")
    return loops


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root-mean-square difference of two equal-length arrays (same unit as the inputs)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    return float(np.sqrt(np.mean((a - b) ** 2)))


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


def _warm_sequence(loop: Loop) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(t, x, v, n_warm)``: one period of warm-up followed by the loop itself."""
    n_warm = _period_samples(loop)
    t = loop.time_s
    # Time runs on continuously: the loop starts one sample interval after the warm-up ends.
    shift = t[n_warm - 1] - t[0] + (t[1] - t[0])
    t2 = np.concatenate([t[:n_warm], t + shift])
    x2 = np.concatenate([loop.stroke_m[:n_warm], loop.stroke_m])
    v2 = np.concatenate([loop.stroke_rate_m_s[:n_warm], loop.stroke_rate_m_s])
    return t2, x2, v2, n_warm


@njit(cache=True)
def _bouc_wen_z(x, starts, ends, a_coef, gamma, beta, out):  # pragma: no cover - numba
    """Hysteretic variable along each segment ``x[starts[s]:ends[s]]``, from z = 0 (exact)."""
    for s in range(starts.shape[0]):
        z = 0.0
        prev = x[starts[s]]
        for k in range(starts[s], ends[s]):
            z = hysteresis_update(z, x[k] - prev, a_coef, gamma, beta)
            prev = x[k]
            out[k] = z


class _BoucWenSequences:
    """Concatenated warm-up + loop strokes of several loops, for fast repeated simulation."""

    def __init__(self, loops: Sequence[Loop]) -> None:
        parts, starts, ends, scored = [], [], [], []
        offset = 0
        for loop in loops:
            _, x2, _, n_warm = _warm_sequence(loop)
            parts.append(x2)
            starts.append(offset)
            ends.append(offset + x2.size)
            scored.append(np.arange(offset + n_warm, offset + x2.size))
            offset += x2.size
        self.x = np.ascontiguousarray(np.concatenate(parts))
        self.starts = np.asarray(starts, dtype=np.int64)
        self.ends = np.asarray(ends, dtype=np.int64)
        self.scored = np.concatenate(scored)
        self._out = np.zeros_like(self.x)

    def z(self, a_coef: float, gamma: float, beta: float) -> np.ndarray:
        """Hysteretic variable (m when A = 1) at the scored samples of every loop, in order."""
        _bouc_wen_z(self.x, self.starts, self.ends, a_coef, gamma, beta, self._out)
        return self._out[self.scored]


def predict_force(damper: DamperParams, loop: Loop, substeps: int = 4) -> np.ndarray:
    """Force (N) of a forward model on a loop's samples, at the loop's current.

    Algebraic models (Bi-exponential, tanh, linear) are evaluated sample by sample with
    :func:`capsule_env.dampers.damper_force`. Models with internal states are simulated from
    zero state over one preceding period of the stroke (the loop itself when periodic), so
    the prediction is the steady response: Bouc-Wen with the exact hysteresis update on the
    stroke samples, the reference damper with :func:`capsule_env.dynamics.simulate_damper`.
    """
    x, v, i = loop.stroke_m, loop.stroke_rate_m_s, np.full(loop.n_samples, loop.current_a)
    if damper.code == BOUC_WEN:
        seq = _BoucWenSequences([loop])
        z = seq.z(damper.a_coef, damper.gamma, damper.beta)
        state = np.stack([z, np.zeros_like(z)], axis=-1)
        return damper_force(damper, x, v, i, state=state)[0]
    if damper.code == REFERENCE:
        t2, x2, v2, n_warm = _warm_sequence(loop)
        out = simulate_damper(damper, t2, x2, v2, loop.current_a, substeps=substeps)
        return out["force_n"][n_warm:]
    return damper_force(damper, x, v, i)[0]


def _group_by_current(loops: Sequence[Loop]) -> tuple[np.ndarray, list[list[Loop]]]:
    currents = sorted({float(loop.current_a) for loop in loops})
    groups = [[loop for loop in loops if float(loop.current_a) == i] for i in currents]
    return np.asarray(currents), groups


def _stack(loops: Sequence[Loop]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    x = np.concatenate([lp.stroke_m for lp in loops])
    v = np.concatenate([lp.stroke_rate_m_s for lp in loops])
    f = np.concatenate([lp.force_n for lp in loops])
    i = np.concatenate([np.full(lp.n_samples, lp.current_a) for lp in loops])
    return x, v, f, i


def _lstsq(
    phi: np.ndarray, f: np.ndarray, lower: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients and residual of ``phi @ c ~ f``, optionally ``c >= lower``.

    The columns are normalised and the problem reduced to its small triangular form through
    the Cholesky factor of the Gram matrix (fast for tall ``phi``); a nearly rank-deficient
    ``phi`` falls back to the SVD (or, with bounds, the full bounded solver).
    """
    scale = np.linalg.norm(phi, axis=0)
    scale[scale == 0.0] = 1.0
    a = phi / scale
    gram = a.T @ a
    rhs = a.T @ f
    try:
        r = np.linalg.cholesky(gram).T  # upper triangular, gram = r.T r
        well_posed = float(np.min(np.abs(np.diag(r)))) > 1e-5
    except np.linalg.LinAlgError:
        well_posed = False
    if lower is None:
        if well_posed:
            coef = linalg.cho_solve((r, False), rhs)
        else:
            coef = np.linalg.lstsq(a, f, rcond=None)[0]
    else:
        bounds = (np.asarray(lower, float), np.full(phi.shape[1], np.inf))
        if well_posed:
            y = linalg.solve_triangular(r, rhs, trans="T")
            coef = optimize.lsq_linear(r, y, bounds=bounds, method="bvls").x
        else:
            coef = optimize.lsq_linear(a, f, bounds=bounds, method="bvls").x
    coef = coef / scale
    return coef, f - phi @ coef


def _velocity_scale(loops: Sequence[Loop]) -> float:
    v_ref = max(float(np.max(np.abs(lp.stroke_rate_m_s))) for lp in loops)
    if not v_ref > 0.0:
        raise ValueError("the loops have zero stroke rate everywhere; nothing to identify")
    return v_ref


# -------------------------------------------------------------------------- Bi-exponential
def _s_d(v: np.ndarray, d: float) -> np.ndarray:
    return np.sign(v) * -np.expm1(-d * np.abs(v))


def _biexp_linear(v: np.ndarray, f: np.ndarray, d: float) -> tuple[np.ndarray, float]:
    """``(a, b, c)`` and the RMSE of ``F = a S_d(v) + b v + c`` at fixed d."""
    phi = np.column_stack([_s_d(v, d), v, np.ones_like(v)])
    coef, res = _lstsq(phi, f)
    return coef, float(np.sqrt(np.mean(res**2)))


def _biexp_free_d(
    v: np.ndarray, f: np.ndarray, d_lo: float, d_hi: float, grid_points: int
) -> tuple[float, np.ndarray, float]:
    """Best d in [d_lo, d_hi] (log grid, then a bounded scalar search): ``(d, abc, rmse)``."""
    grid = np.geomspace(d_lo, d_hi, grid_points)
    errs = np.array([_biexp_linear(v, f, d)[1] for d in grid])
    k = int(np.argmin(errs))
    lo, hi = math.log(grid[max(k - 1, 0)]), math.log(grid[min(k + 1, grid.size - 1)])
    res = optimize.minimize_scalar(
        lambda s: _biexp_linear(v, f, math.exp(s))[1],
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 1e-8},
    )
    d = math.exp(res.x) if res.fun <= errs[k] else float(grid[k])
    coef, err = _biexp_linear(v, f, d)
    return d, coef, err


@dataclass(frozen=True, eq=False)
class BiExponentialTrends:
    """The Bi-exponential identification, step by step (the paper's Figures 5, 6, Table 2).

    Attributes
    ----------
    currents_a : the distinct loop currents (A).
    free : per branch (``"upper"``, ``"lower"``) the per-current free fits: arrays ``a`` (N),
        ``b`` (N s/m), ``c`` (N), ``d`` (s/m) and ``rmse_n`` (N) over the branch's samples
        (Figure 5).
    fixed_d : per branch the per-current refits at the branch's mean ``d``: ``a``, ``b``, ``c``,
        ``rmse_n`` (Figure 6).
    table : per branch the linear laws ``a0, a1, b0, b1, c0, c1, d`` (Table 2): ``a = a0 + a1 i``
        (N, N/A), ``b = b0 + b1 i`` (N s/m, N s/(m A)), ``c = c0 + c1 i`` (N, N/A), ``d`` (s/m).
    """

    currents_a: np.ndarray
    free: dict[str, dict[str, np.ndarray]]
    fixed_d: dict[str, dict[str, np.ndarray]]
    table: dict[str, dict[str, float]]

    def to_json_dict(self) -> dict[str, Any]:
        """Plain-JSON form (lists of floats)."""

        def conv(block: dict[str, dict[str, np.ndarray]]) -> dict[str, dict[str, list[float]]]:
            return {b: {k: [float(u) for u in a] for k, a in p.items()} for b, p in block.items()}

        return {
            "currents_a": [float(i) for i in self.currents_a],
            "free": conv(self.free),
            "fixed_d": conv(self.fixed_d),
            "table": {b: {k: float(u) for k, u in p.items()} for b, p in self.table.items()},
        }


def fit_bi_exponential(
    loops: Sequence[Loop],
    d_bounds: tuple[float, float] | None = None,
    grid_points: int = 41,
    d_rule: str = "mean",
) -> tuple[BiExponentialDamper, BiExponentialTrends]:
    """Identify the Bi-exponential model (MODEL.md 4.4 and 6.2) from force loops.

    Per current and branch (upper ``x >= 0``, lower ``x < 0``): ``a, b, c, d`` by variable
    projection (``a, b, c`` by linear least squares inside a search over ``d``: a log grid of
    ``grid_points`` values, then a bounded scalar search around the best). Then, with
    ``d_rule="mean"`` (the paper's procedure, MODEL.md 6.2): ``d`` per branch = the mean over
    currents, ``a, b, c`` refitted at that ``d`` per current, and each fitted as a line in
    current (with one distinct current: ``p0`` = the value, ``p1 = 0``, and each branch keeps
    its own fitted ``d``). With ``d_rule="joint"`` (an alternative, not the paper's): per
    branch, ``d`` and the six linear-law coefficients are fitted together to all currents'
    samples at once (variable projection again), which minimises the final model's error; the
    per-current refits are then reported at that ``d``.

    Parameters
    ----------
    loops : force loops (several currents for the current laws, or one measured loop).
    d_bounds : search range of ``d`` (s/m); default ``(0.1, 1000) / max|v|`` (so ``d |v|``
        spans a near-linear to a near-Coulomb shape whatever the stroke rate).
    grid_points : log-grid points of the coarse search (>= 5).
    d_rule : ``"mean"`` (default, the paper's) or ``"joint"``.

    Returns
    -------
    The fitted :class:`~capsule_env.dampers.BiExponentialDamper` (``max_current_a`` at least the
    largest loop current, 1.5 A by default) and the :class:`BiExponentialTrends`.
    """
    loops = _check_loops(loops)
    grid_points = _check_int("grid_points", grid_points, 5)
    if d_rule not in D_RULES:
        raise ValueError(f"unknown d_rule {d_rule!r}; accepted values: {', '.join(D_RULES)}")
    v_ref = _velocity_scale(loops)
    if d_bounds is None:
        d_lo, d_hi = 0.1 / v_ref, 1000.0 / v_ref
    else:
        d_lo = check_positive("d_bounds[0]", d_bounds[0])
        d_hi = check_positive("d_bounds[1]", d_bounds[1])
        if not d_hi > d_lo:
            raise ValueError(f"d_bounds must be (low, high) with high > low > 0, got {d_bounds}")
    currents, groups = _group_by_current(loops)
    data = {b: [] for b in _BRANCHES}
    blend = BiExponentialDamper.branch_blend_m  # samples inside the blend belong to neither
    for i_group, group in zip(currents, groups):
        x, v, f, _ = _stack(group)
        for branch, mask in zip(_BRANCHES, (x >= blend, x <= -blend)):
            if np.count_nonzero(mask) < 4:
                raise ValueError(
                    f"the {branch} branch ({'x >= 0' if branch == 'upper' else 'x < 0'}) of the "
                    f"loops at {group[0].current_a:g} A has fewer than 4 samples; the stroke "
                    "must cross zero"
                )
            data[branch].append((v[mask], f[mask], np.full(np.count_nonzero(mask), i_group)))
    free: dict[str, dict[str, np.ndarray]] = {}
    fixed: dict[str, dict[str, np.ndarray]] = {}
    table: dict[str, dict[str, float]] = {}
    for branch in _BRANCHES:
        rows = [_biexp_free_d(v, f, d_lo, d_hi, grid_points) for v, f, _ in data[branch]]
        free[branch] = {
            "a": np.array([r[1][0] for r in rows]),
            "b": np.array([r[1][1] for r in rows]),
            "c": np.array([r[1][2] for r in rows]),
            "d": np.array([r[0] for r in rows]),
            "rmse_n": np.array([r[2] for r in rows]),
        }
        if d_rule == "joint" and currents.size > 1:
            v_all, f_all, i_all = (np.concatenate(a) for a in zip(*data[branch]))
            d_mean, law = _biexp_joint(v_all, f_all, i_all, d_lo, d_hi, grid_points)
        else:
            d_mean, law = float(np.mean(free[branch]["d"])), None
        refits = [_biexp_linear(v, f, d_mean) for v, f, _ in data[branch]]
        fixed[branch] = {
            "a": np.array([r[0][0] for r in refits]),
            "b": np.array([r[0][1] for r in refits]),
            "c": np.array([r[0][2] for r in refits]),
            "rmse_n": np.array([r[1] for r in refits]),
        }
        row: dict[str, float] = {}
        for k, p in enumerate(("a", "b", "c")):
            if law is None:
                p0, p1 = _line(currents, fixed[branch][p])
            else:
                p0, p1 = float(law[2 * k]), float(law[2 * k + 1])
            row[f"{p}0"], row[f"{p}1"] = p0, p1
        row["d"] = d_mean
        table[branch] = row
    values = {f"{b}_{k}": table[b][k] for b in _BRANCHES for k in table[b]}
    damper = BiExponentialDamper(max_current_a=max(1.5, float(currents.max())), **values)
    return damper, BiExponentialTrends(currents, free, fixed, table)


def _biexp_joint(
    v: np.ndarray, f: np.ndarray, i: np.ndarray, d_lo: float, d_hi: float, grid_points: int
) -> tuple[float, np.ndarray]:
    """``(d, [a0, a1, b0, b1, c0, c1])`` of the linear-law model fitted to all currents."""

    def solve(d: float) -> tuple[np.ndarray, float]:
        s_d = _s_d(v, d)
        phi = np.column_stack([s_d, i * s_d, v, i * v, np.ones_like(v), i])
        coef, res = _lstsq(phi, f)
        return coef, float(np.sqrt(np.mean(res**2)))

    grid = np.geomspace(d_lo, d_hi, grid_points)
    errs = np.array([solve(d)[1] for d in grid])
    k = int(np.argmin(errs))
    lo, hi = math.log(grid[max(k - 1, 0)]), math.log(grid[min(k + 1, grid.size - 1)])
    res = optimize.minimize_scalar(lambda s: solve(math.exp(s))[1], bounds=(lo, hi),
                                   method="bounded", options={"xatol": 1e-8})  # fmt: skip
    d = math.exp(res.x) if res.fun <= errs[k] else float(grid[k])
    return d, solve(d)[0]


def _line(currents: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """``(p0, p1)`` of the least-squares line ``p0 + p1 i`` (``p1 = 0`` for one current)."""
    if currents.size == 1:
        return float(values[0]), 0.0
    p1, p0 = np.polyfit(currents, values, 1)
    return float(p0), float(p1)


# ------------------------------------------------------------------------------------ tanh
def _tanh_design(sign_x, v, i, x, beta, delta, with_current: bool) -> np.ndarray:
    t = np.tanh(beta * v + delta * sign_x)
    one = np.ones_like(v)
    if with_current:
        return np.column_stack([v, i * v, x, i * x, t, i * t, one, i])
    return np.column_stack([v, x, t, one])


def fit_tanh(loops: Sequence[Loop], starts: int = 3) -> TanhDamper:
    """Identify the hyperbolic-tangent model (MODEL.md 4.3) from force loops.

    ``F = c v + k x + alpha tanh(beta v + delta sign(x)) + f0`` with ``c, k, alpha, f0`` linear in
    current (``p = p_a + p_b i``; with one distinct current the ``_b`` terms are 0) and
    ``beta`` (s/m), ``delta`` (-) constant. Variable projection: the 8 (or 4) linear
    coefficients by linear least squares inside :func:`scipy.optimize.least_squares` over
    ``(log beta, delta)``, started from the best ``starts`` points of a coarse grid; bounds
    ``beta |v|_max`` in [0.01, 1e4] and ``delta`` in [-20, 20].
    """
    loops = _check_loops(loops)
    starts = _check_int("starts", starts, 1)
    x, v, f, i = _stack(loops)
    # the model's sign(x), blended over its branch_blend_m (TanhDamper)
    sign_x = 2.0 * branch_weights(np.ascontiguousarray(x), TanhDamper.branch_blend_m) - 1.0
    with_current = np.unique(i).size > 1
    v_ref = _velocity_scale(loops)
    lb = np.array([math.log(0.01 / v_ref), -20.0])
    ub = np.array([math.log(1e4 / v_ref), 20.0])

    def residual(p: np.ndarray) -> np.ndarray:
        phi = _tanh_design(sign_x, v, i, x, math.exp(p[0]), p[1], with_current)
        return _lstsq(phi, f)[1]

    grid = [
        np.array([math.log(s / v_ref), dl])
        for s in (0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0)
        for dl in (-1.0, 0.0, 0.5, 1.0, 2.0)
    ]
    costs = [float(np.sum(residual(p) ** 2)) for p in grid]
    best = None
    for k in np.argsort(costs)[:starts]:
        sol = optimize.least_squares(residual, grid[k], bounds=(lb, ub),
                                     xtol=1e-10, ftol=1e-10, gtol=1e-10)  # fmt: skip
        if best is None or sol.cost < best.cost:
            best = sol
    beta, delta = math.exp(best.x[0]), float(best.x[1])
    coef, _ = _lstsq(_tanh_design(sign_x, v, i, x, beta, delta, with_current), f)
    if not with_current:
        coef = np.array([coef[0], 0.0, coef[1], 0.0, coef[2], 0.0, coef[3], 0.0])
    names = ("c_a", "c_b", "k_a", "k_b", "alpha_a", "alpha_b", "f0_a", "f0_b")
    values = {n: float(c) for n, c in zip(names, coef)}
    return TanhDamper(beta=beta, delta=delta, max_current_a=max(1.5, float(np.max(i))), **values)


# -------------------------------------------------------------------------------- Bouc-Wen
def _bw_shape(log_zy: float, ratio: float) -> tuple[float, float]:
    """``(gamma, beta)`` (1/m^2) for A = 1 from the yield displacement and the shape ratio."""
    s = math.exp(-2.0 * log_zy)  # gamma + beta = 1 / z_y^2
    return 0.5 * (1.0 - ratio) * s, 0.5 * (1.0 + ratio) * s


def fit_bouc_wen(loops: Sequence[Loop], starts: int = 3) -> BoucWenDamper:
    """Identify the Bouc-Wen model (MODEL.md 4.2, n = 2, A = 1) from force loops.

    ``F = c0 v + k0 (x - x0) + alpha z`` with ``alpha = alpha_a + alpha_b i``,
    ``c0 = c0a + c0b i``; ``z' = -gamma |v| z |z| - beta v z^2 + v``. With ``A = 1`` fixed (the
    model's scale degeneracy), the shape is set by the yield displacement
    ``z_y = 1/sqrt(gamma + beta)`` (m) and the ratio ``r = (beta - gamma)/(beta + gamma)`` in
    (-1, 1). For fixed ``(z_y, r)`` the force is linear in ``c0a, c0b, alpha_a, alpha_b, k0``
    and the offset ``-k0 x0``, solved by bounded linear least squares (the five coefficients
    >= 0); :func:`scipy.optimize.least_squares` searches ``(log z_y, r)`` from the best
    ``starts`` points of a coarse grid, within ``z_y`` in [1e-5, 10] x max|x| and ``r`` in
    [-0.999, 0.999]. The response is simulated exactly over all loops at once (warm-up of one
    period from ``z = 0``, see :func:`predict_force`). ``x0`` is fitted when the stiffness
    ``k0 > 0`` carries a plausible offset (|x0| <= max|x|), else fixed at 0.

    On a Spencer-type damper the optimum tends to the near-Bingham limit (small ``z_y``, ``r``
    at its lower bound): a plain Bouc-Wen element cannot follow the low-velocity roll-off that
    Spencer's series dashpot produces, which is why its error grows with current.
    """
    loops = _check_loops(loops)
    starts = _check_int("starts", starts, 1)
    seq = _BoucWenSequences(loops)
    x, v, f, i = _stack(loops)
    with_current = np.unique(i).size > 1
    x_ref = max(float(np.max(np.abs(lp.stroke_m))) for lp in loops)
    if not x_ref > 0.0:
        raise ValueError("the loops have zero stroke everywhere; nothing to identify")

    def design(p: np.ndarray, with_offset: bool) -> np.ndarray:
        z = seq.z(1.0, *_bw_shape(p[0], p[1]))
        cols = [v, i * v, z, i * z, x] if with_current else [v, z, x]
        if with_offset:
            cols.append(np.ones_like(v))
        return np.column_stack(cols)

    def solve(phi: np.ndarray, with_offset: bool) -> tuple[np.ndarray, np.ndarray]:
        lower = np.zeros(phi.shape[1])
        if with_offset:
            lower[-1] = -np.inf
        return _lstsq(phi, f, lower)

    def fit(with_offset: bool) -> tuple[np.ndarray, np.ndarray, float]:
        def residual(p: np.ndarray) -> np.ndarray:
            return solve(design(p, with_offset), with_offset)[1]

        grid = [
            np.array([math.log(s * x_ref), r])
            for s in (0.003, 0.01, 0.03, 0.1, 0.3, 1.0)
            for r in (-0.5, 0.0, 0.5)
        ]
        costs = [float(np.sum(residual(p) ** 2)) for p in grid]
        lb = np.array([math.log(1e-5 * x_ref), -0.999])
        ub = np.array([math.log(10.0 * x_ref), 0.999])
        best = None
        for k in np.argsort(costs)[:starts]:
            sol = optimize.least_squares(residual, grid[k], bounds=(lb, ub),
                                         xtol=1e-10, ftol=1e-10, gtol=1e-10)  # fmt: skip
            if best is None or sol.cost < best.cost:
                best = sol
        coef, res = solve(design(best.x, with_offset), with_offset)
        return best.x, coef, float(np.sum(res**2))

    p, coef, _ = fit(with_offset=True)
    k0 = coef[-2]
    x0 = -coef[-1] / k0 if k0 > 0.0 else math.inf
    if not abs(x0) <= x_ref:
        # No stiffness to carry a force offset (or an implausible one): fix x0 = 0.
        p, coef, _ = fit(with_offset=False)
        x0 = 0.0
        coef = np.append(coef, 0.0)
    if with_current:
        c0a, c0b, alpha_a, alpha_b, k0 = coef[:5]
    else:
        (c0a, alpha_a, k0), c0b, alpha_b = coef[:3], 0.0, 0.0
    gamma, beta = _bw_shape(p[0], p[1])
    return BoucWenDamper(
        c0a=float(c0a),
        c0b=float(c0b),
        alpha_a=float(alpha_a),
        alpha_b=float(alpha_b),
        k0=float(k0),
        x0=float(x0),
        gamma=gamma,
        beta=beta,
        a_coef=1.0,
        max_current_a=max(1.5, float(np.max(i))),
    )


# -------------------------------------------------------------------------- the whole run
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
            "force_offset_n": float(self.force_offset_n),
            "d_rule": self.d_rule,
            "table": self.bi_exponential.to_json_dict()["table"],
            "bi_exponential_trends": self.bi_exponential.to_json_dict(),
            "paper_rmse_n": dict(PAPER_RMSE_N),
            "timings_s": {k: float(t) for k, t in self.timings_s.items()},
        }


def _rmse_per_current(damper: DamperParams, loops: Sequence[Loop]) -> dict[float, float]:
    currents, groups = _group_by_current(loops)
    out = {}
    for i, group in zip(currents, groups):
        err = np.concatenate([predict_force(damper, lp) - lp.force_n for lp in group])
        out[float(i)] = float(np.sqrt(np.mean(err**2)))
    return out


def identify_loops(
    loops: Sequence[Loop], source: str | None = None, d_rule: str = "mean"
) -> IdentificationResult:
    """Fit the Bi-exponential, Bouc-Wen and tanh models to a set of loops (MODEL.md 6).

    Each model's RMSE is evaluated with the package's own forward model
    (:func:`predict_force`) on every loop; ``rmse_n`` is the RMSE at the largest current.
    ``d_rule`` picks the Bi-exponential ``d`` rule (:func:`fit_bi_exponential`).
    """
    import time

    loops = _check_loops(loops)
    if max(lp.peak_force_n for lp in loops) == 0.0:
        raise ValueError("the loops' force is zero everywhere: nothing to identify")
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
    return IdentificationResult(
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


def identify_measured(path: str | Path) -> IdentificationResult:
    """Identify all models from one measured Labcontrol file (one unknown constant current).

    The file is loaded by :func:`load_measured_loop` (SI units, centred stroke, mean force
    removed) and fitted as a single loop at ``i = 0``: the current-independent coefficients
    carry everything, the per-ampere ones are 0, and each Bi-exponential branch keeps its own
    ``d``. ``rmse_n`` is the RMSE over the whole record.
    """
    loop = load_measured_loop(path)
    return identify_loops([loop], source=loop.source)


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


# ----------------------------------------------------------------------------------- plots
_MODEL_LABELS = {"bi_exponential": "Bi-exponential", "bouc_wen": "Bouc-Wen", "tanh": "tanh"}


def plot_fits(
    result: IdentificationResult,
    loops: Sequence[Loop] | None = None,
    directory: str | Path = ".",
    prefix: str = "",
) -> list[Path]:
    """Write PNG figures of an identification and return their paths.

    - ``{prefix}force_velocity.png`` and ``{prefix}force_displacement.png``: data (dots) against
      each fitted model (lines), every current (the paper's Figure 7 analogue, all models).
    - ``{prefix}top_current_branches.png``: the loop at the reporting current split by the sign
      of the stroke (upper/lower branches, the paper's Figure 4) with the Bi-exponential branches.
    - ``{prefix}bi_exponential_trends.png`` (several currents only): a, b, c, d against current,
      free per-current fits and the refit at the mean d with its linear law (Figures 5 and 6).

    ``loops`` defaults to ``result.loops``; ``directory`` is created if needed.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    loops = list(result.loops if loops is None else _check_loops(loops))
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    currents, groups = _group_by_current(loops)
    cmap = plt.get_cmap("viridis")
    colours = [cmap(k / max(len(currents) - 1, 1)) for k in range(len(currents))]
    paths: list[Path] = []

    def ordered(loop: Loop) -> np.ndarray:
        # close a periodic loop for a continuous line
        idx = np.arange(loop.n_samples)
        return np.append(idx, 0) if loop.periodic else idx

    def kilo(ax) -> None:
        ax.grid(True, alpha=0.3)

    peak = result.peak_force_n
    where = f"at {result.rmse_current_a:g} A" if len(currents) > 1 else "(whole record)"
    scale, unit = (1e-3, "kN") if peak >= 2e3 else (1.0, "N")
    for kind, xlabel in (("velocity", "stroke rate v (m/s)"), ("displacement", "stroke x (mm)")):
        fig, axes = plt.subplots(1, len(MODEL_NAMES), figsize=(5.2 * len(MODEL_NAMES), 4.4),
                                 sharey=True, constrained_layout=True)  # fmt: skip
        for ax, name in zip(axes, MODEL_NAMES):
            fit = result.models[name]
            for colour, i, group in zip(colours, currents, groups):
                for n, loop in enumerate(group):
                    model = predict_force(fit.damper, loop)
                    idx = ordered(loop)
                    xs = loop.stroke_rate_m_s if kind == "velocity" else loop.stroke_m * 1e3
                    step = max(1, loop.n_samples // (250 if loop.periodic else 3000))
                    single = len(currents) == 1
                    ax.plot(xs[::step], loop.force_n[::step] * scale, ".", ms=2.5,
                            color="0.45" if single else colour, alpha=0.5,
                            label=("data" if single else f"data {i:g} A") if n == 0 else None)  # fmt: skip
                    ax.plot(xs[idx], model[idx] * scale, "-", lw=1.1,
                            color="tab:red" if single else colour,
                            label="model" if single and n == 0 else None)  # fmt: skip
            ax.set_title(f"{_MODEL_LABELS[name]}: RMSE {fit.rmse_n:.1f} N {where}")
            ax.set_xlabel(xlabel)
            kilo(ax)
        axes[0].set_ylabel(f"damper force F ({unit})")
        axes[0].legend(fontsize=7, loc="upper left", title="dots: data, lines: model",
                       title_fontsize=7, framealpha=0.9)  # fmt: skip
        fig.suptitle(f"Force-{kind} loops, data vs identified models ({result.source})")
        path = directory / f"{prefix}force_{kind}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)

    # The reporting current, split by branch (Figures 4 and 7).
    top = groups[-1]
    bi = result.models["bi_exponential"].damper
    fig, (ax_x, ax_v) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    for loop in top:
        up = loop.upper
        for mask, label, colour in ((up, "upper (x >= 0)", "tab:red"),
                                    (~up, "lower (x < 0)", "tab:blue")):  # fmt: skip
            ax_x.plot(loop.stroke_m[mask] * 1e3, loop.force_n[mask] * scale, ".", ms=2,
                      color=colour, label=f"data, {label}")  # fmt: skip
            ax_v.plot(loop.stroke_rate_m_s[mask], loop.force_n[mask] * scale, ".", ms=2,
                      color=colour, label=f"data, {label}")  # fmt: skip
    v_max = max(float(np.max(np.abs(lp.stroke_rate_m_s))) for lp in top)
    vv = np.linspace(-v_max, v_max, 400)
    i_top = float(currents[-1])
    for x_sign, label, colour in ((1.0, "upper", "darkred"), (-1.0, "lower", "navy")):
        f_model = damper_force(bi, np.full_like(vv, 0.5 * x_sign), vv, i_top)[0]
        ax_v.plot(vv, f_model * scale, "-", lw=2, color=colour,
                  label=f"Bi-exponential, {label} branch")  # fmt: skip
    ax_x.set_xlabel("stroke x (mm)")
    ax_v.set_xlabel("stroke rate v (m/s)")
    for ax in (ax_x, ax_v):
        ax.set_ylabel(f"damper force F ({unit})")
        kilo(ax)
        ax.legend(fontsize=7)
    fig.suptitle(f"Loop at {i_top:g} A split by the sign of the stroke; Bi-exponential RMSE "
                 f"{result.models['bi_exponential'].rmse_n:.1f} N ({result.source})")  # fmt: skip
    path = directory / f"{prefix}top_current_branches.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    paths.append(path)

    trends = result.bi_exponential
    if trends.currents_a.size > 1:
        units = {"a": "a (N)", "b": "b (N s/m)", "c": "c (N)", "d": "d (s/m)"}
        fig, axes = plt.subplots(2, 4, figsize=(16, 7.5), constrained_layout=True)
        ii = trends.currents_a
        fine = np.linspace(ii.min(), ii.max(), 50)
        styles = (("upper", "tab:red", "o", 9), ("lower", "tab:blue", "s", 4))
        for branch, colour, marker, size in styles:
            for col, p in enumerate("abcd"):
                ax = axes[0, col]
                ax.plot(ii, trends.free[branch][p], marker + "-", color=colour, ms=size,
                        mfc="none" if size > 5 else colour, label=branch)  # fmt: skip
                if p == "d":
                    ax.axhline(trends.table[branch]["d"], color=colour, ls="--",
                               label=f"{branch} mean {trends.table[branch]['d']:.4g}")  # fmt: skip
                ax.set_title(f"free fit: {units[p]}")
            for col, p in enumerate("abc"):
                ax = axes[1, col]
                row = trends.table[branch]
                ax.plot(ii, trends.fixed_d[branch][p], marker, color=colour, ms=size,
                        mfc="none" if size > 5 else colour,
                        label=f"{branch}, d = {row['d']:.4g}")  # fmt: skip
                ax.plot(fine, row[f"{p}0"] + row[f"{p}1"] * fine, "-", color=colour,
                        label=_law_label(p, row))  # fmt: skip
                ax.set_title(f"fixed d: {units[p]}")
            mfc = "none" if size > 5 else colour
            axes[1, 3].plot(ii, trends.fixed_d[branch]["rmse_n"], marker + "-", color=colour,
                            ms=size, mfc=mfc, label=f"{branch}, fixed d")  # fmt: skip
            axes[1, 3].plot(ii, trends.free[branch]["rmse_n"], marker + ":", color=colour,
                            ms=size, mfc=mfc, label=f"{branch}, free d")  # fmt: skip
        axes[1, 3].set_title("branch RMSE (N) per current")
        for ax in axes.flat:
            ax.set_xlabel("current i (A)")
            kilo(ax)
            ax.legend(fontsize=7)
        fig.suptitle(
            "Bi-exponential parameters vs current: free per-current fits (top, paper Fig. 5) "
            f"and refit at the {result.d_rule} d with linear laws (bottom, Fig. 6 / Table 2)"
        )
        path = directory / f"{prefix}bi_exponential_trends.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def _law_label(p: str, row: dict[str, float]) -> str:
    """Legend text of a linear law ``p = p0 + p1 i`` (used by :func:`plot_fits`)."""
    return f"{p} = {row[p + '0']:.4g} + {row[p + '1']:.4g} i"
