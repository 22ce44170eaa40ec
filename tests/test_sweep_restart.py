"""The sweep's train trials after a stop before their first checkpoint (issue 40): train.py
starts only in a folder without another run's files, so the trial's own start is cleared and
the trial runs again, but never while a process still trains in that folder."""

from __future__ import annotations

import json
import os

import pytest
from test_sweep import NO_RL, TINY_PPO, rows, write_study

from capsule_env.sweep.__main__ import main


def test_a_train_trial_stopped_before_its_first_checkpoint_runs_again(tmp_path, capsys):
    pytest.importorskip("stable_baselines3", reason=NO_RL)
    pytest.importorskip("yaml", reason=NO_RL)
    fcntl = pytest.importorskip("fcntl")  # flock, as train.py's lock
    out = tmp_path / "out"
    study = write_study(tmp_path, {"name": "one", "trials": [
        {"kind": "train", "name": "ppo", "params": TINY_PPO}]})  # fmt: skip
    run = out / "trials" / "ppo-000" / "run"
    (run / "checkpoints").mkdir(parents=True)
    killed = '{"num_timesteps": 999}\n'  # what the start stopped before a checkpoint logged
    (run / "evaluations.jsonl").write_text(killed)
    fd = os.open(run, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # that start still at work in its folder
    try:
        assert main([str(study), "--out", str(out), "--no-ray"]) == 1
    finally:
        os.close(fd)
    assert "is in use by another train.py" in capsys.readouterr().err
    assert (run / "evaluations.jsonl").read_text() == killed  # left alone
    assert main([str(study), "--out", str(out), "--no-ray"]) == 0  # it ended: run again
    logged = (run / "evaluations.jsonl").read_text().splitlines()
    assert [json.loads(line)["num_timesteps"] for line in logged] == [2048]  # its own only
    assert rows(out)[0]["status"] == "finished" and rows(out)[0]["num_timesteps"] == 2048
