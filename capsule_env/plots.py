"""Figures: the evaluation (the paper's Figures 10 and 11 analogues, damper loops under
control) and the damper-model identification (the paper's Figures 4 to 7 analogues)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.dampers import damper_force
from capsule_env.identification.loops import Loop, check_loops, group_by_current
from capsule_env.identification.predict import predict_force
from capsule_env.identification.results import MODEL_NAMES, IdentificationResult
from capsule_env.metrics import DEFAULT_BANDS_HZ, amplitude_spectrum

#: Controllers drawn in the paper's figures (others are drawn if these are absent).
FIGURE_CONTROLLERS = ("passive", "skyhook-csdc", "skyhook-biexp")


def _pyplot(force: bool = True) -> Any:
    """``matplotlib.pyplot`` on the Agg backend (``force``: as :func:`matplotlib.use`)."""
    import matplotlib

    matplotlib.use("Agg", force=force)
    import matplotlib.pyplot as plt

    return plt


def evaluation_figures(rollouts: dict[tuple[str, str], Any], directory: Path) -> list[Path]:
    """Write the figures for every setting in ``rollouts`` (keyed ``(setting, controller)``);
    returns the written paths."""
    plt = _pyplot()
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    settings = sorted({s for s, _ in rollouts})
    for setting in settings:
        names = [n for (s, n) in rollouts if s == setting]
        shown = [n for n in FIGURE_CONTROLLERS if n in names] or names[:3]
        extra = [n for n in names if n not in shown and n.startswith("ppo")]
        shown += extra
        # Figure 10: time histories (episode 0)
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
        for name in shown:
            r = rollouts[(setting, name)]
            t = np.arange(r.signals["car_body_displacement_m"].shape[1]) * r.dt_s
            axes[0].plot(t, 1e3 * r.signals["car_body_displacement_m"][0], label=name, lw=1)
            axes[1].plot(t, 1e3 * r.signals["bogie_displacement_m"][0], label=name, lw=1)
        axes[0].set_ylabel("car body displacement (mm)")
        axes[1].set_ylabel("bogie displacement (mm)")
        axes[1].set_xlabel("time (s)")
        axes[0].legend(loc="upper right", fontsize=8)
        fig.suptitle(f"{setting}: time histories, first guideway seed (paper Fig. 10/14)")
        written.append(_save(fig, directory / f"{setting}_time_history.png", plt))
        # Figure 11: amplitude spectra (mean over episodes) with the mode bands
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
        for name in shown:
            r = rollouts[(setting, name)]
            for ax, key in zip(
                axes, ("car_body_displacement_m", "bogie_displacement_m"), strict=True
            ):
                f, a = amplitude_spectrum(r.signals[key], r.dt_s)
                ax.plot(f, 1e3 * a.mean(axis=0), label=name, lw=1)
        for ax, title in zip(axes, ("car body", "bogie"), strict=True):
            for lo, hi in DEFAULT_BANDS_HZ.values():
                ax.axvspan(lo, hi, color="0.9", zorder=0)
            ax.set_xlim(0, 10)
            ax.set_xlabel("frequency (Hz)")
            ax.set_ylabel("amplitude (mm)")
            ax.set_title(f"{title} displacement spectrum (shaded: mode bands)")
        axes[0].legend(fontsize=8)
        fig.suptitle(f"{setting}: frequency domain (paper Fig. 11/15)")
        written.append(_save(fig, directory / f"{setting}_spectra.png", plt))
        # Damper force-velocity loops under control
        controlled = [n for n in shown if n != "passive"]
        fig, axes = plt.subplots(
            1, max(len(controlled), 1), figsize=(4.5 * max(len(controlled), 1), 4),
            constrained_layout=True, squeeze=False,
        )  # fmt: skip
        for ax, name in zip(axes[0], controlled, strict=False):
            r = rollouts[(setting, name)]
            ax.plot(r.signals["stroke_rate_m_s"][0], 1e-3 * r.signals["damper_force_n"][0],
                    ".", ms=1.5, label="delivered")  # fmt: skip
            if r.action_mode == "force":
                ax.plot(r.signals["stroke_rate_m_s"][0], 1e-3 * r.signals["desired_force_n"][0],
                        ".", ms=1.0, alpha=0.5, label="requested")  # fmt: skip
            ax.set_title(name)
            ax.set_xlabel("stroke rate (m/s)")
            ax.set_ylabel("damper force (kN)")
            ax.legend(fontsize=8, markerscale=6)
        fig.suptitle(f"{setting}: damper force vs stroke rate under control")
        written.append(_save(fig, directory / f"{setting}_force_velocity.png", plt))
    return written


def _save(fig: Any, path: Path, plt: Any) -> Path:
    fig.savefig(path, dpi=110)
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


def _sweep_label(name: str, law: dict[str, Any]) -> str:
    """A sweep's legend entry: the law and its signals in words, the gain swept and its range."""
    words, _ = _FAMILIES.get(_family(name), (name, "tab:gray"))
    signals = "measured" if law["observation"] == "measured" else "ideal sensors"
    gain, unit = _GAIN_WORDS.get(law["swept_gain"], (law["swept_gain"], ""))
    lo, hi = min(law["values"]), max(law["values"])
    return f"{words}, {signals} ({name}):\n  {gain} {lo:.3g} to {hi:.3g} {unit}".rstrip()


def pareto_figure(data: dict[str, Any], path: Path) -> Path:
    """The comfort trade-offs of ``experiments/pareto.py``'s ``data``: Wk-weighted RMS body
    acceleration against the body's first-mode VRE (left, with a zoom on the tuned laws and
    the policies) and against the worst ``max |stroke|`` (right). Each law's gain sweep is a
    curve (measured: solid, ideal sensors: dashed; a circle at the swept gain's lowest value)
    with its tuned gains starred; open-loop references and learned policies are points, each
    with its own marker in the legend (no text on the axes, so nothing overlaps)."""
    plt = _pyplot()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(15, 6.4), constrained_layout=True)
    panels = (("vre_body_mode1_pct", 1.0, "body first-mode VRE (%)   (higher: smaller peak)"),
              ("max_stroke_m", 1e3, "worst max |stroke| over the episodes (mm)"))  # fmt: skip
    top = 1.03 * max(max(law["wk_rms_body_acc_m_s2"]) for law in data["laws"].values())
    handles: dict[str, Any] = {}
    for ax, (key, scale, label) in zip(axes, panels, strict=True):
        _draw_sweeps(ax, data["laws"], key, scale, handles)
        _draw_points(ax, data["points"], key, scale, top, handles)
        ax.set_ylim(top=top)
        ax.set_xlabel(label)
        ax.set_ylabel("ISO 2631-1 Wk-weighted RMS body acceleration (m/s²)   (lower: better)")
        ax.grid(alpha=0.3)
    if data.get("stroke_limit_m"):
        x_mm = 1e3 * data["stroke_limit_m"]
        axes[1].axvline(x_mm, color="0.3", ls=":", lw=1)
        axes[1].text(x_mm, axes[1].get_ylim()[0], "tuning's stroke limit (training bank) ",
                     rotation=90, va="bottom", ha="right", fontsize=8, color="0.3")  # fmt: skip
    _zoom(axes[0], data, handles)
    _pareto_legend(axes[1], handles)
    seeds = data["seeds"]
    fig.suptitle(
        f"{data['setting']}: each tuned law with one gain swept over its search range, the others "
        f"at their tuned values; EVALUATION bank (guideway_seed {data['guideway_seed']}, seeds "
        f"{seeds[0]}..{seeds[-1]}), for this figure only.\nStars: the gains tuned on the TRAINING "
        "bank (guideway_seed 0). Solid: measured signals; dashed: ideal sensors; open circle: "
        "the swept gain's lowest value.",
        fontsize=10,
    )
    return _save(fig, path, plt)


def _draw_sweeps(ax: Any, laws: dict[str, dict], key: str, scale: float,
                 handles: dict[str, Any]) -> None:  # fmt: skip
    """Each law's sweep (its tuned point starred, its lowest gain circled) against ``key``."""
    for name, law in laws.items():
        _, colour = _FAMILIES.get(_family(name), (name, "tab:gray"))
        x = scale * np.asarray(law[key], dtype=float)
        y = np.asarray(law["wk_rms_body_acc_m_s2"])
        style = "-" if law["observation"] == "measured" else "--"
        (line,) = ax.plot(x, y, style, color=colour, lw=1.5, marker=".", ms=4)
        handles.setdefault(_sweep_label(name, law), line)
        low = int(np.argmin(law["values"]))
        ax.plot(x[low], y[low], "o", color=colour, mfc="white", ms=6)
        k = law["tuned_index"]
        ax.plot(x[k], y[k], "*", color=colour, ms=15, mec="black", mew=0.8)


def _zoom(ax: Any, data: dict[str, Any], handles: dict[str, Any]) -> None:
    """An inset (upper left of the VRE panel, where no curve runs) magnifying the tuned gains
    and the learned policies: every star and policy below the passive damper's Wk."""
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
        return
    inset = ax.inset_axes([0.13, 0.53, 0.44, 0.42])
    _draw_sweeps(inset, data["laws"], "vre_body_mode1_pct", 1.0, {})
    _draw_points(inset, data["points"], "vre_body_mode1_pct", 1.0, np.inf, {})
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    inset.set_xlim(x0 - 0.08 * (x1 - x0), x1 + 0.08 * (x1 - x0))
    inset.set_ylim(y0 - 0.1 * (y1 - y0), y1 + 0.1 * (y1 - y0))
    inset.tick_params(labelsize=7)
    inset.grid(alpha=0.3)
    inset.set_title("zoom: tuned gains and learned policies", fontsize=8)
    ax.indicate_inset_zoom(inset, edgecolor="0.4")


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
                         mfc="none" if kind == "policy" else colour, mew=1.6, ms=10, ls="none")  # fmt: skip
        reads = point["observation"].replace("full_state", "ideal sensors").replace("+", " + ")
        label = f"{name}: {'learned policy' if kind == 'policy' else 'open loop'}, reads {reads}"
        handles.setdefault(label + (f" (off scale: Wk {y:.3f})" if y > top else ""), dot)


def _pareto_legend(ax: Any, handles: dict[str, Any]) -> None:
    """One legend right of the panels: the sweeps, then the points, then the markers' key."""
    from matplotlib.lines import Line2D

    star = Line2D([], [], ls="none", marker="*", color="0.5", mec="black", ms=14)
    low = Line2D([], [], ls="none", marker="o", color="0.5", mfc="white", ms=6)
    entries = {**handles, "tuned gains (training bank)": star, "swept gain's lowest value": low}
    ax.legend(entries.values(), entries.keys(), fontsize=8, loc="upper left",
              bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, labelspacing=0.6)  # fmt: skip
