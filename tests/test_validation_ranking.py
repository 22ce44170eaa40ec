"""experiments/validation_ranking.py on hand-made groups whose means, choice and rank
correlation are known, and its bad input (one line, exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import load_script

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def vr():
    return load_script("experiments/validation_ranking.py")


def _run(validation: float, evaluation: float) -> dict:
    return {"validation_wk_m_s2": validation, "eval_wk_m_s2": evaluation}


RUNS = {
    # means: a (0.21, 0.31), b (0.22, 0.30), c (0.23, 0.33); a run without a validation figure
    # is left out of both of c's means
    "a": [_run(0.20, 0.30), _run(0.22, 0.32)],
    "b": [_run(0.22, 0.29), _run(0.22, 0.31)],
    "c": [_run(0.23, 0.33), {"validation_wk_m_s2": None, "eval_wk_m_s2": 9.0}],
}


def test_means_choice_and_rank_correlation(vr):
    means = vr.group_means(vr.paired_figures(RUNS, "hand-made"))
    assert means["a"]["validation_mean_m_s2"] == pytest.approx(0.21)
    assert means["c"]["evaluation_mean_m_s2"] == pytest.approx(0.33) and means["c"]["seeds"] == 1
    r = vr.ranking(means)
    assert r["by_validation"] == ["a", "b", "c"]
    assert r["validation_choice"] == "a" and r["evaluation_best"] == "b"
    # ranks: validation 1, 2, 3; evaluation 2, 1, 3 -> 1 - 6 * (1 + 1 + 0) / (3 * 8) = 0.5
    assert r["spearman"] == pytest.approx(0.5)


def test_one_seed_per_group_chooses_by_chance(vr):
    # x's two runs read 0.20 and 0.30 on validation, y's one 0.25: one seed per group chooses
    # x exactly when x's draw is its 0.20 run, half of the time
    figures = vr.paired_figures({"x": [_run(0.20, 0.30), _run(0.30, 0.30)],
                                 "y": [_run(0.25, 0.40)]}, "hand-made")  # fmt: skip
    rate = vr.one_seed_rate(figures, "x", draws=20_000, seed=1)
    assert rate == pytest.approx(0.5, abs=0.02)  # binomial sd 0.0035
    assert vr.one_seed_rate(figures, "y", draws=1000, seed=1) == pytest.approx(1 - rate, abs=0.05)
    # two groups: no rank correlation to speak of
    assert vr.ranking(vr.group_means(figures))["spearman"] is None


def test_the_script_writes_its_json(tmp_path):
    data = tmp_path / "lb.json"
    data.write_text(json.dumps({"task": "CapsuleRide-v0", "runs": RUNS}))
    out = tmp_path / "r.json"
    result = subprocess.run([sys.executable, "experiments/validation_ranking.py", str(data),
                             "--json", str(out)], cwd=ROOT, capture_output=True, text=True,
                            timeout=120)  # fmt: skip
    assert result.returncode == 0, result.stderr
    task = json.loads(out.read_text())["tasks"]["CapsuleRide-v0"]
    assert task["validation_choice"] == "a" and task["spearman"] == pytest.approx(0.5)


@pytest.mark.parametrize(
    "content, words",
    [
        ("not json", "not JSON"),
        ("[1, 2]", "no 'runs' object"),
        ('{"runs": {"a": []}}', "fewer than 2 groups"),
        ('{"runs": {"a": [1, 2], "b": [3]}}', "group 'a', run 0: validation_wk_m_s2 must be"),
        (
            '{"runs": {"a": [{"validation_wk_m_s2": NaN, "eval_wk_m_s2": 0.2}]}}',
            "validation_wk_m_s2 must be a finite number",
        ),
        ('{"runs": {"a": [{"validation_wk_m_s2": 0.2}]}}', "eval_wk_m_s2 must be a finite"),
        ('{"runs": {"a": 3}}', "group 'a' must be a list"),
        ('{"runs": [1]}', "'runs' must be an object"),
    ],
)
def test_bad_input_is_one_line(tmp_path, content, words):
    path = tmp_path / "bad.json"
    path.write_text(content)
    result = subprocess.run([sys.executable, "experiments/validation_ranking.py", str(path)],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)  # fmt: skip
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert str(path) in lines[0] and words in lines[0], lines[0]


def test_two_files_of_one_task_are_refused(tmp_path):
    data = tmp_path / "lb.json"
    data.write_text(json.dumps({"task": "CapsuleRide-v0", "runs": RUNS}))
    result = subprocess.run([sys.executable, "experiments/validation_ranking.py", str(data),
                             str(data)], cwd=ROOT, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert result.returncode == 2 and "task CapsuleRide-v0 is already" in result.stderr
