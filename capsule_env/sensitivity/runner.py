"""Running the points of the sensitivity study, and its table and tornado figure.

:func:`run_point` runs passive and both Skyhook pairs of a
:class:`~capsule_env.sensitivity.points.Point` on the same evaluation-bank episodes (as
``evaluate.py`` does) and returns, per pair, the vibration reduction effect at the four mode
peaks, the force it delivered and its current; :func:`format_table` writes a setting's results
as a Markdown table and :func:`plot_tornado` draws the figure.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env import metrics
from capsule_env.dampers import LinearDamper, make_damper
from capsule_env.evaluation.episodes import Rollout, episode_metrics, run_episodes
from capsule_env.sensitivity.csdc_variants import CSDCVariant, InverseSkyhook
from capsule_env.sensitivity.intervals import paired_t_interval, t_interval
from capsule_env.sensitivity.points import Point
from capsule_env.sensitivity.policies import ForceSkyhook, PassivePolicy
from capsule_env.sensitivity.variable_step import variable_step_rollout

__all__ = ["PAPER_GAP", "PAPER_VRE", "format_table", "plot_tornado", "run_point"]

#: The paper's body first-mode VRE (%) [paper]: Table 5 (sim); Table 6's values are lost, its
#: text gives the Bi-exponential "about 10 % more" than Bouc-Wen.
PAPER_VRE = {"sim": {"biexp": 72.33, "csdc": 41.66}, "hils": {}}
PAPER_GAP = {"sim": 72.33 - 41.66, "hils": 10.0}
_INVERSE = {"csdc": "csdc", "biexp": "bi_exponential"}
_PLANT = {"csdc": "bouc_wen", "biexp": "bi_exponential"}
_MODES = ("body_mode1", "body_mode2", "bogie_mode1", "bogie_mode2")


def _variable_step(point: Point, side: str, spec: dict, seeds: Sequence[int],
                   length_s: float) -> Rollout:  # fmt: skip
    env = spec["env"]
    gw = {k: v for k, v in env.items() if k == "guideway_params"}
    solver = spec["solver"]
    if side == "passive":
        damper = LinearDamper()
    else:
        damper = make_damper(_PLANT[side], **env.get("damper_params", {}))
    return variable_step_rollout(side, damper, seeds, length_s, spec["c_max"],
                                 method=solver["method"], rtol=solver["rtol"], env_kwargs=gw)  # fmt: skip


def _pair_rollout(point: Point, side: str, seeds: Sequence[int], length_s: float) -> Rollout:
    spec = getattr(point, side)
    env = {**spec["env"], "setting": point.setting}
    if spec["solver"] is not None:
        return _variable_step(point, side, spec, seeds, length_s)
    if spec["variant"] is not None:
        v = spec["variant"]
        model = make_damper("bouc_wen", **spec["env"].get("inverse_params", {}))

        def make_inverse(n: int) -> CSDCVariant:
            return CSDCVariant(model, n, v["observer"], v["law"], 0.005, v["substeps"])

        plant = "bouc_wen" if point.setting == "sim" else None
        params = spec["env"].get("damper_params", {})
        policy = InverseSkyhook(make_inverse, spec["c_max"], damper_params=params,
                                plant_damper=plant)  # fmt: skip
        extra = {k: val for k, val in env.items() if k != "damper_params"}
        return run_episodes(policy, {**policy.env_kwargs, **extra}, seeds=seeds,
                            episode_length_s=length_s)  # fmt: skip
    ctrl = ForceSkyhook(_INVERSE[side], c_max=spec["c_max"], c_min=0.0)
    return run_episodes(ctrl, {**ctrl.env_kwargs, **env}, seeds=seeds, episode_length_s=length_s)


def _passive(point: Point, seeds: Sequence[int], length_s: float, cache: dict) -> Rollout:
    solver = point.csdc["solver"]
    key = json.dumps([point.setting, point.passive_env, solver], sort_keys=True)
    if key not in cache:
        if solver is not None:
            spec = {"env": point.passive_env, "c_max": 0.0, "solver": solver}
            cache[key] = _variable_step(point, "passive", spec, seeds, length_s)
        else:
            p = PassivePolicy()
            env = {**p.env_kwargs, **point.passive_env, "setting": point.setting}
            cache[key] = run_episodes(p, env, seeds=seeds, episode_length_s=length_s)
    return cache[key]


def _per_episode_vre(roll: Rollout, passive: Rollout) -> dict[str, list[float]]:
    """Each episode's VRE (%) per mode, as :func:`episode_metrics` averages them."""
    out = {}
    for body, key in (("body", "car_body_displacement_m"), ("bogie", "bogie_displacement_m")):
        for mode, band in metrics.DEFAULT_BANDS_HZ.items():
            v = metrics.vibration_reduction_effect(
                passive.signals[key], roll.signals[key], roll.dt_s, band
            )
            out[f"vre_{body}_{mode}_pct"] = [float(x) for x in np.atleast_1d(v)]
    return out


def _summary(roll: Rollout, passive: Rollout) -> dict[str, Any]:
    m = episode_metrics(roll, passive)
    force = roll.signals["damper_force_n"]
    out = {f"vre_{k}_pct": float(v) for k, v in m["vre_pct"].items()}
    out.update({
        "mean_abs_force_n": float(np.mean(np.abs(force))),
        "rms_force_n": float(np.sqrt(np.mean(force**2))),
        "mean_current_a": float(m["mean_current_a"]),
        "wk_rms_body_acc_m_s2": float(m["wk_rms_body_acc_m_s2"]),
        "terminated_episodes": int(m["terminated_episodes"]),
    })  # fmt: skip
    if "force_tracking_error_rel" in m:
        out["force_tracking_error_rel"] = float(m["force_tracking_error_rel"])
    out["per_episode"] = _per_episode_vre(roll, passive)
    return out


def _intervals(out: dict[str, Any]) -> dict[str, dict[str, list[float]]]:
    """95 % intervals over the episodes (:mod:`capsule_env.sensitivity.intervals`): each pair's
    VRE (t interval) and the gap (paired t interval), per mode; empty with one episode."""
    ci: dict[str, dict[str, list[float]]] = {"csdc": {}, "biexp": {}, "gap": {}}
    for mode in _MODES:
        k = f"vre_{mode}_pct"
        a, b = out["csdc"]["per_episode"][k], out["biexp"]["per_episode"][k]
        if len(a) < 2:
            return {}
        ci["csdc"][k], ci["biexp"][k] = list(t_interval(a)), list(t_interval(b))
        ci["gap"][f"gap_{mode}_pct"] = list(paired_t_interval(a, b))
    return ci


def run_point(point: Point, seeds: Sequence[int], episode_length_s: float = 10.0,
              cache: dict | None = None) -> dict[str, Any]:  # fmt: skip
    """Passive and both pairs of ``point`` on episodes ``seeds`` of the evaluation bank;
    returns ``{"csdc": {...}, "biexp": {...}, "gap_body_mode1_pct": biexp - csdc, ...}``
    (``cache``: passive rollouts shared between points of the same guideway and solver)."""
    cache = {} if cache is None else cache
    passive = _passive(point, seeds, episode_length_s, cache)
    out: dict[str, Any] = {"key": point.key, "setting": point.setting, "factor": point.factor,
                           "label": point.label, "why": point.why, "notes": point.notes}  # fmt: skip
    for side in ("csdc", "biexp"):
        out[side] = _summary(_pair_rollout(point, side, seeds, episode_length_s), passive)
    for mode in _MODES:
        k = f"vre_{mode}_pct"
        out[f"gap_{mode}_pct"] = out["biexp"][k] - out["csdc"][k]
    out["ci95"] = _intervals(out)
    return out


def _cell(r: dict[str, Any], side: str, key: str, signed: bool = False) -> str:
    """A table cell: the mean over the episodes and, where the result has it, the half-width
    of its 95 % interval (``63.1 ± 2.3``)."""
    value = r[key] if side == "gap" else r[side][key]
    text = f"{value:+.1f}" if signed else f"{value:.1f}"
    ci = r.get("ci95", {}).get(side, {}).get(key)
    return text if not ci else f"{text} ± {(ci[1] - ci[0]) / 2.0:.1f}"


def _rmse_cell(notes: dict[str, Any]) -> str:
    """The fit's RMSE at 1.5 A, or both pairs' (``CSDC / Bi-exp``) where both were refitted."""
    if "rmse_1p5A_n_csdc" in notes:
        return f"{notes['rmse_1p5A_n_csdc']:.0f} / {notes['rmse_1p5A_n_biexp']:.0f}"
    rmse = notes.get("rmse_1p5A_n")
    return "" if rmse is None else f"{rmse:.0f}"


def format_table(results: Sequence[dict[str, Any]], setting: str) -> str:
    """A setting's results as a Markdown table: per point the body first-mode VRE of both
    pairs and their gap, the body second-mode and bogie second-mode VREs (each ``mean ± half
    width of its 95 % interval over the episodes`` where the result has intervals), the mean
    force and current each delivered, and the fit's RMSE where the point has one."""
    head = ("| factor | point | CSDC m1 % | Bi-exp m1 % | gap m1 | CSDC m2 % | Bi-exp m2 % | "
            "CSDC bogie m2 % | Bi-exp bogie m2 % | CSDC mean abs F N | Bi-exp mean abs F N | "
            "CSDC I A | Bi-exp I A | fit RMSE 1.5 A N |")  # fmt: skip
    lines = [head, "| --- | --- |" + " ---: |" * 12]
    for r in results:
        if r["setting"] != setting:
            continue
        c, b = r["csdc"], r["biexp"]
        rmse = _rmse_cell(r["notes"])
        cells = [r["factor"], r["label"], _cell(r, "csdc", "vre_body_mode1_pct"),
                 _cell(r, "biexp", "vre_body_mode1_pct"),
                 _cell(r, "gap", "gap_body_mode1_pct", signed=True),
                 _cell(r, "csdc", "vre_body_mode2_pct"), _cell(r, "biexp", "vre_body_mode2_pct"),
                 _cell(r, "csdc", "vre_bogie_mode2_pct"),
                 _cell(r, "biexp", "vre_bogie_mode2_pct"),
                 f"{c['mean_abs_force_n']:.0f}", f"{b['mean_abs_force_n']:.0f}",
                 f"{c['mean_current_a']:.3f}", f"{b['mean_current_a']:.3f}",
                 rmse]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_tornado(results: Sequence[dict[str, Any]], path: Path) -> None:
    """The figure: per setting, each point's body first-mode VRE of both pairs (dots) and
    the gap Bi-exponential - CSDC (bar from the baseline's gap), with the paper's values; at
    the docs' width and fonts (:data:`capsule_env.plots.DOC_STYLE`), long point names on two
    lines."""
    import textwrap

    from capsule_env.plots import DOC_STYLE, DOC_WIDTH_IN, _pyplot

    plt = _pyplot()
    settings = [s for s in ("sim", "hils") if any(r["setting"] == s for r in results)]
    rows = {s: [r for r in results if r["setting"] == s] for s in settings}
    heights = [0.34 * len(rows[s]) + 0.9 for s in settings]
    with plt.rc_context(DOC_STYLE):
        fig, axes = plt.subplots(len(settings), 2, figsize=(DOC_WIDTH_IN, sum(heights)),
                                 squeeze=False, layout="constrained",
                                 gridspec_kw={"width_ratios": [1.2, 1], "height_ratios": heights})  # fmt: skip
        for row_axes, s in zip(axes, settings):
            _tornado_row(row_axes, s, rows[s], textwrap)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _xerr(rs: list[dict[str, Any]], side: str, key: str, x: np.ndarray) -> np.ndarray | None:
    """The error bars (2, n) of the 95 % intervals around ``x``, or None where a result has
    none (one episode, or a JSON from before the intervals)."""
    ci = [r.get("ci95", {}).get(side, {}).get(key) for r in rs]
    if not all(ci):
        return None
    lo, hi = np.array([c[0] for c in ci]), np.array([c[1] for c in ci])
    return np.vstack([x - lo, hi - x])


def _point_name(r: dict[str, Any], textwrap: Any) -> str:
    """A point's tick label: ``factor: label``, on two lines (at the colon) when long."""
    name = f"{r['factor']}: {r['label']}"
    return name if len(name) <= 44 else f"{r['factor']}:\n" + textwrap.fill(r["label"], 44)


def _tornado_row(row_axes: Any, s: str, rs: list[dict[str, Any]], textwrap: Any) -> None:
    """One setting's two panels of :func:`plot_tornado`."""
    y = np.arange(len(rs))[::-1]
    base = next((r for r in rs if r["factor"] == "baseline"), rs[0])
    ax = row_axes[0]
    for side, marker, name in (("csdc", "s", "Bouc-Wen + CSDC"), ("biexp", "o", "Bi-exponential")):
        x = np.array([r[side]["vre_body_mode1_pct"] for r in rs])
        ax.errorbar(x, y, xerr=_xerr(rs, side, "vre_body_mode1_pct", x), fmt=marker, ms=4,
                    elinewidth=0.7, capsize=1.5, label=name)  # fmt: skip
    for side, ls in (("csdc", "--"), ("biexp", ":")):
        if side in PAPER_VRE[s]:
            ax.axvline(PAPER_VRE[s][side], ls=ls, color="k", lw=0.8)
    ax.set_yticks(y, [_point_name(r, textwrap) for r in rs], fontsize=8)
    ax.set_ylim(-0.7, len(rs) - 0.3)
    ax.set_xlabel(f"{s}: body first-mode VRE (%)\npaper: dashed CSDC, dotted Bi-exp")
    ax.legend(loc="lower left")
    ax.grid(alpha=0.3)
    ax = row_axes[1]
    gaps = np.array([r["gap_body_mode1_pct"] for r in rs])
    g0 = base["gap_body_mode1_pct"]
    ax.barh(y, gaps - g0, left=g0, color=np.where(gaps >= g0, "tab:blue", "tab:red"))
    err = _xerr(rs, "gap", "gap_body_mode1_pct", gaps)
    if err is not None:
        ax.errorbar(gaps, y, xerr=err, fmt="none", ecolor="k", elinewidth=0.7, capsize=1.5)
    ax.axvline(g0, color="grey", lw=0.8)
    ax.axvline(PAPER_GAP[s], color="k", ls="--", lw=0.8)
    ax.set_yticks(y, [""] * len(rs))
    ax.set_ylim(-0.7, len(rs) - 0.3)
    ax.set_xlabel(f"{s}: gap Bi-exp - CSDC (points)\n95 % CI; dashed: paper's {PAPER_GAP[s]:.1f}")
    ax.grid(alpha=0.3)
