"""The half-car's speed beside the quarter-car's, in one run (issue 42's bar: the half-car vector
env with 1024 vehicles at >= 0.4x ``CapsuleRide-v0``'s vehicle-steps per second).

    python benchmarks/bench_half_car.py            # prints the table
    python benchmarks/bench_half_car.py --quick    # short windows (a smoke test)

Measures, alternating windows of each (3 repeats, the median), zero actions:

1. ``CapsuleRide-v0`` and ``CapsuleHalfRide-v0`` native vector envs at N = 1024 (vehicle-steps
   per second, and their ratio);
2. the declared plant alone at N = 1024 (all cores): on the quarter-car's declaration (beside
   the first row: what the generic loops cost on the quarter-car's physics) and on the
   half-car.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import subprocess
import time
from typing import Any

import gymnasium as gym
import numpy as np

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env.plant.declared import declared_step_parallel


def _env_rate(env: Any, steps: int) -> float:
    actions = np.zeros(env.action_space.shape, dtype=np.float32)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(actions)
    return env.num_envs * steps / (time.perf_counter() - start)


def _plant_rate(batch: Any, steps: int) -> float:
    step = declared_step_parallel(batch.damper.code)
    start = time.perf_counter()
    for _ in range(steps):
        step(batch.num_envs, batch.plant, batch.state, batch.command, batch.route, batch.dt,
             batch.out)  # fmt: skip
    return batch.num_envs * steps / (time.perf_counter() - start)


def _median_windows(funcs: dict[str, Any], repeats: int) -> dict[str, float]:
    rates: dict[str, list[float]] = {name: [] for name in funcs}
    for _ in range(repeats):
        for name, f in funcs.items():  # alternating: the same machine state for each
            rates[name].append(f())
    return {name: statistics.median(r) for name, r in rates.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="short windows")
    p.add_argument("--num-envs", type=int, default=1024)
    args = p.parse_args()
    n, steps = args.num_envs, (20 if args.quick else 300)
    ride = gym.make_vec("CapsuleRide-v0", num_envs=n, vectorization_mode="vector_entry_point")
    half = gym.make_vec("CapsuleHalfRide-v0", num_envs=n, vectorization_mode="vector_entry_point")
    for env in (ride, half):
        env.reset(seed=0)
        _env_rate(env, 3)  # compile
    qd = _declared_batch(n)
    qd.reset()
    half_batch = half.unwrapped.batch
    _plant_rate(qd, 2), _plant_rate(half_batch, 2)
    rates = _median_windows({
        "CapsuleRide-v0 env": lambda: _env_rate(ride, steps),
        "CapsuleHalfRide-v0 env": lambda: _env_rate(half, steps // 4),
        "declared plant, quarter_car": lambda: _plant_rate(qd, steps // 2),
        "declared plant, half_car": lambda: _plant_rate(half_batch, steps // 4),
    }, 1 if args.quick else 3)  # fmt: skip
    cpu = _cpu()
    print(f"{time.strftime('%Y-%m-%d')}, {cpu}, {platform.python_version()}, N = {n}")
    print(f"{'what':32s} {'vehicle-steps/s':>16s}")
    for name, rate in rates.items():
        print(f"{name:32s} {rate:16.4g}")
    ratio = rates["CapsuleHalfRide-v0 env"] / rates["CapsuleRide-v0 env"]
    print(f"half-car / ride: {ratio:.3f} (bar: >= 0.4)")


def _declared_batch(n: int) -> Any:
    """The declared plant on the quarter-car's declaration, the ride task's hils damper."""
    from capsule_env.envs.declared_vector import DeclaredVectorEnv

    env = DeclaredVectorEnv(n, vehicle="quarter_car", setting="hils", observation="sensors")
    return env.batch


def _cpu() -> str:
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


if __name__ == "__main__":
    main()
