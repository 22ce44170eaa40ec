"""experiments/paper_sensitivity.py on a tiny configuration: it writes its JSON, table and
figure, resumes without rerunning what is done, and refuses a JSON of other arguments.

Facts used: a resumed run finds every point done (no new runtime); the study's CSDC-variant
point with the exact observer and 100 Euler steps per control step (converged, see
tests/test_csdc_variants.py) gives the baseline's first-mode VRE within a point, while one
Euler step per 5 ms diverges on the 7 um-yield fit and leaves CSDC near passive.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location(
        "paper_sensitivity", ROOT / "experiments" / "paper_sensitivity.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_tiny_study_writes_resumes_and_refuses(study, tmp_path, capsys):
    out, fig = tmp_path / "s.json", tmp_path / "s.png"
    argv = ["--settings", "sim", "--episodes", "2", "--episode-length", "2", "--quick-fits",
            "--only", "CSDC variant", "--json", str(out), "--figure", str(fig)]  # fmt: skip
    assert study.main(argv) == 0
    data = json.loads(out.read_text())
    keys = list(data["results"])
    assert keys[0] == "sim/baseline/today's reproduction" and len(keys) == 5
    assert fig.stat().st_size > 10_000
    assert "| CSDC variant | two-level law" in capsys.readouterr().out
    res = data["results"]
    base = res[keys[0]]["csdc"]["vre_body_mode1_pct"]
    converged = res["sim/CSDC variant/Euler z observer, 100 steps per 5 ms"]["csdc"]
    diverged = res["sim/CSDC variant/Euler z observer, 1 step per 5 ms"]["csdc"]
    assert converged["vre_body_mode1_pct"] == pytest.approx(base, abs=1.0)
    assert diverged["vre_body_mode1_pct"] < 0.3 * base
    # per episode: their mean is evaluate.py's VRE; the paired interval holds the gap
    for point in res.values():
        for side in ("csdc", "biexp"):
            per = point[side]["per_episode"]["vre_body_mode1_pct"]
            assert len(per) == 2
            assert sum(per) / 2 == pytest.approx(point[side]["vre_body_mode1_pct"], abs=1e-9)
        low, high = point["ci95"]["gap"]["gap_body_mode1_pct"]
        assert low <= point["gap_body_mode1_pct"] <= high
    runtime = data["runtime_s"]
    assert study.main(argv) == 0  # resumed: nothing left to run
    assert json.loads(out.read_text())["runtime_s"] == runtime
    capsys.readouterr()
    assert study.main([*argv[:5], "3", *argv[6:]]) == 1  # other episode length
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "other arguments" in err[0]


def test_bad_settings_is_one_line(study, capsys, tmp_path):
    assert study.main(["--settings", "lab", "--json", str(tmp_path / "a.json")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--settings" in err[0]


@pytest.mark.parametrize("extra, words", [
    (["--measured-data", "no/such/folder"], "--measured-data: measured-data folder"),
    (["--measured-data", ".", "--settings", "sim"], "needs the hils setting"),
    (["--measured-data", "docs"], "holds no .mat files"),
])  # fmt: skip
def test_bad_measured_data_is_one_line(study, capsys, tmp_path, extra, words):
    out = tmp_path / "a.json"
    assert study.main([*extra, "--json", str(out), "--figure", str(tmp_path / "a.png")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and not out.exists()


def test_page_tables_are_the_json_tables():
    from capsule_env.sensitivity.runner import format_table

    data = json.loads((ROOT / "docs/figures/paper_sensitivity.json").read_text())
    results = list(data["results"].values())
    want = ("**`sim` (Table 5)**\n\n" + format_table(results, "sim") + "\n**`hils` (Table 6)**\n\n"
            + format_table(results, "hils"))  # fmt: skip
    page = (ROOT / "docs/paper-reproduction.md").read_text()
    start, end = "<!-- sensitivity tables: begin -->\n", "<!-- sensitivity tables: end -->"
    assert page[page.index(start) + len(start) : page.index(end)] == want
    # the baseline is evaluate.py's paper rows (docs/figures/evaluation.json, same seeds)
    ev = json.loads((ROOT / "docs/figures/evaluation.json").read_text())
    rows = ev["settings"]["sim"]["controllers"]
    base = data["results"]["sim/baseline/today's reproduction"]
    for side, name in (("csdc", "skyhook-csdc"), ("biexp", "skyhook-biexp")):
        want_vre = rows[name]["vre_pct"]["body_mode1"]
        assert base[side]["vre_body_mode1_pct"] == pytest.approx(want_vre, abs=0.01), name
