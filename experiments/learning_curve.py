"""Plot the learning curves of training runs (``evaluations.jsonl`` written by train.py).

    python experiments/three_seeds.py        # trains runs/three-seeds/seed0..2 (about 2.5 min each)
    python experiments/learning_curve.py runs/three-seeds/seed0 runs/three-seeds/seed1 \
        runs/three-seeds/seed2 --out docs/figures/learning_curve.png \
        --json docs/figures/learning_curve.json
    python experiments/learning_curve.py --from-json docs/figures/learning_curve.json  # redraw

Left: the Wk-weighted RMS car-body acceleration of each evaluation during training; right: the
car-body first-mode vibration reduction effect. The dashed reference lines are the passive
damper and the reference Skyhook on the same evaluation episodes, as train.py measured them
(``best_model.json``: ``eval.references``), each labelled with its name and value in the legend;
the title names the evaluation episodes (``eval.guideway_seed`` and ``eval.seeds``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.common.safe_io import atomic_write_text  # noqa: E402

#: The reference lines' colours: the passive damper black, the others (train.py's reference
#: Skyhook) in turn from these, none of them a colour of the first three runs' curves.
REFERENCE_COLOURS = ("C3", "C4", "C5")
METRICS = (("wk_rms_body_acc_m_s2", "m/s²", ".4f"), ("vre_body_mode1_pct", "%", ".1f"))


def read_run(run: Path) -> tuple[list[dict], dict]:
    """A run's evaluations (``evaluations.jsonl``) and its ``best_model.json`` (``{}`` if none)."""
    rows = [json.loads(line) for line in (run / "evaluations.jsonl").read_text().splitlines()]
    meta = run / "best_model.json"
    return rows, json.loads(meta.read_text()) if meta.is_file() else {}


def collect(runs: list[Path]) -> dict:
    """The figure's data: each run's evaluations, and the first run's evaluation block
    (``best_model.json``'s ``eval``: its episodes and references) without its metrics."""
    data: dict = {"runs": {}, "eval": {}}
    for run in runs:
        rows, meta = read_run(run)
        data["runs"][run.name] = rows
        if not data["eval"] and meta.get("eval"):
            data["eval"] = {k: v for k, v in meta["eval"].items() if k != "metrics"}
    return data


def draw_references(axes: Any, refs: dict[str, dict]) -> None:
    """Each reference as a dashed line on the panels whose metric it has, labelled with its
    name and value (the legend shows them)."""
    others = iter(REFERENCE_COLOURS * len(refs))
    for name, figures in refs.items():
        colour = "k" if name == "passive" else next(others)
        for ax, (key, unit, fmt) in zip(axes, METRICS):
            if key in figures:
                label = f"{name} (reference): {figures[key]:{fmt}} {unit}"
                ax.axhline(figures[key], ls="--", lw=1.2, color=colour, label=label)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("runs", nargs="*", type=Path, help="training output folders")
    p.add_argument("--out", type=Path, default=Path("docs/figures/learning_curve.png"))
    p.add_argument("--json", type=Path, help="also write the plotted data here")
    p.add_argument("--from-json", type=Path, help="redraw from a --json file (no runs needed)")
    args = p.parse_args(argv)
    if args.from_json is not None:
        data = json.loads(args.from_json.read_text())
    else:
        missing = [str(r) for r in args.runs if not (r / "evaluations.jsonl").is_file()]
        if not args.runs or missing:
            sys.exit("learning_curve.py: error: give run folders holding evaluations.jsonl "
                     f"(missing in: {', '.join(missing) or 'no folder given'}) or --from-json")  # fmt: skip
        data = collect(args.runs)
    draw(data, args.out)
    print(f"wrote {args.out}")
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(data, indent=1))
        print(f"wrote {args.json}")
    return 0


def draw(data: dict, out: Path) -> None:
    """The two panels of ``data`` (:func:`collect`) with the reference lines, to ``out``; one
    legend below them (the docs' width and fonts: :data:`capsule_env.plots.DOC_STYLE`)."""
    import textwrap

    from capsule_env.plots import DOC_STYLE, DOC_WIDTH_IN, _pyplot

    plt = _pyplot()
    with plt.rc_context(DOC_STYLE):
        fig, axes = plt.subplots(1, 2, figsize=(DOC_WIDTH_IN, 5.2), layout="constrained")
        for name, rows in data["runs"].items():
            steps = [r["num_timesteps"] / 1e6 for r in rows]
            for ax, (key, _, _) in zip(axes, METRICS):
                ax.plot(steps, [r[key] for r in rows], label=name)
        evaluation = data["eval"]
        draw_references(axes, evaluation.get("references", {}))
        axes[0].set_ylabel("ISO 2631-1 Wk-weighted RMS\nbody acceleration (m/s²)")
        axes[1].set_ylabel("car-body first-mode VRE (%)")
        entries: dict[str, Any] = {}
        for ax in axes:
            ax.set_xlabel("environment steps (millions)")
            ax.grid(alpha=0.3)
            for handle, label in zip(*ax.get_legend_handles_labels()):
                entries.setdefault(label, handle)
        fig.legend(entries.values(), entries.keys(), loc="outside lower center", ncols=3)
        seeds = evaluation.get("seeds", ["?", "?"])
        fig.suptitle(textwrap.fill(
            f"PPO in hils: evaluation during training, guideway bank "
            f"{evaluation.get('guideway_seed', '?')}, seeds {seeds[0]}..{seeds[-1]} "
            "(the validation bank: not the evaluation bank the results tables use)", 90))  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
