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

from capsule_env.evaluation import evaluate
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
