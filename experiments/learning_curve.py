"""Plot the learning curves of training runs (``evaluations.jsonl`` written by train.py).

    python experiments/learning_curve.py runs/three-seeds/seed0 runs/three-seeds/seed1 \
        --out docs/figures/learning_curve.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("runs", nargs="+", type=Path, help="training output folders")
    p.add_argument("--out", type=Path, default=Path("docs/figures/learning_curve.png"))
    args = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    refs = None
    for run in args.runs:
        rows = [json.loads(line) for line in (run / "evaluations.jsonl").read_text().splitlines()]
        steps = [r["num_timesteps"] / 1e6 for r in rows]
        axes[0].plot(steps, [r["wk_rms_body_acc_m_s2"] for r in rows], label=run.name)
        axes[1].plot(steps, [r["vre_body_mode1_pct"] for r in rows], label=run.name)
        meta = run / "best_model.json"
        if refs is None and meta.is_file():
            refs = json.loads(meta.read_text())["eval"].get("references")
    if refs:  # passive and Skyhook on the same evaluation seeds
        for name, figures in refs.items():
            for key, ax in (("wk_rms_body_acc_m_s2", axes[0]), ("vre_body_mode1_pct", axes[1])):
                if key in figures:
                    value = figures[key]
                    ax.axhline(value, ls="--", lw=1, color="k" if name == "passive" else "C3")
                    ax.annotate(name, (0, value), fontsize=8, va="bottom")
    axes[0].set_ylabel("ISO Wk-weighted RMS body acceleration (m/s^2)")
    axes[1].set_ylabel("car-body first-mode VRE (%)")
    for ax in axes:
        ax.set_xlabel("environment steps (millions)")
        ax.legend(fontsize=8)
    fig.suptitle("PPO in hils: held-out evaluation during training (seeds 5000..5009)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
