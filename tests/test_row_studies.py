"""Rows studies and experiments/check_row_studies.py: a study's trial trains the very run that
``train.py`` trained with the same arguments (the same policy weights, bit for bit: both runs
are in one process on one CPU with one torch thread, so torch does the same operations in the
same order; across machines this is not promised), the checker accepts that study
against the run's record and names the key of a study that would train something else, and the
repository's rows studies are valid studies."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import NO_SB3, NO_YAML, load_script

pytest.importorskip("stable_baselines3", reason=NO_SB3)
pytest.importorskip("yaml", reason=NO_YAML)

REPO = Path(__file__).resolve().parents[1]

TINY = {"total_timesteps": 1024, "num_envs": 4, "eval_freq": 0, "eval_episodes": 2,
        "eval_episode_length": 1.0, "checkpoint_freq": 0}  # fmt: skip
TINY_HP = {"hp.n_steps": 128, "hp.batch_size": 256, "hp.n_epochs": 2}


def _train_cli_run(folder: Path, seed: int) -> Path:
    """A run trained by train.py's own entry point (not the sweep), with the hyperparameter
    file written by hand."""
    import yaml
    from capsule_env.agents.learning.train import Args, train

    hp_file = folder / "tiny.yml"
    base = yaml.safe_load((REPO / "hyperparams" / "ppo.yml").read_text())
    entry = next(iter(base.values()))
    entry.update(n_steps=128, batch_size=256, n_epochs=2)
    hp_file.write_text(yaml.safe_dump(base, sort_keys=False))
    out = folder / "cli-run"
    train(Args(**TINY, seed=seed, hyperparams=str(hp_file), output_dir=str(out), name="cli",
               progress=False))  # fmt: skip
    return out


def _weights(zip_path: Path) -> dict:
    from stable_baselines3 import PPO

    return {k: v.detach().clone() for k, v in PPO.load(zip_path).policy.state_dict().items()}


def test_a_study_trial_is_the_train_py_run_and_the_checker_says_so(tmp_path):
    import torch

    from capsule_env.sweep.kinds import run_train
    from capsule_env.sweep.study import load_study

    check = load_script("experiments/check_row_studies.py")
    run = _train_cli_run(tmp_path, seed=3)
    table = tmp_path / "table.json"
    table.write_text(json.dumps({"runs": {"tiny": [{"seed": 3, "folder": str(run)}]}}))

    def study(params: dict, seeds: list[int], name: str) -> Path:
        path = tmp_path / f"{name}.json"
        block = {"kind": "train", "name": "tiny", "seeds": seeds, "params": params}
        path.write_text(json.dumps({"name": name, "trials": [block]}))
        return path

    same = study({**TINY, **TINY_HP}, [3], "same")
    assert check.check(same, table) == 0
    # the sweep's trial of that study trains the same weights as train.py did
    trial = load_study(same, tmp_path / "sweep").trials[0]
    result = run_train(trial)
    a = _weights(run / "final_model.zip")
    b = _weights(Path(result["output_dir"]) / "final_model.zip")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    # a study that would train something else, or another seed, is named
    other_lr = study({**TINY, **TINY_HP, "hp.learning_rate": 0.0001}, [3], "lr")
    assert check.check(other_lr, table) == 1
    other_seed = study({**TINY, **TINY_HP}, [4], "seed")  # no run of seed 4, run 3 not a trial
    assert check.check(other_seed, table) == 2
    longer = study({**TINY, **TINY_HP, "total_timesteps": 2048}, [3], "longer")
    assert check.check(longer, table) == 1


def test_the_checker_names_the_differing_key(tmp_path, capsys):
    check = load_script("experiments/check_row_studies.py")
    want = {"algo": "ppo", "hyperparams": {"learning_rate": 0.001, "n_timesteps": 1e6}}
    got = {"algo": "ppo", "hyperparams": {"learning_rate": 0.0003, "n_timesteps": 2e6}}
    assert check.differences(want, got, explicit_total=True) == [
        "hp.learning_rate: study 0.001, run 0.0003"
    ]
    assert len(check.differences(want, got, explicit_total=False)) == 2
    with pytest.raises(SystemExit) as exc:
        check.main([str(tmp_path / "none.yml"), str(tmp_path / "t.json")])
    assert exc.value.code == 2
    assert "study: no file" in capsys.readouterr().err


ROWS = {"rows-CapsuleRide-v0": "learned_baselines.json",
        "rows-CapsuleRidePreview-v0": "learned_baselines-CapsuleRidePreview-v0.json",
        "rows-CapsuleTrip-v0": "learned_baselines-CapsuleTrip-v0.json"}  # fmt: skip


@pytest.mark.parametrize("name", sorted(ROWS))
def test_each_rows_study_has_its_tables_rows_and_seeds(tmp_path, name):
    """Every group of the table's JSON (what experiments/learned_baselines.py recorded of the
    runs it evaluated) is a block of the rows study with the same seeds, and nothing else."""
    from capsule_env.sweep.study import load_study

    study = load_study(REPO / "experiments" / "studies" / f"{name}.yml", tmp_path)
    table = json.loads((REPO / "docs" / "figures" / ROWS[name]).read_text())["runs"]
    assert set(study.blocks()) == set(table)
    for block, runs in table.items():
        seeds = sorted(t.seed for t in study.trials if t.block == block)
        assert seeds == sorted(r["seed"] for r in runs), block


def test_the_checker_reports_what_it_cannot_match(tmp_path, capsys):
    """A table run without a record, a group without a block and a seed the block lacks are
    each a problem line; a table of the wrong shape is one error line (exit 2)."""
    check = load_script("experiments/check_row_studies.py")
    study = tmp_path / "s.json"
    block = {"kind": "train", "name": "g", "seeds": [0], "params": TINY}
    study.write_text(json.dumps({"trials": [block]}))
    (tmp_path / "empty").mkdir()
    table = tmp_path / "t.json"
    table.write_text(json.dumps({"runs": {"g": [{"seed": 0, "folder": "empty"},
                                                {"seed": 5, "folder": "empty"}],
                                          "h": [{"seed": 0, "folder": "empty"}]}}))  # fmt: skip
    assert check.main([str(study), str(table), "--runs-root", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert f"g-000: run {tmp_path / 'empty'} has no readable final_model.json" in out
    assert "group 'h': no block of that name in the study" in out
    assert "group 'g': its run of seed 5 is not a trial of the block" in out
    assert "3 problem(s)" in out
    for bad in ([1, 2], {"runs": []}, {"runs": {"g": ["r"]}}, {"x": 1}):
        table.write_text(json.dumps(bad))
        with pytest.raises(SystemExit) as exc:
            check.main([str(study), str(table)])
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "expected 'runs' mapping each group" in err[0]
