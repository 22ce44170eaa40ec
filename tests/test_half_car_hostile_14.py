"""A hostile user of the half-car's learned policy scripts (session 14): a run folder resumed or
evaluated with other options than it was trained with, an ``--out`` that is a file or a
folder, the selection script run where no run is saved, and the shipped residual on a
non-finite observation or on another task's observation."""

from __future__ import annotations

import copy
import json
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the tasks)
from tests.test_half_car_review import PPO_SCRIPT, ROOT, _ppo_script

SELECT_SCRIPT = ROOT / "experiments" / "half_car_select.py"
MPC = "wheelbase-mpc-biexp-meas"


def _refused(proc: subprocess.CompletedProcess, name: str) -> None:
    """Exit status 2, one line on stderr naming ``name``, no traceback."""
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and name in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


def _run(script, *argv: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(script), *argv], capture_output=True, text=True,
                          timeout=300, cwd=cwd)  # fmt: skip


def _train_nothing(monkeypatch, script) -> None:
    """``main`` without the training and the evaluation (what this file tests is around them)."""
    monkeypatch.setattr(script, "train_seed", lambda args, seed: args.out / f"seed{seed}")
    monkeypatch.setattr(script, "evaluate", lambda args: {})


def test_a_run_folder_records_the_options_it_is_trained_with(tmp_path, monkeypatch):
    """Training writes ``run.json`` in the run folder with the options that shape the saved
    networks: the law a residual rides on, the learning rate, the vehicles per step."""
    script = _ppo_script()
    _train_nothing(monkeypatch, script)
    out = tmp_path / "run"
    script.main(["--out", str(out), "--residual", "--law", MPC, "--learning-rate", "1e-4",
                 "--num-envs", "8", "--seeds", "0"])  # fmt: skip
    recorded = json.loads((out / "run.json").read_text())
    assert recorded == {"residual": True, "law": MPC, "learning_rate": 1e-4, "num_envs": 8}


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["--residual"], "--law"),  # resumed on the per-bogie LQR: another law under the network
        ([], "--residual"),  # resumed as PPO from scratch
        (["--residual", "--law", MPC, "--learning-rate", "1e-3"], "--learning-rate"),
        (["--residual", "--law", MPC, "--learning-rate", "1e-4", "--num-envs", "4"], "--num-envs"),
        (["--evaluate"], "--residual"),  # scored without its law
        (["--evaluate", "--residual"], "--law"),  # scored on another law
    ],
)
def test_a_run_resumed_or_evaluated_with_other_options_is_refused(tmp_path, argv, name):
    """A run folder trained as a residual on the MPC at 1e-4 with 8 vehicles: resuming it (or
    scoring it with ``--evaluate``) with another law, no residual, another learning rate or
    another number of vehicles would silently continue or score its networks as something
    they are not. One line naming the option, exit 2, nothing written."""
    out = tmp_path / "run"
    (out / "seed0").mkdir(parents=True)
    record = {"residual": True, "law": MPC, "learning_rate": 1e-4, "num_envs": 8}
    (out / "run.json").write_text(json.dumps(record))
    before = sorted(p.name for p in out.rglob("*"))
    proc = _run(PPO_SCRIPT, "--out", str(out), "--seeds", "0", *argv)
    _refused(proc, name)
    assert sorted(p.name for p in out.rglob("*")) == before
    assert json.loads((out / "run.json").read_text()) == record


def test_evaluate_ignores_the_training_only_options(tmp_path, monkeypatch):
    """``--evaluate`` reads the saved networks: the learning rate and the vehicles per step
    they were trained with do not change their score and need not be repeated."""
    script = _ppo_script()
    _train_nothing(monkeypatch, script)
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.json").write_text(json.dumps({"residual": True, "law": MPC,
                                              "learning_rate": 1e-4, "num_envs": 8}))  # fmt: skip
    assert script.main(["--out", str(out), "--evaluate", "--residual", "--law", MPC]) == 0


def test_an_out_that_is_a_file_is_refused(tmp_path):
    target = tmp_path / "notes.txt"
    target.write_text("keep me")
    proc = _run(PPO_SCRIPT, "--out", str(target), "--total-timesteps", "1")
    _refused(proc, "--out")
    assert target.read_text() == "keep me"


def test_select_refuses_an_out_that_is_a_folder(tmp_path):
    """Before scoring anything (minutes): ``--out`` names the JSON file to write."""
    (tmp_path / "runs" / "half_car_ppo" / "seed0").mkdir(parents=True)
    (tmp_path / "runs" / "half_car_ppo" / "seed0" / "final.zip").write_bytes(b"")
    folder = tmp_path / "chosen"
    folder.mkdir()
    proc = _run(SELECT_SCRIPT, "--out", str(folder), cwd=tmp_path)
    _refused(proc, "--out")
    assert list(folder.iterdir()) == []


def test_select_without_any_saved_run_is_refused(tmp_path):
    """Run where ``runs/half_car_*`` hold no ``final.zip`` (another working folder, or before
    training): one line naming the folders it looked in, before scoring the laws, and no
    file written."""
    proc = _run(SELECT_SCRIPT, "--out", str(tmp_path / "select.json"), cwd=tmp_path)
    _refused(proc, "runs/half_car_ppo")
    assert list(tmp_path.iterdir()) == []


def test_the_shipped_residual_rides_its_law_through_a_non_finite_observation():
    """The wheelbase MPC plans around a vehicle whose observation holds a NaN (0 N for it, the
    others untouched: docs/controllers.md); the shipped residual on it raised torch's
    ``ValueError`` for the whole batch. Now that vehicle gets its law's action alone (no
    residual on a signal the network cannot read) and the others what they get without it."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("daqp")
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, load_policy

    policy = load_policy(PRETRAINED_DIR / "residual-ppo-mpc-half-car.zip")
    env = gym.make_vec("CapsuleHalfRide-v0", num_envs=3, vectorization_mode="vector_entry_point",
                       episode_length_s=0.1)  # fmt: skip
    obs, _ = env.reset(seed=4)
    broken = obs.copy()
    broken[1, 0] = np.nan  # the front stroke of vehicle 1
    start = np.ones(3, dtype=bool)
    clean_action, _ = copy.deepcopy(policy).predict(obs, episode_start=start)
    action, _ = copy.deepcopy(policy).predict(broken, episode_start=start)
    law_action, _ = copy.deepcopy(policy.law).predict(broken, episode_start=start)
    assert np.all(np.isfinite(action))
    np.testing.assert_array_equal(action[1], law_action[1])
    np.testing.assert_array_equal(action[[0, 2]], clean_action[[0, 2]])


@pytest.mark.parametrize("task", ["CapsuleHalfRidePreview-v0", "CapsuleRide-v0"])
def test_the_shipped_half_car_policy_on_another_tasks_observation_names_it(task):
    """The shipped half-car policy reads the 16 measured columns of ``CapsuleHalfRide-v0``:
    on the preview task's 80 columns its law reads the first 16 (documented) but the network's
    normaliser failed with numpy's "operands could not be broadcast"; on the quarter-car's a
    clear error came from the law. Both now name the observation and its width."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("daqp")
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, load_policy

    policy = load_policy(PRETRAINED_DIR / "residual-ppo-mpc-half-car.zip")
    obs, _ = gym.make(task, episode_length_s=0.05).reset(seed=1)
    with pytest.raises(ValueError, match=r"observation must .*16 columns"):
        policy.predict(obs)


@pytest.mark.parametrize("seeds", ["-1", "0,0", str(2**32)])
def test_seeds_out_of_range_or_repeated_are_refused(tmp_path, seeds):
    """``--seeds=-1`` created the run folder and ``seed-1/`` and then died with the env's
    seed ``ValueError`` traceback; a repeated seed trained once and was scored as one seed
    (no interval) without a word."""
    out = tmp_path / "run"
    proc = _run(PPO_SCRIPT, "--out", str(out), f"--seeds={seeds}", "--total-timesteps", "1",
                "--num-envs", "1")  # fmt: skip
    _refused(proc, "--seeds")
    assert not out.exists()


def test_select_refuses_a_run_folder_recorded_with_another_law(tmp_path):
    """``runs/half_car_residual_mpc`` is scored as a residual on the wheelbase MPC; a folder
    whose ``run.json`` says it was trained on the per-bogie LQR would be scored on a law its
    networks never saw. Refused in one line naming the record, before anything is scored."""
    folder = tmp_path / "runs" / "half_car_residual_mpc"
    (folder / "seed0").mkdir(parents=True)
    (folder / "seed0" / "final.zip").write_bytes(b"")
    (folder / "run.json").write_text(json.dumps({"residual": True, "law": "lqr-clipped-biexp-meas",
                                                 "learning_rate": 1e-3, "num_envs": 256}))  # fmt: skip
    proc = _run(SELECT_SCRIPT, "--out", str(tmp_path / "select.json"), cwd=tmp_path)
    _refused(proc, "run.json")
    assert not (tmp_path / "select.json").exists()
