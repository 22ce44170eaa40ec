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

- each group's mean over its seeds on both banks, and how many times its runs were evaluated
  during training;
- the group the validation means choose, the group with the lowest evaluation mean and the
  one with the lowest evaluation IQM (the JSON's ``statistics``, when it has them);
- the Spearman rank correlation of the two orderings (``scipy.stats.spearmanr``; null for
  fewer than 3 groups);
- how often **one** seed per group would choose the group with the lowest evaluation mean:
  ``--draws`` (20,000) draws of one run per group (fixed seed), the group of the lowest
  validation figure chosen in each.

A run's validation figure is the best of its evaluations during training, so it is biased
low, and more so for a run evaluated more often (3 to 21 times in the issue-30 rows): a group
of long runs gains from it. The ranking is the question, not the level. Bad input (a file that
is not such a JSON, a run without a finite figure): one line naming the file, exit status 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.common.cli import ArgumentParser  # noqa: E402

#: The seed of the one-seed draws (fixed: the figures are reproducible).
DRAW_SEED = 20261126


def _figure(run: Any, key: str, where: str, optional: bool = False) -> float | None:
    """``run[key]`` as a finite float (None allowed when ``optional``); ``ValueError`` naming
    ``where`` and ``key`` otherwise."""
    value = run.get(key) if isinstance(run, dict) else "(not an object)"
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ValueError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)


def paired_figures(runs: Any, where: str) -> dict[str, np.ndarray]:
    """Per group, the runs with a validation figure as rows ``(validation, evaluation)``
    (m/s^2); ``ValueError`` naming the group and run of a bad one."""
    if not isinstance(runs, dict):
        raise ValueError(f"{where}: 'runs' must be an object of groups")
    out = {}
    for name, group in runs.items():
        if not isinstance(group, list):
            raise ValueError(f"{where}: group {name!r} must be a list of runs")
        rows = []
        for k, run in enumerate(group):
            at = f"{where}: group {name!r}, run {k}"
            validation = _figure(run, "validation_wk_m_s2", at, optional=True)
            evaluation = _figure(run, "eval_wk_m_s2", at)
            if validation is not None:
                rows.append((validation, evaluation))
        if rows:
            out[name] = np.array(rows)
    return out


def group_means(figures: dict[str, np.ndarray]) -> dict[str, dict]:
    """Per group: seeds, mean validation Wk and mean evaluation Wk (m/s^2), over the runs that
    have both (so each group's two means use one set)."""
    return {name: {"seeds": len(rows), "validation_mean_m_s2": float(rows[:, 0].mean()),
                   "evaluation_mean_m_s2": float(rows[:, 1].mean())}
            for name, rows in figures.items()}  # fmt: skip


def one_seed_rate(figures: dict[str, np.ndarray], best: str, draws: int, seed: int) -> float:
    """The share of ``draws`` draws of one run per group in which the group with the lowest
    validation figure is ``best``."""
    rng = np.random.default_rng(seed)
    names = list(figures)
    picks = np.stack([figures[n][rng.integers(0, len(figures[n]), draws), 0] for n in names])
    chosen = np.argmin(picks, axis=0)
    return float(np.mean(chosen == names.index(best)))


def ranking(means: dict[str, dict]) -> dict:
    """The validation's choice, the evaluation's best and the Spearman correlation."""
    from scipy.stats import spearmanr

    names = sorted(means, key=lambda k: means[k]["validation_mean_m_s2"])
    validation = [means[k]["validation_mean_m_s2"] for k in names]
    evaluation = [means[k]["evaluation_mean_m_s2"] for k in names]
    rho = float(spearmanr(validation, evaluation).statistic) if len(names) > 2 else None
    return {"by_validation": names, "validation_choice": names[0],
            "evaluation_best": min(names, key=lambda k: means[k]["evaluation_mean_m_s2"]),
            "spearman": rho}  # fmt: skip


def evaluations_per_run(runs: dict[str, list[dict]]) -> dict[str, list[int]]:
    """Per group, the fewest and most evaluations a run had during training (its ``curve``)."""
    counts = {name: [len(r.get("curve") or []) for r in group] for name, group in runs.items()}
    return {name: [min(c), max(c)] for name, c in counts.items() if c}


def task_result(path: Path, draws: int) -> tuple[str, dict]:
    """The task's name and its figures (the module docstring's list) from one JSON file."""
    try:
        data = json.loads(path.read_text())
    except ValueError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from None
    if not isinstance(data, dict) or "runs" not in data:
        raise ValueError(f"{path}: not a learned_baselines JSON (no 'runs' object)")
    figures = paired_figures(data["runs"], str(path))
    if len(figures) < 2:
        raise ValueError(f"{path}: fewer than 2 groups with validation figures")
    means = group_means(figures)
    result = {"groups": means, **ranking(means)}
    statistics = data.get("statistics") if isinstance(data.get("statistics"), dict) else {}
    iqm = {k: v["iqm_wk_m_s2"] for k, v in statistics.items()
           if k in means and isinstance(v, dict) and "iqm_wk_m_s2" in v}  # fmt: skip
    result["evaluation_best_iqm"] = min(iqm, key=iqm.__getitem__) if iqm else None
    result["one_seed_choice_rate"] = one_seed_rate(figures, result["evaluation_best"], draws,
                                                   DRAW_SEED)  # fmt: skip
    result["draws"] = draws
    result["evaluations_per_run"] = evaluations_per_run(data["runs"])
    return str(data.get("task") or path.stem), result


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="validation_ranking.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", type=Path, help="learned_baselines JSON files")
    parser.add_argument("--draws", type=int, default=20_000, help="one-seed draws (1..10**6)")
    parser.add_argument("--json", type=Path, help="write the results here (atomically)")
    args = parser.parse_args(argv)
    from capsule_env.common.safe_io import atomic_write_text, check_writable_file

    results: dict[str, dict] = {}
    try:
        if not 1 <= args.draws <= 10**6:
            raise ValueError(f"--draws must be in [1, 10**6], got {args.draws}")
        if args.json is not None:
            check_writable_file(args.json, "--json")
        for path in args.files:
            task, result = task_result(path, args.draws)
            if task in results:
                raise ValueError(f"{path}: task {task} is already in an earlier file")
            results[task] = result
    except (OSError, ValueError) as exc:
        parser.error(str(exc))
    for task, r in results.items():
        rho = "-" if r["spearman"] is None else f"{r['spearman']:.3f}"
        print(f"{task}: the validation means choose {r['validation_choice']}, the evaluation's "
              f"best mean is {r['evaluation_best']} (best IQM {r['evaluation_best_iqm']}); "
              f"Spearman {rho}; one seed per group chooses it in "
              f"{100 * r['one_seed_choice_rate']:.0f} % of {r['draws']} draws")  # fmt: skip
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
