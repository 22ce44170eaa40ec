"""Identification of the Bi-exponential MR-damper model (docs/model.md 4.5 and 6.2, paper eq. 4).

Split each loop by the sign of the stroke (upper branch ``x >= 0``, lower ``x < 0``); per
current and branch fit ``a, b, c, d`` of ``F = a S_d(v) + b v + c`` with
``S_d(v) = sign(v) (1 - exp(-d |v|))``; set ``d`` per branch to the mean over currents; refit
``a, b, c`` at that ``d``; fit each as a line in current. This is the paper's Table 2
(:attr:`BiExponentialTrends.table`) and its Figures 5 and 6. An alternative rule
(``d_rule="joint"``) fits ``d`` and the linear laws to all currents at once.

Variable projection: ``a, b, c`` (or the six linear-law coefficients) by linear least squares
(:func:`~capsule_env.identification.least_squares.lstsq`) inside a search over ``d``: a log grid,
then a bounded scalar search around the best grid point.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import optimize

from capsule_env.common.validation import check_in_range, check_positive
from capsule_env.dampers import BiExponentialDamper
from capsule_env.identification.least_squares import line_fit, lstsq, velocity_scale
from capsule_env.identification.loops import (
    Loop,
    check_int,
    check_loops,
    group_by_current,
    stack_loops,
)

__all__ = ["D_RULES", "BiExponentialTrends", "fit_bi_exponential"]

#: Rules for the Bi-exponential d (:func:`fit_bi_exponential`): the paper's mean, or a joint fit.
D_RULES: tuple[str, ...] = ("mean", "joint")
_BRANCHES = ("upper", "lower")


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
    branch_gap_m: float | None = None,
) -> tuple[BiExponentialDamper, BiExponentialTrends]:
    """Identify the Bi-exponential model (docs/model.md 4.5 and 6.2) from force loops.

    Per current and branch (upper ``x >= 0``, lower ``x < 0``): ``a, b, c, d`` by variable
    projection (``a, b, c`` by linear least squares inside a search over ``d``: a log grid of
    ``grid_points`` values, then a bounded scalar search around the best). Then, with
    ``d_rule="mean"`` (the paper's procedure, docs/model.md 6): ``d`` per branch = the mean over
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
    branch_gap_m : samples with ``|x| < branch_gap_m`` (m) belong to neither branch (upper
        ``x >= gap``, lower ``x <= -gap``); None (default): the model's ``branch_blend_m``
        (1e-4 m), within which its force blends the two branches. ``0`` is the literal split
        (upper ``x >= 0``, lower ``x < 0``) with which the shipped
        :class:`~capsule_env.dampers.BiExponentialDamper` defaults were identified: on the
        reference loops the default drops the two zero-crossing samples of each loop (at the
        peak stroke rate, ``x`` about +-1e-17 m), which moves the fitted values by up to
        0.58 % (docs/model.md 6).

    Returns
    -------
    The fitted :class:`~capsule_env.dampers.BiExponentialDamper` (``max_current_a`` at least the
    largest loop current, 1.5 A by default) and the :class:`BiExponentialTrends`.
    """
    loops = check_loops(loops)
    grid_points = check_int("grid_points", grid_points, 5)
    if d_rule not in D_RULES:
        raise ValueError(f"unknown d_rule {d_rule!r}; accepted values: {', '.join(D_RULES)}")
    v_ref = velocity_scale(loops)
    if d_bounds is None:
        d_lo, d_hi = 0.1 / v_ref, 1000.0 / v_ref
    else:
        d_lo = check_positive("d_bounds[0]", d_bounds[0])
        d_hi = check_positive("d_bounds[1]", d_bounds[1])
        if not d_hi > d_lo:
            raise ValueError(f"d_bounds must be (low, high) with high > low > 0, got {d_bounds}")
    if branch_gap_m is None:
        gap = BiExponentialDamper.branch_blend_m  # samples inside the blend belong to neither
    else:
        gap = check_in_range("branch_gap_m", branch_gap_m, 0.0, 1e-2)
    currents, groups = group_by_current(loops)
    data = _branch_samples(currents, groups, gap)
    free: dict[str, dict[str, np.ndarray]] = {}
    fixed: dict[str, dict[str, np.ndarray]] = {}
    table: dict[str, dict[str, float]] = {}
    for branch in _BRANCHES:
        rows = [_free_d(v, f, d_lo, d_hi, grid_points) for v, f, _ in data[branch]]
        free[branch] = {
            "a": np.array([r[1][0] for r in rows]),
            "b": np.array([r[1][1] for r in rows]),
            "c": np.array([r[1][2] for r in rows]),
            "d": np.array([r[0] for r in rows]),
            "rmse_n": np.array([r[2] for r in rows]),
        }
        if d_rule == "joint" and currents.size > 1:
            v_all, f_all, i_all = (np.concatenate(a) for a in zip(*data[branch]))
            d_mean, law = _joint_d(v_all, f_all, i_all, d_lo, d_hi, grid_points)
        else:
            d_mean, law = float(np.mean(free[branch]["d"])), None
        refits = [_fixed_d(v, f, d_mean) for v, f, _ in data[branch]]
        fixed[branch] = {
            "a": np.array([r[0][0] for r in refits]),
            "b": np.array([r[0][1] for r in refits]),
            "c": np.array([r[0][2] for r in refits]),
            "rmse_n": np.array([r[1] for r in refits]),
        }
        row: dict[str, float] = {}
        for k, p in enumerate(("a", "b", "c")):
            if law is None:
                p0, p1 = line_fit(currents, fixed[branch][p])
            else:
                p0, p1 = float(law[2 * k]), float(law[2 * k + 1])
            row[f"{p}0"], row[f"{p}1"] = p0, p1
        row["d"] = d_mean
        table[branch] = row
    values = {f"{b}_{k}": table[b][k] for b in _BRANCHES for k in table[b]}
    damper = BiExponentialDamper(max_current_a=max(1.5, float(currents.max())), **values)
    return damper, BiExponentialTrends(currents, free, fixed, table)


def _branch_samples(
    currents: np.ndarray, groups: Sequence[Sequence[Loop]], gap_m: float
) -> dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """Per branch, per current: ``(v, F, i)`` of the samples with ``x >= gap_m`` (upper) or
    ``x <= -gap_m`` (lower; ``x < 0`` when ``gap_m`` is 0); ``ValueError`` when a branch has
    fewer than 4 samples."""
    data: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {b: [] for b in _BRANCHES}
    for i_group, group in zip(currents, groups):
        x, v, f, _ = stack_loops(group)
        lower = x <= -gap_m if gap_m > 0.0 else x < 0.0
        for branch, mask in zip(_BRANCHES, (x >= gap_m, lower)):
            if np.count_nonzero(mask) < 4:
                raise ValueError(
                    f"the {branch} branch ({'x >= 0' if branch == 'upper' else 'x < 0'}) of the "
                    f"loops at {group[0].current_a:g} A has fewer than 4 samples; the stroke "
                    "must cross zero"
                )
            data[branch].append((v[mask], f[mask], np.full(np.count_nonzero(mask), i_group)))
    return data


def _s_d(v: np.ndarray, d: float) -> np.ndarray:
    """``S_d(v) = sign(v) (1 - exp(-d |v|))``."""
    return np.sign(v) * -np.expm1(-d * np.abs(v))


def _fixed_d(v: np.ndarray, f: np.ndarray, d: float) -> tuple[np.ndarray, float]:
    """``(a, b, c)`` and the RMSE of ``F = a S_d(v) + b v + c`` at fixed d."""
    phi = np.column_stack([_s_d(v, d), v, np.ones_like(v)])
    coef, res = lstsq(phi, f)
    return coef, float(np.sqrt(np.mean(res**2)))


def _search_d(error: Callable[[float], float], d_lo: float, d_hi: float, grid_points: int) -> float:
    """The ``d`` in ``[d_lo, d_hi]`` of least ``error(d)``: the best of a log grid of
    ``grid_points`` values, improved by a bounded scalar search between its neighbours."""
    grid = np.geomspace(d_lo, d_hi, grid_points)
    errs = np.array([error(d) for d in grid])
    k = int(np.argmin(errs))
    lo, hi = math.log(grid[max(k - 1, 0)]), math.log(grid[min(k + 1, grid.size - 1)])
    res = optimize.minimize_scalar(lambda s: error(math.exp(s)), bounds=(lo, hi),
                                   method="bounded", options={"xatol": 1e-8})  # fmt: skip
    return math.exp(res.x) if res.fun <= errs[k] else float(grid[k])


def _free_d(
    v: np.ndarray, f: np.ndarray, d_lo: float, d_hi: float, grid_points: int
) -> tuple[float, np.ndarray, float]:
    """Best d in [d_lo, d_hi] (log grid, then a bounded scalar search): ``(d, abc, rmse)``."""
    d = _search_d(lambda d: _fixed_d(v, f, d)[1], d_lo, d_hi, grid_points)
    coef, err = _fixed_d(v, f, d)
    return d, coef, err


def _joint_d(
    v: np.ndarray, f: np.ndarray, i: np.ndarray, d_lo: float, d_hi: float, grid_points: int
) -> tuple[float, np.ndarray]:
    """``(d, [a0, a1, b0, b1, c0, c1])`` of the linear-law model fitted to all currents."""

    def solve(d: float) -> tuple[np.ndarray, float]:
        s_d = _s_d(v, d)
        phi = np.column_stack([s_d, i * s_d, v, i * v, np.ones_like(v), i])
        coef, res = lstsq(phi, f)
        return coef, float(np.sqrt(np.mean(res**2)))

    d = _search_d(lambda d: solve(d)[1], d_lo, d_hi, grid_points)
    return d, solve(d)[0]
