"""experiments/learned_baselines.py: its statistics against figures computed by hand (IQM of 5
runs = mean of the middle 3; probability of improvement over a deterministic law = the share of
runs above it; curves' ratio), a task without an oracle, each task's references read from its
own evaluation file, and its bad input."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

pytest.importorskip("rliable")

ROOT = Path(__file__).resolve().parents[1]
REFS = {"passive": 0.26, "oracle": 0.21, "lqr-clipped-biexp-meas": 0.24, "mpc-biexp-meas": 0.235}
LAWS = ["lqr-clipped-biexp-meas", "mpc-biexp-meas"]


@pytest.fixture(scope="module")
def lb():
    spec = importlib.util.spec_from_file_location(
        "learned_baselines", ROOT / "experiments" / "learned_baselines.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _record(wk: float, curve: list) -> dict:
    return {"eval_wk_m_s2": wk, "num_timesteps": 100, "wall_time_s": 5.0, "folder": str(wk),
            "curve": curve}  # fmt: skip


def test_statistics_match_hand_computed_figures(lb):
    wks = [0.230, 0.235, 0.238, 0.242, 0.250]  # scores 0.6, 0.5, 0.44, 0.36, 0.2
    row = lb._statistics({"a": [_record(w, []) for w in wks]}, REFS, LAWS)["a"]
    assert row["scores"] == pytest.approx([0.6, 0.5, 0.44, 0.36, 0.2])
    assert row["iqm_score"] == pytest.approx((0.5 + 0.44 + 0.36) / 3)
    assert row["iqm_wk_m_s2"] == pytest.approx((0.235 + 0.238 + 0.242) / 3)
    assert row["ratio_to_lqr-clipped-biexp-meas"] == pytest.approx(0.715 / 3 / 0.24)
    low, high = row["iqm_ci95"]
    assert 0.2 <= low < row["iqm_score"] < high <= 0.6
    # the LQR (score 0.4): 3 of 5 runs above it; the MPC (0.5): 1 above, 1 tie (one half)
    assert row["p_improvement_over_lqr-clipped-biexp-meas"][0] == pytest.approx(0.6)
    assert row["p_improvement_over_mpc-biexp-meas"][0] == pytest.approx(0.3)


def test_curves_are_the_law_over_the_runs_wk(lb):
    runs = [_record(0.24, [(10, 1.0, 0.25), (20, 2.0, 0.2)]),
            _record(0.24, [(10, 3.0, 0.25), (20, 4.0, 0.2), (30, 5.0, 0.1)])]  # fmt: skip
    curve = lb._curves({"a": runs}, 0.2)["a"]
    assert curve["env_steps"] == [10, 20]  # the steps every run evaluated
    assert curve["mean_wall_s"] == pytest.approx([2.0, 3.0])
    assert curve["iqm"] == pytest.approx([0.8, 1.0])


def test_a_group_without_two_runs_is_one_line(lb, tmp_path, capsys):
    assert lb.main(["--group", f"a={tmp_path}/none*", "--json", str(tmp_path / "x.json")]) == 2
    assert "--group" in capsys.readouterr().err


def test_without_an_oracle_the_statistics_are_in_wk(lb):
    # the trip task's file has no oracle yet: no normalised score, the same IQM in Wk
    refs = {k: v for k, v in REFS.items() if k != "oracle"}
    wks = [0.250, 0.230, 0.242, 0.238, 0.235]  # sorted: 0.230 | 0.235 0.238 0.242 | 0.250
    row = lb._statistics({"a": [_record(w, []) for w in wks]}, refs, LAWS)["a"]
    assert row["iqm_score"] is None and row["iqm_ci95"] is None and row["scores"] is None
    assert row["iqm_wk_m_s2"] == pytest.approx((0.235 + 0.238 + 0.242) / 3)
    low, high = row["iqm_wk_ci95_m_s2"]
    assert 0.230 <= low < row["iqm_wk_m_s2"] < high <= 0.250
    assert row["ratio_to_mpc-biexp-meas"] == pytest.approx(0.715 / 3 / 0.235)
    # runs below (better than) the LQR's 0.24: 0.230, 0.238, 0.235 -> 3 of 5
    assert row["p_improvement_over_lqr-clipped-biexp-meas"][0] == pytest.approx(0.6)
    # the MPC's 0.235: 0.230 better, 0.235 a tie (one half) -> 1.5 of 5
    assert row["p_improvement_over_mpc-biexp-meas"][0] == pytest.approx(0.3)


@pytest.mark.parametrize("task, file, laws", [
    ("CapsuleRide-v0", "evaluation.json", ["lqr-clipped-biexp-meas", "mpc-biexp-meas"]),
    ("CapsuleRidePreview-v0", "evaluation.json",
     ["preview-lq-biexp-meas", "preview-mpc-biexp-meas"]),
    ("CapsuleTrip-v0", "evaluation-CapsuleTrip-v0.json",
     ["lqr-sched-biexp-meas", "mpc-biexp-meas", "lqr-clipped-biexp-meas"]),
])  # fmt: skip
def test_each_task_reads_its_own_references(lb, task, file, laws):
    import json

    refs = lb._references(task)
    figures = ROOT / "docs" / "figures"
    own = json.loads((figures / file).read_text())["settings"]["hils"]["controllers"]
    assert refs["passive"] == own["passive"]["wk_rms_body_acc_m_s2"]
    assert ("oracle" in refs) == ("oracle" in own)
    assert list(lb.TASK_LAWS[task]) == laws
    for law in laws:  # every law's figure is one of the project's evaluation files (the
        # quarter-car's and the half-car's: evaluate.py's schema, with "settings")
        found = [
            json.loads(f.read_text())
            .get("settings", {})
            .get("hils", {})
            .get("controllers", {})
            .get(law, {})
            .get("wk_rms_body_acc_m_s2")
            for f in figures.glob("*evaluation*.json")
        ]
        assert refs[law] in found, law


def test_an_unknown_task_is_one_line(lb, tmp_path, capsys):
    argv = ["--task", "CapsuleNone-v0", "--group", "a=x*", "--json", str(tmp_path / "x.json")]
    assert lb.main(argv) == 2
    assert "--task must be one of" in capsys.readouterr().err


def test_curves_in_normalised_score_with_the_validation_oracle(lb):
    runs = [_record(0.24, [(10, 1.0, 0.25), (20, 2.0, 0.22)]),
            _record(0.24, [(10, 3.0, 0.25), (20, 4.0, 0.22)])]  # fmt: skip
    # passive 0.26, oracle 0.21 on the validation bank: 0.25 -> 0.2, 0.22 -> 0.8
    curve = lb._curves({"a": runs}, 0.2, (0.26, 0.21))["a"]
    assert curve["iqm"] == pytest.approx([0.2, 0.8])


def test_validation_references_are_the_validation_banks(lb):
    """The ride and preview tasks read one file (same plant and guideway); its passive is the
    validation bank's (0.2501 m/s^2 in train.py's evaluations), not the evaluation bank's."""
    import json

    ride = lb._validation_references("CapsuleRide-v0")
    assert ride == lb._validation_references("CapsuleRidePreview-v0")
    path = ROOT / "docs" / "figures" / lb.VALIDATION_FILES["CapsuleRide-v0"]
    meta = json.loads(path.read_text())
    assert meta["settings"]["hils"]["controllers"]["passive"]["wk_rms_body_acc_m_s2"] == ride[0]
    assert ride[0] == pytest.approx(0.2501, abs=5e-5) and ride[1] < ride[0]
    trip = lb._validation_references("CapsuleTrip-v0")  # its own file: the trip's physics
    assert trip is not None and trip[1] < trip[0] and trip[0] > ride[0]


def test_the_law_level_line_is_its_normalised_score(lb):
    # the ride task's validation bank: passive 0.2501, oracle 0.2051, clipped LQR 0.2319
    assert float(lb.normalised(0.2319, (0.2501, 0.2051))) == pytest.approx(0.0182 / 0.045)


def test_a_validation_file_made_on_other_episodes_is_refused(lb, tmp_path, monkeypatch):
    import json

    source = ROOT / "docs" / "figures" / lb.VALIDATION_FILES["CapsuleRide-v0"]
    data = json.loads(source.read_text())
    data["seeds"] = [5000, 5019]
    data["episodes"] = 20
    (tmp_path / "docs" / "figures").mkdir(parents=True)
    (tmp_path / "docs" / "figures" / source.name).write_text(json.dumps(data))
    monkeypatch.setattr(lb, "ROOT", tmp_path)
    with pytest.raises(ValueError, match="not the validation bank's"):
        lb._validation_references("CapsuleRide-v0")


def test_paired_ratios_need_every_run_per_episode(lb):
    # each run a fixed multiple of the law on every episode: the ratio is the IQM of the
    # multiples whatever episodes are drawn; a run without its episodes (a JSON made before
    # they were kept) leaves the paired ratio out
    law = [0.30, 0.45, 0.38, 0.52]
    runs = [{"eval_wk_per_episode_m_s2": [k * w for w in law], "eval_wk_m_s2": k * 0.4125,
             "num_timesteps": 1, "wall_time_s": 1.0} for k in (0.97, 0.98, 0.99, 1.00, 1.01)]  # fmt: skip
    row = lb._statistics({"a": runs}, REFS, LAWS, {"mpc-biexp-meas": law})["a"]
    paired = row["ratio_paired_to_mpc-biexp-meas"]
    assert paired["value"] == pytest.approx(0.99)  # the middle three's mean
    low, high = paired["seeds_and_episodes"]
    assert 0.97 <= low < 0.99 < high <= 1.01
    assert paired["seeds_only"] == pytest.approx([low, high], abs=0.005)
    assert "ratio_paired_to_lqr-clipped-biexp-meas" not in row  # no episodes given for it
    del runs[0]["eval_wk_per_episode_m_s2"]
    row = lb._statistics({"a": runs}, REFS, LAWS, {"mpc-biexp-meas": law})["a"]
    assert "ratio_paired_to_mpc-biexp-meas" not in row
