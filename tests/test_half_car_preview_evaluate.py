"""``evaluate.py --task CapsuleHalfRidePreview-v0`` and the preview task's card.

The survey changes what a law reads, not the plant: on the same episodes every row without the
survey is the half-car task's own row, bit for bit (checked by running both tasks, and on the
two files in docs/figures); the survey law's row says what it reads; the oracle, started also
from the survey law's currents, is below every row episode by episode and never above the
half-car task's oracle; the task card (docs/tasks.md) and the README's table carry the task,
their figures the file's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from capsule_env.evaluation import evaluate
from capsule_env.evaluation.task_cards import CARDED, load_results, readme_table, task_cards
from capsule_env.tasks import DECLARED_TASKS

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
TASK = next(t for t in DECLARED_TASKS if t.env_id == "CapsuleHalfRidePreview-v0")
HALF = next(t for t in DECLARED_TASKS if t.env_id == "CapsuleHalfRide-v0")
SURVEY = "survey-preview-lq-biexp-meas"


def _rows(data: dict) -> dict[str, dict]:
    return data["settings"]["hils"]["controllers"]


def test_evaluate_runs_the_preview_task_with_the_half_car_tasks_rows(tmp_path):
    files = {}
    for task in (HALF.env_id, TASK.env_id):
        files[task] = tmp_path / f"{task}.json"
        assert evaluate.main(["--task", task, "--episodes", "2", "--seed", "1003",
                              "--no-shipped-policy", "--json", str(files[task])]) == 0  # fmt: skip
    half, preview = (json.loads(files[t].read_text()) for t in (HALF.env_id, TASK.env_id))
    assert preview["condition"]["task"] == TASK.env_id and preview["seeds"] == [1003, 1004]
    assert preview["condition"]["env_kwargs"] == TASK.kwargs
    rows = _rows(preview)
    assert set(rows) == set(_rows(half)) | {SURVEY}
    for name, row in _rows(half).items():  # the same plant and episodes: the same rows
        assert rows[name] == row, name
    survey = rows[SURVEY]
    assert survey["preview"] is True and survey["uses_unmeasured_signals"] is False
    assert survey["observation"] == "measured" and survey["gains_tuned"] is True
    assert survey["env_kwargs"]["preview_points"] == TASK.kwargs["preview_points"]
    assert survey["env_kwargs"]["preview_horizon_s"] == TASK.kwargs["preview_horizon_s"]
    # the best law without the survey: the lowest Wk on measured signals, the survey's base
    laws = {n: r["wk_rms_body_acc_m_s2"] for n, r in rows.items()
            if n not in ("passive", SURVEY) and not r["uses_unmeasured_signals"]}  # fmt: skip
    best = min(laws, key=laws.__getitem__)
    assert preview["best_without_survey"] == best
    ratio = survey["wk_rms_body_acc_m_s2"] / laws[best]
    assert survey["ratio_to_best_without_survey"] == ratio
    low, high = survey["ratio_to_best_without_survey_ci95"]
    assert low <= ratio <= high


def test_the_preview_tasks_other_options_are_refused_by_name(tmp_path, capsys):
    out = tmp_path / "preview.json"
    argv = ["--task", TASK.env_id, "--env", "speed_kmh=400", "--json", str(out)]
    assert evaluate.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("evaluate.py: error: --env not supported")
    assert "half_car_preview" in err and not out.exists()


def test_the_preview_file_is_the_half_car_files_rows_and_the_surveys():
    half, preview = (json.loads((FIGURES / t.results).read_text()) for t in (HALF, TASK))
    assert preview["condition"]["env_kwargs"] == TASK.kwargs
    assert (preview["seeds"], preview["guideway_seed"]) == (half["seeds"], half["guideway_seed"])
    assert preview["policies"] == half["policies"]
    rows, half_rows = _rows(preview), _rows(half)
    assert set(rows) == set(half_rows) | {SURVEY}
    for name, row in half_rows.items():
        if name != "oracle":
            assert rows[name] == row, name
    # the oracle: per episode at or below every row, and never above the half-car task's
    oracle = np.array(rows["oracle"]["per_episode_wk_m_s2"])
    for name, row in rows.items():
        assert np.all(oracle <= np.array(row["per_episode_wk_m_s2"]) * (1 + 1e-12)), name
    assert np.all(oracle <= np.array(half_rows["oracle"]["per_episode_wk_m_s2"]) * (1 + 1e-12))
    assert preview["command"].startswith(
        f"python -m capsule_env.evaluation.evaluate --task {TASK.env_id} --episodes 10"
    )


def test_the_preview_task_is_carded_from_its_file():
    # every declared task is carded, and evaluate.py evaluates each (its card's file)
    assert TASK in CARDED and all(t in CARDED for t in DECLARED_TASKS)
    assert set(evaluate._declared_evaluations()) == {t.env_id for t in DECLARED_TASKS}
    results = load_results(FIGURES)
    page = (ROOT / "docs" / "tasks.md").read_text()
    cards = task_cards(results)
    assert cards in page and readme_table(results) in (ROOT / "README.md").read_text()
    card = cards[cards.index(f"## `{TASK.env_id}`") :]
    assert "ISO 2631-1 Wk" in card and "`wk_rms_body_acc_m_s2`" in card
    wk = {n: r["wk_rms_body_acc_m_s2"] for n, r in _rows(results[TASK.results]).items()}
    score = (wk["passive"] - wk[SURVEY]) / (wk["passive"] - wk["oracle"])
    assert (f"| `{SURVEY}` | best tuned classical law | measured + preview (0.5 s) | "
            f"{wk[SURVEY]:.4f} | {score:.3f} |") in card  # fmt: skip
    # the card's best law: the lowest Wk of the laws on measured signals and the survey
    laws = {n: w for n, w in wk.items() if n not in ("oracle", "passive", *_policies(results))
            and not _rows(results[TASK.results])[n]["uses_unmeasured_signals"]}  # fmt: skip
    assert min(laws, key=laws.__getitem__) == TASK.best_classical == SURVEY
    # the advice quotes the file's ratio to the best law without the survey
    best = results[TASK.results]["best_without_survey"]
    assert best == "wheelbase-mpc-biexp-meas" and f"{wk[SURVEY] / wk[best]:.3f} x" in TASK.use
    assert f"{wk[SURVEY] / wk['lqr-clipped-biexp-meas']:.3f} x" in TASK.use


def _policies(results: dict) -> list[str]:
    return list(results[TASK.results].get("policies", {}))
