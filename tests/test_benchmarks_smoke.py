"""The benchmark scripts start and print their tables (a smoke test: no speed is asserted)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


@pytest.mark.slow
def test_bench_env_quick_runs(tmp_path):
    out = tmp_path / "bench.json"
    subprocess.run(
        [sys.executable, "benchmarks/bench_env.py", "--quick", "--json", str(out)], check=True,
        capture_output=True,
    )  # fmt: skip
    data = json.loads(out.read_text())
    assert {"single", "vector", "sb3", "realtime", "memory", "startup"} <= set(data)


def test_bench_training_runs(tmp_path):
    out = tmp_path / "train.json"
    subprocess.run(
        [sys.executable, "benchmarks/bench_training.py", "--timesteps", "512", "--num-envs", "4",
         "--n-steps", "64", "--batch-size", "64", "--n-epochs", "1", "--json", str(out)],
        check=True, capture_output=True,
    )  # fmt: skip
    data = json.loads(out.read_text())
    assert data["timesteps"] >= 512 and 0.0 < data["env_share_of_wall"] < 1.0
    assert data["first_step_s"] > 0.0  # the one-time kernel load, reported apart


def test_soak_quick_runs_and_counts(tmp_path):
    out = tmp_path / "soak.json"
    subprocess.run(
        [sys.executable, "benchmarks/soak.py", "--quick", "--json", str(out)], check=True,
        capture_output=True,
    )  # fmt: skip
    data = json.loads(out.read_text())
    assert data["total"]["vehicle_steps"] == sum(r["vehicle_steps"] for r in data["configurations"])
    assert data["total"]["non_finite"] == 0 and data["total"]["out_of_space"] == 0
    assert len(data["configurations"]) == 6
