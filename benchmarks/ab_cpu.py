"""CPU time per env step of two checkouts, interleaved: a speed check for a refactoring on a
shared machine, where wall-clock rates move with the other users' load.

    python benchmarks/ab_cpu.py /path/to/checkout_a /path/to/checkout_b --repeats 5

Each repeat runs, for each checkout in turn, a fresh interpreter (``PYTHONPATH`` the checkout,
its own ``NUMBA_CACHE_DIR``, one thread) that steps the single env (``sim``, ``hils``) and the
native vector env at N = 63 (the serial block kernel) and N = 1024 (one thread), and reports
the process CPU time per env-step (``time.process_time``: the time this process ran, not the
time it waited for a core). Prints the median over repeats of each and the ratio b / a.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

CHILD = r"""
import json, sys, time
import numpy as np
import gymnasium as gym
import capsule_env
from capsule_env.envs import CapsuleSuspensionVectorEnv
out = {}
for setting in ("sim", "hils"):
    env = gym.make("CapsuleSuspension-v0", setting=setting)
    env.reset(seed=0)
    acts = np.random.default_rng(0).uniform(-1, 1, (4000, 1))
    for a in acts[:200]:
        env.step(a)
    t0 = time.process_time()
    for a in acts:
        _, _, te, tr, _ = env.step(a)
        if te or tr:
            env.reset()
    out[f"single-{setting}"] = (time.process_time() - t0) / len(acts) * 1e6
    for n, steps in ((63, 300), (1024, 40)):
        vec = CapsuleSuspensionVectorEnv(num_envs=n, setting=setting)
        vec.reset(seed=0)
        acts = np.random.default_rng(0).uniform(-1, 1, (steps, n, 1))
        for a in acts[:5]:
            vec.step(a)
        t0 = time.process_time()
        for a in acts:
            vec.step(a)
        out[f"vector-{setting}/N={n}"] = (time.process_time() - t0) / (steps * n) * 1e6
print(json.dumps(out))
"""


def run(checkout: str, cache: str) -> dict[str, float]:
    env = {**os.environ, "PYTHONPATH": checkout, "NUMBA_CACHE_DIR": cache, "NUMBA_NUM_THREADS": "1",
           "OMP_NUM_THREADS": "1"}  # fmt: skip
    done = subprocess.run([sys.executable, "-c", CHILD], env=env, cwd=checkout, check=True,
                          capture_output=True, text=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("a")
    parser.add_argument("b")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    caches = {k: tempfile.mkdtemp(prefix=f"ab_cpu_{k}_") for k in "ab"}
    for k in "ab":  # compile once, untimed
        run(getattr(args, k), caches[k])
    results: dict[str, list[dict[str, float]]] = {"a": [], "b": []}
    for _ in range(args.repeats):
        for k in "ab":
            results[k].append(run(getattr(args, k), caches[k]))
    print(
        f"{'us CPU per env-step':24s} {'a':>9s} {'b':>9s} {'b/a':>6s}  (median of {args.repeats})"
    )
    for key in results["a"][0]:
        a = statistics.median(r[key] for r in results["a"])
        b = statistics.median(r[key] for r in results["b"])
        print(f"{key:24s} {a:9.3f} {b:9.3f} {b / a:6.3f}")


if __name__ == "__main__":
    main()
