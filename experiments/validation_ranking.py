"""Would the validation bank, averaged over each group's seeds, choose the group the evaluation
bank ranks first?

    python experiments/validation_ranking.py docs/figures/learned_baselines.json \
        docs/figures/learned_baselines-CapsuleRidePreview-v0.json \
        docs/figures/learned_baselines-CapsuleTrip-v0.json --json ranking.json

The searches of issue 30 ran one seed per point on the validation bank (guideway bank 7), and
their picks did not hold over five seeds: the spread between seeds was larger than the
differences between points. This script asks the question with the rows that exist: each
group of ``experiments/learned_baselines.py``'s JSON (5 or 10 seeds, one configuration) has,
per run, the validation Wk of its best checkpoint (``validation_wk_m_s2``) and its Wk on the
evaluation bank (``eval_wk_m_s2``). Per task it reports:

- each group's mean over its seeds on both banks;
- the group the validation means choose and the group with the lowest evaluation mean;
- the Spearman rank correlation of the two orderings (``scipy.stats.spearmanr``).

A group's validation figure is the best of its evaluations during training, so it is biased
low, by a similar amount for every group (each run evaluated 4-20 times). The ranking is the
question, not the level. Bad input (a file that is not such a JSON): one line, exit status 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env._cli import ArgumentParser  # noqa: E402


def group_means(runs: dict[str, list[dict]]) -> dict[str, dict]:
    """Per group: seeds, mean validation Wk and mean evaluation Wk (m/s^2). Runs without a
    validation figure are left out of both means, so each group's two means use one set."""
    out = {}
    for name, group in runs.items():
        kept = [r for r in group if r.get("validation_wk_m_s2") is not None]
        if not kept:
            continue
        out[name] = {"seeds": len(kept),
                     "validation_mean_m_s2": float(np.mean([r["validation_wk_m_s2"] for r in kept])),
                     "evaluation_mean_m_s2": float(np.mean([r["eval_wk_m_s2"] for r in kept]))}  # fmt: skip
    return out


def ranking(means: dict[str, dict]) -> dict:
    """The validation's choice, the evaluation's best and the Spearman correlation."""
    from scipy.stats import spearmanr

    names = sorted(means, key=lambda k: means[k]["validation_mean_m_s2"])
    validation = [means[k]["validation_mean_m_s2"] for k in names]
    evaluation = [means[k]["evaluation_mean_m_s2"] for k in names]
    rho = spearmanr(validation, evaluation).statistic if len(names) > 2 else float("nan")
    return {"by_validation": names, "validation_choice": names[0],
            "evaluation_best": min(names, key=lambda k: means[k]["evaluation_mean_m_s2"]),
            "spearman": float(rho)}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="validation_ranking.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", type=Path, help="learned_baselines JSON files")
    parser.add_argument("--json", type=Path, help="write the results here (atomically)")
    args = parser.parse_args(argv)
    from capsule_env.safe_io import atomic_write_text, check_writable_file

    results = {}
    try:
        if args.json is not None:
            check_writable_file(args.json, "--json")
        for path in args.files:
            try:
                data = json.loads(path.read_text())
            except ValueError as exc:
                raise ValueError(f"{path}: not JSON ({exc})") from None
            if not isinstance(data, dict) or not isinstance(data.get("runs"), dict):
                raise ValueError(f"{path}: not a learned_baselines JSON (no 'runs' object)")
            means = group_means(data["runs"])
            if len(means) < 2:
                raise ValueError(f"{path}: fewer than 2 groups with validation figures")
            results[data.get("task") or path.stem] = {"groups": means, **ranking(means)}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        parser.error(str(exc))
    for task, r in results.items():
        print(f"{task}: the validation means choose {r['validation_choice']}, the evaluation's "
              f"best is {r['evaluation_best']}; Spearman {r['spearman']:.3f}")  # fmt: skip
        for name in r["by_validation"]:
            g = r["groups"][name]
            print(f"  {g['validation_mean_m_s2']:.4f}  {g['evaluation_mean_m_s2']:.4f}  "
                  f"{name} ({g['seeds']} seeds)")  # fmt: skip
    if args.json is not None:
        command = "python experiments/validation_ranking.py " + " ".join(
            sys.argv[1:] if argv is None else argv)  # fmt: skip
        atomic_write_text(args.json, json.dumps({"command": command, "tasks": results}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
