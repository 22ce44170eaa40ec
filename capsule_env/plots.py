"""Figures: the evaluation (the paper's Figures 10 and 11 analogues, damper loops under
control) and the damper-model identification (the paper's Figures 4 to 7 analogues)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.common.safe_io import StagedFiles
from capsule_env.dampers import damper_force
from capsule_env.identification.loops import Loop, check_loops, group_by_current
from capsule_env.identification.predict import predict_force
from capsule_env.identification.results import MODEL_NAMES, IdentificationResult
from capsule_env.metrics import DEFAULT_BANDS_HZ, amplitude_spectrum

#: Controllers drawn in the paper's figures (others are drawn if these are absent).
FIGURE_CONTROLLERS = ("passive", "skyhook-csdc", "skyhook-biexp")

#: The width (inches) of the figures shown in the docs. furo shows an image at most 736 px
#: wide (its content column in a 1280 px window), so an 8-inch figure is shown at 92 px per
#: inch and :data:`DOC_STYLE`'s smallest font (8 pt) is 10 px tall there
#: (``tests/test_figures_legible.py`` checks every figure of the docs).
DOC_WIDTH_IN = 8.0
#: Font sizes (pt) of the docs' figures: nothing under 8 pt at :data:`DOC_WIDTH_IN`.
DOC_STYLE = {
    "font.size": 9.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 9.0,
    "xtick.labelsize": 8.5,
    "ytick.labelsize": 8.5,
    "legend.fontsize": 8.0,
    "legend.title_fontsize": 8.5,
    "figure.titlesize": 10.5,
}


def _pyplot(force: bool = True) -> Any:
    """``matplotlib.pyplot`` on the Agg backend (``force``: as :func:`matplotlib.use`)."""
    import matplotlib

    matplotlib.use("Agg", force=force)
    import matplotlib.pyplot as plt

    return plt


def evaluation_figures(rollouts: dict[tuple[str, str], Any], directory: Path) -> list[Path]:
    """Write the figures for every setting in ``rollouts`` (keyed ``(setting, controller)``):
    ``{setting}_time_history.png``, ``{setting}_spectra.png`` and
    ``{setting}_force_velocity.png``; returns the written paths."""
    plt = _pyplot()
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for setting in sorted({s for s, _ in rollouts}):
        names = [n for (s, n) in rollouts if s == setting]
        shown = [n for n in FIGURE_CONTROLLERS if n in names] or names[:3]
        shown += [n for n in names if n not in shown and n.startswith("ppo")]
        runs = {name: rollouts[(setting, name)] for name in shown}
        with plt.rc_context(DOC_STYLE):
            figures = {
                "time_history": _time_history_figure(plt, setting, runs),
                "spectra": _spectra_figure(plt, setting, runs),
                "force_velocity": _force_velocity_figure(plt, setting, runs),
            }
        for kind, fig in figures.items():
            written.append(_save(fig, directory / f"{setting}_{kind}.png", plt))
    return written


def _time_history_figure(plt: Any, setting: str, runs: dict[str, Any]) -> Any:
    """The paper's Figure 10: body and bogie displacements of the first episode."""
    fig, axes = plt.subplots(2, 1, figsize=(DOC_WIDTH_IN, 5.6), sharex=True,
                             layout="constrained")  # fmt: skip
    for name, r in runs.items():
        t = np.arange(r.signals["car_body_displacement_m"].shape[1]) * r.dt_s
        axes[0].plot(t, 1e3 * r.signals["car_body_displacement_m"][0], label=name, lw=1)
        axes[1].plot(t, 1e3 * r.signals["bogie_displacement_m"][0], label=name, lw=1)
    axes[0].set_ylabel("car body displacement (mm)")
    axes[1].set_ylabel("bogie displacement (mm)")
    axes[1].set_xlabel("time (s)")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center",
               ncols=min(len(runs), 3))  # fmt: skip
    fig.suptitle(f"{setting}: time histories, first guideway seed (paper Fig. 10/14)")
    return fig


def _spectra_figure(plt: Any, setting: str, runs: dict[str, Any]) -> Any:
    """The paper's Figure 11: amplitude spectra (mean over episodes) with the mode bands."""
    fig, axes = plt.subplots(1, 2, figsize=(DOC_WIDTH_IN, 3.6), layout="constrained")
    for name, r in runs.items():
        for ax, key in zip(axes, ("car_body_displacement_m", "bogie_displacement_m"), strict=True):
            f, a = amplitude_spectrum(r.signals[key], r.dt_s)
            ax.plot(f, 1e3 * a.mean(axis=0), label=name, lw=1)
    for ax, title in zip(axes, ("car body", "bogie"), strict=True):
        for lo, hi in DEFAULT_BANDS_HZ.values():
            ax.axvspan(lo, hi, color="0.9", zorder=0)
        ax.set_xlim(0, 10)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("amplitude (mm)")
        ax.set_title(f"{title} displacement spectrum")
    axes[0].legend()
    fig.suptitle(f"{setting}: frequency domain, shaded: mode bands (paper Fig. 11/15)")
    return fig


def _force_velocity_figure(plt: Any, setting: str, runs: dict[str, Any]) -> Any:
    """Damper force against stroke rate (first episode) of each controller but the passive
    one, three panels a row; one legend, in the last row's spare panel or below."""
    from matplotlib.ticker import MaxNLocator

    controlled = [n for n in runs if n != "passive"] or list(runs)
    cols = min(len(controlled), 3)
    rows = -(-len(controlled) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(DOC_WIDTH_IN, 0.6 + 2.6 * rows),
                             layout="constrained", squeeze=False)  # fmt: skip
    spare = list(axes.flat[len(controlled) :])  # the first holds the legend, if any
    for ax in spare[1:]:
        ax.remove()
    legend: dict[str, Any] = {}
    for ax, name in zip(axes.flat, controlled):
        sig = runs[name].signals
        (dot,) = ax.plot(sig["stroke_rate_m_s"][0], 1e-3 * sig["damper_force_n"][0], ".", ms=1.5)
        legend.setdefault("delivered", dot)
        if runs[name].action_mode == "force":
            (dot,) = ax.plot(sig["stroke_rate_m_s"][0], 1e-3 * sig["desired_force_n"][0], ".",
                             ms=1.0, alpha=0.5)  # fmt: skip
            legend.setdefault("requested", dot)
        ax.set_title(name)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.set_xlabel("stroke rate (m/s)")
        ax.set_ylabel("damper force (kN)")
    if spare:
        spare[0].set_axis_off()
        spare[0].legend(legend.values(), legend.keys(), loc="center", markerscale=8)
    else:
        fig.legend(legend.values(), legend.keys(), loc="outside lower center", ncols=2,
                   markerscale=8)  # fmt: skip
    fig.suptitle(f"{setting}: damper force vs stroke rate under control (first episode)")
    return fig


def _save(fig: Any, path: Path, plt: Any) -> Path:
    """``fig`` into ``path`` atomically (a Ctrl-C or a full disk during the save leaves the
    earlier figure, not a cut-off PNG), closed; the format is ``path``'s suffix."""
    try:
        with StagedFiles() as staged:
            fig.savefig(staged.temp_for(path), dpi=110, format=Path(path).suffix[1:] or "png")
    finally:
        plt.close(fig)
    return path


# ---------------------------------------------------------------------------- identification
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
    plt = _pyplot(force=False)
    loops = list(result.loops if loops is None else check_loops(loops))
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    currents, groups = group_by_current(loops)
    scale, unit = (1e-3, "kN") if result.peak_force_n >= 2e3 else (1.0, "N")
    paths: list[Path] = []
    for kind in ("velocity", "displacement"):
        fig = _fit_loops_figure(plt, result, currents, groups, kind, (scale, unit))
        paths.append(_save(fig, directory / f"{prefix}force_{kind}.png", plt))
    fig = _branches_figure(plt, result, currents, groups, (scale, unit))
    paths.append(_save(fig, directory / f"{prefix}top_current_branches.png", plt))
    if result.bi_exponential.currents_a.size > 1:
        fig = _trends_figure(plt, result)
        paths.append(_save(fig, directory / f"{prefix}bi_exponential_trends.png", plt))
    return paths


def _closed(loop: Loop) -> np.ndarray:
    """The sample order of ``loop``, a periodic loop closed for a continuous line."""
    idx = np.arange(loop.n_samples)
    return np.append(idx, 0) if loop.periodic else idx


def _fit_loops_figure(
    plt: Any,
    result: IdentificationResult,
    currents: np.ndarray,
    groups: list[list[Loop]],
    kind: str,
    force_unit: tuple[float, str],
) -> Any:
    """Force against stroke rate (``kind`` "velocity") or stroke ("displacement"): data
    (dots) and each model (lines), one panel per model, every current."""
    scale, unit = force_unit
    xlabel = "stroke rate v (m/s)" if kind == "velocity" else "stroke x (mm)"
    cmap = plt.get_cmap("viridis")
    colours = [cmap(k / max(len(currents) - 1, 1)) for k in range(len(currents))]
    where = f"at {result.rmse_current_a:g} A" if len(currents) > 1 else "(whole record)"
    single = len(currents) == 1
    fig, axes = plt.subplots(1, len(MODEL_NAMES), figsize=(5.2 * len(MODEL_NAMES), 4.4),
                             sharey=True, constrained_layout=True)  # fmt: skip
    for ax, name in zip(axes, MODEL_NAMES):
        fit = result.models[name]
        for colour, i, group in zip(colours, currents, groups):
            for n, loop in enumerate(group):
                model = predict_force(fit.damper, loop)
                idx = _closed(loop)
                xs = loop.stroke_rate_m_s if kind == "velocity" else loop.stroke_m * 1e3
                step = max(1, loop.n_samples // (250 if loop.periodic else 3000))
                ax.plot(xs[::step], loop.force_n[::step] * scale, ".", ms=2.5,
                        color="0.45" if single else colour, alpha=0.5,
                        label=("data" if single else f"data {i:g} A") if n == 0 else None)  # fmt: skip
                ax.plot(xs[idx], model[idx] * scale, "-", lw=1.1,
                        color="tab:red" if single else colour,
                        label="model" if single and n == 0 else None)  # fmt: skip
        ax.set_title(f"{_MODEL_LABELS[name]}: RMSE {fit.rmse_n:.1f} N {where}")
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel(f"damper force F ({unit})")
    axes[0].legend(fontsize=7, loc="upper left", title="dots: data, lines: model",
                   title_fontsize=7, framealpha=0.9)  # fmt: skip
    fig.suptitle(f"Force-{kind} loops, data vs identified models ({result.source})")
    return fig


def _branches_figure(
    plt: Any,
    result: IdentificationResult,
    currents: np.ndarray,
    groups: list[list[Loop]],
    force_unit: tuple[float, str],
) -> Any:
    """The loop at the reporting current split by the sign of the stroke, with the
    Bi-exponential branches (Figures 4 and 7)."""
    scale, unit = force_unit
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
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    at = f"at {i_top:g} A" if result.current_known else "(current unknown)"
    fig.suptitle(f"Loop {at} split by the sign of the stroke; Bi-exponential RMSE "
                 f"{result.models['bi_exponential'].rmse_n:.1f} N ({result.source})")  # fmt: skip
    return fig


def _trends_figure(plt: Any, result: IdentificationResult) -> Any:
    """Bi-exponential a, b, c, d against current: free per-current fits (top, Figure 5) and
    the refit at the chosen d with its linear laws (bottom, Figure 6), and branch RMSEs."""
    trends = result.bi_exponential
    units = {"a": "a (N)", "b": "b (N s/m)", "c": "c (N)", "d": "d (s/m)"}
    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5), constrained_layout=True)
    ii = trends.currents_a
    fine = np.linspace(ii.min(), ii.max(), 50)
    styles = (("upper", "tab:red", "o", 9), ("lower", "tab:blue", "s", 4))
    for branch, colour, marker, size in styles:
        mfc = "none" if size > 5 else colour
        row = trends.table[branch]
        for col, p in enumerate("abcd"):
            ax = axes[0, col]
            ax.plot(ii, trends.free[branch][p], marker + "-", color=colour, ms=size,
                    mfc=mfc, label=branch)  # fmt: skip
            if p == "d":
                ax.axhline(row["d"], color=colour, ls="--",
                           label=f"{branch} mean {row['d']:.4g}")  # fmt: skip
            ax.set_title(f"free fit: {units[p]}")
        for col, p in enumerate("abc"):
            ax = axes[1, col]
            ax.plot(ii, trends.fixed_d[branch][p], marker, color=colour, ms=size, mfc=mfc,
                    label=f"{branch}, d = {row['d']:.4g}")  # fmt: skip
            ax.plot(fine, row[f"{p}0"] + row[f"{p}1"] * fine, "-", color=colour,
                    label=_law_label(p, row))  # fmt: skip
            ax.set_title(f"fixed d: {units[p]}")
        axes[1, 3].plot(ii, trends.fixed_d[branch]["rmse_n"], marker + "-", color=colour,
                        ms=size, mfc=mfc, label=f"{branch}, fixed d")  # fmt: skip
        axes[1, 3].plot(ii, trends.free[branch]["rmse_n"], marker + ":", color=colour,
                        ms=size, mfc=mfc, label=f"{branch}, free d")  # fmt: skip
    axes[1, 3].set_title("branch RMSE (N) per current")
    for ax in axes.flat:
        ax.set_xlabel("current i (A)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(
        "Bi-exponential parameters vs current: free per-current fits (top, paper Fig. 5) "
        f"and refit at the {result.d_rule} d with linear laws (bottom, Fig. 6 / Table 2)"
    )
    return fig


def _law_label(p: str, row: dict[str, float]) -> str:
    """Legend text of a linear law ``p = p0 + p1 i`` (used by :func:`plot_fits`)."""
    return f"{p} = {row[p + '0']:.4g} + {row[p + '1']:.4g} i"


# ----------------------------------------------------------------------------- Pareto fronts
#: Each law family's name in words and colour (the ideal-sensor and measured versions share it).
_FAMILIES = {
    "skyhook": ("on-off Skyhook", "tab:blue"),
    "skyhook-cont": ("continuous Skyhook", "tab:orange"),
    "hybrid": ("hybrid Skyhook-groundhook", "tab:green"),
    "add": ("acceleration-driven damper (ADD)", "tab:red"),
    "sh-add": ("mixed Skyhook-ADD", "tab:purple"),
    "lqr-clipped": ("clipped-optimal LQR", "tab:brown"),
    "preview-lq": ("LQ optimal preview", "tab:pink"),
    "mpc": ("semi-active MPC", "tab:olive"),
    "preview-mpc": ("semi-active preview MPC", "tab:cyan"),
}
#: The swept gains in words, with the unit of their range in the legend.
_GAIN_WORDS = {
    "c_sky_n_s_m": ("Skyhook gain c_sky", "N s/m"),
    "i_on_a": ("on-current i_on", "A"),
    "r_force_1_kg2": ("force weight r", "1/kg²"),
    "alpha_s": ("crossover alpha", "s"),
    "alpha_rel": ("Skyhook share alpha", ""),
}
#: Markers of the single points: open-loop references, then learned policies.
_POINT_MARKERS = {"open loop": "osv^", "policy": "DPXh"}


def _family(name: str) -> str:
    base = name.removesuffix("-meas")
    for tag in ("-biexp", "-csdc", "-tanh"):
        base = base.removesuffix(tag)
    return base


def _family_labels(laws: dict[str, dict]) -> dict[str, str]:
    """Each law family's legend entry (family key -> text): the family in words and its laws
    (``name(-meas)``: with ideal sensors and measured), then the gain swept and its range."""
    members: dict[str, list[str]] = {}
    for name in laws:
        members.setdefault(_family(name), []).append(name)
    labels = {}
    for family, names in members.items():
        words, _ = _FAMILIES.get(family, (family, "tab:gray"))
        shown = [n for n in names if not (n.endswith("-meas") and n[:-5] in names)]
        shown = [f"{n}(-meas)" if f"{n}-meas" in names else n for n in shown]
        gains = sorted({laws[n]["swept_gain"] for n in names})
        gain, unit = (
            _GAIN_WORDS.get(gains[0], (gains[0], "")) if len(gains) == 1 else (", ".join(gains), "")
        )
        values = [v for n in names for v in laws[n]["values"]]
        swept = f"{gain} {min(values):.3g} to {max(values):.3g} {unit}".rstrip()
        labels[family] = f"{words}: {', '.join(shown)}\n  {swept}"
    return labels


def pareto_figure(data: dict[str, Any], path: Path) -> Path:
    """The comfort trade-offs of ``experiments/pareto.py``'s ``data``: Wk-weighted RMS body
    acceleration against the body's first-mode VRE (top left; top right: a zoom on the tuned
    laws and the policies) and against the worst ``max |stroke|`` (bottom left). Each law's
    gain sweep is a curve (measured: solid, ideal sensors: dashed; a circle at the swept
    gain's lowest value) with its tuned gains starred; open-loop references and learned
    policies are points, each with its own marker. The points' legend is beside the stroke
    panel, the laws' legend (one entry per family, by colour) below the panels: no text on the
    axes, so nothing overlaps. :data:`DOC_WIDTH_IN` wide, in :data:`DOC_STYLE`."""
    import textwrap

    plt = _pyplot()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with plt.rc_context(DOC_STYLE):
        fig, axes = plt.subplot_mosaic([["vre", "zoom"], ["stroke", "points"]],
                                       figsize=(DOC_WIDTH_IN, 9.6), layout="constrained")  # fmt: skip
        top = 1.03 * max(max(law["wk_rms_body_acc_m_s2"]) for law in data["laws"].values())
        handles: dict[str, Any] = {}
        panels = (("vre", "vre_body_mode1_pct", 1.0, "body first-mode VRE (%), higher: smaller peak"),
                  ("stroke", "max_stroke_m", 1e3, "worst max |stroke| over the episodes (mm)"))  # fmt: skip
        for name, key, scale, label in panels:
            ax = axes[name]
            _draw_sweeps(ax, data["laws"], key, scale)
            _draw_points(ax, data["points"], key, scale, top, handles)
            ax.set_ylim(top=top)
            ax.set_xlabel(label)
            ax.set_ylabel("ISO 2631-1 Wk-weighted RMS body\nacceleration (m/s²), lower: better")
            ax.grid(alpha=0.3)
        if data.get("stroke_limit_m"):
            x_mm = 1e3 * data["stroke_limit_m"]
            axes["stroke"].axvline(x_mm, color="0.3", ls=":", lw=1)
            axes["stroke"].text(x_mm, top, "tuning's stroke limit ", rotation=90, va="top",
                                ha="right", color="0.3")  # fmt: skip
        _zoom(axes["vre"], axes["zoom"], data)
        _pareto_legends(fig, axes["points"], data["laws"], handles)
        seeds = data["seeds"]
        fig.suptitle(textwrap.fill(
            f"{data['setting']}: each tuned law with one gain swept over its search range, the "
            f"others at their tuned values; EVALUATION bank (guideway_seed "
            f"{data['guideway_seed']}, seeds {seeds[0]}..{seeds[-1]}), for this figure only. "
            "Stars: the gains tuned on the TRAINING bank (guideway_seed 0); the stroke limit of "
            "that tuning dotted.", 100))  # fmt: skip
    return _save(fig, path, plt)


def _draw_sweeps(ax: Any, laws: dict[str, dict], key: str, scale: float) -> None:
    """Each law's sweep (its tuned point starred, its lowest gain circled) against ``key``."""
    for name, law in laws.items():
        _, colour = _FAMILIES.get(_family(name), (name, "tab:gray"))
        x = scale * np.asarray(law[key], dtype=float)
        y = np.asarray(law["wk_rms_body_acc_m_s2"])
        style = "-" if law["observation"] == "measured" else "--"
        ax.plot(x, y, style, color=colour, lw=1.5, marker=".", ms=4)
        low = int(np.argmin(law["values"]))
        ax.plot(x[low], y[low], "o", color=colour, mfc="white", ms=6)
        k = law["tuned_index"]
        ax.plot(x[k], y[k], "*", color=colour, ms=13, mec="black", mew=0.8)


def _zoom(ax: Any, zoom: Any, data: dict[str, Any]) -> None:
    """``zoom`` magnifies the tuned gains and the learned policies of the VRE panel ``ax``
    (every star and policy below the passive damper's Wk), its box drawn on ``ax``."""
    wk_passive = data["points"].get("passive", {}).get("wk_rms_body_acc_m_s2", np.inf)
    xy = [
        (
            law["vre_body_mode1_pct"][law["tuned_index"]],
            law["wk_rms_body_acc_m_s2"][law["tuned_index"]],
        )
        for law in data["laws"].values()
    ]
    xy += [(p["vre_body_mode1_pct"], p["wk_rms_body_acc_m_s2"])
           for p in data["points"].values() if p["kind"] == "policy"]  # fmt: skip
    xy = np.array([(x, y) for x, y in xy if x is not None and y < wk_passive - 0.005])
    if len(xy) < 2:
        zoom.remove()
        return
    _draw_sweeps(zoom, data["laws"], "vre_body_mode1_pct", 1.0)
    _draw_points(zoom, data["points"], "vre_body_mode1_pct", 1.0, np.inf, {})
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    zoom.set_xlim(x0 - 0.08 * (x1 - x0), x1 + 0.08 * (x1 - x0))
    zoom.set_ylim(y0 - 0.1 * (y1 - y0), y1 + 0.1 * (y1 - y0))
    zoom.grid(alpha=0.3)
    zoom.set_title("zoom (grey box): tuned gains, policies")
    zoom.set_xlabel("body first-mode VRE (%)")
    (lo_x, hi_x), (lo_y, hi_y) = zoom.get_xlim(), zoom.get_ylim()
    ax.indicate_inset((lo_x, lo_y, hi_x - lo_x, hi_y - lo_y), edgecolor="0.4")


def _draw_points(ax: Any, points: dict[str, dict], key: str, scale: float, top: float,
                 handles: dict[str, Any]) -> None:  # fmt: skip
    """The open-loop references and the learned policies, each with its own marker; a point
    above ``top`` (Wk) is left off the axes and its legend entry says so."""
    used = {"open loop": 0, "policy": 0}
    for name, point in points.items():
        kind = "policy" if point["kind"] == "policy" else "open loop"
        marker = _POINT_MARKERS[kind][used[kind] % len(_POINT_MARKERS[kind])]
        used[kind] += 1
        y = point["wk_rms_body_acc_m_s2"]
        x = scale * (point.get(key) or 0.0)  # passive: no VRE against itself
        colour = "black" if kind == "policy" else "0.45"
        (dot,) = ax.plot(x if y <= top else [], y if y <= top else [], marker, color=colour,
                         mfc="none" if kind == "policy" else colour, mew=1.6, ms=9, ls="none")  # fmt: skip
        reads = point["observation"].replace("full_state", "ideal sensors").replace("+", " + ")
        label = (
            f"{name}: learned policy,\n  reads {reads}"
            if kind == "policy"
            else f"{name}: open loop"
        )
        handles.setdefault(label + (f" (off scale:\n  Wk {y:.3f})" if y > top else ""), dot)


def _pareto_legends(fig: Any, ax: Any, laws: dict[str, dict], handles: dict[str, Any]) -> None:
    """The points and the markers' key in ``ax`` (its axes hidden); the law families by
    colour below the panels."""
    from matplotlib.lines import Line2D

    key = {
        "tuned gains (training bank)": Line2D(
            [], [], ls="none", marker="*", color="0.5", mec="black", ms=12
        ),  # fmt: skip
        "swept gain's lowest value": Line2D(
            [], [], ls="none", marker="o", color="0.5", mfc="white", ms=6
        ),  # fmt: skip
        "solid: measured signals": Line2D([], [], color="0.3", lw=1.5),
        "dashed: ideal sensors": Line2D([], [], color="0.3", lw=1.5, ls="--"),
    }
    ax.set_axis_off()
    entries = {**handles, **key}
    ax.legend(entries.values(), entries.keys(), loc="center left", borderaxespad=0.0,
              title="points and key", alignment="left")  # fmt: skip
    families = _family_labels(laws)
    lines = [Line2D([], [], color=_FAMILIES.get(f, (f, "tab:gray"))[1], lw=2.5) for f in families]
    fig.legend(lines, families.values(), loc="outside lower center", ncols=2,
               title="gain sweeps of the tuned laws (colour: the law)", alignment="left")  # fmt: skip
