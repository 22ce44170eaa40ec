"""The native vector env's speed on each registered task, side by side in one run.

    python benchmarks/bench_tasks.py [--num-envs 1024] [--steps 400] [--repeats 5] [--json out.json]

For each task of :mod:`capsule_env.tasks` (``gymnasium.make_vec(id, num_envs,
vectorization_mode="vector_entry_point")``), random actions, autoreset on: vehicle-steps per
second of wall time and of process CPU time (``time.process_time``: what this process ran, not
what it waited for on a shared machine). The tasks are measured in turn within each repeat
(interleaved, so a change of the machine's load hits them alike); the median over repeats is
reported, with each task's ratio to the paper's task ``CapsuleSuspension-v0``. The kernels are
compiled (or loaded from numba's cache) and warmed before timing.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import gymnasium as gym
import numpy as np

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env.tasks import TASKS


def _time_task(env, actions: np.ndarray) -> tuple[float, float]:
    """Seconds of wall and CPU time for ``len(actions)`` vector steps."""
    wall, cpu = time.perf_counter(), time.process_time()
    for a in actions:
        env.step(a)
    return time.perf_counter() - wall, time.process_time() - cpu


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=1024, help="vehicles per vector env")
    parser.add_argument("--steps", type=int, default=400, help="vector steps per measurement")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved repeats")
    parser.add_argument("--json", help="also write the results to this JSON file")
    args = parser.parse_args(argv)
    if args.num_envs < 1 or args.steps < 1 or args.repeats < 1:
        parser.error("--num-envs, --steps and --repeats must be at least 1")
    rng = np.random.default_rng(0)
    envs, actions = {}, rng.uniform(-1, 1, (args.steps, args.num_envs, 1)).astype(np.float32)
    for task in TASKS:
        env = gym.make_vec(task.env_id, num_envs=args.num_envs,
                           vectorization_mode="vector_entry_point")  # fmt: skip
        env.reset(seed=0)
        _time_task(env, actions[: min(50, args.steps)])  # compile or load, warm the caches
        envs[task.env_id] = env
    wall: dict[str, list[float]] = {t: [] for t in envs}
    cpu: dict[str, list[float]] = {t: [] for t in envs}
    for _ in range(args.repeats):
        for task_id, env in envs.items():
            w, c = _time_task(env, actions)
            wall[task_id].append(args.steps * args.num_envs / w)
            cpu[task_id].append(args.steps * args.num_envs / c)
    paper = "CapsuleSuspension-v0"
    results = {
        "num_envs": args.num_envs, "steps": args.steps, "repeats": args.repeats,
        "machine": platform.processor() or platform.machine(), "cores": os.cpu_count(),
        "load_average": os.getloadavg(), "date": time.strftime("%Y-%m-%d"),
        "tasks": {t: {"wall_steps_per_s": statistics.median(wall[t]),
                      "cpu_steps_per_s": statistics.median(cpu[t]),
                      "wall_ratio_to_paper": statistics.median(wall[t]) / statistics.median(wall[paper]),
                      "cpu_ratio_to_paper": statistics.median(cpu[t]) / statistics.median(cpu[paper])}
                  for t in envs},
    }  # fmt: skip
    print(f"native vector env, N={args.num_envs}, median of {args.repeats} x {args.steps} steps "
          f"(load {results['load_average'][0]:.1f})")  # fmt: skip
    print(f"{'task':26s} {'wall steps/s':>14s} {'ratio':>6s} {'CPU steps/s':>14s} {'ratio':>6s}")
    for t, r in results["tasks"].items():
        print(f"{t:26s} {r['wall_steps_per_s']:14,.0f} {r['wall_ratio_to_paper']:6.2f} "
              f"{r['cpu_steps_per_s']:14,.0f} {r['cpu_ratio_to_paper']:6.2f}")  # fmt: skip
    if args.json:
        from capsule_env.common.safe_io import atomic_write_text

        atomic_write_text(args.json, json.dumps(results, indent=1))
    for env in envs.values():
        env.close()
    return results


if __name__ == "__main__":
    main()
