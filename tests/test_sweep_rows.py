"""capsule_env.sweep for rows studies: --block runs some blocks of a study (serially and on
Ray, each set of blocks its own Tune experiment), and a study that grew runs its new trials on
Ray (a Tune experiment that lacks them is not restored)."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_sweep import GAINS, attempts, rows, write_study

from capsule_env.sweep.__main__ import main


def _two_blocks(tmp_path: Path) -> Path:
    one = {**GAINS, "grid": {"gain.c_sky": [3000.0]}}
    return write_study(tmp_path, {"name": "rows", "trials": [{**one, "name": "a"},
                                                             {**one, "name": "b"}]})  # fmt: skip


def _block_runs(tmp_path: Path, capsys, mode: list[str]) -> None:
    study, out = _two_blocks(tmp_path), tmp_path / "out"
    assert main([str(study), "--out", str(out), "--block", "zz", *mode]) == 2
    assert "--block: no block 'zz' in study.json; its blocks: a, b" in capsys.readouterr().err
    assert main([str(study), "--out", str(out), "--block", "b", *mode]) == 0
    assert [(r["trial"], r["status"]) for r in rows(out)] == [("a-000", "not run"),
                                                              ("b-000", "finished")]  # fmt: skip
    assert not (out / "trials" / "a-000" / "result.json").exists()
    assert main([str(study), "--out", str(out), "--block", "a", *mode]) == 0
    table = rows(out)
    assert [r["status"] for r in table] == ["finished", "finished"]
    # the two blocks are the same law and gain on the same episodes: the same figure
    assert table[0]["wk_rms_body_acc_m_s2"] == table[1]["wk_rms_body_acc_m_s2"]
    assert (attempts(out, "a-000"), attempts(out, "b-000")) == (1, 1)
    assert main([str(study), "--out", str(out), *mode]) == 0  # the whole study: nothing to run
    assert (attempts(out, "a-000"), attempts(out, "b-000")) == (1, 1)


def test_block_runs_one_row_of_a_study_without_ray(tmp_path, capsys):
    """--block runs that block's trials only, records the others as not run (or as they
    were), and a later --block or whole run in the same folder leaves finished ones alone."""
    _block_runs(tmp_path, capsys, ["--no-ray"])


@pytest.mark.scale
def test_block_runs_one_row_of_a_study_on_ray(local_ray, tmp_path, capsys):
    """The same on Ray: each set of blocks has its own Tune experiment, so a second block in
    the same folder is not mistaken for the first one's finished experiment."""
    _block_runs(tmp_path, capsys, ["--quiet"])


@pytest.mark.scale
def test_a_grown_study_runs_its_new_trials_on_ray(local_ray, tmp_path):
    """A study run whole on Ray, then grown by a block: Tune's experiment of the first run
    does not hold the new trial, so restoring it would not run it; the new trial runs (in a
    second experiment) and the finished ones are not run again."""
    one = {**GAINS, "grid": {"gain.c_sky": [3000.0]}}
    out = tmp_path / "out"
    first = write_study(tmp_path, {"name": "g", "trials": [{**one, "name": "a"}]}, "1.json")
    assert main([str(first), "--out", str(out), "--quiet"]) == 0
    grown = write_study(tmp_path, {"name": "g", "trials": [{**one, "name": "a"},
                                                           {**one, "name": "b"}]}, "2.json")  # fmt: skip
    assert main([str(grown), "--out", str(out), "--quiet"]) == 0
    assert [r["status"] for r in rows(out)] == ["finished", "finished"]
    assert (attempts(out, "a-000"), attempts(out, "b-000")) == (1, 1)
    assert (out / "tune").is_dir() and (out / "tune-2").is_dir()
