"""``benchmarks/bench_half_car.py --kernel-from PATH``: the half-car env and lanes plant with
another ``declared_lanes.py``'s kernel, timed beside the package's, and the ratios printed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _bench(*args: str) -> subprocess.CompletedProcess:
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    return subprocess.run([sys.executable, "benchmarks/bench_half_car.py", "--quick",
                           "--num-envs", "64", *args], cwd=ROOT, env=env, capture_output=True,
                          text=True)  # fmt: skip


@pytest.mark.slow
def test_kernel_from_times_the_files_kernel_beside_the_packages(tmp_path):
    source = (ROOT / "capsule_env" / "plant" / "declared_lanes.py").read_text()
    path = tmp_path / "lanes_copy.py"
    path.write_text(source)
    result = _bench("--kernel-from", str(path))
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.splitlines()
    last = next(i for i, line in enumerate(lines) if line.startswith("half-car / ride"))
    rates = {line[:32].strip(): float(line[32:]) for line in lines[2:last]}
    assert {"CapsuleHalfRide-v0 env, file's", "lanes plant, half_car, file's"} <= set(rates)
    assert all(r > 0.0 for r in rates.values())
    verdict = next(line for line in lines if line.startswith(f"with {path}'s kernel"))
    env_gain = float(verdict.split("env ")[1].split(",")[0])
    expected = rates["CapsuleHalfRide-v0 env"] / rates["CapsuleHalfRide-v0 env, file's"]
    assert abs(env_gain - expected) <= 0.005 + 1e-3 * expected  # printed to 2 decimals


def test_kernel_from_a_missing_file_is_one_line_on_stderr(tmp_path):
    result = _bench("--kernel-from", str(tmp_path / "absent.py"))
    assert result.returncode != 0 and result.stdout == ""
    assert result.stderr.strip().splitlines() == [
        f"bench_half_car.py: error: --kernel-from: no file {tmp_path / 'absent.py'}"
    ]
