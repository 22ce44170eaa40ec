"""The learned baselines of a task with rliable statistics (docs/learned-baselines.md).

    python experiments/learned_baselines.py \
        --group residual-ppo='runs/suite/rppo-seed*' --group ppo='runs/suite/ppo-seed*' \
        --json docs/figures/learned_baselines.json --plot docs/figures/learned_baselines.png
    python experiments/learned_baselines.py --task CapsuleTrip-v0 \
        --group ppo='runs/tasks30/trip-ppo-seed*' --json trip.json
    python experiments/learned_baselines.py --from-json docs/figures/learned_baselines.json \
        --plot docs/figures/learned_baselines.png      # redraw the figure only (runs nothing)

``--task ID`` (default ``CapsuleRide-v0``) names the registered task the runs were trained on:
its env options are the evaluation's (a run's own training options over them, as evaluate.py
runs a policy), and its references come from that task's evaluation file
(:attr:`capsule_env.tasks.Task.results`, the ``hils`` block; :data:`TASK_LAWS` lists the
classical laws read for each task and the files they are in).

Per training run (a ``train.py`` output folder): its ``best_model`` (chosen during training on
the VALIDATION bank, guideway seed 7, episodes 5000..5009) evaluated once on the EVALUATION
bank (guideway seed 2026, episodes 1000..1009, 10 s, ``hils``), the Wk-weighted RMS car-body
acceleration normalised between the passive damper (0) and the oracle (1) of that bank. A task
whose file has no oracle (the trip task until one is added) has no normalised score: its
statistics are computed on ``Wk_passive - Wk`` (m/s^2; the IQM and its interval are the same
runs' as for any affine score) and reported as Wk. Per group (an algorithm): the IQM of the
runs' scores with a 95 % stratified-bootstrap interval, the probability of improvement over
each of the task's classical laws (each a deterministic law: its one score entered as two
identical runs, so ``P`` is the share of runs above it, ties one half, with the bootstrap over
the learned runs), the IQM's Wk and its ratio to each law, the env steps and wall-clock
seconds of the runs. These intervals resample the seeds only, each run's Wk being its mean over
the same 10 episodes. Every law of the task is re-evaluated here episode by episode (the
first, the check law, must reproduce the file's figure: a check of the pipeline), each run's
Wk is kept per episode (``eval_wk_per_episode_m_s2``), and the IQM's ratio to each law gets a
paired interval over seeds AND episodes (:func:`capsule_env.evaluation.rl_statistics.
paired_ratio_interval`, the episodes drawn jointly for the group and the law):
``ratio_paired_to_LAW`` = ``{"value", "seeds_and_episodes", "seeds_only"}``.

Curves: the runs' training-time evaluations (``evaluations.jsonl``, validation bank) as the
normalised score on that bank, ``(passive - Wk) / (passive - oracle)`` with the passive damper
and the oracle of the same 10 validation episodes (:data:`VALIDATION_FILES`, ``evaluate.py
--env guideway_seed=7 --seed 5000 --oracle``; the check law's level drawn as a dashed line), or,
for a task without that file, as ``Wk(check law) / Wk`` (1: the law's level); IQM and interval
per evaluation step, against env steps and the runs' mean wall-clock seconds.
"""

from __future__ import annotations

import glob
import json
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
LAW = "lqr-clipped-biexp-meas"
MPC = "mpc-biexp-meas"
EPISODES, FIRST_SEED, LENGTH_S = 10, 1000, 10.0
VAL_EPISODES, VAL_FIRST_SEED = 10, 5000
TRIP_FILE = "evaluation-CapsuleTrip-v0.json"
# Per task, the file (docs/figures) with the passive damper and the oracle on the VALIDATION
# bank (guideway seed 7, episodes 5000..5009, 10 s): the curves' normalised score. The preview
# task's plant and guideway are the ride task's (the preview is an observation only).
VALIDATION_FILES = {"CapsuleRide-v0": "validation-CapsuleRide-v0.json",
                    "CapsuleRidePreview-v0": "validation-CapsuleRide-v0.json",
                    "CapsuleTrip-v0": "validation-CapsuleTrip-v0.json"}  # fmt: skip
# Per task, the classical laws whose evaluation-bank Wk is read (name: file under docs/figures,
# its hils block); the first is the check law re-evaluated here and the curves' reference.
TASK_LAWS: dict[str, dict[str, str]] = {
    "CapsuleRide-v0": {LAW: "evaluation.json", MPC: "mpc_evaluation.json"},
    "CapsuleRidePreview-v0": {"preview-lq-biexp-meas": "evaluation.json",
                              "preview-mpc-biexp-meas": "mpc_evaluation.json"},
    "CapsuleTrip-v0": {"lqr-sched-biexp-meas": TRIP_FILE, MPC: TRIP_FILE, LAW: TRIP_FILE},
}  # fmt: skip


def _references(task_id: str = "CapsuleRide-v0") -> dict[str, float]:
    """Evaluation-bank Wk (m/s^2) of the passive damper, the oracle (absent when the task's file
    has none) and the task's laws (:data:`TASK_LAWS`), from the ``hils`` blocks."""
    from capsule_env.tasks import task_named

    figures = ROOT / "docs" / "figures"
    wk = "wk_rms_body_acc_m_s2"

    def block(name: str) -> dict:
        return json.loads((figures / name).read_text())["settings"]["hils"]["controllers"]

    own = block(task_named(task_id).results)
    refs = {"passive": own["passive"][wk]}
    if "oracle" in own:
        refs["oracle"] = own["oracle"][wk]
    refs.update({law: block(name)[law][wk] for law, name in TASK_LAWS[task_id].items()})
    return refs


def _wk_episodes(policy, guideway_seed: int, episodes: int, first_seed: int,
                 task: dict) -> list[float]:  # fmt: skip
    """Wk of ``policy`` on each episode of the task's options ``task``, its own over them."""
    from capsule_env import metrics
    from capsule_env.evaluation.episodes import run_episodes

    kwargs = {**task, **policy.env_kwargs, "setting": "hils", "guideway_seed": guideway_seed}
    rollout = run_episodes(policy, kwargs, episodes, first_seed, LENGTH_S)
    acc = rollout.signals["car_body_acceleration_m_s2"]
    return [float(w) for w in metrics.wk_weighted_rms(acc, rollout.dt_s)]


def _validation_references(task_id: str) -> tuple[float, float] | None:
    """(passive, oracle) Wk on the validation bank from :data:`VALIDATION_FILES`, or None
    where the file is absent or has no oracle; ``ValueError`` if the file was made on other
    episodes than train.py's evaluations (guideway seed 7, seeds 5000..5009, 10 s)."""
    name = VALIDATION_FILES.get(task_id, "")
    path = ROOT / "docs" / "figures" / name
    if not name or not path.is_file():
        return None
    data = json.loads(path.read_text())
    condition = data["condition"]
    made_on = (condition["env_kwargs"].get("guideway_seed"), data["seeds"], data["episodes"],
               condition["episode_length_s"])  # fmt: skip
    wanted = (7, [VAL_FIRST_SEED, VAL_FIRST_SEED + VAL_EPISODES - 1], VAL_EPISODES, LENGTH_S)
    if made_on != wanted:
        raise ValueError(f"{name}: made on (guideway seed, seeds, episodes, length) {made_on}, "
                         f"not the validation bank's {wanted}")  # fmt: skip
    block = data["settings"]["hils"]["controllers"]
    if "oracle" not in block:
        return None
    wk = "wk_rms_body_acc_m_s2"
    return block["passive"][wk], block["oracle"][wk]


def normalised(wk, refs: tuple[float, float]):
    """``(passive - wk) / (passive - oracle)`` with ``refs = (passive, oracle)``."""
    passive, oracle = refs
    return (passive - np.asarray(wk, dtype=float)) / (passive - oracle)


def _machine() -> str:
    """The CPU's model name and core count (``/proc/cpuinfo`` where there is one)."""
    import os

    info = Path("/proc/cpuinfo")
    names = [line.split(":", 1)[1].strip() for line in
             (info.read_text().splitlines() if info.is_file() else [])
             if line.startswith("model name")]  # fmt: skip
    return f"{names[0] if names else platform.machine()}, {os.cpu_count()} cores"


def _run_record(folder: Path, task: dict) -> dict:
    """One training run: evaluation-bank Wk of its best model, validation Wk, steps, wall."""
    from capsule_env.agents.learning.sb3_policy import load_policy

    from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED

    best = json.loads((folder / "best_model.json").read_text())
    final_path = folder / "final_model.json"
    final = json.loads(final_path.read_text()) if final_path.is_file() else best
    lines = (folder / "evaluations.jsonl").read_text().splitlines()
    curve = [json.loads(line) for line in lines if line.strip()]
    policy = load_policy(folder / "best_model.zip")
    per_episode = _wk_episodes(policy, EVALUATION_GUIDEWAY_SEED, EPISODES, FIRST_SEED, task)
    return {
        "folder": str(folder),
        "seed": best.get("seed"),
        "residual": best.get("residual"),
        "env_kwargs": best.get("env_kwargs"),
        "eval_wk_m_s2": float(np.mean(per_episode)),
        "eval_wk_per_episode_m_s2": per_episode,
        "validation_wk_m_s2": best["best"]["wk_rms_body_acc_m_s2"],
        "best_at_timesteps": best["best"]["num_timesteps"],
        "num_timesteps": final["num_timesteps"],
        "wall_time_s": final["wall_time_s"],
        "finished": final_path.is_file(),
        "curve": [(c["num_timesteps"], c["wall_time_s"], c["wk_rms_body_acc_m_s2"]) for c in curve],
    }


def _law_wk(law: str, guideway_seed: int, episodes: int, first_seed: int,
            task: dict) -> list[float]:  # fmt: skip
    """The law's Wk on each episode."""
    from capsule_env.agents.controllers.classical import make_controller

    return _wk_episodes(make_controller(law), guideway_seed, episodes, first_seed, task)


def _paired_ratios(runs: list[dict], law_episodes: dict[str, list[float]]) -> dict:
    """Per law, the group's IQM Wk over the law's on the same episodes with paired intervals
    over seeds and episodes and over seeds alone; empty unless every run has its Wk per
    episode on the law's episodes (JSONs made before these were kept)."""
    from capsule_env.evaluation.rl_statistics import paired_ratio_interval

    per_episode = [r.get("eval_wk_per_episode_m_s2") for r in runs]
    out = {}
    for law, law_wk in law_episodes.items():
        if any(p is None or len(p) != len(law_wk) for p in per_episode):
            continue
        both = paired_ratio_interval(np.array(per_episode), np.array(law_wk))
        seeds = paired_ratio_interval(np.array(per_episode), np.array(law_wk), resample="seeds")
        out[f"ratio_paired_to_{law}"] = {"value": both.value,
                                         "seeds_and_episodes": [both.low, both.high],
                                         "seeds_only": [seeds.low, seeds.high]}  # fmt: skip
    return out


def _statistics(records: dict[str, list[dict]], refs: dict[str, float], laws: list[str],
                law_episodes: dict[str, list[float]] | None = None) -> dict:  # fmt: skip
    """Per group: IQM score and Wk with 95 % intervals, ratio to and P(improvement) over each
    of ``laws``; the normalised score when ``refs`` has an oracle, else ``Wk_passive - Wk``
    (m/s^2) underneath and ``iqm_score`` None; with ``law_episodes`` (each law's Wk per
    evaluation episode) the paired seeds x episodes ratios of :func:`_paired_ratios`."""
    from capsule_env.evaluation.rl_statistics import iqm, probability_of_improvement

    passive, oracle = refs["passive"], refs.get("oracle")
    span = passive - oracle if oracle is not None else 1.0
    if not span > 0.0:
        raise ValueError(f"the passive Wk ({passive}) must exceed the oracle's ({oracle})")

    def score(wk) -> np.ndarray:
        return (passive - np.asarray(wk, dtype=float)) / span

    def to_wk(s: float) -> float:
        return passive - s * span

    scores = {g: score([[r["eval_wk_m_s2"]] for r in rs]) for g, rs in records.items()}
    out = {}
    for group, est in iqm(scores).items():
        normalised = oracle is not None
        row = {"runs": len(records[group]), "iqm_score": est.value if normalised else None,
               "iqm_ci95": [est.low, est.high] if normalised else None,
               "iqm_wk_m_s2": to_wk(est.value), "iqm_wk_ci95_m_s2": [to_wk(est.high),
               to_wk(est.low)], "scores": scores[group][:, 0].tolist() if normalised else None,
               "eval_wk_m_s2": [r["eval_wk_m_s2"] for r in records[group]]}  # fmt: skip
        for law in laws:
            poi = probability_of_improvement(scores[group], np.full((2, 1), score(refs[law])))
            row[f"p_improvement_over_{law}"] = [poi.value, poi.low, poi.high]
            row[f"ratio_to_{law}"] = to_wk(est.value) / refs[law]
        row.update(_paired_ratios(records[group], law_episodes or {}))
        row["env_steps"] = [r["num_timesteps"] for r in records[group]]
        row["wall_time_s"] = [r["wall_time_s"] for r in records[group]]
        out[group] = row
    return out


def _curves(records: dict[str, list[dict]], law_val_wk: float,
            val_refs: tuple[float, float] | None = None) -> dict:  # fmt: skip
    """Per group, the IQM and interval of the runs' training-time evaluations (validation
    bank) at the steps every run evaluated: the normalised score ``(passive - Wk) / (passive -
    oracle)`` with the validation bank's ``val_refs``, else ``Wk(law) / Wk``."""
    from capsule_env.evaluation.rl_statistics import iqm_curves

    out = {}
    for group, rs in records.items():
        steps = sorted(set.intersection(*(set(c[0] for c in r["curve"]) for r in rs)))
        if len(rs) < 2 or not steps:
            continue
        table = [{c[0]: c for c in r["curve"]} for r in rs]
        wk = np.array([[run[s][2] for s in steps] for run in table])
        wall = np.array([[run[s][1] for s in steps] for run in table])
        score = law_val_wk / wk if val_refs is None else normalised(wk, val_refs)
        est = iqm_curves({group: score[:, None, :]})[group]
        out[group] = {"env_steps": steps, "mean_wall_s": wall.mean(axis=0).tolist(),
                      "iqm": est[0].tolist(), "low": est[1].tolist(), "high": est[2].tolist()}  # fmt: skip
    return out


def _plot(curves: dict, path: Path, law: str = LAW, law_level: float | None = None) -> None:
    """The curves against env steps and wall-clock seconds (log axes: the groups' budgets span
    200k to 4M steps); ``law_level``: the law's normalised score on the validation bank
    (normalised curves), None for ``Wk(law)/Wk``. The y axis spans the IQMs (intervals below
    them are cut at 0.1 under the lowest IQM: early evaluations of some runs are far below).
    Groups past the tenth colour are dash-dotted; one legend below the panels (the docs' width
    and fonts, :data:`capsule_env.plots.DOC_STYLE`)."""
    from matplotlib.ticker import NullFormatter

    from capsule_env.plots import DOC_STYLE, DOC_WIDTH_IN, _pyplot

    plt = _pyplot()
    with plt.rc_context(DOC_STYLE):
        rows = -(-(len(curves) + 1) // 3)
        fig, axes = plt.subplots(1, 2, figsize=(DOC_WIDTH_IN, 3.6 + 0.22 * rows), sharey=True,
                                 layout="constrained")  # fmt: skip
        for k, (group, c) in enumerate(curves.items()):
            style = {"color": f"C{k % 10}", "ls": "-" if k < 10 else "-."}
            for ax, x in zip(axes, (np.array(c["env_steps"]) / 1e6, c["mean_wall_s"]), strict=True):
                ax.plot(x, c["iqm"], label=group, **style)
                ax.fill_between(x, c["low"], c["high"], alpha=0.25, color=style["color"])
        for ax, label in zip(axes, ("env steps (millions)", "wall-clock s (mean of the runs)"),
                             strict=True):  # fmt: skip
            ax.axhline(1.0 if law_level is None else law_level, color="k", lw=0.8, ls="--",
                       label=law if ax is axes[0] else None)  # fmt: skip
            ax.set_xlabel(label)
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())  # decades labelled, not every minor tick
            ax.grid(alpha=0.3, which="both")
        values = [v for c in curves.values() for v in c["iqm"]]
        if values:
            reference = 1.0 if law_level is None else law_level
            top = max([reference, *(v for c in curves.values() for v in c["high"])])
            axes[0].set_ylim(min([reference, *values]) - 0.1, top + 0.05)
        axes[0].set_ylabel(f"Wk({law}) / Wk, validation bank" if law_level is None
                           else "normalised score, validation bank")  # fmt: skip
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=3)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _redraw(source: Path, plot: Path | None) -> int:
    """``--from-json``: the figure of a JSON this script wrote, to ``plot``; nothing is run."""
    if plot is None:
        print("learned_baselines.py: error: --from-json needs --plot PNG", file=sys.stderr)
        return 2
    try:
        result = json.loads(source.read_text())
        refs = result.get("validation_passive_oracle_wk_m_s2")
        level = None if refs is None else float(normalised(result["law_validation_wk_m_s2"], refs))
        curves, law = result["curves"], result["laws"][0]
    except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
        print(f"learned_baselines.py: error: --from-json {source}: not a JSON this script "
              f"wrote ({type(exc).__name__}: {exc})", file=sys.stderr)  # fmt: skip
        return 2
    _plot(curves, plot, law, level)
    return 0


def _summary(result: dict, laws: list[str]) -> list[str]:
    """One line per group (score when normalised, Wk, ratio to and P over the best law)."""
    refs = result["references_eval_wk_m_s2"]
    best = min(laws, key=lambda law: refs[law])
    lines = []
    for group, row in result["statistics"].items():
        score = ("" if row["iqm_score"] is None else f"IQM score {row['iqm_score']:.3f} "
                 f"[{row['iqm_ci95'][0]:.3f}, {row['iqm_ci95'][1]:.3f}], ")  # fmt: skip
        lo, hi = row["iqm_wk_ci95_m_s2"]
        paired = row.get(f"ratio_paired_to_{best}")
        both = ("" if paired is None else ", paired over seeds and episodes [{:.3f}, {:.3f}]"
                .format(*paired["seeds_and_episodes"]))  # fmt: skip
        lines.append(f"{group}: {score}IQM Wk {row['iqm_wk_m_s2']:.4f} [{lo:.4f}, {hi:.4f}] = "
                     f"{row[f'ratio_to_{best}']:.3f} x {best}{both}, P(> {best}) "
                     f"{row[f'p_improvement_over_{best}'][0]:.2f}")  # fmt: skip
    check = laws[0]
    lines.append(f"{check} re-evaluated {result['law_check_eval_wk_m_s2']:.4f} (file "
                 f"{refs[check]:.4f}); validation {result['law_validation_wk_m_s2']:.4f}")  # fmt: skip
    return lines


def _groups(items: list[str]) -> dict[str, list[Path]] | None:
    groups = {}
    for item in items:
        name, sep, pattern = item.partition("=")
        folders = sorted(
            Path(f) for f in glob.glob(pattern) if (Path(f) / "best_model.zip").is_file()
        )
        if not sep or len(folders) < 2:
            print(f"learned_baselines.py: error: --group {item!r} must be NAME=GLOB matching >= 2 "
                  "run folders with a best_model.zip", file=sys.stderr)  # fmt: skip
            return None
        groups[name] = folders
    return groups


def _parse(argv: list[str] | None) -> tuple[Any, Any]:
    """The command line's arguments, and the parser (for usage errors in one line)."""
    from capsule_env.common.cli import ArgumentParser  # usage errors in one line

    p = ArgumentParser(prog="learned_baselines.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--group", action="append", metavar="NAME=GLOB",
                   help="an algorithm's run folders (repeatable; required unless --from-json)")  # fmt: skip
    p.add_argument("--task", default="CapsuleRide-v0", metavar="ID",
                   help=f"the runs' task, one of {', '.join(TASK_LAWS)} (default CapsuleRide-v0)")  # fmt: skip
    p.add_argument("--json", type=Path, help="the result (required unless --from-json)")
    p.add_argument("--plot", type=Path)
    p.add_argument("--from-json", type=Path, metavar="PATH",
                   help="redraw --plot from a --json this script wrote (runs nothing)")  # fmt: skip
    return p.parse_args(argv), p


def main(argv: list[str] | None = None) -> int:
    args, p = _parse(argv)
    if args.from_json is not None:
        return _redraw(args.from_json, args.plot)
    if not args.group or args.json is None:
        p.error("--group and --json are required (or --from-json PATH --plot PNG)")
    if args.task not in TASK_LAWS:
        print(f"learned_baselines.py: error: --task must be one of {', '.join(TASK_LAWS)}, got "
              f"{args.task!r}", file=sys.stderr)  # fmt: skip
        return 2
    groups = _groups(args.group)
    if groups is None:
        return 2
    from capsule_env.agents.learning.sb3_policy import use_one_torch_thread

    from capsule_env.common.safe_io import atomic_write_text
    from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, VALIDATION_GUIDEWAY_SEED
    from capsule_env.tasks import task_named

    try:  # before any evaluation: a validation file made on other episodes
        val_refs = _validation_references(args.task)
    except ValueError as error:
        print(f"learned_baselines.py: error: {error}", file=sys.stderr)
        return 2
    use_one_torch_thread()
    task, laws = dict(task_named(args.task).kwargs), list(TASK_LAWS[args.task])
    refs = _references(args.task)
    law_episodes = {law: _law_wk(law, EVALUATION_GUIDEWAY_SEED, EPISODES, FIRST_SEED, task)
                    for law in laws}  # fmt: skip
    law_eval = float(np.mean(law_episodes[laws[0]]))
    law_val = float(np.mean(_law_wk(laws[0], VALIDATION_GUIDEWAY_SEED, VAL_EPISODES,
                                    VAL_FIRST_SEED, task)))  # fmt: skip
    records = {g: [_run_record(f, task) for f in fs] for g, fs in groups.items()}
    law_level = None if val_refs is None else float(normalised(law_val, val_refs))
    result = {"task": args.task, "laws": laws, "references_eval_wk_m_s2": refs,
              "law_check_eval_wk_m_s2": law_eval, "law_validation_wk_m_s2": law_val,
              "laws_eval_wk_per_episode_m_s2": law_episodes, "machine": _machine(),
              "statistics": _statistics(records, refs, laws, law_episodes),
              "validation_passive_oracle_wk_m_s2": val_refs,
              "curves_score": "wk_law_over_wk" if val_refs is None else "normalised",
              "curves": _curves(records, law_val, val_refs), "runs": records}  # fmt: skip
    atomic_write_text(args.json, json.dumps(result, indent=1) + "\n")
    if args.plot:
        _plot(result["curves"], args.plot, laws[0], law_level)
    print("\n".join(_summary(result, laws)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
