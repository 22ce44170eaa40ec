"""The task cards of docs/tasks.md, generated from an evaluation's JSON file.

``python -m capsule_env.evaluation.task_cards docs/tasks.md`` rewrites the block between the page's
``<!-- generated: task cards -->`` markers, and the README's table of the tasks between its
``<!-- generated: readme tasks -->`` markers, from ``docs/figures/evaluation.json`` (written by
``evaluate.py --oracle --json``): per task, the Wk-weighted RMS car-body acceleration and the
normalised score of the passive damper, the task's best tuned classical law, its shipped policy
and the oracle, with what each reads. The declared vehicles' tasks that ``evaluate.py``
evaluates (``DECLARED_TASKS``: the half-car's, ``CapsuleHalfRide-v0`` and
``CapsuleHalfRidePreview-v0``) are carded from their own files, in its layout (``evaluate.py
--task ID --oracle --json``), with the comfort metric their card states (``Task.metric``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from capsule_env.common.safe_io import atomic_write_text
from capsule_env.tasks import DECLARED_TASKS, TASKS, Task, normalised_score

#: Every carded task: the quarter-car's, then the declared vehicles' (``evaluate.py --task``
#: evaluates each, their file in its layout): the half-car's, without and with the survey.
CARDED = TASKS + DECLARED_TASKS

__all__ = ["task_cards", "readme_table", "load_results", "sync_page"]


def _reads(row: dict) -> str:
    """What a results row reads: its observation, and its preview's horizon when it has one
    (a preview law reads its own, which may be longer than the task's)."""
    if not row["preview"]:
        return str(row["observation"])
    horizon_s = row.get("env_kwargs", {}).get("preview_horizon_s")
    return row["observation"] + (f" + preview ({horizon_s:g} s)" if horizon_s else " + preview")


def _card(task: Task, results: dict) -> list[str]:
    controllers = results["settings"][task.setting]["controllers"]
    needed = [task.best_classical, task.shipped_policy, "passive"]
    missing = [name for name in needed if name and name not in controllers]
    if missing:
        raise ValueError(f"{task.results} has no row {', '.join(missing)} for {task.env_id} "
                         "(an MPC row needs pip install 'capsule-env[mpc]' when it is made)")  # fmt: skip
    wk = {name: controllers[name]["wk_rms_body_acc_m_s2"] for name in controllers}
    has_oracle = "oracle" in wk
    rows = [("passive", "passive damper")]
    rows += [(task.best_classical, "best tuned classical law")]
    if task.shipped_policy:
        rows += [(task.shipped_policy, "shipped learned policy")]
    if has_oracle:
        rows += [("oracle", "clairvoyant search (a reference, not a law or a limit)")]
    metric = ("Wk-weighted RMS acceleration of the car body's floor, the mean of three points "
              "(the comfort metric below)") if task.metric else "Wk-weighted RMS car-body acceleration"  # fmt: skip
    lines = [f"## `{task.env_id}`", "", task.summary, "", f"- Reads: {task.reads}.",
             f"- Options: `{json.dumps(task.kwargs)}` (everything else the env's defaults).",
             f"- Reward: the env's (docs/env.md); reported metric: {metric} on guideway seeds "
             f"{results['seeds'][0]}..{results['seeds'][1]} (`docs/figures/{task.results}`).",
             *([f"- Comfort metric: {task.metric}."] if task.metric else []),
             f"- Use as the baseline: {task.use}",
             ""]  # fmt: skip
    floor_wk, floor_says = _floor(results["settings"][task.setting])
    if not has_oracle:
        lines += ["No normalised score: the results file has no oracle row (`evaluate.py "
                  "--oracle`), so the scale has no upper end.", ""]  # fmt: skip
    else:
        lines += [f"Bracket on the clairvoyant semi-active optimum: [{floor_wk:.4f}, "
                  f"{wk['oracle']:.4f}] m/s² (below: {floor_says}; above: the oracle, a "
                  "local search's best). Normalised score: passive 0, oracle 1; against the "
                  "floor: the share of the gap passive -> floor closed.", ""]  # fmt: skip
    lines += ["| controller | what it is | reads | Wk (m/s²) | normalised score | "
              "against the floor |", "|---|---|---|---|---|---|"]  # fmt: skip
    for name, what in rows:
        score = (
            f"{normalised_score(wk[name], wk['passive'], wk['oracle']):.3f}"
            if has_oracle
            else "n/a"
        )
        to_floor = (wk["passive"] - wk[name]) / (wk["passive"] - floor_wk)
        lines.append(f"| `{name}` | {what} | {_reads(controllers[name])} | {wk[name]:.4f} | "
                     f"{score} | {to_floor:.3f} |")  # fmt: skip
    return lines + [""]


def _floor(block: dict) -> tuple[float, str]:
    """The lower end of a card's bracket and what it is: the certified floor of the results
    (``evaluate.py --floor``) where it was run, else 0, which every Wk is above (the
    certified floor covers only the ``sim`` plant on episodes of at most 2.2 s, and there it
    proves 0: docs/fair-comparison.md)."""
    if "floor" in block:
        return float(block["floor"]["wk_rms_body_acc_m_s2"]), "the certified floor"
    return 0.0, (
        "0, the only floor proven for these episodes: the certified floor (`capsule_env.bounds`, "
        "docs/fair-comparison.md) covers the `sim` plant on episodes of at most 2.2 s, and "
        "there it proves 0 too"
    )


def load_results(folder: Path) -> dict[str, dict]:
    """Every evaluation file the tasks' cards read (``Task.results``), by file name, from
    ``folder`` (docs/figures)."""
    return {t.results: json.loads((folder / t.results).read_text()) for t in CARDED}


def task_cards(results: dict[str, dict]) -> str:
    """The task cards as Markdown, reference scores from ``evaluate.py --json`` files'
    contents by file name (:func:`load_results`; run with ``--oracle`` where the task allows)."""
    lines: list[str] = []
    for task in CARDED:
        lines += _card(task, results[task.results])
    return "\n".join(lines)


def _readme_cell(wk: dict[str, float], name: str) -> str:
    return f"{wk[name]:.4f} `{name}`" if name else "-"


def readme_table(results: dict[str, dict]) -> str:
    """The README's one table of the tasks: per task, the Wk (m/s²) of passive, the best tuned
    classical law, the shipped policy and the oracle, from the same files as the cards."""
    lines = ["| task | what it is | passive | best classical law | shipped policy | oracle |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for task in CARDED:
        rows = results[task.results]["settings"][task.setting]["controllers"]
        wk = {name: row["wk_rms_body_acc_m_s2"] for name, row in rows.items()}
        oracle = f"{wk['oracle']:.4f}" if "oracle" in wk else "-"
        lines.append(f"| `{task.env_id}` | {task.headline} | {wk['passive']:.4f} | "
                     f"{_readme_cell(wk, task.best_classical)} | "
                     f"{_readme_cell(wk, task.shipped_policy)} | {oracle} |")  # fmt: skip
    return "\n".join(lines)


BEGIN, END = "<!-- generated: task cards -->", "<!-- end generated: task cards -->"
README_BEGIN, README_END = (
    "<!-- generated: readme tasks -->",
    "<!-- end generated: readme tasks -->",
)


def _replace_block(page: Path, begin: str, end: str, block: str) -> bool:
    text = page.read_text()
    head, found, rest = text.partition(begin)
    if not found or end not in rest:
        raise ValueError(f"{page} has no block between {begin} and {end}")
    _, _, tail = rest.partition(end)
    new = f"{head}{begin}\n{block}\n{end}{tail}"
    if new != text:
        atomic_write_text(page, new)  # a Ctrl-C or full disk: the page as it was
    return new != text


def sync_page(page: Path, results_json: Path) -> bool:
    """Rewrite the generated block of ``page`` (docs/tasks.md); True when it changed."""
    cards = task_cards(load_results(results_json.parent))
    return _replace_block(page, BEGIN, END, f"\n{cards}")


def sync_readme(readme: Path, figures: Path) -> bool:
    """Rewrite the README's generated table of the tasks from ``figures``; True when changed."""
    return _replace_block(readme, README_BEGIN, README_END, readme_table(load_results(figures)))


def main(argv: list[str] | None = None) -> int:
    """``python -m capsule_env.evaluation.task_cards [docs/tasks.md [README.md]]``: rewrite the
    cards and the README's table; a missing file or folder: one line, exit status 2."""
    from capsule_env.common.cli import ArgumentParser  # errors: one line, exit status 2

    p = ArgumentParser(prog="python -m capsule_env.evaluation.task_cards",
                       description="Rewrite docs/tasks.md's task cards and the README's "
                       "table of the tasks from docs/figures/*.json.")  # fmt: skip
    p.add_argument("page", nargs="?", type=Path, default=Path("docs/tasks.md"))
    p.add_argument("readme", nargs="?", type=Path, default=None)
    args = p.parse_args(argv)
    figures = args.page.parent / "figures"
    readme = args.readme or args.page.parent.parent / "README.md"
    for path in (args.page, readme, figures):
        if not path.exists():
            p.error(f"{path} does not exist (give docs/tasks.md, and README.md beside docs/)")
    try:
        changed = sync_page(args.page, figures / "evaluation.json")
        print(("updated " if changed else "unchanged ") + str(args.page))
        print(("updated " if sync_readme(readme, figures) else "unchanged ") + str(readme))
    except (OSError, ValueError, KeyError) as exc:
        p.error(f"cannot make the cards: {exc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
