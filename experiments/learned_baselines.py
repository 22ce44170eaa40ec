"""The learned baselines on the ride task with rliable statistics (docs/learned-baselines.md).

    python experiments/learned_baselines.py \
        --group residual-ppo='runs/suite/rppo-seed*' --group ppo='runs/suite/ppo-seed*' \
        --json docs/figures/learned_baselines.json --plot docs/figures/learned_baselines.png

Per training run (a ``train.py`` output folder): its ``best_model`` (chosen during training on
the VALIDATION bank, guideway seed 7, episodes 5000..5009) evaluated once on the EVALUATION
bank (guideway seed 2026, episodes 1000..1009, 10 s, ``hils``), the Wk-weighted RMS car-body
acceleration normalised between the passive damper (0) and the oracle (1) of that bank
(``docs/figures/evaluation.json``'s ``hils`` block). Per group (an algorithm): the IQM of the
runs' scores with a 95 % stratified-bootstrap interval, the probability of improvement over the
clipped LQR and over the semi-active MPC (each a deterministic law: its one score entered as
two identical runs, so ``P`` is the share of runs above it, ties one half, with the bootstrap
over the learned runs), the IQM's Wk and its ratio to each law, the env steps and wall-clock
seconds of the runs. The clipped LQR is re-evaluated here on the same episodes as a check of
the pipeline (it must reproduce the file's figure).

Curves: the runs' training-time evaluations (``evaluations.jsonl``, validation bank) as the
score ``Wk(clipped LQR) / Wk`` (1: the LQR's level on the validation bank, higher is better),
IQM and interval per evaluation step, against env steps and the runs' mean wall-clock seconds.
"""

from __future__ import annotations

import argparse
import glob
import json
import platform
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
LAW = "lqr-clipped-biexp-meas"
MPC = "mpc-biexp-meas"
EPISODES, FIRST_SEED, LENGTH_S = 10, 1000, 10.0
VAL_EPISODES, VAL_FIRST_SEED = 10, 5000


def _references() -> dict[str, float]:
    """Evaluation-bank Wk (m/s^2) of passive, oracle, clipped LQR (evaluation.json, hils) and
    the semi-active MPC on measured signals (mpc_evaluation.json, hils)."""
    figures = ROOT / "docs" / "figures"
    hils = json.loads((figures / "evaluation.json").read_text())["settings"]["hils"]
    mpc = json.loads((figures / "mpc_evaluation.json").read_text())["settings"]["hils"]
    wk = "wk_rms_body_acc_m_s2"
    return {"passive": hils["controllers"]["passive"][wk],
            "oracle": hils["controllers"]["oracle"][wk],
            LAW: hils["controllers"][LAW][wk], MPC: mpc["controllers"][MPC][wk]}  # fmt: skip


def _wk(policy, guideway_seed: int, episodes: int, first_seed: int) -> float:
    from capsule_env.evaluation import episode_metrics, run_episodes

    kwargs = {**policy.env_kwargs, "setting": "hils", "guideway_seed": guideway_seed}
    rollout = run_episodes(policy, kwargs, episodes, first_seed, LENGTH_S)
    return float(episode_metrics(rollout, None)["wk_rms_body_acc_m_s2"])


def _machine() -> str:
    """The CPU's model name and core count (``/proc/cpuinfo`` where there is one)."""
    import os

    info = Path("/proc/cpuinfo")
    names = [line.split(":", 1)[1].strip() for line in
             (info.read_text().splitlines() if info.is_file() else [])
             if line.startswith("model name")]  # fmt: skip
    return f"{names[0] if names else platform.machine()}, {os.cpu_count()} cores"


def _run_record(folder: Path) -> dict:
    """One training run: evaluation-bank Wk of its best model, validation Wk, steps, wall."""
    from capsule_env.agents.sb3_policy import load_policy

    from capsule_env.evaluation import EVALUATION_GUIDEWAY_SEED

    best = json.loads((folder / "best_model.json").read_text())
    final_path = folder / "final_model.json"
    final = json.loads(final_path.read_text()) if final_path.is_file() else best
    lines = (folder / "evaluations.jsonl").read_text().splitlines()
    curve = [json.loads(line) for line in lines if line.strip()]
    policy = load_policy(folder / "best_model.zip")
    return {
        "folder": str(folder),
        "seed": best.get("seed"),
        "residual": best.get("residual"),
        "eval_wk_m_s2": _wk(policy, EVALUATION_GUIDEWAY_SEED, EPISODES, FIRST_SEED),
        "validation_wk_m_s2": best["best"]["wk_rms_body_acc_m_s2"],
        "best_at_timesteps": best["best"]["num_timesteps"],
        "num_timesteps": final["num_timesteps"],
        "wall_time_s": final["wall_time_s"],
        "finished": final_path.is_file(),
        "curve": [(c["num_timesteps"], c["wall_time_s"], c["wk_rms_body_acc_m_s2"]) for c in curve],
    }


def _law_wk(guideway_seed: int, episodes: int, first_seed: int) -> float:
    from capsule_env.agents.classical import make_controller

    return _wk(make_controller(LAW), guideway_seed, episodes, first_seed)


def _statistics(records: dict[str, list[dict]], refs: dict[str, float]) -> dict:
    from capsule_env.rl_statistics import iqm, normalised_scores, probability_of_improvement

    passive, oracle = np.array([refs["passive"]]), np.array([refs["oracle"]])

    def score(wk: float) -> float:
        return float(normalised_scores(np.array([[wk]]), passive, oracle)[0, 0])

    scores = {g: normalised_scores(np.array([[r["eval_wk_m_s2"]] for r in rs]), passive, oracle)
              for g, rs in records.items()}  # fmt: skip
    estimates = iqm(scores)
    out = {}
    for group, est in estimates.items():
        to_wk = lambda s: refs["passive"] - s * (refs["passive"] - refs["oracle"])  # noqa: E731
        row = {"runs": len(records[group]), "iqm_score": est.value,
               "iqm_ci95": [est.low, est.high], "iqm_wk_m_s2": to_wk(est.value),
               "iqm_wk_ci95_m_s2": [to_wk(est.high), to_wk(est.low)],
               "scores": scores[group][:, 0].tolist()}  # fmt: skip
        for law in (LAW, MPC):
            law_scores = np.full((2, 1), score(refs[law]))
            poi = probability_of_improvement(scores[group], law_scores)
            row[f"p_improvement_over_{law}"] = [poi.value, poi.low, poi.high]
            row[f"ratio_to_{law}"] = to_wk(est.value) / refs[law]
        rs = records[group]
        row["env_steps"] = [r["num_timesteps"] for r in rs]
        row["wall_time_s"] = [r["wall_time_s"] for r in rs]
        out[group] = row
    return out


def _curves(records: dict[str, list[dict]], law_val_wk: float) -> dict:
    from capsule_env.rl_statistics import iqm_curves

    out = {}
    for group, rs in records.items():
        steps = sorted(set.intersection(*(set(c[0] for c in r["curve"]) for r in rs)))
        if len(rs) < 2 or not steps:
            continue
        table = [{c[0]: c for c in r["curve"]} for r in rs]
        wk = np.array([[run[s][2] for s in steps] for run in table])
        wall = np.array([[run[s][1] for s in steps] for run in table])
        est = iqm_curves({group: (law_val_wk / wk)[:, None, :]})[group]
        out[group] = {"env_steps": steps, "mean_wall_s": wall.mean(axis=0).tolist(),
                      "iqm": est[0].tolist(), "low": est[1].tolist(), "high": est[2].tolist()}  # fmt: skip
    return out


def _plot(curves: dict, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for group, c in curves.items():
        for ax, x in zip(axes, (np.array(c["env_steps"]) / 1e6, c["mean_wall_s"]), strict=True):
            ax.plot(x, c["iqm"], label=group)
            ax.fill_between(x, c["low"], c["high"], alpha=0.25)
    for ax, label in zip(axes, ("env steps (millions)", "wall-clock s (mean of the runs)"),
                         strict=True):  # fmt: skip
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("Wk(clipped LQR) / Wk, validation bank")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--group",
        action="append",
        required=True,
        metavar="NAME=GLOB",
        help="an algorithm's run folders (repeatable)",
    )
    p.add_argument("--json", type=Path, required=True)
    p.add_argument("--plot", type=Path)
    args = p.parse_args(argv)
    groups = {}
    for item in args.group:
        name, sep, pattern = item.partition("=")
        folders = sorted(
            Path(f) for f in glob.glob(pattern) if (Path(f) / "best_model.zip").is_file()
        )
        if not sep or len(folders) < 2:
            print(f"learned_baselines.py: error: --group {item!r} must be NAME=GLOB matching >= 2 "
                  "run folders with a best_model.zip", file=sys.stderr)  # fmt: skip
            return 2
        groups[name] = folders
    from capsule_env.agents.sb3_policy import use_one_torch_thread

    from capsule_env.evaluation import EVALUATION_GUIDEWAY_SEED, VALIDATION_GUIDEWAY_SEED

    use_one_torch_thread()
    refs = _references()
    law_eval = _law_wk(EVALUATION_GUIDEWAY_SEED, EPISODES, FIRST_SEED)
    law_val = _law_wk(VALIDATION_GUIDEWAY_SEED, VAL_EPISODES, VAL_FIRST_SEED)
    records = {g: [_run_record(f) for f in fs] for g, fs in groups.items()}
    result = {"references_eval_wk_m_s2": refs, "law_check_eval_wk_m_s2": law_eval,
              "law_validation_wk_m_s2": law_val, "machine": _machine(),
              "statistics": _statistics(records, refs), "curves": _curves(records, law_val),
              "runs": records}  # fmt: skip
    from capsule_env.safe_io import atomic_write_text

    atomic_write_text(args.json, json.dumps(result, indent=1) + "\n")
    if args.plot:
        _plot(result["curves"], args.plot)
    for group, row in result["statistics"].items():
        print(
            f"{group}: IQM score {row['iqm_score']:.3f} [{row['iqm_ci95'][0]:.3f}, "
            f"{row['iqm_ci95'][1]:.3f}], Wk {row['iqm_wk_m_s2']:.4f} = "
            f"{row[f'ratio_to_{LAW}']:.3f} x LQR, P(> LQR) {row[f'p_improvement_over_{LAW}'][0]:.2f}"
        )
    print(f"LQR re-evaluated {law_eval:.4f} (file {refs[LAW]:.4f}); validation {law_val:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
