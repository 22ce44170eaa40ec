"""experiments/learning_curve.py: the reference lines carry their name and value in the
legend, the title names the evaluation episodes, and the plotted data round-trips."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import load_script


@pytest.fixture(scope="module")
def lc():
    return load_script("experiments/learning_curve.py")


REFS = {"passive": {"wk_rms_body_acc_m_s2": 0.2501},
        "skyhook-cont-biexp": {"wk_rms_body_acc_m_s2": 0.2335, "vre_body_mode1_pct": 55.44}}  # fmt: skip


def fake_run(folder: Path, wk: list[float]) -> Path:
    folder.mkdir()
    rows = [{"num_timesteps": 200_000 * (k + 1), "wk_rms_body_acc_m_s2": w,
             "vre_body_mode1_pct": 40.0 + k} for k, w in enumerate(wk)]  # fmt: skip
    (folder / "evaluations.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    meta = {"eval": {"guideway_seed": 7, "seeds": [5000, 5009], "references": REFS,
                     "metrics": {"wk_rms_body_acc_m_s2": min(wk)}}}  # fmt: skip
    (folder / "best_model.json").write_text(json.dumps(meta))
    return folder


def test_reference_lines_are_labelled_with_their_values(lc):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2)
    lc.draw_references(axes, REFS)
    wk_labels = axes[0].get_legend_handles_labels()[1]
    vre_labels = axes[1].get_legend_handles_labels()[1]
    plt.close(fig)
    assert wk_labels == ["passive (reference): 0.2501 m/s²",
                         "skyhook-cont-biexp (reference): 0.2335 m/s²"]  # fmt: skip
    assert vre_labels == ["skyhook-cont-biexp (reference): 55.4 %"]  # passive has no VRE


def test_runs_to_json_and_back(lc, tmp_path):
    runs = [fake_run(tmp_path / "seed0", [0.26, 0.24]), fake_run(tmp_path / "seed1", [0.25, 0.23])]
    png, data = tmp_path / "lc.png", tmp_path / "lc.json"
    assert lc.main([*map(str, runs), "--out", str(png), "--json", str(data)]) == 0
    saved = json.loads(data.read_text())
    assert (
        list(saved["runs"]) == ["seed0", "seed1"]
        and saved["runs"]["seed1"][1]["wk_rms_body_acc_m_s2"] == 0.23
    )
    assert saved["eval"] == {"guideway_seed": 7, "seeds": [5000, 5009], "references": REFS}
    redrawn = tmp_path / "again.png"
    assert lc.main(["--from-json", str(data), "--out", str(redrawn)]) == 0
    assert redrawn.read_bytes() == png.read_bytes()


def test_no_runs_is_one_line(lc, tmp_path):
    with pytest.raises(SystemExit, match="evaluations.jsonl"):
        lc.main([str(tmp_path)])
