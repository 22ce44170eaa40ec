"""Evaluate ``CapsuleHalfRidePreview-v0``: the survey-preview LQ beside the laws without it.

The metric, the banks, the episodes, the intervals, the rows without the survey and the JSON
layout are :mod:`capsule_env.evaluation.half_car`'s (``evaluate.py``'s layout; the evaluation
bank, ``guideway_seed`` 2026, episode seeds 1000..; 95 % bootstrap intervals, paired for
ratios): the survey changes what a law reads, not the plant, so every row without it equals
its row in ``CapsuleHalfRide-v0``'s file. Added: ``survey-preview-lq-biexp-meas``
(:class:`capsule_env.agents.controllers.wheelbase.SurveyPreviewLQ`, the task's 32 points over
0.5 s per bogie), its weights tuned on the training bank (``guideway_seed`` 0, episode seeds
0..9) on a grid of 48 (:data:`_GRID`), with its ratio to the best law without the survey;
the oracle (``--oracle``) is also started from its currents.

    python -m capsule_env.evaluation.evaluate --task CapsuleHalfRidePreview-v0 --oracle --json F
    python -m capsule_env.evaluation.half_car_preview --oracle-iterations 30 --out F  # the same
"""

from __future__ import annotations

import itertools
import sys
from typing import Any

import numpy as np

from capsule_env.evaluation.half_car import (
    ORACLE_ITERATIONS,
    TASK_KWARGS,
    TRAINING_GUIDEWAY_SEED,
    TUNED_COUPLED,
    _own_shipped,
    _ratio_interval,
    episode_metrics,
    evaluate,
    format_rows,
    layout,
    rollout,
    run_cli,
)

__all__ = ["TASK_ID", "PREVIEW_KWARGS", "TUNED_SURVEY", "SURVEY_LAW", "ORACLE_ITERATIONS",
           "tune_survey", "evaluation_results", "format_rows", "main"]  # fmt: skip

#: The task evaluated here, and its options (``capsule_env.tasks.DECLARED_TASKS``).
TASK_ID = "CapsuleHalfRidePreview-v0"
PREVIEW_KWARGS: dict[str, Any] = {**TASK_KWARGS, "preview_points": 32, "preview_horizon_s": 0.5}
#: The survey law's row name.
SURVEY_LAW = "survey-preview-lq-biexp-meas"
#: The survey-preview LQ's weights when not re-tuned: ``--tune``'s result (docs/half-car.md).
TUNED_SURVEY = {"q_stroke": 10.0, "q_levitation": 10.0, "r_force": 1e-7}
_GRID = {"q_stroke": (0.01, 0.1, 1.0, 10.0), "q_levitation": (0.1, 1.0, 10.0),
         "r_force": (3e-8, 1e-7, 3e-7, 1e-6)}  # fmt: skip


def _survey_law(weights: dict[str, float]) -> Any:
    from capsule_env.agents.controllers.wheelbase import SurveyPreviewLQ

    law = SurveyPreviewLQ(weights["q_stroke"], weights["q_levitation"], weights["r_force"],
                          preview_points=PREVIEW_KWARGS["preview_points"],
                          preview_horizon_s=PREVIEW_KWARGS["preview_horizon_s"])  # fmt: skip
    law.gains_tuned = True  # the grid's best on the training bank (:func:`tune_survey`)
    return law


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


def evaluation_results(seeds: list[int], oracle_iterations: int = 0, shipped: bool = True,
                       command: str = "", tune: bool = False) -> dict[str, Any]:  # fmt: skip
    """The evaluation of the episodes ``seeds`` in ``evaluate.py``'s layout
    (:func:`capsule_env.evaluation.half_car.layout`): the half-car task's rows (its laws, its
    shipped policies when ``shipped``, the oracle with ``oracle_iterations``) and the survey
    law's (its weights re-tuned when ``tune``); ``best_without_survey`` names the law of the
    lowest Wk without the survey and the survey law's row has its ratio to it."""
    survey, training_wk = tune_survey() if tune else (dict(TUNED_SURVEY), None)
    rows = evaluate(seeds, dict(TUNED_COUPLED), oracle_iterations, shipped,
                    survey_laws={SURVEY_LAW: _survey_law(survey)})  # fmt: skip
    others = {"passive", "oracle", SURVEY_LAW, *(_own_shipped() if shipped else ())}
    laws = [n for n, r in rows.items() if n not in others and not r["uses_unmeasured_signals"]]
    best = min(laws, key=lambda n: rows[n]["wk_rms_body_acc_m_s2"])
    mine, base = (np.array(rows[n]["per_episode_wk_m_s2"]) for n in (SURVEY_LAW, best))
    rows[SURVEY_LAW]["ratio_to_best_without_survey"] = float(mine.mean() / base.mean())
    rows[SURVEY_LAW]["ratio_to_best_without_survey_ci95"] = _ratio_interval(mine, base)
    result = layout(TASK_ID, PREVIEW_KWARGS, seeds, rows, command, dict(TUNED_COUPLED), shipped)
    result.update(best_without_survey=best, survey_weights=survey)
    if training_wk is not None:  # re-tuned: the tuned weights' Wk on the training bank
        result["survey_training_wk_m_s2"] = training_wk
    return result


def main(argv: list[str] | None = None) -> int:
    return run_cli(argv, "half_car_preview", __doc__.split("\n\n")[0], evaluation_results,
                   "re-tune the survey law's weights")  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
