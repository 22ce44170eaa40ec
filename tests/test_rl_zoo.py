"""RL Zoo reads hyperparams/ppo.yml and trains on CapsuleSuspension-v0 (issue: "tested if
rl_zoo3 is installed"; rl_zoo3 is not a dependency, so this test is skipped without it)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest


@pytest.mark.slow
@pytest.mark.skipif(
    importlib.util.find_spec("rl_zoo3") is None,
    reason="rl_zoo3 is not installed (optional: pip install rl_zoo3)",
)
def test_rl_zoo_trains_from_our_hyperparameters(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "CapsuleSuspension-v0",
         "--gym-packages", "capsule_env", "--conf-file", "hyperparams/ppo.yml", "-n", "20000",
         "--log-folder", str(tmp_path), "--eval-freq", "-1"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert list(tmp_path.glob("ppo/CapsuleSuspension-v0_*/CapsuleSuspension-v0.zip"))
