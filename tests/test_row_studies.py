"""Rows studies and experiments/check_row_studies.py: a study's trial trains the very run that
``train.py`` trained with the same arguments (the same policy weights, bit for bit, on this
machine: both are our code on one CPU with one torch thread), the checker accepts that study
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

    from capsule_env.train import Args, train

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
    other_seed = study({**TINY, **TINY_HP}, [4], "seed")
    assert check.check(other_seed, table) == 1
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


@pytest.mark.parametrize("name", ["rows-CapsuleRide-v0", "rows-CapsuleRidePreview-v0",
                                  "rows-CapsuleTrip-v0"])  # fmt: skip
def test_the_rows_studies_are_valid_studies(tmp_path, name):
    from capsule_env.sweep.study import load_study

    study = load_study(REPO / "experiments" / "studies" / f"{name}.yml", tmp_path)
    blocks = study.blocks()
    assert len(blocks) >= 9
    for block in blocks:
        seeds = [t.seed for t in study.trials if t.block == block]
        assert len(seeds) >= 5 and len(set(seeds)) == len(seeds)
