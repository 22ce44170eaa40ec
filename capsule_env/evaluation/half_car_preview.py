"""Evaluate the survey-preview LQ on ``CapsuleHalfRidePreview-v0`` beside the laws without it.

The metric, the banks, the episodes and the intervals are :mod:`capsule_env.evaluation.half_car`'s
(the evaluation bank, ``guideway_seed`` 2026, episode seeds 1000..; 95 % bootstrap intervals,
paired for ratios). Rows: the passive damper, the independent clipped LQRs (the ratios' base),
the discrete LQ and the wheelbase-preview LQ of the half-car task (no survey), and
``survey-preview-lq-biexp-meas`` (:class:`capsule_env.agents.controllers.wheelbase.SurveyPreviewLQ`,
the task's 32 points over 0.5 s per bogie), its weights tuned on the training bank
(``guideway_seed`` 0, episode seeds 0..9) on a grid of 48 (:data:`_GRID`).

    python -m capsule_env.evaluation.half_car_preview --out docs/figures/evaluation-CapsuleHalfRidePreview-v0.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import tempfile
from typing import Any

import numpy as np

from capsule_env.evaluation.half_car import (
    EVALUATION_GUIDEWAY_SEED,
    TRAINING_GUIDEWAY_SEED,
    TUNED_COUPLED,
    _interval,
    _ratio_interval,
    episode_metrics,
    rollout,
)

__all__ = ["TUNED_SURVEY", "tune_survey", "evaluate", "main"]

#: The survey-preview LQ's weights when not re-tuned: ``--tune``'s result (docs/half-car.md).
TUNED_SURVEY = {"q_stroke": 10.0, "q_levitation": 10.0, "r_force": 1e-7}
_GRID = {"q_stroke": (0.01, 0.1, 1.0, 10.0), "q_levitation": (0.1, 1.0, 10.0),
         "r_force": (3e-8, 1e-7, 3e-7, 1e-6)}  # fmt: skip


def _survey_law(weights: dict[str, float]) -> Any:
    from capsule_env.agents.controllers.wheelbase import SurveyPreviewLQ

    return SurveyPreviewLQ(weights["q_stroke"], weights["q_levitation"], weights["r_force"])


def tune_survey(seeds: list[int] | None = None) -> tuple[dict[str, float], float]:
    """The grid's weights with the lowest mean headline Wk on the training bank, and that Wk."""
    seeds = list(range(10)) if seeds is None else seeds
    best, best_wk = dict(TUNED_SURVEY), np.inf
    for values in itertools.product(*_GRID.values()):
        weights = dict(zip(_GRID, values, strict=True))
        roll = rollout(_survey_law(weights), seeds, TRAINING_GUIDEWAY_SEED)
        wk = float(episode_metrics(roll)["wk_rms_body_acc_m_s2"].mean())
        if wk < best_wk:
            best, best_wk = weights, wk
    return best, best_wk


def evaluate(seeds: list[int], survey: dict[str, float]) -> dict:
    """Every row's metrics (means and intervals over the episodes ``seeds``); ratios to the
    independent clipped LQRs and to the best law without the survey."""
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR
    from capsule_env.agents.controllers.wheelbase import WheelbasePreviewLQ

    w = (TUNED_COUPLED["q_stroke"], TUNED_COUPLED["q_levitation"], TUNED_COUPLED["r_force"])
    laws = {"passive": None, "lqr-clipped-biexp-meas": IndependentClippedLQR(),
            "lq-discrete-biexp-meas": WheelbasePreviewLQ(*w, preview=False),
            "wheelbase-lq-biexp-meas": WheelbasePreviewLQ(*w),
            "survey-preview-lq-biexp-meas": _survey_law(survey)}  # fmt: skip
    metrics = {name: episode_metrics(rollout(law, seeds, EVALUATION_GUIDEWAY_SEED))
               for name, law in laws.items()}  # fmt: skip
    head = {name: m["wk_rms_body_acc_m_s2"] for name, m in metrics.items()}
    without = [n for n in laws if n not in ("passive", "survey-preview-lq-biexp-meas")]
    best = min(without, key=lambda n: head[n].mean())
    rows: dict[str, Any] = {}
    for name, m in metrics.items():
        row = {k: float(np.mean(v)) for k, v in m.items()}
        row["wk_rms_body_acc_m_s2_ci95"] = _interval(head[name])
        for key, base in (
            ("independent_lqr", "lqr-clipped-biexp-meas"),
            ("best_without_survey", best),
        ):
            row[f"ratio_to_{key}"] = float(head[name].mean() / head[base].mean())
            row[f"ratio_to_{key}_ci95"] = _ratio_interval(head[name], head[base])
        row["per_episode_wk_m_s2"] = head[name].tolist()
        rows[name] = row
    return {"best_without_survey": best, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="", help="JSON file to write (atomically)")
    p.add_argument("--episodes", type=int, default=10, help="evaluation episodes (>= 2)")
    p.add_argument("--tune", action="store_true", help="re-tune the survey law's weights")
    args = p.parse_args(argv)
    if args.episodes < 2:
        print("error: --episodes must be >= 2", file=sys.stderr)
        return 2
    if args.out and not os.path.isdir(os.path.dirname(os.path.abspath(args.out))):
        print(f"error: --out's folder must exist, got {args.out!r}", file=sys.stderr)
        return 2
    survey, training_wk = tune_survey() if args.tune else (dict(TUNED_SURVEY), None)
    seeds = list(range(1000, 1000 + args.episodes))
    result = {"task": "CapsuleHalfRidePreview-v0", "episodes": seeds,
              "guideway_seed": EVALUATION_GUIDEWAY_SEED, "survey_weights": survey,
              "survey_training_wk_m_s2": training_wk,
              "command": "python -m capsule_env.evaluation.half_car_preview "
              + " ".join(sys.argv[1:] if argv is None else argv),
              **evaluate(seeds, survey)}  # fmt: skip
    text = json.dumps(result, indent=1)
    if args.out:
        folder = os.path.dirname(os.path.abspath(args.out))
        with tempfile.NamedTemporaryFile("w", dir=folder, delete=False, suffix=".tmp") as f:
            f.write(text)
        os.replace(f.name, args.out)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
