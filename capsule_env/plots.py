"""Figures of the evaluation (the paper's Figures 10 and 11 analogues, damper loops)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.metrics import DEFAULT_BANDS_HZ, amplitude_spectrum

#: Controllers drawn in the paper's figures (others are drawn if these are absent).
FIGURE_CONTROLLERS = ("passive", "skyhook-csdc", "skyhook-biexp")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
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


def _save(fig, path: Path, plt) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
