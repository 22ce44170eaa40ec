"""The benchmark scripts run and report consistent figures (no speed is asserted: the
machine decides it; what the report must get right is its arithmetic and its time line)."""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import DT, NO_SB3

ROOT = Path(__file__).resolve().parents[1]


def run_script(*argv: str) -> float:
    """Run a benchmark script on this checkout's package (not an installed copy); returns the
    wall time of its whole process, s."""
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    t0 = time.perf_counter()
    result = subprocess.run(
        [sys.executable, *argv], cwd=ROOT, env=env, capture_output=True, text=True
    )
    process_s = time.perf_counter() - t0
    assert result.returncode == 0, result.stderr[-3000:]
    return process_s


@pytest.mark.slow
@pytest.mark.rl
def test_bench_env_quick_runs(tmp_path):
    pytest.importorskip("stable_baselines3", reason=NO_SB3)  # its SB3 VecEnv section
    out = tmp_path / "bench.json"
    out.write_text("an older report, to be replaced whole")
    process_s = run_script(
        "benchmarks/bench_env.py", "--quick", "--substep-ceiling", "--json", str(out)
    )
    data = json.loads(out.read_text())
    assert [p.name for p in tmp_path.iterdir()] == ["bench.json"]  # no temporary file left
    assert {"single", "vector", "sb3", "realtime", "memory", "startup"} <= set(data)
    assert set(data["vector"]) == {f"{env}/N={n}" for n in (1, 64, 1024, 4096)
                                   for env in ("CartPole-v1", "capsule-sim", "capsule-hils")}  # fmt: skip
    assert set(data["sb3"]) == {f"capsule-{s}/N={n}" for n in (64, 1024) for s in ("sim", "hils")}
    for section in ("single", "vector", "sb3"):
        for name, rate in data[section].items():
            assert 0.0 < rate < math.inf, (section, name)
    # the real-time factor: simulated seconds per wall second, one step = one control interval
    for setting in ("sim", "hils"):
        expected = data["single"][f"capsule-{setting}"] * DT
        assert data["realtime"][setting] == pytest.approx(expected, rel=1e-12)
    assert data["memory"]["bytes_per_env"] > 0 and data["memory"]["guideway_bank_bytes"] > 0
    # the fresh interpreter's import and first step ran inside this process's lifetime
    startup = data["startup"]
    assert 0.0 < startup["import_s"] and 0.0 < startup["first_step_s"]
    assert startup["import_s"] + startup["first_step_s"] < process_s
    # the long windows: each side's median of its interleaved windows, and their ratio
    windows = data["long_window"]
    compared = {k for k, v in windows.items() if isinstance(v, dict) and "ratio" in v}
    assert compared == {"vector-sim/N=1024", "vector-hils/N=1024", "single-sim", "single-hils"}
    for name in compared:
        cmp = windows[name]
        assert set(cmp["rates"]) == {"capsule", cmp["reference"]}
        for side, rates in cmp["rates"].items():
            assert len(rates) == windows["repeats"] and all(0.0 < r < math.inf for r in rates)
            assert cmp["median"][side] == statistics.median(rates)
        ratio = cmp["median"]["capsule"] / cmp["median"][cmp["reference"]]
        assert cmp["ratio"] == pytest.approx(ratio, rel=1e-12)
    # the substep ceiling: every configuration's windows against CartPole's median
    ceiling = data["substep_ceiling"]
    cart = statistics.median(ceiling["runs"]["CartPole-v1"]["rates"])
    assert set(ceiling["runs"]) == {"CartPole-v1"} | {
        f"{s}/substeps={n}" for s in ("sim", "hils") for n in ("auto", 1, 2)
    }
    for run in ceiling["runs"].values():
        assert len(run["rates"]) == ceiling["repeats"] and all(
            0 < r < math.inf for r in run["rates"]
        )
        assert run["median"] == statistics.median(run["rates"])
        assert run["ratio"] == pytest.approx(run["median"] / cart, rel=1e-12)
    # the substeps each configuration took: the forced counts exactly; the automatic ones from
    # the tables (sim: the Bi-exponential plant, 2 at every current; hils: the reference
    # damper, 3 at 0 A to 8 at 1.5 A, random currents in between)
    for setting in ("sim", "hils"):
        for forced in (1, 2):
            assert ceiling["runs"][f"{setting}/substeps={forced}"]["mean_substeps"] == forced
    assert ceiling["runs"]["sim/substeps=auto"]["mean_substeps"] == 2.0
    assert 3.0 < ceiling["runs"]["hils/substeps=auto"]["mean_substeps"] < 8.0
    # --quick leaves out the cold start (an empty numba cache: compiling takes a while)
    assert data["cold_start"] is None and data["cold_demo"] is None


@pytest.mark.parametrize("bad", ["a folder", "a path under a file", "a pipe", "empty"])
def test_bench_env_refuses_an_unwritable_json_path(tmp_path, bad):
    if bad == "a path under a file":
        (tmp_path / "file").write_text("a file where a folder is needed")
    elif bad == "a pipe":
        os.mkfifo(tmp_path / "pipe")
    target = {"a folder": str(tmp_path), "a path under a file": str(tmp_path / "file" / "out.json"),
              "a pipe": str(tmp_path / "pipe"), "empty": ""}[bad]  # fmt: skip
    result = subprocess.run(
        [sys.executable, "benchmarks/bench_env.py", "--quick", "--json", target],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        env=dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])),
    )  # fmt: skip
    assert result.returncode == 2
    assert "--json" in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert result.stdout == ""  # nothing measured


@pytest.mark.rl
def test_bench_training_runs_one_algorithm_end_to_end(tmp_path):
    """A tiny budget: PPO on 4 vehicles up to 2048 steps, eager then with its update compiled
    (``--compile both``), evaluated every 0.5 s on 2 one-second validation episodes; the bar
    measured on the same episodes; the figures add up."""
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    from capsule_env.agents import classical_controllers

    from capsule_env.evaluation.episodes import (
        VALIDATION_GUIDEWAY_SEED,
        episode_metrics,
        run_episodes,
    )

    out = tmp_path / "train.json"
    process_s = run_script(
        "benchmarks/bench_training.py", "--algos", "ppo", "--budget-s", "60", "--eval-every-s",
        "0.5", "--timesteps", "2000", "--num-envs", "4", "--hp", "n_steps=256", "--hp",
        "batch_size=256", "--hp", "n_epochs=1", "--eval-episodes", "2", "--eval-episode-length",
        "1", "--compile", "both", "--json", str(out),
    )  # fmt: skip
    data = json.loads(out.read_text())
    # the bar: the clipped LQR on measured signals, hils, validation bank 7, seeds 5000, 5001
    law = classical_controllers()["lqr-clipped-biexp-meas"]
    kwargs = {"setting": "hils", "observation": "measured", **law.env_kwargs,
              "guideway_seed": VALIDATION_GUIDEWAY_SEED}  # fmt: skip
    lqr = episode_metrics(run_episodes(law, kwargs, 2, 5000, 1.0), None)
    assert data["bar"]["wk_rms_body_acc_m_s2"] == pytest.approx(lqr["wk_rms_body_acc_m_s2"])
    assert list(data["results"]) == ["ppo", "ppo+compile"]
    overhead_s = 0.0
    for name, r in data["results"].items():
        assert r["compiled_update"] == (name == "ppo+compile")
        _check_training_run(r, data["bar"]["wk_rms_body_acc_m_s2"])
        overhead_s += r["first_step_s"] + r["train_s"] + r["eval_s"]
    assert overhead_s < process_s


def _check_training_run(r: dict, bar: float) -> None:
    """One run of bench_training.py's JSON: its budget, clocks and time line agree."""
    # PPO collects whole rollouts of 4 x 256: 2000 asked, two rollouts run (unless the bar
    # stopped it first, at a step of the first or second rollout)
    assert r["num_envs"] == 4 and r["hyperparams"]["n_steps"] == 256
    assert r["stopped_by"] in ("timesteps", "bar")
    if r["stopped_by"] == "timesteps":
        assert r["num_timesteps"] == 2048 and r["time_to_bar_s"] is None
    assert r["env_steps_per_s"] == pytest.approx(r["num_timesteps"] / r["train_s"], rel=1e-12)
    # the phases are parts of the training time, the evaluations apart from it
    phases = r["env_s"] + r["rollout_other_s"] + r["update_s"]
    assert min(r["env_s"], r["rollout_other_s"], r["update_s"]) > 0 and phases <= r["train_s"]
    assert 0 < r["first_update_s"] <= r["update_s"]
    # the time line: evaluations in order, the last one of the final policy; the bar is
    # reached exactly when an evaluation is at or below it, and training stopped there
    evals = r["evaluations"]
    assert [e["train_s"] for e in evals] == sorted(e["train_s"] for e in evals)
    assert evals[-1] == r["final"] and evals[-1]["num_timesteps"] == r["num_timesteps"]
    wk = [e["wk_rms_body_acc_m_s2"] for e in evals]
    assert r["best"]["wk_rms_body_acc_m_s2"] == min(wk)
    below = [e for e in evals if e["wk_rms_body_acc_m_s2"] <= bar]
    assert (r["time_to_bar_s"] is None) == (not below)
    if below:
        assert r["time_to_bar_s"] == below[0]["train_s"] and below[0] == evals[-1]


@pytest.mark.rl
def test_bench_training_bad_input_is_one_line():
    for argv in (["--algos", "ppo", "a2c"], ["--budget-s", "0"], ["--hp", "n_steps"],
                 ["--compile", "on", "--algos", "sac"], ["--compile", "maybe"]):  # fmt: skip
        result = subprocess.run(
            [sys.executable, "benchmarks/bench_training.py", *argv], cwd=ROOT,
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert result.returncode == 2, argv
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
        assert argv[0] in result.stderr and result.stdout == "", (argv, result.stderr)


def test_soak_quick_runs_and_counts(tmp_path):
    out = tmp_path / "soak.json"
    run_script("benchmarks/soak.py", "--quick", "--json", str(out))
    data = json.loads(out.read_text())
    assert data["total"]["vehicle_steps"] == sum(r["vehicle_steps"] for r in data["configurations"])
    assert data["total"]["non_finite"] == 0 and data["total"]["out_of_space"] == 0
    assert len(data["configurations"]) == 6


@pytest.mark.rl
def test_bench_compile_times_both_and_checks_its_arithmetic(tmp_path):
    """bench_compile.py times an eager and a compiled PPO step; its speed-up and break-even
    are the quotients of its own figures (no speed asserted); bad input is one line."""
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    out = tmp_path / "compile.json"
    run_script("benchmarks/bench_compile.py", "--batch", "64", "--steps", "3", "--json", str(out))
    data = json.loads(out.read_text())
    eager, compiled = data["eager"], data["compiled"]
    assert eager["ms_per_step"] > 0 and compiled["ms_per_step"] > 0
    assert math.isclose(data["speed_up"], eager["ms_per_step"] / compiled["ms_per_step"])
    saved_s = (eager["ms_per_step"] - compiled["ms_per_step"]) / 1e3
    if saved_s > 0:
        expected = (compiled["first_call_s"] - eager["first_call_s"]) / saved_s
        assert math.isclose(data["break_even_steps"], expected)
    else:
        assert data["break_even_steps"] is None
    for argv in (["--steps", "0"], ["--batch", str(10**9)], ["--json", str(tmp_path)]):
        result = subprocess.run([sys.executable, "benchmarks/bench_compile.py", *argv], cwd=ROOT,
                                capture_output=True, text=True)  # fmt: skip
        assert result.returncode == 2
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr
        assert "bench_compile.py: error: --" in result.stderr


@pytest.mark.slow
def test_bench_half_car_quick_runs():
    """The half-car benchmark runs both envs (and the env's path before the lanes kernel) and
    both plants in both layouts, and reports the ratios."""
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    result = subprocess.run([sys.executable, "benchmarks/bench_half_car.py", "--quick",
                             "--num-envs", "64"], cwd=ROOT, env=env, capture_output=True,
                            text=True)  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.splitlines()
    last = next(i for i, line in enumerate(lines) if line.startswith("half-car / ride"))
    rates = {line[:32].strip(): float(line[32:]) for line in lines[2:last]}
    assert set(rates) == {"CapsuleRide-v0 env", "CapsuleHalfRide-v0 env",
                          "CapsuleHalfRide-v0 env, before", "declared plant, quarter_car",
                          "lanes plant, quarter_car", "declared plant, half_car",
                          "lanes plant, half_car"}  # fmt: skip
    ratio = float(lines[last].split(":")[1].split()[0])
    expected = rates["CapsuleHalfRide-v0 env"] / rates["CapsuleRide-v0 env"]
    assert abs(ratio - expected) <= 0.0005 + 1e-3 * expected  # printed to 3 decimals
    speedup = float(lines[last].split(":")[-1])
    expected = rates["CapsuleHalfRide-v0 env"] / rates["CapsuleHalfRide-v0 env, before"]
    assert abs(speedup - expected) <= 0.005 + 1e-3 * expected  # printed to 2 decimals
