"""Choose the half-car policy to ship by its score on a validation bank.

    python experiments/half_car_select.py --out runs/half_car_select.json

Every saved seed of ``experiments/half_car_ppo.py``'s runs (``runs/half_car_ppo``, PPO from
scratch; ``runs/half_car_residual``, the residual on the per-bogie clipped LQR;
``runs/half_car_residual_mpc`` and ``runs/half_car_residual_mpc_lr1e-4``, the residual on the
wheelbase MPC at the learning rates 1e-3 and 1e-4, under the working folder; a run not on
disk is skipped, and none on disk is refused before anything is scored), its
deterministic policy (``final.zip`` with its normaliser), on the validation bank: guideway seed 7,
episodes 5000..5009 (the quarter-car tasks' validation bank), disjoint from the training bank
(guideway seed 0) and from ``evaluate.py``'s evaluation bank (guideway seed 2026, episodes
1000..1009), which plays no part in the choice. The run with the lowest mean headline Wk
(``wk_rms_body_acc_m_s2``, the floor's three points' mean) is chosen; the per-bogie LQR's score on
the same episodes is written beside it, and the wheelbase MPC's.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

VALIDATION_GUIDEWAY_SEED = 7
VALIDATION_EPISODES = list(range(5000, 5010))
_MPC = "wheelbase-mpc-biexp-meas"
#: group -> (run folder, residual, the residual's law).
RUNS = {"ppo": (Path("runs/half_car_ppo"), False, None),
        "residual-ppo": (Path("runs/half_car_residual"), True, "lqr-clipped-biexp-meas"),
        "residual-ppo-mpc": (Path("runs/half_car_residual_mpc"), True, _MPC),
        "residual-ppo-mpc-lr1e-4": (Path("runs/half_car_residual_mpc_lr1e-4"), True, _MPC)}  # fmt: skip


def _score(policy: object) -> list[float]:
    from capsule_env.evaluation.half_car import episode_metrics, rollout

    roll = rollout(policy, VALIDATION_EPISODES, VALIDATION_GUIDEWAY_SEED)
    return episode_metrics(roll)["wk_rms_body_acc_m_s2"].tolist()


def _record_problem() -> str:
    """A run folder whose ``run.json`` (``half_car_ppo.py``'s record) says it was trained
    otherwise than :data:`RUNS` scores it (another law under its networks); ``""`` if none."""
    from half_car_ppo import RUN_RECORD, read_record

    for group, (folder, residual, law) in RUNS.items():
        try:
            recorded = read_record(folder)
        except ValueError as exc:
            return str(exc)
        if recorded is not None and (recorded.get("residual"), recorded.get("law")) != (
            residual, law
        ):  # fmt: skip
            return (f"{folder / RUN_RECORD} records residual={recorded.get('residual')!r}, "
                    f"law={recorded.get('law')!r}; {group} is scored as residual={residual!r}, "
                    f"law={law!r}")  # fmt: skip
    return ""


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, type=Path, help="the JSON file to write")
    args = p.parse_args(argv)
    if not args.out.resolve().parent.is_dir():
        p.exit(2, f"error: --out's folder must exist, got {args.out}\n")
    if args.out.is_dir():
        p.exit(2, f"error: --out must name the JSON file to write, got the folder {args.out}\n")
    if not any(any(folder.glob("seed*/final.zip")) for folder, _, _ in RUNS.values()):
        p.exit(2, "error: no saved run (seed*/final.zip) in "
                  f"{', '.join(str(folder) for folder, _, _ in RUNS.values())} "
                  f"under the working folder {Path.cwd()}\n")  # fmt: skip
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    problem = _record_problem()
    if problem:
        p.exit(2, f"error: {problem}\n")
    import torch
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR
    from half_car_ppo import _law, _Policy

    torch.set_num_threads(1)
    scores: dict[str, list[float]] = {"lqr-clipped-biexp-meas": _score(IndependentClippedLQR()),
                                      _MPC: _score(_law(_MPC))}  # fmt: skip
    for group, (folder, residual, law) in RUNS.items():
        for seed_dir in sorted(folder.glob("seed*")):
            if (seed_dir / "final.zip").exists():
                policy = _Policy(seed_dir, residual, law or "lqr-clipped-biexp-meas")
                scores[f"{group}/{seed_dir.name}"] = _score(policy)
                print(seed_dir, np.mean(scores[f"{group}/{seed_dir.name}"]), flush=True)
    runs = [k for k in scores if "/" in k]
    chosen = min(runs, key=lambda k: float(np.mean(scores[k])))
    result = {"command": "python experiments/half_car_select.py " + " ".join(argv or sys.argv[1:]),
              "guideway_seed": VALIDATION_GUIDEWAY_SEED, "episodes": VALIDATION_EPISODES,
              "mean_wk_m_s2": {k: float(np.mean(v)) for k, v in scores.items()},
              "chosen": chosen, "per_episode_wk_m_s2": scores}  # fmt: skip
    with tempfile.NamedTemporaryFile("w", dir=args.out.resolve().parent, suffix=".tmp",
                                     delete=False) as f:  # fmt: skip
        json.dump(result, f, indent=1)
    os.replace(f.name, args.out)
    print(json.dumps({k: result[k] for k in ("mean_wk_m_s2", "chosen")}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
